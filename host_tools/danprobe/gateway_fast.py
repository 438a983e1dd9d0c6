"""The gateway's compact ESC exchanges (docs/PROTOCOL.md section 7, "Fast
ESC exchanges"; libdan's dan/can_gw/msgs_fast.h): ESC_FAST (0x59) answers
with the gateway flags only, ESC_FAST_T (0x5A) with the flags and one
10-byte record of one ESC's esc.Status (round robin). The request is
ESC_CMD's 14-bit value stream without its count: the length says n.

Inner payloads (the client seals them). Unlike the other messages, both
directions have exact lengths: a request's length is its value count, and a
response is 1 or 11 bytes; anything else raises PayloadError.
tests/vectors/gateway.txt pins the layouts.
"""

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Optional

from danprobe.gateway_msgs import (
    ESC_MAX,
    EscStatusFloats,
    _signed,
    _twos,
    check_range,
    encode_esc_cmd,
    flags_dict,
)
from danprobe.payloads import PayloadError, Reader, Writer, attrs

CODE_ESC_FAST = 0x59
CODE_ESC_FAST_T = 0x5A

REC_SIZE = 10
AGE_UNIT_MS = 4  # the record's age byte counts 4 ms steps
AGE_MAX = 255  # saturated: 1020 ms or older


def fast_size(n: int) -> int:
    """Request bytes for n values: ceil(14 n / 8)."""
    return (14 * n + 7) // 8


def encode_esc_fast(values: Sequence[int]) -> bytes:
    """The values (1..20, each -8192..8191) bit-packed, no count byte."""
    return encode_esc_cmd(values)[1:]


def decode_esc_fast(payload) -> list[int]:
    """n from the length (exactly fast_size(n) bytes); padding bits zero."""
    payload = bytes(payload)
    n = len(payload) * 8 // 14
    if not 1 <= n <= ESC_MAX or fast_size(n) != len(payload):
        raise PayloadError(f"ESC_FAST: {len(payload)} bytes is no count of 14-bit values")
    acc = int.from_bytes(payload, "little")
    if acc >> (14 * n):
        raise PayloadError("ESC_FAST: padding bits set")
    return [_signed((acc >> (14 * i)) & 0x3FFF, 14) for i in range(n)]


@dataclass
class FastRecord(EscStatusFloats):
    """u16 voltage, u16 current, u16 temperature (binary16 bits as the ESC
    sent them), u24 rpm int18 | esc_index << 18 | fresh << 23, u8 age in
    4 ms units (255: 1020 ms or older)."""

    esc_index: int = 0
    fresh: bool = False  # a new esc.Status since this ESC's last record
    age_4ms: int = 0
    voltage_f16: int = 0
    current_f16: int = 0
    temperature_f16: int = 0  # kelvin
    rpm: int = 0

    def put(self, w: Writer):
        check_range(self.esc_index, 0, 31, "esc_index")
        check_range(self.age_4ms, 0, AGE_MAX, "age_4ms")
        check_range(self.rpm, -(1 << 17), (1 << 17) - 1, "rpm")
        packed = _twos(self.rpm, 18, "rpm") | self.esc_index << 18 | int(self.fresh) << 23
        w.u16(self.voltage_f16).u16(self.current_f16).u16(self.temperature_f16)
        w.u24(packed).u8(self.age_4ms)

    @classmethod
    def get(cls, r: Reader) -> "FastRecord":
        v, c, t = r.u16("voltage"), r.u16("current"), r.u16("temperature")
        packed, age = r.u24("rpm/index/fresh"), r.u8("age")
        return cls(
            (packed >> 18) & 0x1F, bool(packed >> 23), age, v, c, t, _signed(packed & 0x3FFFF, 18)
        )

    @property
    def age_ms(self) -> int:
        return self.age_4ms * AGE_UNIT_MS

    def as_dict(self) -> dict:
        names = ("fresh", "age_ms", "voltage", "current", "temperature", "rpm")
        return {"index": self.esc_index, **attrs(self, *names)}


@dataclass
class FastResponse:
    """u8 gateway flags, then the record (ESC_FAST_T, when an ESC reported)."""

    flags: int = 0
    record: Optional[FastRecord] = None

    def encode(self) -> bytes:
        w = Writer().u8(self.flags)
        if self.record is not None:
            self.record.put(w)
        return w.bytes()

    @classmethod
    def decode(cls, payload) -> "FastResponse":
        if len(payload) not in (1, 1 + REC_SIZE):
            raise PayloadError(f"ESC_FAST response: {len(payload)} bytes, not 1 or 11")
        r = Reader(payload)
        flags = r.u8("flags")
        return cls(flags, FastRecord.get(r) if len(payload) > 1 else None)

    def as_dict(self) -> dict:
        return {
            **flags_dict(self.flags),
            "record": self.record.as_dict() if self.record else None,
        }
