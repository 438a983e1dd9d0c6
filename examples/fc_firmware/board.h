/*
 * Board support for the fc_firmware example on QEMU's mps2-an386
 * (Cortex-M4, CMSDK APB UART, 25 MHz system and UART clock): a monotonic
 * microsecond clock from SysTick, UART0 and UART1 (the DAN buses) with RX
 * interrupts feeding a dan_rxring_t each, UART2 as a polled control input,
 * and ARM semihosting for console output and the exit code.
 *
 * No vendor HAL: the few registers are defined in board.c, with sources.
 */
#ifndef FC_BOARD_H
#define FC_BOARD_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "dan/link.h"
#include "dan/rxring.h"

#define BOARD_CPU_HZ       25000000u /* mps2-an386 SYSCLK (and UART PCLK) */
#define BOARD_UART_MIN_DIV 16u       /* CMSDK UART: BAUDDIV >= 16 */
/* The fast bauds (docs/PROTOCOL.md section 6) this board's UART can do,
 * ascending (board.c says which and why); n gets the count. */
const uint32_t *board_fast_bauds(size_t *n);

/* ---- clock ---- */
void clock_init(void);
/* Monotonic microseconds since clock_init(): the 1 kHz SysTick count plus
 * the elapsed part of the current tick (1 us resolution). Main loop only. */
uint64_t clock_now_us(void);

/* ---- UART0 and UART1: the DAN buses ---- */
#define BOARD_UARTS 2u /* UART0 (bus 0) and UART1 (bus 1, buses=2) */

typedef struct {
    uint32_t rx_overruns; /* the UART lost bytes (RX overrun flag) */
    uint32_t rx_irqs;
    uint32_t tx_bytes;
    uint32_t baud_changes;
} uart_stats_t;

extern dan_rxring_t uart_rx[BOARD_UARTS]; /* filled by the RX interrupts */
extern volatile uart_stats_t uart_stats[BOARD_UARTS];

/* Sets UART k's baud, enables TX and RX and the RX interrupt. */
void uart_init(unsigned k, uint32_t baud);
/* The dan_port_t of UART k (single wire: echo = true). */
const dan_port_t *uart_port(unsigned k);
/* Baud actually programmed: 25 MHz / BAUDDIV. */
uint32_t uart_actual_baud(unsigned k);

/* ---- UART2: a control line from the host (RX only, polled) ---- */
void ctl_init(void);
/* The next byte the host sent, or -1. */
int ctl_getc(void);

/* ---- sleep ---- */
/* Sleeps until an interrupt (SysTick every 1 ms, or a received byte) unless
 * a byte is already waiting in a bus's ring. */
void board_idle(void);

/* ---- semihosting (QEMU -semihosting-config enable=on,target=native) ---- */
void sh_puts(const char *s);                      /* SYS_WRITE0 */
void sh_exit(int code) __attribute__((noreturn)); /* SYS_EXIT_EXTENDED */
/* The command line (SYS_GET_CMDLINE): QEMU's -append text, or the
 * semihosting-config arg= words. Empty on failure. */
void sh_cmdline(char *buf, size_t cap);

#endif /* FC_BOARD_H */
