/* Chores shared by the C tools and the gateway daemon (see dan_tool.h). */
#include "dan_tool.h"

#include <ctype.h>
#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <time.h>

#include "dan/identity_json.h"
#include "dan/posix.h"

const char *tool_prog = "dan";
volatile sig_atomic_t tool_stop;

static void on_signal(int sig)
{
    (void)sig;
    tool_stop = 1;
}

void tool_catch_signal(int sig)
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sigaction(sig, &sa, NULL);
}

void tool_verror(const char *fmt, va_list ap)
{
    fprintf(stderr, "%s: ", tool_prog);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
}

void tool_error(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    tool_verror(fmt, ap);
    va_end(ap);
}

int tool_ms_until(uint64_t deadline_us, uint64_t now_us, int cap_ms)
{
    uint64_t ms;
    if (deadline_us <= now_us) {
        return 0;
    }
    ms = (deadline_us - now_us + 999u) / 1000u;
    return ms > (uint64_t)cap_ms ? cap_ms : (int)ms;
}

int tool_poll_until(struct pollfd *p, nfds_t n, uint64_t deadline_us, int cap_ms)
{
    struct timespec ts;
    uint64_t now = dan_posix_now_us();
    uint64_t us = (deadline_us > now) ? deadline_us - now : 0u;
    uint64_t cap = (uint64_t)(cap_ms > 0 ? cap_ms : 0) * 1000u;
    if (us > cap) {
        us = cap;
    }
    ts.tv_sec = (time_t)(us / 1000000u);
    ts.tv_nsec = (long)(us % 1000000u) * 1000L;
    return ppoll(p, n, &ts, NULL);
}

int tool_wait_fd(int fd, short events, uint64_t deadline_us, int cap_ms)
{
    struct pollfd p;
    p.fd = fd;
    p.events = events;
    p.revents = 0;
    return tool_poll_until(&p, 1, deadline_us, cap_ms);
}

void tool_fine_timers(void)
{
    (void)prctl(PR_SET_TIMERSLACK, 1000UL, 0UL, 0UL, 0UL);
}

void tool_json_str(FILE *f, const char *s)
{
    /* Room for 255 bytes escaped at 6 each and the quotes: more than any
     * name or message the tools print. */
    char buf[6u * 255u + 3u];
    dan_json_str(buf, sizeof buf, s);
    fputs(buf, f);
}

int tool_parse_ulong(const char *s, int base, unsigned long lo, unsigned long hi,
                     unsigned long *out)
{
    char *end;
    unsigned long v;
    if (base == 0 && s[0] == '0' && (s[1] == 'x' || s[1] == 'X')) {
        s += 2; /* hex; any other leading 0 is decimal, not C's octal */
        base = 16;
    } else if (base == 0) {
        base = 10;
    }
    if (!isxdigit((unsigned char)s[0])) {
        return -1; /* strtoul would take a sign or white space: -1 is ULONG_MAX */
    }
    errno = 0;
    v = strtoul(s, &end, base);
    if (errno != 0 || end == s || *end != '\0' || v < lo || v > hi) {
        return -1;
    }
    *out = v;
    return 0;
}

int tool_parse_u32(const char *s, uint32_t lo, uint32_t hi, uint32_t *out)
{
    unsigned long v;
    if (tool_parse_ulong(s, 0, lo, hi, &v) != 0) {
        return -1;
    }
    *out = (uint32_t)v;
    return 0;
}

int tool_parse_types(const char *list, const dan_type_info_t **out, size_t cap, size_t *n,
                     char *bad, size_t badlen)
{
    char buf[128]; /* longer lists are cut here, as the tools always did */
    char *save = NULL, *tok;
    snprintf(buf, sizeof buf, "%s", list);
    *n = 0;
    for (tok = strtok_r(buf, ",", &save); tok != NULL; tok = strtok_r(NULL, ",", &save)) {
        const dan_type_info_t *t = dan_type_lookup(tok);
        if (t == NULL || *n >= cap) {
            snprintf(bad, badlen, "%s", tok);
            return -1;
        }
        out[(*n)++] = t;
    }
    return 0;
}
