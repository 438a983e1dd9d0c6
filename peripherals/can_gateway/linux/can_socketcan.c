/*
 * SocketCAN backend: a CAN_RAW socket bound to one interface.
 *
 * Kernels or containers without AF_CAN fail in socket() with
 * EAFNOSUPPORT; dan_canif_open() then reports that clearly.
 */
#include "can_backend.h"

#include <errno.h>
#include <fcntl.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <stdio.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

/* Reads per recv call at most (bad frames are skipped), so a flood of
 * them cannot keep the caller's loop here. */
#define READS_PER_CALL 8

#ifndef PF_CAN
#define PF_CAN 29
#endif

/* Closes what open got so far and reports why. */
static int fail(dan_canif_t *c, char *err, size_t errlen, int code, const char *ifname,
                const char *what, int errnum)
{
    if (c->fd >= 0) {
        close(c->fd);
    }
    c->fd = -1;
    c->kind = DAN_CANIF_NONE;
    return dan_canif_errf(err, errlen, code, "socketcan", ifname, what, errnum);
}

int dan_canif_socketcan_open(dan_canif_t *c, const char *ifname, char *err, size_t errlen)
{
    struct ifreq ifr;
    int ifindex;
    struct sockaddr_can addr;
    can_err_mask_t errmask = CAN_ERR_MASK;
    int fd, fl;

    c->fd = -1;
    if (strlen(ifname) >= IFNAMSIZ) {
        return fail(c, err, errlen, DAN_ERR_ARG, ifname, "interface name too long", 0);
    }
    fd = socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW);
    if (fd < 0) {
        int e = errno;
        return fail(c, err, errlen,
                    (e == EAFNOSUPPORT || e == EPROTONOSUPPORT) ? DAN_ERR_UNSUPPORTED : DAN_ERR_IO,
                    ifname,
                    (e == EAFNOSUPPORT || e == EPROTONOSUPPORT)
                        ? "SocketCAN (AF_CAN) not available on this system "
                          "(modprobe can can_raw; or use slcan:)"
                        : "socket(PF_CAN, SOCK_RAW, CAN_RAW)",
                    e);
    }
    c->fd = fd;
    c->kind = DAN_CANIF_SOCKETCAN;
    snprintf(c->name, sizeof c->name, "%s", ifname);

    memset(&ifr, 0, sizeof ifr);
    memcpy(ifr.ifr_name, ifname, strlen(ifname) + 1);
    if (ioctl(fd, SIOCGIFINDEX, &ifr) < 0) {
        int e = errno;
        return fail(c, err, errlen, e == ENODEV ? DAN_ERR_NOTFOUND : DAN_ERR_IO, ifname,
                    "no such CAN interface (SIOCGIFINDEX)", e);
    }
    ifindex = ifr.ifr_ifindex; /* ifr is a union: SIOCGIFFLAGS overwrites it */
    /* bind() takes an interface that is down, and every write then fails
     * (ENETDOWN): lost, reopened, lost again each second. Down is "not yet". */
    if (ioctl(fd, SIOCGIFFLAGS, &ifr) < 0 || (ifr.ifr_flags & IFF_UP) == 0) {
        return fail(c, err, errlen, DAN_ERR_NOTFOUND, ifname,
                    "CAN interface is down (ip link set IF up)", ENETDOWN);
    }
    memset(&addr, 0, sizeof addr);
    addr.can_family = AF_CAN;
    addr.can_ifindex = ifindex;
    if (bind(fd, (struct sockaddr *)&addr, sizeof addr) < 0) {
        int e = errno;
        return fail(c, err, errlen, DAN_ERR_IO, ifname, "bind", e);
    }
    /* Deliver controller error frames (bus-off, error passive, ...). */
    if (setsockopt(fd, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &errmask, sizeof errmask) < 0) {
        int e = errno;
        return fail(c, err, errlen, DAN_ERR_IO, ifname, "setsockopt(CAN_RAW_ERR_FILTER)", e);
    }
    fl = fcntl(fd, F_GETFL);
    if (fl < 0 || fcntl(fd, F_SETFL, fl | O_NONBLOCK) < 0) {
        int e = errno;
        return fail(c, err, errlen, DAN_ERR_IO, ifname, "O_NONBLOCK", e);
    }
    return 0;
}

int dan_canif_socketcan_send(dan_canif_t *c, const dan_can_frame_t *f)
{
    struct can_frame cf;
    ssize_t w;
    int ext = (f->flags & DAN_CAN_EXT) != 0;

    if ((f->flags & DAN_CAN_ERR) || f->dlc > 8 ||
        f->id > (ext ? DAN_CAN_EFF_MASK : DAN_CAN_SFF_MASK)) {
        return DAN_ERR_ARG;
    }
    memset(&cf, 0, sizeof cf);
    cf.can_id = f->id;
    if (ext) {
        cf.can_id |= CAN_EFF_FLAG;
    }
    if (f->flags & DAN_CAN_RTR) {
        cf.can_id |= CAN_RTR_FLAG;
    }
    cf.can_dlc = f->dlc;
    if (!(f->flags & DAN_CAN_RTR)) {
        memcpy(cf.data, f->data, f->dlc);
    }
    do {
        w = write(c->fd, &cf, sizeof cf);
    } while (w < 0 && errno == EINTR);
    if (w < 0) {
        /* ENOBUFS: the interface's tx queue is full. */
        if (errno == EAGAIN || errno == EWOULDBLOCK || errno == ENOBUFS) {
            c->stats.tx_dropped++;
            return DAN_ERR_BUSY;
        }
        c->stats.errors++;
        return DAN_ERR_IO;
    }
    if ((size_t)w != sizeof cf) {
        c->stats.errors++;
        return DAN_ERR_IO;
    }
    c->stats.tx++;
    return 0;
}

int dan_canif_socketcan_recv(dan_canif_t *c, dan_can_frame_t *f)
{
    for (int tries = 0; tries < READS_PER_CALL; tries++) {
        struct can_frame cf;
        ssize_t n = read(c->fd, &cf, sizeof cf);
        if (n < 0) {
            if (errno == EINTR) {
                continue;
            }
            if (errno == EAGAIN || errno == EWOULDBLOCK) {
                return 0;
            }
            c->stats.errors++;
            return DAN_ERR_IO; /* e.g. ENETDOWN: interface went down */
        }
        if ((size_t)n != sizeof cf || cf.can_dlc > 8) {
            c->stats.errors++; /* not a classic CAN frame */
            continue;
        }
        memset(f, 0, sizeof *f);
        f->dlc = cf.can_dlc;
        memcpy(f->data, cf.data, cf.can_dlc);
        if (cf.can_id & CAN_ERR_FLAG) {
            f->flags = DAN_CAN_ERR;
            f->id = cf.can_id & CAN_ERR_MASK; /* error class bits */
            c->stats.errors++;
            return 1;
        }
        if (cf.can_id & CAN_EFF_FLAG) {
            f->flags |= DAN_CAN_EXT;
            f->id = cf.can_id & CAN_EFF_MASK;
        } else {
            f->id = cf.can_id & CAN_SFF_MASK;
        }
        if (cf.can_id & CAN_RTR_FLAG) {
            f->flags |= DAN_CAN_RTR;
            memset(f->data, 0, sizeof f->data);
        }
        c->stats.rx++;
        return 1;
    }
    return 0;
}

void dan_canif_socketcan_close(dan_canif_t *c)
{
    if (c->fd >= 0) {
        close(c->fd);
    }
    c->fd = -1;
}
