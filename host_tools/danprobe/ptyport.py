"""A local pseudo-terminal for the tunnel and slcan commands: any serial
tool opens its path (or the --link symlink) as if it were a device.

We keep the slave side open ourselves, so a client may close and reopen
the path at will (reading the master never fails with EIO in between). The
line is raw (no echo, no line editing, 8 bits); the master side is
non-blocking. POSIX only.
"""

import errno
import os
import select
import termios
import tty
from typing import Optional

from danprobe.port import PortError


class Pty:
    def __init__(self, link: Optional[str] = None):
        self.master, self._slave = os.openpty()
        tty.setraw(self._slave)
        os.set_blocking(self.master, False)
        self.path = os.ttyname(self._slave)
        self.link = None
        if link:
            try:
                if os.path.islink(link):
                    os.unlink(link)
                os.symlink(self.path, link)
            except OSError as e:
                self.close()
                raise PortError(f"{link}: cannot create the link: {e.strerror}") from None
            self.link = link

    def fileno(self) -> int:
        return self.master

    def read(self) -> bytes:
        """What the client wrote (b"" if nothing)."""
        try:
            return os.read(self.master, 4096)
        except BlockingIOError:
            return b""
        except OSError as e:
            if e.errno == errno.EIO:  # no client (not with our slave open; be safe)
                return b""
            raise

    def write(self, data) -> int:
        """Writes what the pty takes now; returns the count (the rest waits)."""
        if not data:
            return 0
        try:
            return os.write(self.master, data)
        except BlockingIOError:
            return 0
        except OSError as e:
            if e.errno in (errno.EIO, errno.EAGAIN):
                return 0
            raise

    def wait_readable(self, timeout: float) -> bool:
        r, _, _ = select.select([self.master], [], [], max(timeout, 0.0))
        return bool(r)

    def discard_output(self):
        """Drops what we wrote that the client has not read yet."""
        termios.tcflush(self._slave, termios.TCIFLUSH)

    def close(self):
        if self.link:
            try:
                if os.path.islink(self.link) and os.readlink(self.link) == self.path:
                    os.unlink(self.link)
            except OSError:
                pass
            self.link = None
        for fd in (self.master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass
        self.master = self._slave = -1

    def __enter__(self) -> "Pty":
        return self

    def __exit__(self, *exc):
        self.close()
