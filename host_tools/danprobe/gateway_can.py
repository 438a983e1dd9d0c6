"""The gateway's raw CAN messages (docs/PROTOCOL.md section 7: CAN_SEND,
CAN_RECV, CAN_FILTER), the classic CAN frame they carry and cansend's
ID#DATA text for it. Same rules as gateway_msgs.py: decoders never read
past the payload and raise PayloadError for a field out of range.

Bus management added two things ("Bus management" in the document): bit
29 of a received frame's id_flags marks a frame the gateway itself sent
(CanFrame.own), and a filter entry with bit 29 passes those too
(Filter.own); CAN_RECV's optional opts byte asks for receive times (the
gateway's microsecond clock, low 32 bits: t0_us, then dt_us per frame)."""

import re
from dataclasses import asdict, dataclass, field

from danprobe.gateway_msgs import (
    CAN_FRAMES_MAX,
    CAN_ID_EXT,
    CAN_ID_OWN,
    CAN_ID_RTR,
    EFF_MASK,
    FILTER_READ,
    FILTERS_MAX,
    SFF_MASK,
    check_range,
)
from danprobe.payloads import PayloadError, Reader, Record, Writer, attrs


@dataclass
class CanFrame:
    id: int = 0
    data: bytes = b""
    ext: bool = False
    rtr: bool = False
    rtr_dlc: int = 0  # dlc of a remote frame (it has no data)
    own: bool = False  # received: the gateway itself sent it (id_flags bit 29)

    @property
    def dlc(self) -> int:
        return self.rtr_dlc if self.rtr else len(self.data)

    @property
    def id_flags(self) -> int:
        return (
            self.id
            | (CAN_ID_EXT if self.ext else 0)
            | (CAN_ID_RTR if self.rtr else 0)
            | (CAN_ID_OWN if self.own else 0)
        )

    def same_frame(self, other: "CanFrame") -> bool:
        """The same frame on the bus (whoever sent it)."""
        return (self.id, self.ext, self.rtr, self.dlc, self.data) == (
            other.id,
            other.ext,
            other.rtr,
            other.dlc,
            other.data,
        )

    def check(self) -> "CanFrame":
        if not 0 <= self.id <= (EFF_MASK if self.ext else SFF_MASK):
            raise ValueError(
                f"CAN id {self.id:X} out of range for a {'29' if self.ext else '11'}-bit identifier"
            )
        if self.dlc > 8 or (self.rtr and self.data):
            raise ValueError("CAN frame: at most 8 data bytes, none in a remote frame")
        return self

    def put(self, w: Writer):
        self.check()
        w.u32(self.id_flags).u8(self.dlc)
        if not self.rtr:
            w.raw(self.data)

    @classmethod
    def get(cls, r: Reader) -> "CanFrame":
        idf, dlc = r.u32("id_flags"), r.u8("dlc")
        ext, rtr, own = bool(idf & CAN_ID_EXT), bool(idf & CAN_ID_RTR), bool(idf & CAN_ID_OWN)
        fid = idf & EFF_MASK
        if dlc > 8 or (not ext and fid > SFF_MASK):
            raise PayloadError(f"CAN frame: id_flags {idf:08X} dlc {dlc} out of range")
        if rtr:
            return cls(fid, b"", ext, True, dlc, own)
        return cls(fid, r.raw(dlc, "frame data"), ext, own=own)

    def candump(self) -> str:
        """can-utils' ID#DATA (3 or 8 hex digits; ID#R[len] for a remote frame)."""
        ident = f"{self.id:08X}" if self.ext else f"{self.id:03X}"
        if self.rtr:
            return f"{ident}#R" + (f"{self.rtr_dlc:X}" if self.rtr_dlc else "")
        return f"{ident}#{self.data.hex().upper()}"

    def as_dict(self) -> dict:
        d = attrs(self, "id", "ext", "rtr", "dlc")
        return {**d, "data": self.data.hex(), "text": self.candump(), "own": self.own}


_HEX = set("0123456789abcdefABCDEF")
_CANSEND_DATA = re.compile(r"\.?(?:[0-9A-Fa-f]{2}\.?)*")


def parse_cansend(text: str) -> CanFrame:
    """cansend's <id>#<data>: up to 3 hex digits an 11-bit id, 4..8 a 29-bit
    one (cansend: exactly 3 or 8); data as hex bytes, '.' allowed between
    them; <id>#R or <id>#R<len> a remote frame."""
    ident, sep, rest = text.partition("#")
    if not sep or not 1 <= len(ident) <= 8 or not set(ident) <= _HEX:
        raise ValueError(f"{text!r}: expected ID#DATA (ID: 3 or 8 hex digits)")
    ext = len(ident) > 3
    if rest[:1] in ("R", "r"):
        n = rest[1:]
        if len(n) > 1 or (n and n not in "012345678"):
            raise ValueError(f"{text!r}: remote frame length must be R or R0..R8")
        return CanFrame(int(ident, 16), b"", ext, True, int(n or "0")).check()
    # a '.' only between whole bytes (and one at either end), as cansend
    # reads it: 123#0.011 is refused, not taken as 00 11
    if not _CANSEND_DATA.fullmatch(rest):
        raise ValueError(f"{text!r}: data must be whole hex bytes")
    digits = rest.replace(".", "")
    try:
        return CanFrame(int(ident, 16), bytes.fromhex(digits), ext).check()
    except ValueError as e:
        raise ValueError(f"{text!r}: {e}") from None


@dataclass
class CanSendRequest:
    seq: int = 0
    frames: list[CanFrame] = field(default_factory=list)

    def encode(self) -> bytes:
        if len(self.frames) > CAN_FRAMES_MAX:
            raise ValueError(f"CAN_SEND: at most {CAN_FRAMES_MAX} frames")
        if any(f.own for f in self.frames):
            raise ValueError("CAN_SEND: bit 29 (own) is for received frames only")
        return Writer().u8(self.seq).items(self.frames).bytes()

    @classmethod
    def decode(cls, payload) -> "CanSendRequest":
        r = Reader(payload)
        s, n = r.u8("seq"), r.u8("count")
        if n > CAN_FRAMES_MAX:
            raise PayloadError(f"count: {n} frames, at most {CAN_FRAMES_MAX}")
        return cls(s, [CanFrame.get(r) for _ in range(n)])

    def as_dict(self) -> dict:
        return {"seq": self.seq, "frames": [f.candump() for f in self.frames]}


@dataclass
class CanSendResponse(Record):
    seq: int = 0
    accepted: int = 0
    queue_free: int = 0

    LAYOUT = (("seq", "u8"), ("accepted", "u8"), ("queue_free", "uvarint"))


RECV_TIMES = 0x01  # CAN_RECV opts: receive times in the response
U32 = 0xFFFFFFFF


@dataclass
class CanRecvRequest:
    """uv next_seq, u8 max, and u8 opts when it is not 0."""

    next_seq: int = 0
    max: int = CAN_FRAMES_MAX
    opts: int = 0

    def encode(self) -> bytes:
        w = Writer().uvarint(self.next_seq).u8(self.max)
        if self.opts:
            w.u8(self.opts)
        return w.bytes()

    @classmethod
    def decode(cls, payload) -> "CanRecvRequest":
        r = Reader(payload)
        q = cls(r.uvarint("next_seq"), r.u8("max"))
        q.opts = r.u8("opts") if r.remaining() else 0
        return q

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass
class CanRecvResponse:
    """uv first_seq, uv dropped, u8 count; with RECV_TIMES asked (opts: the
    request's, it is not on the wire) u32 t0_us, then after each frame uv
    dt_us since the previous one of the response (0 for the first)."""

    first_seq: int = 0
    dropped: int = 0
    frames: list[CanFrame] = field(default_factory=list)
    opts: int = 0
    t0_us: int = 0
    dt_us: list[int] = field(default_factory=list)

    def encode(self) -> bytes:
        if len(self.frames) > CAN_FRAMES_MAX:
            raise ValueError(f"CAN_RECV: at most {CAN_FRAMES_MAX} frames")
        timed = bool(self.opts & RECV_TIMES)
        if timed and len(self.dt_us) != len(self.frames):
            raise ValueError("CAN_RECV: one dt_us per frame")
        w = Writer().uvarint(self.first_seq).uvarint(self.dropped).u8(len(self.frames))
        if timed:
            w.u32(self.t0_us)
        for i, f in enumerate(self.frames):
            f.put(w)
            if timed:
                w.uvarint(self.dt_us[i])
        return w.bytes()

    @classmethod
    def decode(cls, payload, opts: int = 0) -> "CanRecvResponse":
        r = Reader(payload)
        q = cls(r.uvarint("first_seq"), r.uvarint("dropped"), opts=opts)
        n = r.u8("count")
        if n > CAN_FRAMES_MAX:
            raise PayloadError(f"count: {n} frames, at most {CAN_FRAMES_MAX}")
        timed = bool(opts & RECV_TIMES)
        if timed:
            q.t0_us = r.u32("t0_us")
        for _ in range(n):
            q.frames.append(CanFrame.get(r))
            if timed:
                q.dt_us.append(r.uvarint("dt_us"))
        return q

    def times_us(self) -> list[int]:
        """Each frame's receive time on the gateway's clock: t0_us plus the
        deltas (not wrapped at 2^32; the caller unwraps t0_us)."""
        out, t = [], self.t0_us
        for dt in self.dt_us:
            t += dt
            out.append(t)
        return out

    def as_dict(self) -> dict:
        d = {
            "first_seq": self.first_seq,
            "dropped": self.dropped,
            "frames": [f.candump() + ("/own" if f.own else "") for f in self.frames],
        }
        if self.opts & RECV_TIMES:
            d.update(t0_us=self.t0_us, dt_us=self.dt_us)
        return d


@dataclass
class Filter:
    """Passes a frame with the same ext flag and (id & mask) == (self.id & mask)."""

    id: int = 0
    mask: int = 0
    ext: bool = False
    own: bool = False  # also the frames the gateway itself sent (bit 29)

    def matches(self, f: CanFrame) -> bool:
        return (
            f.ext == self.ext
            and (self.own or not f.own)
            and (f.id & self.mask) == (self.id & self.mask)
        )

    def text(self) -> str:
        return (
            f"{self.id:X}:{self.mask:X}"
            + (":ext" if self.ext else "")
            + (":own" if self.own else "")
        )


PASS_ALL = (Filter(0, 0, False), Filter(0, 0, True))  # every 11-bit and 29-bit frame
PASS_ALL_OWN = (Filter(0, 0, False, True), Filter(0, 0, True, True))  # ... and the gateway's


@dataclass
class FilterTable:
    """CAN_FILTER request (op, entries) and response (result, the table)."""

    op: int = FILTER_READ  # request: FILTER_*; response: 0 OK, 1 table full
    filters: list[Filter] = field(default_factory=list)

    def encode(self) -> bytes:
        if len(self.filters) > FILTERS_MAX:
            raise ValueError(f"CAN_FILTER: at most {FILTERS_MAX} entries")
        w = Writer().u8(self.op).u8(len(self.filters))
        for f in self.filters:
            check_range(f.id, 0, EFF_MASK, "filter id")
            check_range(f.mask, 0, EFF_MASK, "filter mask")
            w.u32(f.id | (CAN_ID_EXT if f.ext else 0) | (CAN_ID_OWN if f.own else 0)).u32(f.mask)
        return w.bytes()

    @classmethod
    def decode(cls, payload) -> "FilterTable":
        r = Reader(payload)
        t, n = cls(r.u8("op/result")), r.u8("count")
        if n > FILTERS_MAX:
            raise PayloadError(f"count: {n} filters, at most {FILTERS_MAX}")
        for _ in range(n):
            idf, mask = r.u32("filter id"), r.u32("filter mask")
            if idf & CAN_ID_RTR or mask & 0xE0000000:
                raise PayloadError(f"filter {idf:08X}/{mask:08X}: reserved bits set")
            t.filters.append(
                Filter(idf & EFF_MASK, mask, bool(idf & CAN_ID_EXT), bool(idf & CAN_ID_OWN))
            )
        return t

    def as_dict(self) -> dict:
        return {"op": self.op, "filters": [f.text() for f in self.filters]}
