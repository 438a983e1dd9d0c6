"""The CAN-over-DAN gateway (docs/PROTOCOL.md section 7): the payload codec
of codes 0x42..0x4D and a blocking client over master.Master.

The codec follows the document byte for byte (tests/vectors/gateway.txt
pins it, as it pins libdan's include/dan/gateway_msgs.h): decoders never
read past the payload, raise PayloadError for a truncated payload or a
field out of range, and ignore trailing bytes. Float telemetry stays as
the IEEE binary16 bit patterns the ESC sent; as_dict() converts. The
message classes work on the inner payload; every gateway message travels
sealed (seal()/unseal(), tests/vectors/gateway_sealed.txt): the client
seals its requests and installs reply_check() as the master's reply check,
so a reply whose seal fails is retried, never decoded.

The client mirrors libdan's (src/gateway.c), so retried transactions never
duplicate or lose anything: the master's retries repeat the same request
bytes; tunnel writes carry their stream offset and reads acknowledge by
offset; CAN_SEND carries a sequence number that changes per call, not per
attempt; CAN_RECV acknowledges by sequence number. Two additions for a
tool that joins a running gateway (libdan's FC client starts with it):
the first CAN_SEND of a session is preceded by an empty one that sets the
gateway's "last accepted" sequence number (so our first real sequence
number is never mistaken for a retry of someone else's), and frames the
first CAN_RECV skips are not counted as lost (they were before our time).
A CAN_SEND whose transaction failed is sent again with the same sequence
number by can_send_again(), so a lost response never duplicates frames.
"""

import random
import struct
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Callable, Optional

from danprobe import registry
from danprobe.codec import MalformedError, crc_table, uvarint_encode
from danprobe.master import Malformed, Master, Nack
from danprobe.payloads import PayloadError, Reader, Writer

# ---- codes (block 0x40..0x4F: 0x40 IDENTIFY, 0x41 CONFIGURE) ----
CODE_ESC_CMD = 0x42
CODE_ESC_TELEM = 0x43
CODE_ARM = 0x44
CODE_CONFIG = 0x45
CODE_STATS = 0x46
CODE_NODES = 0x47
CODE_NODE_INFO = 0x48
CODE_TUN_OPEN = 0x49
CODE_TUN_XFER = 0x4A
CODE_CAN_SEND = 0x4B
CODE_CAN_RECV = 0x4C
CAN_RESYNC = 4096  # a CAN_RECV sequence jump beyond this: the gateway restarted
CODE_CAN_FILTER = 0x4D

# ---- limits ----
ESC_MAX = 20
RAW_MIN, RAW_MAX = -8192, 8191
ESC_INDEX_MAX = 31
TUN_CHUNK_MAX = 128
CAN_FRAMES_MAX = 11
FILTERS_MAX = 16
NAME_MAX = 80
NONE = 0xFF

# gateway flags byte
FLAG_ARMED = 0x01
FLAG_FAILSAFE = 0x02
FLAG_CAN_OK = 0x04

ARM_DISARMED, ARM_FULLY_ARMED = 0, 255

# telemetry record flags
TELEM_STATUS = 0x01
TELEM_EXT = 0x02

# CONFIG set mask
CFG_ESC_TIMEOUT = 0x01
CFG_ARMING_RATE = 0x02
ESC_TIMEOUT_RANGE = (50, 60000)
ARMING_RATE_RANGE = (1, 50)

# STATS counters, in wire order (later versions append)
STAT_NAMES = (
    "dan_frames",
    "dan_crc_errors",
    "dan_unknown",
    "dan_errors_sent",
    "dan_requests",
    "can_tx",
    "can_rx",
    "can_tx_dropped",
    "can_errors",
    "dc_transfers",
    "dc_crc_errors",
    "dc_errors",
    "esc_cmds",
    "failsafes",
    "failsafe_active",
    "tun_dropped",
    "raw_dropped",
    "nodes",
    "bad_checks",
    "nodes_dropped",
)

# node table info_state
INFO_NONE, INFO_PENDING, INFO_VALID, INFO_FAILED = 0, 1, 2, 3
INFO_STATE_NAMES = ("not asked", "requested", "valid", "no answer")
HEALTH_NAMES = ("OK", "WARNING", "ERROR", "CRITICAL")
MODE_NAMES = {
    0: "OPERATIONAL",
    1: "INITIALIZATION",
    2: "MAINTENANCE",
    3: "SOFTWARE_UPDATE",
    7: "OFFLINE",
}

# tunnels
TUN_CLOSED, TUN_TARGETTED, TUN_BROADCAST = 0, 1, 2
TUN_LOCK_PORT = 0x01
PROTOCOL_UNDEFINED = 255  # uavcan.tunnel.Protocol, as ArduPilot's Targetted sends

# raw CAN
CAN_ID_EXT = 0x80000000
CAN_ID_RTR = 0x40000000
SFF_MASK = 0x7FF
EFF_MASK = 0x1FFFFFFF
FILTER_REPLACE, FILTER_ADD, FILTER_REMOVE, FILTER_READ = 0, 1, 2, 3


# ---- the seal (every gateway message, requests and responses) ----
# A u16 (little endian) check after the inner payload: CRC-16/CCITT-FALSE
# (poly 0x1021, init 0xFFFF, no reflection, no xorout) over the code's
# uvarint bytes, one direction byte and the inner payload. A frame a
# collision corrupted must pass crc8 and this check bound to its code and
# direction. IDENTIFY, CONFIGURE and error frames carry none.

SEAL_SIZE = 2
REQUEST, RESPONSE = 0, 1
CODE_FIRST, CODE_LAST = CODE_ESC_CMD, 0x4F


_CRC16_TABLE = crc_table(0x1021, 16)


def crc16_ccitt_false(data, crc: int = 0xFFFF) -> int:
    t = _CRC16_TABLE
    for b in data:
        crc = ((crc << 8) & 0xFFFF) ^ t[(crc >> 8) ^ b]
    return crc


def sealed_code(code: int) -> bool:
    return CODE_FIRST <= code <= CODE_LAST


def check(code: int, direction: int, inner: bytes) -> int:
    return crc16_ccitt_false(inner, crc16_ccitt_false(uvarint_encode(code) + bytes([direction])))


def seal(code: int, direction: int, inner: bytes) -> bytes:
    """The payload on the wire: inner + its check."""
    return bytes(inner) + struct.pack("<H", check(code, direction, inner))


def unseal(code: int, direction: int, payload) -> bytes:
    """The inner payload; PayloadError if the check does not match."""
    payload = bytes(payload)
    if len(payload) < SEAL_SIZE:
        raise PayloadError(f"seal: {len(payload)} byte(s), no room for the check")
    inner = payload[:-SEAL_SIZE]
    if struct.unpack("<H", payload[-SEAL_SIZE:])[0] != check(code, direction, inner):
        raise PayloadError("seal: the check does not match")
    return inner


def reply_check(code: int, payload: bytes) -> bool:
    """The master's reply check for a gateway client: sealed codes must
    carry a matching response seal."""
    if not sealed_code(code):
        return True
    try:
        unseal(code, RESPONSE, payload)
    except PayloadError:
        return False
    return True


# ---- helpers ----


def _signed(v: int, bits: int) -> int:
    return v - (1 << bits) if v & (1 << (bits - 1)) else v


def _twos(v: int, bits: int, what: str) -> int:
    if not -(1 << (bits - 1)) <= v < (1 << bits):
        raise ValueError(f"{what}: {v} does not fit {bits} bits")
    return v & ((1 << bits) - 1)


def _check(v: int, lo: int, hi: int, what: str) -> int:
    if not lo <= v <= hi:
        raise ValueError(f"{what}: {v} is outside {lo}..{hi}")
    return v


def f16_to_float(bits: int) -> float:
    """IEEE binary16 bits to float, exactly."""
    return struct.unpack("<e", struct.pack("<H", bits & 0xFFFF))[0]


def off_diff(a: int, b: int) -> int:
    """Signed difference a - b of two 32-bit stream offsets (modulo 2^32)."""
    return _signed((a - b) & 0xFFFFFFFF, 32)


def flags_names(flags: int) -> list[str]:
    return [
        n
        for bit, n in ((FLAG_ARMED, "armed"), (FLAG_FAILSAFE, "failsafe"), (FLAG_CAN_OK, "can-up"))
        if flags & bit
    ]


def flags_dict(flags: int) -> dict:
    return {
        "flags": flags,
        "armed": bool(flags & FLAG_ARMED),
        "failsafe": bool(flags & FLAG_FAILSAFE),
        "can_up": bool(flags & FLAG_CAN_OK),
    }


def throttle_to_raw(pct: float) -> int:
    """Throttle percent (-100..100) to a RawCommand value (100 % = 8191)."""
    _check(pct, -100, 100, "throttle %")
    return max(RAW_MIN, min(RAW_MAX, int(round(pct * RAW_MAX / 100.0))))


# ---- ESC_CMD (0x42) request: u8 n, n x int14 bit-packed LSB first ----


def encode_esc_cmd(values: Sequence[int]) -> bytes:
    if not 1 <= len(values) <= ESC_MAX:
        raise ValueError(f"ESC command: 1..{ESC_MAX} values, not {len(values)}")
    acc = 0
    for i, v in enumerate(values):
        _check(v, RAW_MIN, RAW_MAX, f"ESC value {i}")
        acc |= (v & 0x3FFF) << (14 * i)
    return bytes([len(values)]) + acc.to_bytes((14 * len(values) + 7) // 8, "little")


def decode_esc_cmd(payload) -> list[int]:
    r = Reader(payload)
    n = r.u8("count")
    if not 1 <= n <= ESC_MAX:
        raise PayloadError(f"count: {n} is outside 1..{ESC_MAX}")
    acc = int.from_bytes(r.raw((14 * n + 7) // 8, "values"), "little")
    return [_signed((acc >> (14 * i)) & 0x3FFF, 14) for i in range(n)]


# ---- telemetry (ESC_CMD and ESC_TELEM responses) ----


@dataclass
class TelemRecord:
    esc_index: int = 0
    node_id: int = 0
    flags: int = 0  # TELEM_STATUS | TELEM_EXT
    age_ms: int = 0
    voltage_f16: int = 0
    current_f16: int = 0
    temperature_f16: int = 0
    rpm: int = 0
    power_pct: int = 0
    error_count: int = 0
    ext_age_ms: int = 0
    input_pct: int = 0
    output_pct: int = 0
    motor_temp_c: int = 0
    motor_angle: int = 0
    status_flags: int = 0

    def put(self, w: Writer):
        w.u8(self.esc_index).u8(self.node_id).u8(self.flags & (TELEM_STATUS | TELEM_EXT))
        if self.flags & TELEM_STATUS:
            (
                w.uvarint(self.age_ms)
                .u16(self.voltage_f16)
                .u16(self.current_f16)
                .u16(self.temperature_f16)
                .u24(_twos(self.rpm, 24, "rpm"))
                .u8(self.power_pct)
                .uvarint(self.error_count)
            )
        if self.flags & TELEM_EXT:
            (
                w.uvarint(self.ext_age_ms)
                .u8(self.input_pct)
                .u8(self.output_pct)
                .u16(_twos(self.motor_temp_c, 16, "motor_temp_c"))
                .u16(self.motor_angle)
                .u24(self.status_flags)
            )

    @classmethod
    def get(cls, r: Reader) -> "TelemRecord":
        t = cls(r.u8("esc_index"), r.u8("node_id"), r.u8("record flags"))
        if t.flags & TELEM_STATUS:
            t.age_ms, t.voltage_f16 = r.uvarint("age_ms"), r.u16("voltage")
            t.current_f16, t.temperature_f16 = r.u16("current"), r.u16("temperature")
            t.rpm, t.power_pct = _signed(r.u24("rpm"), 24), r.u8("power_rating_pct")
            t.error_count = r.uvarint("error_count")
        if t.flags & TELEM_EXT:
            t.ext_age_ms, t.input_pct = r.uvarint("ext_age_ms"), r.u8("input_pct")
            t.output_pct = r.u8("output_pct")
            t.motor_temp_c = _signed(r.u16("motor_temperature_degC"), 16)
            t.motor_angle, t.status_flags = r.u16("motor_angle"), r.u24("status_flags")
        return t

    @property
    def voltage(self) -> float:
        return f16_to_float(self.voltage_f16)

    @property
    def current(self) -> float:
        return f16_to_float(self.current_f16)

    @property
    def temperature(self) -> float:
        """Kelvin, as esc.Status carries it."""
        return f16_to_float(self.temperature_f16)

    def as_dict(self) -> dict:
        d = {
            "index": self.esc_index,
            "node": self.node_id,
            "status": bool(self.flags & TELEM_STATUS),
            "extended": bool(self.flags & TELEM_EXT),
        }
        if self.flags & TELEM_STATUS:
            d.update(
                age_ms=self.age_ms,
                voltage=self.voltage,
                current=self.current,
                temperature=self.temperature,
                rpm=self.rpm,
                power_pct=self.power_pct,
                error_count=self.error_count,
            )
        if self.flags & TELEM_EXT:
            d.update(
                ext_age_ms=self.ext_age_ms,
                input_pct=self.input_pct,
                output_pct=self.output_pct,
                motor_temp_c=self.motor_temp_c,
                motor_angle=self.motor_angle,
                status_flags=self.status_flags,
            )
        return d


@dataclass
class Telemetry:
    """Header (u8 flags, u8 aux, u8 count) and records. aux: ESC_CMD, the
    ESCs the gateway knows; ESC_TELEM, the next index to ask (NONE: end)."""

    flags: int = 0
    aux: int = 0
    records: list[TelemRecord] = field(default_factory=list)

    def encode(self) -> bytes:
        w = Writer().u8(self.flags).u8(self.aux).u8(len(self.records))
        for t in self.records:
            t.put(w)
        return w.bytes()

    @classmethod
    def decode(cls, payload) -> "Telemetry":
        r = Reader(payload)
        t = cls(r.u8("flags"), r.u8("aux"))
        t.records = [TelemRecord.get(r) for _ in range(r.u8("count"))]
        return t

    def as_dict(self) -> dict:
        return {
            **flags_dict(self.flags),
            "aux": self.aux,
            "records": [t.as_dict() for t in self.records],
        }


def _u8_payload(what: str):
    def decode(payload) -> int:
        return Reader(payload).u8(what)

    return decode


decode_u8 = _u8_payload("value")


# ---- CONFIG (0x45) ----


@dataclass
class ConfigRequest:
    set_mask: int = 0
    esc_timeout_ms: int = 0
    arming_rate_hz: int = 0

    def encode(self) -> bytes:
        w = Writer().u8(self.set_mask)
        if self.set_mask & CFG_ESC_TIMEOUT:
            w.uvarint(_check(self.esc_timeout_ms, *ESC_TIMEOUT_RANGE, "esc_timeout_ms"))
        if self.set_mask & CFG_ARMING_RATE:
            w.uvarint(_check(self.arming_rate_hz, *ARMING_RATE_RANGE, "arming_rate_hz"))
        return w.bytes()

    @classmethod
    def decode(cls, payload) -> "ConfigRequest":
        r = Reader(payload)
        c = cls(r.u8("set_mask") if r.remaining() else 0)
        try:
            if c.set_mask & CFG_ESC_TIMEOUT:
                c.esc_timeout_ms = _check(
                    r.uvarint("esc_timeout_ms"), *ESC_TIMEOUT_RANGE, "esc_timeout_ms"
                )
            if c.set_mask & CFG_ARMING_RATE:
                c.arming_rate_hz = _check(
                    r.uvarint("arming_rate_hz"), *ARMING_RATE_RANGE, "arming_rate_hz"
                )
        except ValueError as e:
            if isinstance(e, MalformedError):
                raise
            raise PayloadError(str(e)) from None
        return c

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass
class ConfigResponse:
    node_id: int = 0
    esc_timeout_ms: int = 0
    arming_rate_hz: int = 0
    flags: int = 0

    def encode(self) -> bytes:
        return (
            Writer()
            .u8(self.node_id)
            .uvarint(self.esc_timeout_ms)
            .uvarint(self.arming_rate_hz)
            .u8(self.flags)
            .bytes()
        )

    @classmethod
    def decode(cls, payload) -> "ConfigResponse":
        r = Reader(payload)
        return cls(
            r.u8("node_id"), r.uvarint("esc_timeout_ms"), r.uvarint("arming_rate_hz"), r.u8("flags")
        )

    def as_dict(self) -> dict:
        return {
            "node_id": self.node_id,
            "esc_timeout_ms": self.esc_timeout_ms,
            "arming_rate_hz": self.arming_rate_hz,
            **flags_dict(self.flags),
        }


# ---- STATS (0x46): u8 n, n x uvarint ----


def encode_stats(values: Sequence[int]) -> bytes:
    w = Writer().u8(len(values))
    for v in values:
        w.uvarint(v)
    return w.bytes()


def decode_stats(payload) -> list[int]:
    r = Reader(payload)
    return [
        r.uvarint(STAT_NAMES[i] if i < len(STAT_NAMES) else f"counter {i}")
        for i in range(r.u8("count"))
    ]


def stats_dict(values: Sequence[int]) -> dict[str, int]:
    """Counters by the document's names; ones a later version appends are
    named counter_N."""
    return {
        (STAT_NAMES[i] if i < len(STAT_NAMES) else f"counter_{i}"): v for i, v in enumerate(values)
    }


# ---- NODES (0x47) ----


@dataclass
class NodeEntry:
    node_id: int = 0
    health: int = 0
    mode: int = 0
    sub_mode: int = 0
    uptime_sec: int = 0
    vendor_status: int = 0
    age_ms: int = 0
    info_state: int = 0

    def put(self, w: Writer):
        (
            w.u8(self.node_id)
            .u8((self.health & 3) | (self.mode & 7) << 2 | (self.sub_mode & 7) << 5)
            .uvarint(self.uptime_sec)
            .u16(self.vendor_status)
            .uvarint(self.age_ms)
            .u8(self.info_state)
        )

    @classmethod
    def get(cls, r: Reader) -> "NodeEntry":
        nid, hm = r.u8("node_id"), r.u8("health/mode")
        return cls(
            nid,
            hm & 3,
            (hm >> 2) & 7,
            hm >> 5,
            r.uvarint("uptime_sec"),
            r.u16("vendor_status"),
            r.uvarint("age_ms"),
            r.u8("info_state"),
        )

    def as_dict(self) -> dict:
        d = asdict(self)
        d["health_name"] = HEALTH_NAMES[self.health]
        d["mode_name"] = MODE_NAMES.get(self.mode, str(self.mode))
        return d


@dataclass
class NodesPage:
    next: int = 0  # node id to ask for next (0: end)
    entries: list[NodeEntry] = field(default_factory=list)

    def encode(self) -> bytes:
        w = Writer().u8(self.next).u8(len(self.entries))
        for e in self.entries:
            e.put(w)
        return w.bytes()

    @classmethod
    def decode(cls, payload) -> "NodesPage":
        r = Reader(payload)
        p = cls(r.u8("next"))
        p.entries = [NodeEntry.get(r) for _ in range(r.u8("count"))]
        return p

    def as_dict(self) -> dict:
        return {"next": self.next, "nodes": [e.as_dict() for e in self.entries]}


# ---- NODE_INFO (0x48) ----


@dataclass
class NodeInfo:
    node_id: int = 0
    info_state: int = 0
    sw_major: int = 0
    sw_minor: int = 0
    sw_flags: int = 0
    vcs_commit: int = 0
    hw_major: int = 0
    hw_minor: int = 0
    unique_id: bytes = bytes(16)
    name: bytes = b""

    def encode(self) -> bytes:
        w = Writer().u8(self.node_id).u8(self.info_state)
        if self.info_state == INFO_VALID:
            if len(self.unique_id) != 16 or len(self.name) > NAME_MAX:
                raise ValueError("unique_id must be 16 bytes, name at most 80")
            (
                w.u8(self.sw_major)
                .u8(self.sw_minor)
                .u8(self.sw_flags)
                .u32(self.vcs_commit)
                .u8(self.hw_major)
                .u8(self.hw_minor)
                .raw(self.unique_id)
                .array(self.name)
            )
        return w.bytes()

    @classmethod
    def decode(cls, payload) -> "NodeInfo":
        r = Reader(payload)
        i = cls(r.u8("node_id"), r.u8("info_state"))
        if i.info_state == INFO_VALID:
            i.sw_major, i.sw_minor = r.u8("sw_major"), r.u8("sw_minor")
            i.sw_flags, i.vcs_commit = r.u8("sw_flags"), r.u32("vcs_commit")
            i.hw_major, i.hw_minor = r.u8("hw_major"), r.u8("hw_minor")
            i.unique_id, i.name = r.raw(16, "unique_id"), r.array("name")
        return i

    def as_dict(self) -> dict:
        d = {"node_id": self.node_id, "info_state": self.info_state}
        if self.info_state == INFO_VALID:
            d.update(
                name=self.name.decode("utf-8", "backslashreplace"),
                sw=[self.sw_major, self.sw_minor],
                sw_flags=self.sw_flags,
                vcs_commit=self.vcs_commit,
                hw=[self.hw_major, self.hw_minor],
                unique_id=self.unique_id.hex(),
            )
        return d


# ---- TUN_OPEN (0x49) ----


@dataclass
class TunOpen:
    port: int = 0
    mode: int = TUN_CLOSED
    protocol: int = 0
    target: int = 0  # Targetted: node id; Broadcast: channel_id
    serial_id: int = 0  # int8
    options: int = 0
    baud: int = 0

    def encode(self) -> bytes:
        return (
            Writer()
            .u8(self.port)
            .u8(self.mode)
            .u8(self.protocol)
            .u8(self.target)
            .u8(_twos(self.serial_id, 8, "serial_id"))
            .u8(self.options)
            .uvarint(self.baud)
            .bytes()
        )

    @classmethod
    def decode(cls, payload) -> "TunOpen":
        r = Reader(payload)
        return cls(
            r.u8("port"),
            r.u8("mode"),
            r.u8("protocol"),
            r.u8("target"),
            _signed(r.u8("serial_id"), 8),
            r.u8("options"),
            r.uvarint("baud"),
        )

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass
class TunOpenResult:
    port: int = 0
    result: int = 0  # 0 OK, 1 refused

    def encode(self) -> bytes:
        return Writer().u8(self.port).u8(self.result).bytes()

    @classmethod
    def decode(cls, payload) -> "TunOpenResult":
        r = Reader(payload)
        return cls(r.u8("port"), r.u8("result"))

    def as_dict(self) -> dict:
        return asdict(self)


# ---- TUN_XFER (0x4A) ----


def _chunk(r: Reader) -> bytes:
    data = r.array("data")
    if len(data) > TUN_CHUNK_MAX:
        raise PayloadError(f"data: {len(data)} bytes, at most {TUN_CHUNK_MAX}")
    return data


@dataclass
class TunXferRequest:
    port: int = 0
    wr_offset: int = 0  # stream offset of data[0]
    rd_offset: int = 0  # every byte before it was received
    rd_max: int = TUN_CHUNK_MAX
    data: bytes = b""

    def encode(self) -> bytes:
        if len(self.data) > TUN_CHUNK_MAX:
            raise ValueError(f"tunnel data: at most {TUN_CHUNK_MAX} bytes")
        return (
            Writer()
            .u8(self.port)
            .uvarint(self.wr_offset)
            .uvarint(self.rd_offset)
            .uvarint(self.rd_max)
            .array(self.data)
            .bytes()
        )

    @classmethod
    def decode(cls, payload) -> "TunXferRequest":
        r = Reader(payload)
        return cls(
            r.u8("port"),
            r.uvarint("wr_offset"),
            r.uvarint("rd_offset"),
            r.uvarint("rd_max"),
            _chunk(r),
        )

    def as_dict(self) -> dict:
        return {
            "port": self.port,
            "wr_offset": self.wr_offset,
            "rd_offset": self.rd_offset,
            "rd_max": self.rd_max,
            "data": self.data.hex(),
        }


@dataclass
class TunXferResponse:
    port: int = 0
    wr_next: int = 0  # bytes accepted so far
    wr_space: int = 0
    rd_offset: int = 0  # offset of data[0]
    rd_dropped: int = 0  # total bytes dropped, CAN -> DAN
    data: bytes = b""

    def encode(self) -> bytes:
        if len(self.data) > TUN_CHUNK_MAX:
            raise ValueError(f"tunnel data: at most {TUN_CHUNK_MAX} bytes")
        return (
            Writer()
            .u8(self.port)
            .uvarint(self.wr_next)
            .uvarint(self.wr_space)
            .uvarint(self.rd_offset)
            .uvarint(self.rd_dropped)
            .array(self.data)
            .bytes()
        )

    @classmethod
    def decode(cls, payload) -> "TunXferResponse":
        r = Reader(payload)
        return cls(
            r.u8("port"),
            r.uvarint("wr_next"),
            r.uvarint("wr_space"),
            r.uvarint("rd_offset"),
            r.uvarint("rd_dropped"),
            _chunk(r),
        )

    def as_dict(self) -> dict:
        return {
            "port": self.port,
            "wr_next": self.wr_next,
            "wr_space": self.wr_space,
            "rd_offset": self.rd_offset,
            "rd_dropped": self.rd_dropped,
            "data": self.data.hex(),
        }


# ---- raw CAN frames ----


@dataclass
class CanFrame:
    id: int = 0
    data: bytes = b""
    ext: bool = False
    rtr: bool = False
    rtr_dlc: int = 0  # dlc of a remote frame (it has no data)

    @property
    def dlc(self) -> int:
        return self.rtr_dlc if self.rtr else len(self.data)

    @property
    def id_flags(self) -> int:
        return self.id | (CAN_ID_EXT if self.ext else 0) | (CAN_ID_RTR if self.rtr else 0)

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
        ext, rtr = bool(idf & CAN_ID_EXT), bool(idf & CAN_ID_RTR)
        fid = idf & EFF_MASK
        if dlc > 8 or idf & 0x20000000 or (not ext and fid > SFF_MASK):
            raise PayloadError(f"CAN frame: id_flags {idf:08X} dlc {dlc} out of range")
        if rtr:
            return cls(fid, b"", ext, True, dlc)
        return cls(fid, r.raw(dlc, "frame data"), ext)

    def candump(self) -> str:
        """can-utils' ID#DATA (3 or 8 hex digits; ID#R[len] for a remote frame)."""
        ident = f"{self.id:08X}" if self.ext else f"{self.id:03X}"
        if self.rtr:
            return f"{ident}#R" + (f"{self.rtr_dlc:X}" if self.rtr_dlc else "")
        return f"{ident}#{self.data.hex().upper()}"

    def as_dict(self) -> dict:
        return {
            "id": self.id,
            "ext": self.ext,
            "rtr": self.rtr,
            "dlc": self.dlc,
            "data": self.data.hex(),
            "text": self.candump(),
        }


_HEX = set("0123456789abcdefABCDEF")


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
    digits = rest.replace(".", "")
    if len(digits) % 2 or not set(digits) <= _HEX:
        raise ValueError(f"{text!r}: data must be whole hex bytes")
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
        w = Writer().u8(self.seq).u8(len(self.frames))
        for f in self.frames:
            f.put(w)
        return w.bytes()

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
class CanSendResponse:
    seq: int = 0
    accepted: int = 0
    queue_free: int = 0

    def encode(self) -> bytes:
        return Writer().u8(self.seq).u8(self.accepted).uvarint(self.queue_free).bytes()

    @classmethod
    def decode(cls, payload) -> "CanSendResponse":
        r = Reader(payload)
        return cls(r.u8("seq"), r.u8("accepted"), r.uvarint("queue_free"))

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass
class CanRecvRequest:
    next_seq: int = 0
    max: int = CAN_FRAMES_MAX

    def encode(self) -> bytes:
        return Writer().uvarint(self.next_seq).u8(self.max).bytes()

    @classmethod
    def decode(cls, payload) -> "CanRecvRequest":
        r = Reader(payload)
        return cls(r.uvarint("next_seq"), r.u8("max"))

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass
class CanRecvResponse:
    first_seq: int = 0
    dropped: int = 0
    frames: list[CanFrame] = field(default_factory=list)

    def encode(self) -> bytes:
        if len(self.frames) > CAN_FRAMES_MAX:
            raise ValueError(f"CAN_RECV: at most {CAN_FRAMES_MAX} frames")
        w = Writer().uvarint(self.first_seq).uvarint(self.dropped).u8(len(self.frames))
        for f in self.frames:
            f.put(w)
        return w.bytes()

    @classmethod
    def decode(cls, payload) -> "CanRecvResponse":
        r = Reader(payload)
        q = cls(r.uvarint("first_seq"), r.uvarint("dropped"))
        n = r.u8("count")
        if n > CAN_FRAMES_MAX:
            raise PayloadError(f"count: {n} frames, at most {CAN_FRAMES_MAX}")
        q.frames = [CanFrame.get(r) for _ in range(n)]
        return q

    def as_dict(self) -> dict:
        return {
            "first_seq": self.first_seq,
            "dropped": self.dropped,
            "frames": [f.candump() for f in self.frames],
        }


@dataclass
class Filter:
    """Passes a frame with the same ext flag and (id & mask) == (self.id & mask)."""

    id: int = 0
    mask: int = 0
    ext: bool = False

    def matches(self, f: CanFrame) -> bool:
        return f.ext == self.ext and (f.id & self.mask) == (self.id & self.mask)

    def text(self) -> str:
        return f"{self.id:X}:{self.mask:X}" + (":ext" if self.ext else "")


PASS_ALL = (Filter(0, 0, False), Filter(0, 0, True))  # every 11-bit and 29-bit frame


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
            _check(f.id, 0, EFF_MASK, "filter id")
            _check(f.mask, 0, EFF_MASK, "filter mask")
            w.u32(f.id | (CAN_ID_EXT if f.ext else 0)).u32(f.mask)
        return w.bytes()

    @classmethod
    def decode(cls, payload) -> "FilterTable":
        r = Reader(payload)
        t, n = cls(r.u8("op/result")), r.u8("count")
        if n > FILTERS_MAX:
            raise PayloadError(f"count: {n} filters, at most {FILTERS_MAX}")
        for _ in range(n):
            idf, mask = r.u32("filter id"), r.u32("filter mask")
            if idf & 0x60000000 or mask & 0xE0000000:
                raise PayloadError(f"filter {idf:08X}/{mask:08X}: reserved bits set")
            t.filters.append(Filter(idf & EFF_MASK, mask, bool(idf & CAN_ID_EXT)))
        return t

    def as_dict(self) -> dict:
        return {"op": self.op, "filters": [f.text() for f in self.filters]}


# ---- names for sniff ----


def _describer(code: int, direction: int, fn: Callable) -> Callable[[bytes], dict]:
    """A registry describer: unseals a wire payload, decodes the inner one
    (fn returns a dict or an object with as_dict())."""

    def describe(payload: bytes) -> dict:
        v = fn(unseal(code, direction, payload))
        return v.as_dict() if hasattr(v, "as_dict") else v

    return describe


def register_names():
    """Names codes 0x42..0x4D in the registry, with describers of the sealed
    payloads, so sniff shows and decodes them (the CLI calls this at start)."""
    u8 = decode_u8
    for code, name, req, rsp in (
        (CODE_ESC_CMD, "ESC_CMD", lambda p: {"values": decode_esc_cmd(p)}, Telemetry.decode),
        (CODE_ESC_TELEM, "ESC_TELEM", lambda p: {"first": u8(p)}, Telemetry.decode),
        (CODE_ARM, "ARM", lambda p: {"status": u8(p)}, lambda p: flags_dict(u8(p))),
        (CODE_CONFIG, "CONFIG", ConfigRequest.decode, ConfigResponse.decode),
        (CODE_STATS, "STATS", registry.describe_empty, lambda p: stats_dict(decode_stats(p))),
        (CODE_NODES, "NODES", lambda p: {"first": u8(p)}, NodesPage.decode),
        (CODE_NODE_INFO, "NODE_INFO", lambda p: {"node": u8(p)}, NodeInfo.decode),
        (CODE_TUN_OPEN, "TUN_OPEN", TunOpen.decode, TunOpenResult.decode),
        (CODE_TUN_XFER, "TUN_XFER", TunXferRequest.decode, TunXferResponse.decode),
        (CODE_CAN_SEND, "CAN_SEND", CanSendRequest.decode, CanSendResponse.decode),
        (CODE_CAN_RECV, "CAN_RECV", CanRecvRequest.decode, CanRecvResponse.decode),
        (CODE_CAN_FILTER, "CAN_FILTER", FilterTable.decode, FilterTable.decode),
    ):
        registry.register_message(
            code,
            name,
            request=_describer(code, REQUEST, req),
            response=_describer(code, RESPONSE, rsp),
        )


# ---- the client ----


@dataclass
class TunnelState:
    wr_offset: int = 0  # bytes of ours the gateway has accepted
    rd_offset: int = 0  # bytes we have received
    wr_space: int = 0  # gateway buffer space, last seen
    rd_dropped: int = 0  # bytes the gateway dropped (CAN -> DAN)
    rd_lost: int = 0  # bytes skipped here (the gateway dropped them)
    accepted: int = 0  # of the last xfer's data


class GatewayClient:
    """Typed gateway calls over a Master whose bus has the gateway at
    master.baud. Each call is one transaction (the master retries lost
    ones) and raises the master's DanError on failure; a response that does
    not decode raises Malformed (counted in decode_errors)."""

    def __init__(self, master: Master, seed: Optional[int] = None):
        self.m = master
        master.reply_check = reply_check
        self.flags = 0  # from the last response that carries them
        self.escs_known = 0  # ESCs the gateway knows (ESC_CMD response)
        self.esc: dict[int, TelemRecord] = {}  # newest telemetry per ESC index
        self.config: Optional[ConfigResponse] = None
        self.stats: list[int] = []
        self.tun: dict[int, TunnelState] = {}
        self.can_seq: Optional[int] = None  # last CAN_SEND sequence number used
        self._unsent: Optional[CanSendRequest] = None  # a CAN_SEND whose transaction failed
        self.can_accepted = 0
        self.can_queue_free = 0
        self.can_rx_next: Optional[int] = None  # next raw frame sequence number wanted
        self.can_rx_dropped = 0
        self.can_rx_lost = 0
        self.can_rx_resyncs = 0
        self.decode_errors = 0
        self._rng = random.Random(seed)

    def _call(self, code: int, payload: bytes, decode: Callable):
        """One transaction: the request sealed, the reply unsealed (the
        master's reply check already refused a bad seal) and decoded."""
        reply = self.m.request(code, seal(code, REQUEST, payload))
        try:
            return decode(unseal(code, RESPONSE, reply))
        except (MalformedError, ValueError) as e:
            self.decode_errors += 1
            raise Malformed(f"{registry.code_name(code)}: bad response: {e}") from None

    def _malformed(self, code: int, why: str):
        self.decode_errors += 1
        return Malformed(f"{registry.code_name(code)}: {why}")

    # ---- ESCs, arming, settings, counters ----

    def esc_command(self, values: Sequence[int]) -> Optional[TelemRecord]:
        """Sends RawCommand values; returns the telemetry record that came
        back (round robin over the ESCs), also kept in self.esc."""
        t = self._call(CODE_ESC_CMD, encode_esc_cmd(values), Telemetry.decode)
        self.flags, self.escs_known = t.flags, t.aux
        for r in t.records:
            self.esc[r.esc_index] = r
        return t.records[0] if t.records else None

    def telemetry_page(self, first: int = 0) -> Telemetry:
        t = self._call(CODE_ESC_TELEM, bytes([first]), Telemetry.decode)
        self.flags = t.flags
        for r in t.records:
            self.esc[r.esc_index] = r
        return t

    def telemetry(self) -> list[TelemRecord]:
        """Every ESC's newest telemetry, page by page, in index order."""
        out, first = [], 0
        while True:
            t = self.telemetry_page(first)
            out += t.records
            if t.aux == NONE:
                return out
            if t.aux <= first:
                raise self._malformed(CODE_ESC_TELEM, f"next page {t.aux} does not advance")
            first = t.aux

    def arm(self, status: int = ARM_FULLY_ARMED) -> int:
        """ArmingStatus value (0 disarmed, 255 fully armed); returns the flags."""
        self.flags = self._call(
            CODE_ARM, bytes([_check(status, 0, 255, "arming status")]), decode_u8
        )
        return self.flags

    def read_config(self, set_req: Optional[ConfigRequest] = None) -> ConfigResponse:
        self.config = self._call(
            CODE_CONFIG, (set_req or ConfigRequest()).encode(), ConfigResponse.decode
        )
        self.flags = self.config.flags
        return self.config

    def read_stats(self) -> dict[str, int]:
        self.stats = self._call(CODE_STATS, b"", decode_stats)
        return stats_dict(self.stats)

    # ---- DroneCAN nodes ----

    def nodes_page(self, first: int = 1) -> NodesPage:
        return self._call(CODE_NODES, bytes([first]), NodesPage.decode)

    def nodes(self) -> list[NodeEntry]:
        out, first = [], 1
        while True:
            p = self.nodes_page(first)
            out += p.entries
            if p.next == 0:
                return out
            if p.next <= first:
                raise self._malformed(CODE_NODES, f"next page {p.next} does not advance")
            first = p.next

    def node_info(self, node_id: int) -> NodeInfo:
        i = self._call(CODE_NODE_INFO, bytes([node_id]), NodeInfo.decode)
        if i.node_id != node_id:
            raise self._malformed(CODE_NODE_INFO, f"answer for node {i.node_id}, not {node_id}")
        return i

    # ---- tunnels ----

    def tunnel_open(self, cfg: TunOpen) -> None:
        """Opens, reconfigures or (mode TUN_CLOSED) closes a port; both
        offsets restart at 0. Raises Nack if the gateway refused."""
        r = self._call(CODE_TUN_OPEN, cfg.encode(), TunOpenResult.decode)
        if r.port != cfg.port:
            raise self._malformed(CODE_TUN_OPEN, f"answer for port {r.port}, not {cfg.port}")
        if r.result != 0:
            raise Nack(f"the gateway refused tunnel port {cfg.port} ({cfg})")
        self.tun[cfg.port] = TunnelState()

    def tunnel_xfer(self, port: int, data: bytes = b"", rd_max: int = TUN_CHUNK_MAX) -> bytes:
        """Writes the first up to 128 bytes of data (the bytes from our write
        offset on: drop .tun[port].accepted of them afterwards and pass the
        rest again) and returns the new bytes read (up to rd_max)."""
        t = self.tun.setdefault(port, TunnelState())
        data = bytes(data[:TUN_CHUNK_MAX])
        req = TunXferRequest(port, t.wr_offset, t.rd_offset, min(rd_max, TUN_CHUNK_MAX), data)
        t.accepted = 0
        x = self._call(CODE_TUN_XFER, req.encode(), TunXferResponse.decode)
        if x.port != port:
            raise self._malformed(CODE_TUN_XFER, f"answer for port {x.port}, not {port}")
        adv = off_diff(x.wr_next, t.wr_offset)
        if not 0 <= adv <= len(data):
            raise self._malformed(CODE_TUN_XFER, f"took {adv} of {len(data)} bytes")
        skip = off_diff(x.rd_offset, t.rd_offset)
        if skip < 0:
            raise self._malformed(CODE_TUN_XFER, "data older than what we acknowledged")
        t.accepted, t.wr_offset = adv, x.wr_next
        t.wr_space, t.rd_dropped = x.wr_space, x.rd_dropped
        t.rd_lost += skip
        t.rd_offset = (x.rd_offset + len(x.data)) & 0xFFFFFFFF
        return x.data

    # ---- raw frames ----

    def _can_sync(self):
        """An empty CAN_SEND makes its sequence number the gateway's last
        accepted one, so our next (different) number is never taken for a
        retry of an earlier client's request."""
        self.can_seq = self._rng.randrange(256)
        self._call(CODE_CAN_SEND, CanSendRequest(self.can_seq).encode(), CanSendResponse.decode)

    def _can_send(self, req: CanSendRequest) -> int:
        self._unsent = req
        rsp = self._call(CODE_CAN_SEND, req.encode(), CanSendResponse.decode)
        self._unsent = None
        if rsp.seq != req.seq:
            raise self._malformed(CODE_CAN_SEND, f"answer for seq {rsp.seq}, not {req.seq}")
        self.can_accepted, self.can_queue_free = rsp.accepted, rsp.queue_free
        return rsp.accepted

    def can_send(self, frames: Sequence[CanFrame]) -> int:
        """Sends up to 11 frames, all or nothing: returns how many the
        gateway took (0: its queue was full, send them again later)."""
        if len(frames) > CAN_FRAMES_MAX:
            raise ValueError(f"at most {CAN_FRAMES_MAX} frames per CAN_SEND")
        if self.can_seq is None:
            self._can_sync()
        # a new number per call, not per attempt: the master's retries repeat it
        self.can_seq = (self.can_seq + 1) & 0xFF
        return self._can_send(CanSendRequest(self.can_seq, list(frames)))

    @property
    def can_send_failed(self) -> bool:
        """The last CAN_SEND's transaction failed: can_send_again() repeats it."""
        return self._unsent is not None

    def can_send_again(self) -> int:
        """Sends the CAN_SEND whose transaction failed again, with its
        sequence number: if the gateway took it before, it is not sent twice."""
        if self._unsent is None:
            raise ValueError("no failed CAN_SEND to repeat")
        return self._can_send(self._unsent)

    def can_recv(self, max_frames: int = CAN_FRAMES_MAX) -> list[CanFrame]:
        """The next frames that passed the filter (acknowledging the ones
        received before)."""
        first = self.can_rx_next is None
        req = CanRecvRequest(0 if first else self.can_rx_next, min(max_frames, CAN_FRAMES_MAX))
        q = self._call(CODE_CAN_RECV, req.encode(), CanRecvResponse.decode)
        if not first:
            skip = off_diff(q.first_seq, self.can_rx_next)
            if skip < 0 or skip > CAN_RESYNC:
                # not where we left off: the gateway restarted (its sequence
                # starts elsewhere each boot); follow it, as the C client does
                self.can_rx_resyncs += 1
            else:
                self.can_rx_lost += skip
        self.can_rx_next = (q.first_seq + len(q.frames)) & 0xFFFFFFFF
        self.can_rx_dropped = q.dropped
        return q.frames

    def can_listen(self, filters: Sequence[Filter]) -> list[Filter]:
        """Starts receiving with our filter: empties the filter, drops the
        frames still waiting in the gateway (they passed someone else's
        filter, earlier), then sets filters. Returns the table it replaced,
        for can_filter(FILTER_REPLACE, previous) at the end."""
        previous = self.can_filter(FILTER_READ).filters
        self.can_filter(FILTER_REPLACE, [])
        while self.can_recv():
            pass
        if self.can_filter(FILTER_REPLACE, filters).op != 0:
            raise Nack("the gateway's filter table is full")
        return previous

    def can_filter(self, op: int, filters: Sequence[Filter] = ()) -> FilterTable:
        """Changes (or, FILTER_READ, reads) the receive filter; returns the
        result (0 OK, 1 table full) and the gateway's table."""
        return self._call(
            CODE_CAN_FILTER, FilterTable(op, list(filters)).encode(), FilterTable.decode
        )
