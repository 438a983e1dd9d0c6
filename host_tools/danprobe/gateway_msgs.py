"""The CAN-over-DAN gateway's messages (docs/PROTOCOL.md section 7): the
payload codec of codes 0x42..0x4A, the limits and codes of all of them,
and the seal. The raw CAN messages (0x4B..0x4D) are in gateway_can.py,
the bus-management ones (0x4E, 0x4F, 0x52, 0x53) in gateway_mgmt.py, the
outputs (0x54..0x58: safety, servos, lights, buzzer) in gateway_out.py, the
client in gateway_client.py; together they mirror libdan's
peripherals/can_gateway (gw_msgs*.c, gw_client*.c).

The codec follows the document byte for byte (tests/vectors/gateway.txt
pins it, as it pins libdan's dan/can_gw/msgs.h): decoders never
read past the payload, raise PayloadError for a truncated payload or a
field out of range, and ignore trailing bytes. Float telemetry stays as
the IEEE binary16 bit patterns the ESC sent; as_dict() converts. The
message classes work on the inner payload; every gateway message travels
sealed (seal()/unseal(), tests/vectors/gateway_sealed.txt): the client
seals its requests and installs reply_check() as the master's reply check,
so a reply whose seal fails is retried, never decoded.
"""

import binascii
import struct
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Optional

from danprobe.codec import MalformedError, uvarint_encode
from danprobe.gateway_file import FwFollow
from danprobe.payloads import PayloadError, Reader, Record, Writer, attrs

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
CODE_NODE_CALL = 0x4E
CODE_CALL_RESULT = 0x4F
# the second block (0x50..0x5F; 0x50 and 0x51 never used)
CODE_HEALTH = 0x52
CODE_DNA = 0x53
# 0x54..0x58 (outputs): gateway_out.py

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
FLAG_SAFETY_OFF = 0x08  # SafetyState 255 being broadcast
FLAG_NAMES = (
    (FLAG_ARMED, "armed"),
    (FLAG_FAILSAFE, "failsafe"),
    (FLAG_CAN_OK, "can-up"),
    (FLAG_SAFETY_OFF, "safety-off"),
)

ARM_DISARMED, ARM_FULLY_ARMED = 0, 255

# telemetry record flags
TELEM_STATUS = 0x01
TELEM_EXT = 0x02
TELEM_DEVICE = 0x04  # device.Temperature of the ESC's node
TELEM_FLAGS = TELEM_STATUS | TELEM_EXT | TELEM_DEVICE
# device.Temperature error_flags
DEV_OVERHEATING, DEV_OVERCOOLING = 0x01, 0x02
# a record's as_dict keys by the part it holds (TELEM_DEVICE adds two flags)
TELEM_KEYS = (
    (
        TELEM_STATUS,
        ("age_ms", "voltage", "current", "temperature", "rpm", "power_pct", "error_count"),
    ),
    (
        TELEM_EXT,
        ("ext_age_ms", "input_pct", "output_pct", "motor_temp_c", "motor_angle", "status_flags"),
    ),
    (TELEM_DEVICE, ("dev_age_ms", "dev_temperature", "dev_flags")),
)

# CONFIG set mask
CFG_ESC_TIMEOUT = 0x01
CFG_ARMING_RATE = 0x02
CFG_TELEM_TIMEOUT = 0x04
CFG_DNA = 0x08
ESC_TIMEOUT_RANGE = (50, 60000)
ARMING_RATE_RANGE = (1, 50)
TELEM_TIMEOUT_RANGE = (100, 60000)  # or 0: the ESC telemetry check off

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
    "dna_allocations",
    "dna_bad",
    "dna_foreign",
    "duplicates",
    "calls",
    "call_timeouts",
    "servo_cmds",
    "servo_dropped",
    "file_reads",
    "file_bytes",
    "file_errors",
    "upload_bytes",
    "file_commits",
    "upload_errors",
    "fw_begins",
    "file_dropped",
)

# node table info_state
INFO_NONE, INFO_PENDING, INFO_VALID, INFO_FAILED = 0, 1, 2, 3
INFO_STATE_NAMES = ("not asked", "requested", "valid", "no answer")
# the NODES entry's last byte: info_state (bits 0-1) | these flags
INFO_MASK = 0x03
NODE_DUPLICATE = 0x04  # two nodes use this ID
NODE_OFFLINE = 0x08  # seen, then silent over 3 s
NODE_ALLOCATED = 0x10  # its ID came from the gateway's allocator
NODE_FLAG_NAMES = (
    (NODE_DUPLICATE, "duplicate"),
    (NODE_OFFLINE, "offline"),
    (NODE_ALLOCATED, "allocated"),
)
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
TUN_LOCK_PORT = 0x01  # Targetted option
TUN_DEFAULT_SERIAL = -1  # Targetted serial_id: the node's default port (replies: any serial_id)
TUN_ANY_CHANNEL = 0x01  # Broadcast option: replies on any channel_id are taken
PROTOCOL_UNDEFINED = 255  # uavcan.tunnel.Protocol, as ArduPilot's Targetted sends

# raw CAN
CAN_ID_EXT = 0x80000000
CAN_ID_RTR = 0x40000000
CAN_ID_OWN = 0x20000000  # CAN_RECV: a frame the gateway sent; CAN_FILTER: pass those too
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
CODE2_FIRST, CODE2_LAST = 0x52, 0x5F  # the second block's


def crc16_ccitt_false(data, crc: int = 0xFFFF) -> int:
    """CRC-16/CCITT-FALSE (poly 0x1021, no reflection): binascii's C
    crc_hqx is that CRC with the given start; a Python table loop cost
    30 us of every 2 Mbit/s FILE_WRITE exchange."""
    return binascii.crc_hqx(bytes(data), crc)


def sealed_code(code: int) -> bool:
    return CODE_FIRST <= code <= CODE_LAST or CODE2_FIRST <= code <= CODE2_LAST


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


def check_range(v: int, lo: int, hi: int, what: str) -> int:
    """v, if it is inside lo..hi; else ValueError naming what."""
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
    return [n for bit, n in FLAG_NAMES if flags & bit]


def flags_dict(flags: int) -> dict:
    return {
        "flags": flags,
        "armed": bool(flags & FLAG_ARMED),
        "failsafe": bool(flags & FLAG_FAILSAFE),
        "can_up": bool(flags & FLAG_CAN_OK),
        "safety_off": bool(flags & FLAG_SAFETY_OFF),
    }


def throttle_to_raw(pct: float) -> int:
    """Throttle percent (-100..100) to a RawCommand value (100 % = 8191)."""
    check_range(pct, -100, 100, "throttle %")
    return max(RAW_MIN, min(RAW_MAX, int(round(pct * RAW_MAX / 100.0))))


# ---- ESC_CMD (0x42) request: u8 n, n x int14 bit-packed LSB first ----


def encode_esc_cmd(values: Sequence[int]) -> bytes:
    if not 1 <= len(values) <= ESC_MAX:
        raise ValueError(f"ESC command: 1..{ESC_MAX} values, not {len(values)}")
    acc = 0
    for i, v in enumerate(values):
        check_range(v, RAW_MIN, RAW_MAX, f"ESC value {i}")
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


class EscStatusFloats:
    """The esc.Status numbers of a record whose fields voltage_f16,
    current_f16 and temperature_f16 hold binary16 bits (TelemRecord, the
    compact FastRecord)."""

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


@dataclass
class TelemRecord(EscStatusFloats):
    esc_index: int = 0
    node_id: int = 0
    flags: int = 0  # TELEM_STATUS | TELEM_EXT | TELEM_DEVICE
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
    dev_age_ms: int = 0
    dev_temp_f16: int = 0  # kelvin
    dev_flags: int = 0  # DEV_OVERHEATING | DEV_OVERCOOLING

    def put(self, w: Writer):
        w.u8(self.esc_index).u8(self.node_id).u8(self.flags & TELEM_FLAGS)
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
        if self.flags & TELEM_DEVICE:
            w.uvarint(self.dev_age_ms).u16(self.dev_temp_f16).u8(self.dev_flags)

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
        if t.flags & TELEM_DEVICE:
            t.dev_age_ms, t.dev_temp_f16 = r.uvarint("dev_age_ms"), r.u16("dev_temperature")
            t.dev_flags = r.u8("dev_error_flags")
        return t

    @property
    def dev_temperature(self) -> float:
        """Kelvin, as device.Temperature carries it."""
        return f16_to_float(self.dev_temp_f16)

    def as_dict(self) -> dict:
        d = {
            "index": self.esc_index,
            "node": self.node_id,
            "status": bool(self.flags & TELEM_STATUS),
            "extended": bool(self.flags & TELEM_EXT),
            "device": bool(self.flags & TELEM_DEVICE),
        }
        for flag, names in TELEM_KEYS:
            if self.flags & flag:
                d.update(attrs(self, *names))
        if self.flags & TELEM_DEVICE:
            d.update(
                overheating=bool(self.dev_flags & DEV_OVERHEATING),
                overcooling=bool(self.dev_flags & DEV_OVERCOOLING),
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
        return Writer().u8(self.flags).u8(self.aux).items(self.records).bytes()

    @classmethod
    def decode(cls, payload) -> "Telemetry":
        r = Reader(payload)
        t = cls(r.u8("flags"), r.u8("aux"))
        t.records = r.items(TelemRecord.get)
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


def _telem_timeout(v: int) -> int:
    if v != 0:
        check_range(v, *TELEM_TIMEOUT_RANGE, "telem_timeout_ms")
    return v


def _dna_setting(v: int) -> int:
    return check_range(v, 0, 1, "dna")


# set_mask bit, field, check of each settable field, in wire order
_CONFIG_FIELDS = (
    (
        CFG_ESC_TIMEOUT,
        "esc_timeout_ms",
        lambda v: check_range(v, *ESC_TIMEOUT_RANGE, "esc_timeout_ms"),
    ),
    (
        CFG_ARMING_RATE,
        "arming_rate_hz",
        lambda v: check_range(v, *ARMING_RATE_RANGE, "arming_rate_hz"),
    ),
    (CFG_TELEM_TIMEOUT, "telem_timeout_ms", _telem_timeout),
    (CFG_DNA, "dna", _dna_setting),
)


@dataclass
class ConfigRequest:
    """set_mask, then the fields it names: uv esc_timeout_ms, uv
    arming_rate_hz, uv telem_timeout_ms (0 or 100..60000), u8 dna (0/1)."""

    set_mask: int = 0
    esc_timeout_ms: int = 0
    arming_rate_hz: int = 0
    telem_timeout_ms: int = 0
    dna: int = 0

    def encode(self) -> bytes:
        w = Writer().u8(self.set_mask)
        for bit, name, ok in _CONFIG_FIELDS:
            if self.set_mask & bit:
                v = ok(getattr(self, name))
                if bit == CFG_DNA:
                    w.u8(v)
                else:
                    w.uvarint(v)
        return w.bytes()

    @classmethod
    def decode(cls, payload) -> "ConfigRequest":
        r = Reader(payload)
        c = cls(r.u8("set_mask") if r.remaining() else 0)
        try:
            for bit, name, ok in _CONFIG_FIELDS:
                if c.set_mask & bit:
                    setattr(c, name, ok(r.u8(name) if bit == CFG_DNA else r.uvarint(name)))
        except ValueError as e:
            if isinstance(e, MalformedError):
                raise
            raise PayloadError(str(e)) from None
        return c

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass
class ConfigResponse:
    """u8 node_id, uv esc_timeout_ms, uv arming_rate_hz, u8 flags, then (a
    gateway with bus management appends them) uv telem_timeout_ms, u8 dna."""

    node_id: int = 0
    esc_timeout_ms: int = 0
    arming_rate_hz: int = 0
    flags: int = 0
    telem_timeout_ms: int = 0
    dna: int = 0

    def encode(self) -> bytes:
        return (
            Writer()
            .u8(self.node_id)
            .uvarint(self.esc_timeout_ms)
            .uvarint(self.arming_rate_hz)
            .u8(self.flags)
            .uvarint(self.telem_timeout_ms)
            .u8(self.dna)
            .bytes()
        )

    @classmethod
    def decode(cls, payload) -> "ConfigResponse":
        r = Reader(payload)
        c = cls(
            r.u8("node_id"), r.uvarint("esc_timeout_ms"), r.uvarint("arming_rate_hz"), r.u8("flags")
        )
        if r.remaining():
            c.telem_timeout_ms, c.dna = r.uvarint("telem_timeout_ms"), r.u8("dna")
        return c

    def as_dict(self) -> dict:
        names = ("node_id", "esc_timeout_ms", "arming_rate_hz", "telem_timeout_ms", "dna")
        return {**attrs(self, *names), **flags_dict(self.flags)}


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
    info_state: int = 0  # INFO_* (bits 0-1 of the entry's last byte)
    node_flags: int = 0  # NODE_* (the other bits)

    def put(self, w: Writer):
        (
            w.u8(self.node_id)
            .u8((self.health & 3) | (self.mode & 7) << 2 | (self.sub_mode & 7) << 5)
            .uvarint(self.uptime_sec)
            .u16(self.vendor_status)
            .uvarint(self.age_ms)
            .u8((self.info_state & INFO_MASK) | (self.node_flags & ~INFO_MASK & 0xFF))
        )

    @classmethod
    def get(cls, r: Reader) -> "NodeEntry":
        nid, hm = r.u8("node_id"), r.u8("health/mode")
        e = cls(
            nid,
            hm & 3,
            (hm >> 2) & 7,
            hm >> 5,
            r.uvarint("uptime_sec"),
            r.u16("vendor_status"),
            r.uvarint("age_ms"),
        )
        last = r.u8("info_state")
        e.info_state, e.node_flags = last & INFO_MASK, last & ~INFO_MASK
        return e

    @property
    def flag_names(self) -> list[str]:
        return [n for bit, n in NODE_FLAG_NAMES if self.node_flags & bit]

    def as_dict(self) -> dict:
        d = asdict(self)
        d["health_name"] = HEALTH_NAMES[self.health]
        d["mode_name"] = MODE_NAMES.get(self.mode, str(self.mode))
        d.update({n: bool(self.node_flags & bit) for bit, n in NODE_FLAG_NAMES})
        return d


@dataclass
class NodesPage:
    next: int = 0  # node id to ask for next (0: end)
    entries: list[NodeEntry] = field(default_factory=list)

    def encode(self) -> bytes:
        return Writer().u8(self.next).items(self.entries).bytes()

    @classmethod
    def decode(cls, payload) -> "NodesPage":
        r = Reader(payload)
        p = cls(r.u8("next"))
        p.entries = r.items(NodeEntry.get)
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
    # the fields an update is followed by (gateway_file.py); None: a gateway
    # from before them sent none
    follow: Optional[FwFollow] = None

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
        if self.follow is not None:
            self.follow.put(w)
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
        if r.remaining():  # appended: all of them, or malformed
            i.follow = FwFollow.get(r)
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
        if self.follow is not None:
            d["follow"] = self.follow.as_dict()
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
class TunOpenResult(Record):
    port: int = 0
    result: int = 0  # 0 OK, 1 refused

    LAYOUT = (("port", "u8"), ("result", "u8"))


# ---- TUN_XFER (0x4A) ----


def _chunk(r: Reader) -> bytes:
    data = r.array("data")
    if len(data) > TUN_CHUNK_MAX:
        raise PayloadError(f"data: {len(data)} bytes, at most {TUN_CHUNK_MAX}")
    return data


class _TunXfer:
    """Both TUN_XFER layouts: u8 port, the uvarints named in OFFSETS (in that
    order), then the data (uvarint length, at most 128 bytes)."""

    OFFSETS = ()

    def encode(self) -> bytes:
        if len(self.data) > TUN_CHUNK_MAX:
            raise ValueError(f"tunnel data: at most {TUN_CHUNK_MAX} bytes")
        w = Writer().u8(self.port)
        for name in self.OFFSETS:
            w.uvarint(getattr(self, name))
        return w.array(self.data).bytes()

    @classmethod
    def decode(cls, payload):
        r = Reader(payload)
        port = r.u8("port")
        offsets = [r.uvarint(name) for name in cls.OFFSETS]
        return cls(port, *offsets, _chunk(r))

    def as_dict(self) -> dict:
        return {**asdict(self), "data": self.data.hex()}


@dataclass
class TunXferRequest(_TunXfer):
    port: int = 0
    wr_offset: int = 0  # stream offset of data[0]
    rd_offset: int = 0  # every byte before it was received
    rd_max: int = TUN_CHUNK_MAX
    data: bytes = b""

    OFFSETS = ("wr_offset", "rd_offset", "rd_max")


@dataclass
class TunXferResponse(_TunXfer):
    port: int = 0
    wr_next: int = 0  # bytes accepted so far
    wr_space: int = 0
    rd_offset: int = 0  # offset of data[0]
    rd_dropped: int = 0  # total bytes dropped, CAN -> DAN
    data: bytes = b""

    OFFSETS = ("wr_next", "wr_space", "rd_offset", "rd_dropped")
