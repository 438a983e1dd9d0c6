/*
 * Board support: SysTick clock, CMSDK APB UART0 and UART1 with RX
 * interrupts, UART2 polled, semihosting. Register facts, not code, from: the ARMv7-M Architecture
 * Reference Manual (SysTick, NVIC, SCB), the Cortex-M System Design Kit
 * TRM ARM DDI0479 (APB UART), ARM AN385/AN386 (memory map, interrupt
 * numbers), the ARM semihosting specification v2 (operation numbers), and
 * QEMU's behaviour as measured here (README.md, "QEMU facts").
 */
#include "board.h"

#define REG32(addr) (*(volatile uint32_t *)(uintptr_t)(addr))

/* SysTick (ARMv7-M ARM, B3.3) */
#define SYST_CSR           REG32(0xE000E010u)
#define SYST_RVR           REG32(0xE000E014u)
#define SYST_CVR           REG32(0xE000E018u)
#define SYST_CSR_ENABLE    0x1u
#define SYST_CSR_TICKINT   0x2u
#define SYST_CSR_CLKSOURCE 0x4u /* processor clock */

/* NVIC (ARMv7-M ARM, B3.4) */
#define NVIC_ISER0       REG32(0xE000E100u)
#define NVIC_IPR_BYTE(n) (*(volatile uint8_t *)(uintptr_t)(0xE000E400u + (n)))

/* CMSDK APB UART (DDI0479, 4.3); AN386: UART0 at 0x40004000 (RX IRQ 0),
 * UART1 at 0x40005000 (RX IRQ 2), UART2 at 0x40006000 (RX IRQ 4). QEMU
 * gives UART k the k-th -serial option's chardev. */
#define UART2_BASE        0x40006000u
#define UART_DATA(b)      REG32((b) + 0x00u)
#define UART_STATE(b)     REG32((b) + 0x04u)
#define UART_CTRL(b)      REG32((b) + 0x08u)
#define UART_INT(b)       REG32((b) + 0x0Cu) /* read: INTSTATUS, write 1: INTCLEAR */
#define UART_BAUDDIV(b)   REG32((b) + 0x10u)
#define UART_STATE_TXFULL 0x1u
#define UART_STATE_RXFULL 0x2u
#define UART_STATE_RXOVR  0x8u
#define UART_CTRL_TXEN    0x1u
#define UART_CTRL_RXEN    0x2u
#define UART_CTRL_RXINTEN 0x8u
#define UART_INT_RX       0x2u

#define TICK_HZ       1000u
#define TICK_RELOAD   (BOARD_CPU_HZ / TICK_HZ - 1u)
#define CYCLES_PER_US (BOARD_CPU_HZ / 1000000u)

/* ---- clock ---- */

static volatile uint32_t tick_ms; /* written by SysTick_Handler only */

void SysTick_Handler(void);
void SysTick_Handler(void)
{
    tick_ms = tick_ms + 1u;
}

void clock_init(void)
{
    SYST_RVR = TICK_RELOAD;
    SYST_CVR = 0;
    SYST_CSR = SYST_CSR_CLKSOURCE | SYST_CSR_TICKINT | SYST_CSR_ENABLE;
}

uint64_t clock_now_us(void)
{
    /* Extends the 32-bit ms count to 64 bits (it is read far more often
     * than every 49 days) and never goes backwards: a counter that wrapped
     * just before its interrupt ran reads as a whole tick too early (QEMU
     * raises the interrupt a little after the wrap), so such a reading is
     * clamped to the last value returned. */
    static uint32_t last_ms, epoch;
    static uint64_t last_us;
    uint32_t ms, ms2, val;
    uint64_t us;
    do {
        ms = tick_ms;
        val = SYST_CVR;
        ms2 = tick_ms;
    } while (ms != ms2);
    if (ms < last_ms) {
        epoch++;
    }
    last_ms = ms;
    us = ((((uint64_t)epoch << 32) | ms) * 1000u) +
         (TICK_RELOAD - (val & 0xFFFFFFu)) / CYCLES_PER_US;
    if (us < last_us) {
        us = last_us;
    }
    last_us = us;
    return us;
}

/* ---- UART0, UART1 ---- */

static const uint32_t uart_base[BOARD_UARTS] = {0x40004000u, 0x40005000u};
static const uint8_t uart_rx_irq[BOARD_UARTS] = {0u, 2u};
static unsigned uart_index[BOARD_UARTS] = {0u, 1u}; /* the ports' ctx */

dan_rxring_t uart_rx[BOARD_UARTS];
volatile uart_stats_t uart_stats[BOARD_UARTS];

/* The interrupt is the ring's only producer. */
static void uart_rx_isr(unsigned k)
{
    uint32_t base = uart_base[k];
    uart_stats[k].rx_irqs = uart_stats[k].rx_irqs + 1u;
    while ((UART_STATE(base) & UART_STATE_RXFULL) != 0u) {
        uint8_t b;
        /* Clear the flag before reading the data register: the read lets
         * the next byte in, whose flag would otherwise be cleared too. */
        UART_INT(base) = UART_INT_RX;
        b = (uint8_t)UART_DATA(base);
        (void)dan_rxring_put(&uart_rx[k], b); /* full: counted in the ring */
    }
    if ((UART_STATE(base) & UART_STATE_RXOVR) != 0u) {
        UART_STATE(base) = UART_STATE_RXOVR; /* write 1 to clear */
        uart_stats[k].rx_overruns = uart_stats[k].rx_overruns + 1u;
    }
}

void UART0RX_Handler(void);
void UART0RX_Handler(void)
{
    uart_rx_isr(0u);
}

void UART1RX_Handler(void);
void UART1RX_Handler(void)
{
    uart_rx_isr(1u);
}

static uint32_t divisor_of(uint32_t baud)
{
    return (BOARD_CPU_HZ + baud / 2u) / baud;
}

static int port_write(void *ctx, const uint8_t *data, size_t len)
{
    unsigned k = *(const unsigned *)ctx;
    size_t i;
    /* Polled: the CMSDK UART holds one byte, so on hardware this waits for
     * the frame to leave (len * C; 15 ms for 170 bytes at 115200). QEMU
     * sends at once. A TX interrupt with a second ring removes the wait. */
    for (i = 0; i < len; i++) {
        while ((UART_STATE(uart_base[k]) & UART_STATE_TXFULL) != 0u) {
        }
        UART_DATA(uart_base[k]) = data[i];
    }
    uart_stats[k].tx_bytes = uart_stats[k].tx_bytes + (uint32_t)len;
    return (int)len;
}

static int port_set_baud(void *ctx, uint32_t baud)
{
    unsigned k = *(const unsigned *)ctx;
    uint32_t div;
    if (baud == 0u) {
        return DAN_ERR_ARG;
    }
    div = divisor_of(baud);
    if (div < BOARD_UART_MIN_DIV || div > 0xFFFFFu) {
        return DAN_ERR_UNSUPPORTED;
    }
    /* The master switches only after its last frame was echoed, so no byte
     * of ours is in the UART now. */
    UART_BAUDDIV(uart_base[k]) = div;
    uart_stats[k].baud_changes = uart_stats[k].baud_changes + 1u;
    return DAN_OK;
}

static const dan_port_t ports[BOARD_UARTS] = {
    /* max baud: divisor 16; one wire: we hear our bytes */
    {port_write, port_set_baud, NULL, NULL, NULL, &uart_index[0], BOARD_CPU_HZ / BOARD_UART_MIN_DIV,
     true},
    {port_write, port_set_baud, NULL, NULL, NULL, &uart_index[1], BOARD_CPU_HZ / BOARD_UART_MIN_DIV,
     true},
};

void uart_init(unsigned k, uint32_t baud)
{
    uint32_t base = uart_base[k];
    dan_rxring_init(&uart_rx[k]);
    UART_CTRL(base) = 0;
    /* The divisor must be >= 16 before TX is enabled. */
    UART_BAUDDIV(base) = divisor_of(baud);
    UART_INT(base) = 0xFu;
    UART_CTRL(base) = UART_CTRL_TXEN | UART_CTRL_RXEN | UART_CTRL_RXINTEN;
    NVIC_IPR_BYTE(uart_rx_irq[k]) = 0x40u;
    NVIC_ISER0 = 1u << uart_rx_irq[k];
}

const dan_port_t *uart_port(unsigned k)
{
    return &ports[k];
}

/* ---- UART2: the control line ---- */

void ctl_init(void)
{
    UART_CTRL(UART2_BASE) = 0;
    UART_BAUDDIV(UART2_BASE) = divisor_of(115200u);
    UART_CTRL(UART2_BASE) = UART_CTRL_RXEN; /* polled: no interrupt */
}

int ctl_getc(void)
{
    if ((UART_STATE(UART2_BASE) & UART_STATE_RXFULL) == 0u) {
        return -1;
    }
    return (int)(UART_DATA(UART2_BASE) & 0xFFu);
}

/* The divisor (25 MHz / BAUDDIV, BAUDDIV >= 16, so at most 1562500) gives
 * 230400 as 229357, 460800 as 462962, 921600 as 925925, 1000000 exactly,
 * 1500000 as 1470588 (2 % slow); 2000000 is out of reach. Under QEMU the
 * UART is a host tty: QEMU's tty backend picks a termios speed for the
 * rate it is given, and dan-vbus measured what arrives at the pty:
 * 230400, 460800, 921600 and 1500000 arrive as such, but 1000000 arrives
 * as 921600 (7.8 % off: every peer at 1000000 hears garbage). So this
 * board offers these four; on silicon 1000000 would be exact and 1500000
 * marginal. */
static const uint32_t fast_bauds[] = {230400u, 460800u, 921600u, 1500000u};

const uint32_t *board_fast_bauds(size_t *n)
{
    *n = sizeof fast_bauds / sizeof fast_bauds[0];
    return fast_bauds;
}

uint32_t uart_actual_baud(unsigned k)
{
    uint32_t div = UART_BAUDDIV(uart_base[k]);
    return div != 0u ? BOARD_CPU_HZ / div : 0u;
}

void board_idle(void)
{
    /* With interrupts masked, WFI still wakes on a pending interrupt, so a
     * byte that arrives between the check and the WFI is not slept over. */
    unsigned k;
    size_t waiting = 0;
    __asm__ volatile("cpsid i" ::: "memory");
    for (k = 0; k < BOARD_UARTS; k++) {
        waiting += dan_rxring_count(&uart_rx[k]);
    }
    if (waiting == 0u) {
        __asm__ volatile("dsb\n\twfi" ::: "memory");
    }
    __asm__ volatile("cpsie i" ::: "memory");
}

/* ---- semihosting ---- */

#define SH_SYS_WRITE0                   0x04u
#define SH_SYS_GET_CMDLINE              0x15u
#define SH_SYS_EXIT_EXTENDED            0x20u
#define SH_ADP_STOPPED_APPLICATION_EXIT 0x20026u

static uint32_t sh_call(uint32_t op, const void *arg)
{
    register uint32_t r0 __asm__("r0") = op;
    register const void *r1 __asm__("r1") = arg;
    __asm__ volatile("bkpt 0xAB" : "+r"(r0) : "r"(r1) : "memory");
    return r0;
}

void sh_puts(const char *s)
{
    (void)sh_call(SH_SYS_WRITE0, s);
}

void sh_exit(int code)
{
    uint32_t block[2];
    block[0] = SH_ADP_STOPPED_APPLICATION_EXIT;
    block[1] = (uint32_t)code;
    (void)sh_call(SH_SYS_EXIT_EXTENDED, block);
    for (;;) {
        __asm__ volatile("bkpt 0"); /* no debugger: stops here */
    }
}

void sh_cmdline(char *buf, size_t cap)
{
    uint32_t block[2];
    if (cap == 0u) {
        return;
    }
    buf[0] = '\0';
    block[0] = (uint32_t)(uintptr_t)buf;
    block[1] = (uint32_t)cap;
    if (sh_call(SH_SYS_GET_CMDLINE, block) != 0u) {
        buf[0] = '\0';
    }
    buf[cap - 1u] = '\0';
}
