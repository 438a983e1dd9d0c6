"""A DAN UART over pyserial: raw 8N1, exclusive, non-blocking reads.

POSIX only (select on the port's file descriptor): Linux USB-serial
adapters and dan-vbus ptys. The port's termios settings (pyserial makes
them raw at our baud) are put back as they were found when it is closed,
as can-utils' tools do.
"""

import ctypes
import errno
import os
import select
import termios
import time
from typing import Optional

import serial


class PortError(Exception):
    """The port cannot be opened or used; the message says why."""


def _reason(path: str, e: Exception) -> str:
    text = str(e)
    code = getattr(e, "errno", None)
    if "exclusively lock" in text or code in (errno.EBUSY, errno.EAGAIN, errno.EWOULDBLOCK):
        return f"{path}: port busy (another program holds it)"
    if code == errno.EACCES or "Permission denied" in text:
        return f"{path}: permission denied (on Linux, join the 'dialout' group)"
    if "Inappropriate ioctl" in text or code == errno.ENOTTY:
        return f"{path}: not a serial port"
    return f"{path}: {text}"


GONE = (errno.EIO, errno.ENXIO, errno.ENODEV)  # the device went away

PR_SET_TIMERSLACK = 29  # linux/prctl.h


def fine_timers():
    """Timer slack 1 us for this process, as libdan's C tools ask for
    (tool_fine_timers): the default 50 us let every select() and sleep
    wake up to 50 us late, a twentieth of a 2 Mbit/s exchange. Best
    effort: elsewhere than on Linux it costs only speed."""
    try:
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_TIMERSLACK, 1000, 0, 0, 0)
    except (OSError, AttributeError):
        pass


def _errno(e: BaseException) -> Optional[int]:
    """The errno behind e: its own, a termios.error's first argument (it has
    no .errno), or that of the exception it was raised from (pyserial wraps
    OSError and termios.error in SerialException)."""
    while e is not None:
        code = getattr(e, "errno", None)
        if code is None and isinstance(e, termios.error) and e.args:
            code = e.args[0]
        if isinstance(code, int) and code:
            return code
        e = e.__cause__ or e.__context__
    return None


# What a call on a port that went away raises: pyserial's own exception,
# OSError, or termios.error straight from tcdrain/tcflush/tcsetattr.
PORT_ERRORS = (serial.SerialException, OSError, termios.error)


def _opened_termios(path: str) -> tuple[Optional[list], Optional[int]]:
    """The port's termios settings before pyserial changes them, and the
    file descriptor read through (the caller closes it once pyserial has the
    port open: closed first, a hang-up on last close would drop DTR).
    (None, None) if they cannot be read: pyserial's open then says why."""
    try:
        fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    except OSError:
        return None, None
    try:
        return termios.tcgetattr(fd), fd
    except termios.error:
        os.close(fd)
        return None, None


class SerialPort:
    def __init__(self, path: str, baud: int):
        self.path = path
        fine_timers()
        if not os.path.exists(path):
            raise PortError(f"{path}: No such file or directory")
        self._found, fd = _opened_termios(path)
        try:
            self.ser = serial.Serial(port=path, baudrate=baud, timeout=0, exclusive=True)
        except (serial.SerialException, OSError, ValueError, OverflowError) as e:
            self._found = None  # not ours to put back: another program may hold it
            raise PortError(_reason(path, e)) from None  # OverflowError: --baud 3000000000
        finally:
            if fd is not None:
                os.close(fd)
        try:
            self.ser.reset_input_buffer()
        except PORT_ERRORS as e:
            self.close()
            raise self._failed("flush", e) from None
        self._empty_reads = 0
        # ASYNC_LOW_LATENCY, as libdan's POSIX port asks for: the serial
        # driver hands bytes over at once, and ftdi_sio drops its latency
        # timer from 16 ms to 1 ms (docs/VBUS.md "Adapter latency"). A pty
        # or a driver without it refuses; that costs only speed.
        self.low_latency = False
        try:
            self.ser.set_low_latency_mode(True)
            self.low_latency = True
        except (AttributeError, OSError, ValueError, serial.SerialException):
            pass

    @property
    def baud(self) -> int:
        return self.ser.baudrate

    def set_baud(self, baud: int):
        try:
            self.ser.baudrate = baud
        except PORT_ERRORS + (ValueError,) as e:
            if _errno(e) in GONE:
                raise self._failed("set baud", e) from None
            raise PortError(f"{self.path}: cannot set {baud} baud: {e}") from None

    def read(self, timeout: float) -> bytes:
        """Bytes received within timeout seconds (b"" if none)."""
        fd = self.ser.fileno()
        try:
            r, _, _ = select.select([fd], [], [], max(timeout, 0.0))
            data = os.read(fd, 4096) if r else b""
        except BlockingIOError:
            data = b""
        except OSError as e:
            raise self._failed("read", e) from None
        if r and not data:
            # Readable but empty: spurious on a pty now and then (another
            # endpoint closing), for good when the device went away.
            self._empty_reads += 1
            if self._empty_reads >= 100:
                raise PortError(f"{self.path}: device disconnected")
            time.sleep(0.001)
        elif data:
            self._empty_reads = 0
        return data

    def _failed(self, what: str, e: Exception) -> PortError:
        """EIO, ENXIO, ENODEV: the device went away (USB unplugged, the pty's
        other side closed), said the same way whichever call saw it."""
        err = _errno(e)
        if err in GONE:
            return PortError(f"{self.path}: device disconnected ({what}: {os.strerror(err)})")
        return PortError(f"{self.path}: {what} failed: {os.strerror(err) if err else e}")

    def write(self, data: bytes):
        try:
            n = self.ser.write(data)
        except PORT_ERRORS as e:
            raise self._failed("write", e) from None
        if n != len(data):
            raise PortError(f"{self.path}: short write ({n} of {len(data)} bytes)")

    def drain(self):
        """Waits until every byte written has left the UART."""
        try:
            self.ser.flush()
        except PORT_ERRORS as e:
            raise self._failed("drain", e) from None

    def discard_output(self):
        """Drops bytes not sent yet (after a collision)."""
        try:
            self.ser.reset_output_buffer()
        except PORT_ERRORS as e:
            raise self._failed("discard", e) from None

    def close(self):
        """Puts the termios settings found at open back (raw mode and baud
        were ours), then closes the port. Best effort: a device that went
        away takes neither, and says nothing."""
        found, self._found = self._found, None
        if found is not None and self.ser.is_open:
            try:
                termios.tcsetattr(self.ser.fileno(), termios.TCSANOW, found)
            except PORT_ERRORS:
                pass
        try:
            self.ser.close()
        except OSError:
            pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def now() -> float:
    return time.monotonic()
