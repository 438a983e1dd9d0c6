#!/usr/bin/env python3
"""slcan_hub: a virtual CAN bus of emulated SLCAN (Lawicel) USB-CAN adapters.

Creates N pseudo-terminals. Each one behaves like a USB-CAN adapter speaking
the Lawicel/SLCAN ASCII protocol, and all of them sit on one virtual CAN bus:
a frame sent on one open port is received on every other open port.

    slcan_hub.py -n 3 --link /tmp/slcan
    -> READY /dev/pts/5 /dev/pts/6 /dev/pts/7      (one line on stdout)
       /tmp/slcan0 -> /dev/pts/5, /tmp/slcan1 -> /dev/pts/6, ...

Commands (host -> adapter) end with CR; answers are CR (ACK) or BEL (error):
  S0..S8    CAN bitrate (recorded)        sXXYY  BTR (ack)
  O         open channel                  L      open listen-only
  C         close channel (always ACKs)   F      status flags -> F00
  V         version -> V1013              v      -> v1013
  N         serial number -> NA123        Z0/Z1  timestamps off/on
  Mxxxxxxxx / mxxxxxxxx  acceptance code/mask (ack, no filtering)
  tIIIL<data>  11-bit frame -> z CR       TIIIIIIIIL<data>  29-bit -> Z CR
  rIIIL        11-bit RTR   -> z CR       RIIIIIIIIL        29-bit RTR -> Z CR
  empty line   ACK (resets nothing; lets hosts flush the parser)
Frames received from the bus are written to open ports as tIIIL<data> CR
(plus 4 hex digits of milliseconds, 0..59999, when Z1 is on). S/s/O/L on
an open port, frames on a closed or listen-only port, and malformed lines
get BEL and count as errors. Frames for a closed port are dropped and
counted; so are frames for a port whose reader does not keep up (its
output buffer is bounded).

The hub keeps each pty slave open itself, so a client may close and reopen
its port at will. Stale output is discarded when a client sends C.

--control PATH opens a Unix stream socket; one command per line:
  stats      -> one JSON line: {"ports": [{"port", "path", "link", "attached",
                "open", "listen_only", "bitrate", "timestamps", "frames_in",
                "frames_out", "dropped", "errors"}, ...], "bus_frames": n}
  detach K   -> simulates unplugging adapter K: its pty is closed (clients
                get a hangup: read() returns EIO/0) and its --link symlink
                is removed. "ok"
  attach K   -> plugs adapter K in again: a NEW pty, the symlink re-created
                pointing at it, the port closed with default settings. "ok"
  stall K    -> adapter K stays plugged in but stops reading (wedged
                firmware): its client's writes fill the pty and then block
                (EAGAIN). "ok"
  resume K   -> it reads again (what queued meanwhile is taken). "ok"
  quit       -> "ok", then the hub exits 0.
Errors are answered "error: ...".

SIGTERM / SIGINT: exit 0, removing the symlinks and the control socket.
"""

import argparse
import json
import os
import pty
import select
import signal
import socket
import sys
import termios
import time
import tty

# this directory is sys.path[0]; the codec is standard library only
from danprobe import slcan_codec as slcan

OUT_LIMIT = 64 * 1024  # bytes buffered for one port's reader


def set_process_name(name):
    """Sets the kernel comm name (pgrep without -f); the command line
    already contains slcan_hub for pgrep -f. Best effort."""
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(15, name.encode()[:15], 0, 0, 0)  # PR_SET_NAME
    except Exception:
        pass


class Port:
    def __init__(self, index, link):
        self.index = index
        self.link = link
        self.master = -1
        self.slave = -1
        self.path = None
        self.counters = dict(frames_in=0, frames_out=0, dropped=0, errors=0)
        self.stalled = False  # control "stall K": reads nothing
        self.reset_state()

    def reset_state(self):
        self.open = False
        self.listen_only = False
        self.bitrate = None
        self.timestamps = False
        self.inbuf = bytearray()
        self.outbuf = bytearray()
        self.discarding = False

    @property
    def attached(self):
        return self.master >= 0

    def attach(self):
        master, slave = pty.openpty()
        tty.setraw(slave, termios.TCSANOW)
        os.set_blocking(master, False)
        os.set_inheritable(master, False)
        os.set_inheritable(slave, False)
        self.master, self.slave = master, slave
        self.path = os.ttyname(slave)
        self.reset_state()
        if self.link:
            tmp = self.link + ".tmp%d" % os.getpid()
            try:
                os.unlink(tmp)
            except FileNotFoundError:
                pass
            os.symlink(self.path, tmp)
            os.replace(tmp, self.link)

    def detach(self):
        for fd in (self.master, self.slave):
            if fd >= 0:
                try:
                    os.close(fd)
                except OSError:
                    pass
        self.master = self.slave = -1
        self.reset_state()
        self.remove_link()

    def remove_link(self):
        if self.link:
            try:
                if os.path.islink(self.link):
                    os.unlink(self.link)
            except OSError:
                pass

    def write(self, data, frame=False):
        """Queues bytes for the client. Frames beyond the buffer limit are
        dropped and counted; command answers are always queued."""
        if not self.attached:
            return False
        if frame and len(self.outbuf) + len(data) > OUT_LIMIT:
            self.counters["dropped"] += 1
            return False
        self.outbuf += data
        self.flush()
        return True

    def flush(self):
        while self.outbuf and self.attached:
            try:
                n = os.write(self.master, self.outbuf)
            except BlockingIOError:
                return
            except OSError:
                return
            del self.outbuf[:n]

    def stats(self):
        d = dict(
            port=self.index,
            path=self.path,
            link=self.link,
            attached=self.attached,
            open=self.open,
            listen_only=self.listen_only,
            bitrate=self.bitrate,
            timestamps=self.timestamps,
        )
        d.update(self.counters)
        return d


class Hub:
    def __init__(self, n, link_prefix, log_path, control_path):
        self.ports = [Port(i, (link_prefix + str(i)) if link_prefix else None) for i in range(n)]
        self.t0 = time.monotonic()
        self.bus_frames = 0
        self.log = open(log_path, "a", buffering=1) if log_path else None
        self.control_path = control_path
        self.ctl = None
        self.ctl_clients = {}  # fd -> (socket, bytearray)
        self.stop = False
        self.exit_code = 0

    # ---- setup / teardown ----

    def start(self):
        for p in self.ports:
            p.attach()
        if self.control_path:
            try:
                os.unlink(self.control_path)
            except FileNotFoundError:
                pass
            self.ctl = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            self.ctl.bind(self.control_path)
            self.ctl.listen(8)
            self.ctl.setblocking(False)

    def cleanup(self):
        for p in self.ports:
            p.detach()
        for s, _ in list(self.ctl_clients.values()):
            s.close()
        self.ctl_clients.clear()
        if self.ctl:
            self.ctl.close()
            try:
                os.unlink(self.control_path)
            except OSError:
                pass
        if self.log:
            self.log.close()

    # ---- the bus ----

    def timestamp(self):
        return int((time.monotonic() - self.t0) * 1000) % 60000

    def broadcast(self, src, frame):
        self.bus_frames += 1
        if self.log:
            t = time.time()
            idtxt = ("%08X" if frame.ext else "%03X") % frame.id
            if frame.rtr:
                body = "R%d" % frame.dlc if frame.dlc else "R"
            else:
                body = frame.data.hex().upper()
            self.log.write("(%.6f) hub%d %s#%s\n" % (t, src.index, idtxt, body))
        for p in self.ports:
            if p is src:
                continue
            if not p.attached or not p.open:
                p.counters["dropped"] += 1
                continue
            ts = self.timestamp() if p.timestamps else None
            if p.write(slcan.format_frame(frame, ts), frame=True):
                p.counters["frames_out"] += 1

    # ---- SLCAN command interpreter ----

    def handle_line(self, p, line):
        def err():
            p.counters["errors"] += 1
            p.write(slcan.BEL)

        if not line:
            p.write(slcan.ACK)
            return
        c = line[:1]
        arg = line[1:]
        if c in slcan.FRAME_KINDS:
            frame = slcan.parse_frame(line)
            if frame is None or not p.open or p.listen_only:
                err()
                return
            p.counters["frames_in"] += 1
            p.write(slcan.tx_ack(frame.ext))
            self.broadcast(p, frame)
        elif c == b"S":
            if p.open or len(arg) != 1 or arg not in b"012345678":
                err()
                return
            p.bitrate = [10, 20, 50, 100, 125, 250, 500, 800, 1000][int(arg)] * 1000
            p.write(slcan.ACK)
        elif c == b"s":
            if p.open or len(arg) != 4 or not slcan.is_hex(arg):
                err()
                return
            p.bitrate = "btr:" + arg.decode()
            p.write(slcan.ACK)
        elif c in (b"O", b"L"):
            if p.open or arg:
                err()
                return
            p.open, p.listen_only = True, c == b"L"
            p.write(slcan.ACK)
        elif c == b"C":
            if arg:
                err()
                return
            p.open = p.listen_only = False
            # A (re)initialising client: forget stale bytes for it.
            p.outbuf.clear()
            try:
                termios.tcflush(p.slave, termios.TCIFLUSH)
            except termios.error:
                pass
            p.write(slcan.ACK)
        elif c == b"F" and not arg:
            p.write(b"F00\r")
        elif c == b"V" and not arg:
            p.write(b"V1013\r")
        elif c == b"v" and not arg:
            p.write(b"v1013\r")
        elif c == b"N" and not arg:
            p.write(b"NA123\r")
        elif c == b"Z" and arg in (b"0", b"1"):
            p.timestamps = arg == b"1"
            p.write(slcan.ACK)
        elif c in (b"M", b"m") and len(arg) == 8 and slcan.is_hex(arg):
            p.write(slcan.ACK)
        else:
            err()

    def on_readable(self, p):
        try:
            data = os.read(p.master, 4096)
        except BlockingIOError:
            return
        except OSError:
            # EIO: no client has the slave open (cannot happen while we hold
            # the slave, but tolerate it).
            return
        for b in data:
            if b == 0x0D:  # CR ends a command
                if p.discarding:
                    p.discarding = False
                    p.counters["errors"] += 1
                    p.write(slcan.BEL)
                else:
                    self.handle_line(p, bytes(p.inbuf))
                p.inbuf.clear()
            elif b == 0x0A:  # LF: tolerated, ignored
                continue
            elif p.discarding:
                continue
            elif len(p.inbuf) >= slcan.LINE_MAX:
                p.discarding = True
                p.inbuf.clear()
            else:
                p.inbuf.append(b)

    # ---- control socket ----

    def control_command(self, text):
        words = text.split()
        if not words:
            return None
        cmd = words[0]
        if cmd == "stats" and len(words) == 1:
            return json.dumps(
                {"ports": [p.stats() for p in self.ports], "bus_frames": self.bus_frames}
            )
        if cmd in ("detach", "attach", "stall", "resume") and len(words) == 2:
            try:
                k = int(words[1])
                p = self.ports[k]
                if k < 0:
                    raise IndexError
            except (ValueError, IndexError):
                return "error: no port %s" % words[1]
            if cmd in ("stall", "resume"):
                p.stalled = cmd == "stall"
            elif cmd == "detach":
                if not p.attached:
                    return "error: port %d is already detached" % k
                p.detach()
            else:
                if p.attached:
                    return "error: port %d is already attached" % k
                p.attach()
            return "ok"
        if cmd == "quit" and len(words) == 1:
            self.stop = True
            return "ok"
        return "error: unknown command (stats, detach K, attach K, stall K, resume K, quit)"

    def on_control_client(self, fd):
        s, buf = self.ctl_clients[fd]
        try:
            data = s.recv(4096)
        except BlockingIOError:
            return
        except OSError:
            data = b""
        if not data:
            s.close()
            del self.ctl_clients[fd]
            return
        buf += data
        while b"\n" in buf:
            line, _, rest = bytes(buf).partition(b"\n")
            buf[:] = rest
            reply = self.control_command(line.decode("utf-8", "replace"))
            if reply is not None:
                try:
                    s.setblocking(True)
                    s.settimeout(2.0)
                    s.sendall((reply + "\n").encode())
                    s.setblocking(False)
                except OSError:
                    pass

    # ---- main loop ----

    def run(self, wakeup_fd):
        poller = select.poll()
        while not self.stop:
            poller = select.poll()
            poller.register(wakeup_fd, select.POLLIN)
            fdmap = {}
            for p in self.ports:
                if p.attached:
                    ev = (0 if p.stalled else select.POLLIN) | (select.POLLOUT if p.outbuf else 0)
                    if ev:
                        poller.register(p.master, ev)
                        fdmap[p.master] = p
            if self.ctl:
                poller.register(self.ctl.fileno(), select.POLLIN)
                for fd in self.ctl_clients:
                    poller.register(fd, select.POLLIN)
            for fd, ev in poller.poll(500):
                if fd == wakeup_fd:
                    try:
                        os.read(wakeup_fd, 512)
                    except OSError:
                        pass
                elif fd in fdmap:
                    p = fdmap[fd]
                    if ev & select.POLLOUT:
                        p.flush()
                    if (
                        ev & (select.POLLIN | select.POLLHUP | select.POLLERR)
                        and p.attached
                        and not p.stalled
                    ):
                        self.on_readable(p)
                elif self.ctl and fd == self.ctl.fileno():
                    try:
                        s, _ = self.ctl.accept()
                        s.setblocking(False)
                        self.ctl_clients[s.fileno()] = (s, bytearray())
                    except OSError:
                        pass
                elif fd in self.ctl_clients:
                    self.on_control_client(fd)
                if self.stop:
                    break


def main(argv=None):
    ap = argparse.ArgumentParser(
        prog="slcan_hub.py",
        description=__doc__.split("\n\n", 1)[1],
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ap.add_argument(
        "-n", "--ports", type=int, default=2, help="number of emulated adapters (default 2)"
    )
    ap.add_argument(
        "--link", metavar="PREFIX", help="create symlinks PREFIX0, PREFIX1, ... to the ptys"
    )
    ap.add_argument(
        "--log",
        metavar="FILE",
        help="append every bus frame in candump log format: "
        "(t.tttttt) hubN ID#DATA, N = sending port",
    )
    ap.add_argument(
        "--control",
        metavar="PATH",
        help="Unix socket for control commands (stats, detach K, attach K, quit)",
    )
    args = ap.parse_args(argv)
    if not 1 <= args.ports <= 64:
        ap.error("-n must be 1..64")

    set_process_name("slcan_hub")
    hub = Hub(args.ports, args.link, args.log, args.control)

    # Signal handlers only set a flag; the wakeup pipe interrupts poll().
    rfd, wfd = os.pipe()
    os.set_blocking(rfd, False)
    os.set_blocking(wfd, False)
    signal.set_wakeup_fd(wfd, warn_on_full_buffer=False)

    def on_signal(signum, frame):
        hub.stop = True

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGHUP, signal.SIG_IGN)

    try:
        hub.start()
        print("READY " + " ".join(p.path for p in hub.ports), flush=True)
        hub.run(rfd)
    except OSError as e:
        print("slcan_hub: %s" % e, file=sys.stderr)
        hub.exit_code = 1
    finally:
        hub.cleanup()
    return hub.exit_code


if __name__ == "__main__":
    sys.exit(main())
