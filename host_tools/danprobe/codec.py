"""DAN v1 frame codec: crc8_dvb_s2, uvarint, frame encoder and the
resynchronising streaming decoder.

The rules are libdan's (docs/PROTOCOL.md sections 1 and 2; src/frame.c):
the decoder here makes the same decisions on the same bytes, which the
shared vectors in tests/vectors/ pin for both.

    'D' | uvarint code | uvarint length | payload | crc8 (over all after 'D')
"""

from dataclasses import asdict, dataclass
from typing import NamedTuple, Optional

SYNC = 0x44  # 'D'
MAX_PAYLOAD = 160  # DAN_MAX_PAYLOAD, libdan's default build
UVARINT_MAX_BYTES = 5
UINT32_MAX = 0xFFFFFFFF


class MalformedError(ValueError):
    """Bytes that do not follow the format (a bad uvarint, a bad payload)."""


# ---- crc8_dvb_s2: polynomial 0xD5, init 0, no reflection, no final XOR ----


def crc_table(poly: int, bits: int) -> tuple[int, ...]:
    """Byte table of an MSB-first CRC of `bits` bits (no reflection)."""
    top, mask = 1 << (bits - 1), (1 << bits) - 1
    table = []
    for v in range(256):
        c = v << (bits - 8)
        for _ in range(8):
            c = ((c << 1) ^ poly) & mask if c & top else (c << 1) & mask
        table.append(c)
    return tuple(table)


_CRC8_TABLE = crc_table(0xD5, 8)


def crc8(data, crc: int = 0) -> int:
    """crc8_dvb_s2 of data, continuing from crc."""
    t = _CRC8_TABLE
    for b in data:
        crc = t[crc ^ b]
    return crc


# ---- uvarint: 7 bits a byte, low group first, 0x80 = more follows ----


def uvarint_size(v: int) -> int:
    n = 1
    while v >= 0x80:
        v >>= 7
        n += 1
    return n


def uvarint_encode(v: int) -> bytes:
    """Minimal encoding of a 32-bit value."""
    if not 0 <= v <= UINT32_MAX:
        raise ValueError(f"uvarint out of range: {v}")
    out = bytearray()
    while v >= 0x80:
        out.append((v & 0x7F) | 0x80)
        v >>= 7
    out.append(v)
    return bytes(out)


def uvarint_decode(data, pos: int = 0, end: Optional[int] = None) -> tuple[int, int]:
    """Decodes the uvarint at data[pos:end]. Returns (value, size); size 0
    means the input ends before the uvarint does (truncated). Raises
    MalformedError for an encoding longer than 5 bytes or a value above 32
    bits. Non-minimal encodings are accepted."""
    if end is None:
        end = len(data)
    acc = 0
    for i in range(UVARINT_MAX_BYTES):
        if pos + i >= end:
            return 0, 0
        b = data[pos + i]
        if i == UVARINT_MAX_BYTES - 1 and b & 0xF0:
            raise MalformedError("uvarint overlong or over 32 bits")
        acc |= (b & 0x7F) << (7 * i)
        if not b & 0x80:
            return acc, i + 1
    raise AssertionError("not reached")


MAX_FRAME = 1 + UVARINT_MAX_BYTES + uvarint_size(MAX_PAYLOAD) + MAX_PAYLOAD + 1


# ---- frames ----


def frame_size(code: int, length: int) -> int:
    return 1 + uvarint_size(code) + uvarint_size(length) + length + 1


def encode_frame(code: int, payload=b"") -> bytes:
    """The wire bytes of a frame. ValueError for a payload longer than
    MAX_PAYLOAD or a code outside 32 bits."""
    payload = bytes(payload)
    if len(payload) > MAX_PAYLOAD:
        raise ValueError(f"payload of {len(payload)} bytes exceeds {MAX_PAYLOAD}")
    body = uvarint_encode(code) + uvarint_encode(len(payload)) + payload
    return bytes([SYNC]) + body + bytes([crc8(body)])


class Frame(NamedTuple):
    code: int
    payload: bytes
    start: int  # stream offset of its sync byte (bytes fed to the decoder before it)
    size: int  # bytes on the wire


@dataclass
class DecoderStats:
    frames: int = 0  # valid frames returned
    crc_errors: int = 0  # complete candidates whose CRC did not match
    oversize: int = 0  # candidates declaring a payload > MAX_PAYLOAD
    bad_varint: int = 0  # code or length uvarint overlong / overflowing
    garbage: int = 0  # bytes dropped while hunting for a sync byte
    aborted: int = 0  # partial frames dropped by abort()

    def as_dict(self) -> dict:
        return asdict(self)


_WAIT, _REJECTED = 0, -1


class Decoder:
    """Streaming decoder with libdan's resynchronisation rules.

    buf holds the buffered bytes, buf[0] a sync byte when not empty;
    buf[:scanned] is the candidate examined so far; bytes after it are left
    over from a rejected candidate and are examined again before new input;
    buf[:guard] are bytes of rejected candidates (a frame found inside them
    and ending inside them needs a sync byte right after it). buf is always
    the last bytes consumed from the input, so a frame's stream offset is
    consumed - len(buf) when it is found.
    """

    def __init__(self):
        self.stats = DecoderStats()
        self.consumed = 0
        self._clear()

    def _clear(self):
        self.buf = bytearray()
        self.scanned = 0
        self.need = 0
        self.guard = 0
        self.code = 0
        self.hdr = 0

    def reset(self):
        """Drops everything buffered (after a baud change); keeps counters."""
        self._clear()

    def busy(self) -> bool:
        """True while a partial frame is buffered."""
        return len(self.buf) > 0

    def _drop_front(self, n: int) -> int:
        """Drops buf[:n] and the non-sync bytes after it; returns how many
        were skipped after the first n."""
        buf = self.buf
        k = n
        while k < len(buf) and buf[k] != SYNC:
            k += 1
        del buf[:k]
        self.guard = max(self.guard - k, 0)
        self.scanned = 0
        self.need = 0
        return k - n

    def _reject(self, counter: str):
        setattr(self.stats, counter, getattr(self.stats, counter) + 1)
        self.guard = max(self.guard, self.scanned)
        self._drop_front(1)

    def _examine(self):
        """Examines the candidate buf[:scanned]: a Frame, _WAIT or _REJECTED."""
        buf, n = self.buf, self.scanned
        if self.need == 0:
            try:
                code, nc = uvarint_decode(buf, 1, n)
                if nc == 0:
                    return _WAIT
                plen, nl = uvarint_decode(buf, 1 + nc, n)
            except MalformedError:
                self._reject("bad_varint")
                return _REJECTED
            if nl == 0:
                return _WAIT
            total = 1 + nc + nl + plen + 1
            # Also bounds non-minimal length encodings to the buffer.
            if plen > MAX_PAYLOAD or total > MAX_FRAME:
                self._reject("oversize")
                return _REJECTED
            self.need, self.hdr, self.code = total, 1 + nc + nl, code
        if n < self.need:
            return _WAIT
        if crc8(memoryview(buf)[1 : n - 1]) != buf[n - 1]:
            self._reject("crc_errors")
            return _REJECTED
        # A candidate found inside a rejected one and ending inside it passed
        # an 8-bit CRC by chance as often as not: keep it only if another
        # frame starts right after it.
        if n < self.guard and buf[n] != SYNC:
            self._reject("crc_errors")
            return _REJECTED
        self.stats.frames += 1
        frame = Frame(self.code, bytes(buf[self.hdr : n - 1]), self.consumed - len(buf), n)
        self.stats.garbage += self._drop_front(n)
        return frame

    def feed(self, data=b"") -> list[Frame]:
        """Consumes data (any length, b"" too) and returns the frames
        completed, in order."""
        frames = []
        buf = self.buf
        data = bytes(data)
        used, n = 0, len(data)
        while True:
            if self.scanned < len(buf):
                self.scanned += 1  # a pending byte from a rescan
            elif used < n:
                take = 1
                if not buf:
                    s = data.find(SYNC, used)
                    if s < 0:
                        self.stats.garbage += n - used
                        self.consumed += n - used
                        used = n
                        continue
                    self.stats.garbage += s - used
                    self.consumed += s - used
                    used = s
                elif self.need > len(buf):
                    take = min(self.need - len(buf), n - used)  # payload bytes
                buf += data[used : used + take]
                self.consumed += take
                self.scanned = len(buf)
                used += take
            else:
                return frames
            if self.scanned >= 2:
                r = self._examine()
                if isinstance(r, Frame):
                    frames.append(r)

    def _whole_frame_at(self, k: int) -> bool:
        """True if buf[k:] is exactly one complete, valid frame."""
        p = self.buf
        n = len(p) - k
        if n < 4 or p[k] != SYNC:
            return False
        try:
            _, nc = uvarint_decode(p, k + 1)
            if nc == 0:
                return False
            plen, nl = uvarint_decode(p, k + 1 + nc)
        except MalformedError:
            return False
        if nl == 0 or plen > MAX_PAYLOAD or 1 + nc + nl + plen + 1 != n:
            return False
        return crc8(memoryview(p)[k + 1 : len(p) - 1]) == p[-1]

    def abort(self) -> list[Frame]:
        """The line went idle: drops the partial frame (counted in aborted).
        A whole valid frame ending at the last byte received, started inside
        the dropped bytes, is kept and returned."""
        if not self.buf:
            return []
        self.stats.aborted += 1
        for k in range(1, len(self.buf)):
            if self._whole_frame_at(k):
                self._drop_front(k)
                return self.feed(b"")
        self._clear()
        return []

    def drain(self) -> list[Frame]:
        """abort() until nothing is buffered: what an idle line leaves."""
        frames = []
        while self.busy():
            frames += self.abort()
        return frames
