/*
 * The two-bus mode of fc_firmware (command line buses=2; twobus.c): a
 * master and a gateway client on UART0 and on UART1, both driving ESCs.
 */
#ifndef FC_TWOBUS_H
#define FC_TWOBUS_H

/* Runs the two buses until 'q' on UART2 or seconds=N; the exit code. */
int twobus_main(const char *cmdline);

#endif /* FC_TWOBUS_H */
