/* systemd notifications on the plain socket protocol (sd_notify.h). */
#include "sd_notify.h"

#include <errno.h>
#include <fcntl.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include "dan_tool.h"

/* WATCHDOG_USEC, if it is meant for this process (WATCHDOG_PID unset or
 * ours); 0 otherwise. */
static uint64_t watchdog_usec(void)
{
    const char *pid = getenv("WATCHDOG_PID");
    const char *usec = getenv("WATCHDOG_USEC");
    unsigned long v;
    if (usec == NULL) {
        return 0;
    }
    if (pid != NULL &&
        (tool_parse_ulong(pid, 10, 1, 0x7FFFFFFFul, &v) != 0 || (pid_t)v != getpid())) {
        return 0;
    }
    if (tool_parse_ulong(usec, 10, 1, 0xFFFFFFFFul, &v) != 0) {
        return 0;
    }
    return (uint64_t)v;
}

int dan_sd_open(dan_sd_t *s, uint64_t now_us)
{
    const char *path = getenv("NOTIFY_SOCKET");
    struct sockaddr_un sa;
    size_t len;
    memset(s, 0, sizeof *s);
    s->fd = -1;
    if (path == NULL || path[0] == '\0') {
        return 0;
    }
    len = strlen(path);
    if ((path[0] != '/' && path[0] != '@') || len >= sizeof sa.sun_path) {
        errno = EINVAL;
        return -1;
    }
    memset(&sa, 0, sizeof sa);
    sa.sun_family = AF_UNIX;
    memcpy(sa.sun_path, path, len);
    if (path[0] == '@') {
        sa.sun_path[0] = '\0'; /* abstract namespace */
    }
    s->fd = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
    if (s->fd < 0) {
        return -1;
    }
    /* connect() once: every send goes there, and the path is not looked
     * up again after a chroot or a change of the daemon's privileges. */
    if (connect(s->fd, (struct sockaddr *)&sa,
                (socklen_t)(offsetof(struct sockaddr_un, sun_path) + len)) != 0) {
        int e = errno;
        close(s->fd);
        s->fd = -1;
        errno = e;
        return -1;
    }
    s->period_us = watchdog_usec() / 2u;
    s->due_us = now_us;
    return 0;
}

int dan_sd_send(dan_sd_t *s, const char *msg)
{
    if (s->fd < 0) {
        return 0;
    }
    if (send(s->fd, msg, strlen(msg), MSG_NOSIGNAL) < 0) {
        s->send_errors++;
        return -1;
    }
    s->sent++;
    return 0;
}

void dan_sd_poll(dan_sd_t *s, uint64_t now_us)
{
    if (s->fd >= 0 && s->period_us && now_us >= s->due_us) {
        (void)dan_sd_send(s, "WATCHDOG=1");
        s->due_us = now_us + s->period_us;
    }
}

uint64_t dan_sd_next_us(const dan_sd_t *s)
{
    return s->fd >= 0 && s->period_us ? s->due_us : UINT64_MAX;
}

void dan_sd_close(dan_sd_t *s)
{
    if (s->fd >= 0) {
        close(s->fd);
        s->fd = -1;
    }
}
