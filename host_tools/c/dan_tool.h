/*
 * dan_tool: the chores the C tools and the gateway daemon share, in one
 * place as can-utils keeps them in its lib.c: a stop flag that signal
 * handlers set, waiting for file descriptors until a deadline on the
 * port's monotonic microsecond clock (dan_posix_now_us), error messages
 * with the program's name, JSON strings and strict number parsing.
 * Built into build/libdan_tool.a.
 */
#ifndef DAN_TOOL_H
#define DAN_TOOL_H

#include <poll.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "dan/types.h"

/* The program's name, the prefix of tool_error() lines; main sets it. */
extern const char *tool_prog;

/* Set by the handler tool_catch_signal() installs; loops test it. */
extern volatile sig_atomic_t tool_stop;

/* sig only sets tool_stop. No SA_RESTART: a blocking poll() returns early
 * with EINTR, so the loop sees the flag at once. */
void tool_catch_signal(int sig);

/* "PROG: message\n" on stderr. */
void tool_error(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
void tool_verror(const char *fmt, va_list ap) __attribute__((format(printf, 1, 0)));

/* poll()'s timeout from now_us until deadline_us: 0 when due, else rounded
 * up (never wakes before the deadline) and at most cap_ms. */
int tool_ms_until(uint64_t deadline_us, uint64_t now_us, int cap_ms);

/* poll() on one fd for events until deadline_us (UINT64_MAX: none), for at
 * most cap_ms; poll()'s result. To the microsecond (ppoll): at 1-2 Mbit/s
 * a turnaround is 10-20 us, and a timeout rounded up to whole ms would
 * add up to 1 ms to every reply. */
int tool_wait_fd(int fd, short events, uint64_t deadline_us, int cap_ms);
/* The same for n fds. */
int tool_poll_until(struct pollfd *p, nfds_t n, uint64_t deadline_us, int cap_ms);
/* Timer slack 1 us (PR_SET_TIMERSLACK; default 50 us): a process that
 * answers on a fast wire wakes when its deadline is due. */
void tool_fine_timers(void);

/* s as a JSON string on f, escaped as libdan's dan_json_str() does. */
void tool_json_str(FILE *f, const char *s);

/* All of s is one number in base (0: decimal, or hex after 0x; a leading
 * 0 is not octal: "0500" is 500) from lo to hi: 0 with *out set, else -1
 * (empty, a sign or white space, trailing characters, out of range). */
int tool_parse_ulong(const char *s, int base, unsigned long lo, unsigned long hi,
                     unsigned long *out);
/* The same in base 0 for a uint32_t. */
int tool_parse_u32(const char *s, uint32_t lo, uint32_t hi, uint32_t *out);

/* A comma-separated list of type names or first codes (dan_type_lookup)
 * into out[0..cap): 0 with *n set, or -1 with the first unknown name (or
 * the one past cap) copied to bad. */
int tool_parse_types(const char *list, const dan_type_info_t **out, size_t cap, size_t *n,
                     char *bad, size_t badlen);

#endif /* DAN_TOOL_H */
