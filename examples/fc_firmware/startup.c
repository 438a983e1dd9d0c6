/*
 * Vector table and reset handler for a Cortex-M4 (mps2-an386). The reset
 * handler copies .data from flash, zeroes .bss and calls main(). Unused
 * interrupts and faults end the run through semihosting with exit code 3,
 * so a crashed firmware fails its test instead of hanging.
 */
#include <stdint.h>
#include <string.h>

#include "board.h"

extern uint32_t _estack, _sidata, _sdata, _edata, _sbss, _ebss; /* fc_firmware.ld */

int main(void);
void Reset_Handler(void);
void Default_Handler(void);
void HardFault_Handler(void);
void SysTick_Handler(void);
void UART0RX_Handler(void);
void UART1RX_Handler(void);

void Reset_Handler(void)
{
    memcpy(&_sdata, &_sidata, (size_t)((uintptr_t)&_edata - (uintptr_t)&_sdata));
    memset(&_sbss, 0, (size_t)((uintptr_t)&_ebss - (uintptr_t)&_sbss));
    sh_exit(main());
}

void HardFault_Handler(void)
{
    sh_puts("{\"event\":\"hardfault\"}\n");
    sh_exit(3);
}

void Default_Handler(void)
{
    sh_puts("{\"event\":\"unexpected interrupt\"}\n");
    sh_exit(3);
}

#define NUM_IRQS 32u /* AN386 uses IRQ 0..31 for its peripherals */

typedef void (*vector_t)(void);

/* The initial stack pointer is an address stored as the first vector. */
__attribute__((section(".isr_vector"), used)) const vector_t vector_table[16u + NUM_IRQS] = {
    (vector_t)(uintptr_t)&_estack,
    Reset_Handler,
    Default_Handler, /* NMI */
    HardFault_Handler,
    HardFault_Handler, /* MemManage (escalates to HardFault when disabled) */
    HardFault_Handler, /* BusFault */
    HardFault_Handler, /* UsageFault */
    0,
    0,
    0,
    0,
    Default_Handler, /* SVCall */
    Default_Handler, /* DebugMonitor */
    0,
    Default_Handler, /* PendSV */
    SysTick_Handler,
    UART0RX_Handler, /* IRQ 0: UART0 RX */
    Default_Handler,
    UART1RX_Handler, /* IRQ 2: UART1 RX */
    Default_Handler,
    Default_Handler, /* 1..4 */
    Default_Handler,
    Default_Handler,
    Default_Handler,
    Default_Handler, /* 5..8 */
    Default_Handler,
    Default_Handler,
    Default_Handler,
    Default_Handler, /* 9..12 */
    Default_Handler,
    Default_Handler,
    Default_Handler,
    Default_Handler, /* 13..16 */
    Default_Handler,
    Default_Handler,
    Default_Handler,
    Default_Handler, /* 17..20 */
    Default_Handler,
    Default_Handler,
    Default_Handler,
    Default_Handler, /* 21..24 */
    Default_Handler,
    Default_Handler,
    Default_Handler,
    Default_Handler, /* 25..28 */
    Default_Handler,
    Default_Handler,
    Default_Handler, /* 29..31 */
};
