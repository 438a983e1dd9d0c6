/* Any baud on Linux through termios2 and BOTHER. Kept apart from the rest
 * of the port: <asm/termbits.h> and <termios.h> cannot share a file. */
#include <asm/ioctls.h>
#include <asm/termbits.h>
#include <linux/serial.h>
#include <stdint.h>
#include <sys/ioctl.h>

int dan_posix_set_speed(int fd, uint32_t baud);
int dan_posix_low_latency(int fd);
int dan_posix_get_speeds(int fd, uint32_t *ispeed, uint32_t *ospeed);
uint32_t dan_posix_get_speed(int fd);

int dan_posix_set_speed(int fd, uint32_t baud)
{
    struct termios2 t;
    if (ioctl(fd, TCGETS2, &t) != 0) {
        return -1;
    }
    t.c_cflag &= ~(tcflag_t)(CBAUD | (CBAUD << IBSHIFT));
    t.c_cflag |= BOTHER | (BOTHER << IBSHIFT);
    t.c_ispeed = baud;
    t.c_ospeed = baud;
    return ioctl(fd, TCSETS2, &t);
}

int dan_posix_get_speeds(int fd, uint32_t *ispeed, uint32_t *ospeed)
{
    struct termios2 t;
    if (ioctl(fd, TCGETS2, &t) != 0) {
        return -1;
    }
    *ispeed = t.c_ispeed;
    *ospeed = t.c_ospeed;
    return 0;
}

uint32_t dan_posix_get_speed(int fd)
{
    uint32_t in, out;
    return dan_posix_get_speeds(fd, &in, &out) == 0 ? out : 0u;
}

/* ASYNC_LOW_LATENCY: the serial driver hands received bytes to the tty at
 * once instead of batching them (8250 and some USB drivers; ftdi_sio then
 * sets its latency timer to 1 ms). A pty has no serial driver: fails. */
int dan_posix_low_latency(int fd)
{
    struct serial_struct ss;
    if (ioctl(fd, TIOCGSERIAL, &ss) != 0) {
        return -1;
    }
    if ((ss.flags & (int)ASYNC_LOW_LATENCY) != 0) {
        return 0;
    }
    ss.flags = (int)((unsigned)ss.flags | (unsigned)ASYNC_LOW_LATENCY);
    return ioctl(fd, TIOCSSERIAL, &ss);
}
