"""The gateway's bus-management messages (docs/PROTOCOL.md section 7, "Bus
management"; libdan's dan/can_gw/msgs_mgmt.h): node service calls
(NODE_CALL 0x4E, CALL_RESULT 0x4F) and the results they read (parameters,
ExecuteOpcode, RestartNode), the health verdict (HEALTH 0x52) and the
dynamic node ID allocation table (DNA 0x53).

Same rules as gateway_msgs.py: inner payloads (the client seals them),
decoders never read past the payload, raise PayloadError for a truncated
payload or a field out of range and ignore trailing bytes;
tests/vectors/gateway.txt pins every layout. Parameter names and string
values stay bytes, as on the wire; as_dict() shows them as text.
"""

import math
import struct
from dataclasses import dataclass, field
from typing import Union

from danprobe.codec import MAX_PAYLOAD
from danprobe.gateway_file import file_name, get_name
from danprobe.gateway_msgs import SEAL_SIZE, check_range
from danprobe.payloads import PayloadError, Reader, Record, Writer, attrs

# ---- values (uavcan.protocol.param.Value on the DAN wire) ----
# u8 tag, then INTEGER i64 (8 bytes LE), REAL f32 (IEEE bits, 4 bytes LE),
# BOOLEAN u8, STRING array (<= 128); EMPTY nothing.
VALUE_EMPTY, VALUE_INTEGER, VALUE_REAL, VALUE_BOOLEAN, VALUE_STRING = 0, 1, 2, 3, 4
VALUE_TYPE_NAMES = ("empty", "integer", "real", "boolean", "string")
VALUE_STRING_MAX = 128
PARAM_NAME_MAX = 92
# A NODE_CALL must fit one frame with its seal: PARAM_SET's name and string
# value together (each within its own maximum) take at most 151 bytes.
CALL_REQUEST_MAX = MAX_PAYLOAD - SEAL_SIZE
PARAM_INDEX_MAX = 8191

# ---- NODE_CALL ops and call states ----
CALL_PARAM_GET_INDEX = 0
CALL_PARAM_GET_NAME = 1
CALL_PARAM_SET = 2
CALL_PARAM_SAVE = 3
CALL_PARAM_ERASE = 4
CALL_RESTART = 5
CALL_FW_BEGIN = 6  # file.BeginFirmwareUpdate (gateway_file.py: its result)
CALL_OP_MAX = CALL_FW_BEGIN
CALL_OP_NAMES = (
    "param get (index)",
    "param get",
    "param set",
    "param save",
    "param erase",
    "restart",
    "firmware update",
)

CALL_PENDING, CALL_DONE, CALL_TIMEOUT, CALL_BUSY = 0, 1, 2, 3
CALL_STATE_NAMES = ("pending", "done", "timeout", "busy")

RESTART_MAGIC = 0xACCE551B1E  # uavcan.protocol.RestartNode.MAGIC_NUMBER
MAGIC_MAX = (1 << 40) - 1
NODE_ID_MAX = 127

RESULT_CHUNK_MAX = 128  # data bytes of one CALL_RESULT

# param result: which optional values follow the value
PARAM_HAS_DEFAULT, PARAM_HAS_MAX, PARAM_HAS_MIN = 0x01, 0x02, 0x04

# ---- HEALTH ----
HEALTH_OK, HEALTH_FAIL = 0, 1
VERDICT_NAMES = ("OK", "FAIL")
# as libdan's dan_gw_reason_name()
REASON_NAMES = (
    "none",
    "can_down",
    "duplicate",
    "unhealthy",
    "offline",
    "esc_telemetry",
    "dna_conflict",
    "dna_full",
)
(
    REASON_NONE,
    REASON_CAN_DOWN,
    REASON_DUPLICATE,
    REASON_UNHEALTHY,
    REASON_OFFLINE,
    REASON_ESC_TELEMETRY,
    REASON_DNA_CONFLICT,
    REASON_DNA_FULL,
) = range(8)

# ---- DNA ----
DNA_ON, DNA_LOADED, DNA_STORE_ERROR = 0x01, 0x02, 0x04
DNA_FLAG_NAMES = ((DNA_ON, "server on"), (DNA_LOADED, "loaded"), (DNA_STORE_ERROR, "storage error"))
UNIQUE_ID_SIZE = 16
DNA_END = 0xFF


def _le(r: Reader, n: int, what: str) -> int:
    return int.from_bytes(r.raw(n, what), "little")


def _signed(v: int, bits: int) -> int:
    return v - (1 << bits) if v & (1 << (bits - 1)) else v


def reason_name(reason: int) -> str:
    return REASON_NAMES[reason] if reason < len(REASON_NAMES) else f"reason {reason}"


def _text(b: bytes) -> str:
    return b.decode("utf-8", "backslashreplace")


# ---- values ----

ValueType = Union[None, int, float, bytes]


@dataclass
class Value:
    """A parameter value: tag and the Python value (None; int; float; the
    boolean's byte, 0 false; bytes). A REAL is an f32: real_bits are its
    bits, exactly as on the wire."""

    tag: int = VALUE_EMPTY
    value: ValueType = None

    @classmethod
    def integer(cls, v: int) -> "Value":
        check_range(v, -(1 << 63), (1 << 63) - 1, "integer value")
        return cls(VALUE_INTEGER, int(v))

    @classmethod
    def real(cls, v: float) -> "Value":
        return cls(VALUE_REAL, struct.unpack("<f", struct.pack("<f", v))[0])

    @classmethod
    def boolean(cls, v: bool) -> "Value":
        return cls(VALUE_BOOLEAN, 1 if v else 0)

    @classmethod
    def string(cls, v: Union[str, bytes]) -> "Value":
        b = v.encode("utf-8") if isinstance(v, str) else bytes(v)
        if len(b) > VALUE_STRING_MAX:
            raise ValueError(f"string value: {len(b)} bytes, at most {VALUE_STRING_MAX}")
        return cls(VALUE_STRING, b)

    @property
    def real_bits(self) -> int:
        return struct.unpack("<I", struct.pack("<f", self.value))[0]

    @property
    def type_name(self) -> str:
        return VALUE_TYPE_NAMES[self.tag] if self.tag < len(VALUE_TYPE_NAMES) else str(self.tag)

    def put(self, w: Writer):
        w.u8(self.tag)
        if self.tag == VALUE_INTEGER:
            w.raw((self.value & (1 << 64) - 1).to_bytes(8, "little"))
        elif self.tag == VALUE_REAL:
            w.u32(self.real_bits)
        elif self.tag == VALUE_BOOLEAN:
            w.u8(int(self.value))
        elif self.tag == VALUE_STRING:
            if len(self.value) > VALUE_STRING_MAX:
                raise ValueError(f"string value: at most {VALUE_STRING_MAX} bytes")
            w.array(self.value)
        elif self.tag != VALUE_EMPTY:
            raise ValueError(f"value tag {self.tag}")

    @classmethod
    def get(cls, r: Reader, numeric: bool = False, what: str = "value") -> "Value":
        """numeric: only EMPTY, INTEGER and REAL (a max or min value)."""
        tag = r.u8(what + " tag")
        if tag > (VALUE_REAL if numeric else VALUE_STRING):
            raise PayloadError(f"{what}: tag {tag} is not allowed here")
        if tag == VALUE_INTEGER:
            return cls(tag, _signed(_le(r, 8, what), 64))
        if tag == VALUE_REAL:
            return cls(tag, struct.unpack("<f", r.raw(4, what))[0])
        if tag == VALUE_BOOLEAN:
            return cls(tag, r.u8(what))  # the byte as sent (0 false, else true)
        if tag == VALUE_STRING:
            data = r.array(what)
            if len(data) > VALUE_STRING_MAX:
                raise PayloadError(f"{what}: {len(data)} bytes, at most {VALUE_STRING_MAX}")
            return cls(tag, data)
        return cls(tag)

    def __eq__(self, other) -> bool:
        if not isinstance(other, Value) or self.tag != other.tag:
            return False
        if self.tag == VALUE_REAL:  # bit-exact (NaN equals itself)
            return self.real_bits == other.real_bits
        return self.value == other.value

    def plain(self):
        """The value for JSON: None, int, float, bool or str."""
        if self.tag == VALUE_STRING:
            return _text(self.value)
        if self.tag == VALUE_REAL and not math.isfinite(self.value):
            return str(self.value)
        if self.tag == VALUE_BOOLEAN:
            return bool(self.value)
        return self.value

    def text(self) -> str:
        if self.tag == VALUE_EMPTY:
            return "-"
        if self.tag == VALUE_REAL:
            return f"{self.value:.7g}"
        if self.tag == VALUE_BOOLEAN:
            return "true" if self.value else "false"
        if self.tag == VALUE_STRING:
            return repr(_text(self.value))
        return str(self.value)


def _name_bytes(name: Union[str, bytes]) -> bytes:
    b = name.encode("utf-8") if isinstance(name, str) else bytes(name)
    if not 1 <= len(b) <= PARAM_NAME_MAX:
        raise ValueError(f"parameter name: {len(b)} bytes, must be 1..{PARAM_NAME_MAX}")
    return b


# ---- NODE_CALL (0x4E) ----


@dataclass
class NodeCall:
    """Request: u16 call_id, u8 node_id (1..127), u8 op, then per op:
    GET_INDEX uv index; GET_NAME string name; SET string name, value; SAVE,
    ERASE nothing; RESTART u40 magic (5 bytes LE), u8 force; FW_BEGIN string
    name (a committed file's: 1..32 bytes of A-Z a-z 0-9 . _ -)."""

    call_id: int = 0
    node_id: int = 1
    op: int = CALL_PARAM_GET_INDEX
    index: int = 0
    name: bytes = b""
    value: Value = field(default_factory=Value)
    magic: int = RESTART_MAGIC
    force: bool = False

    def encode(self) -> bytes:
        check_range(self.call_id, 0, 0xFFFF, "call_id")
        check_range(self.node_id, 1, NODE_ID_MAX, "node_id")
        check_range(self.op, 0, CALL_OP_MAX, "op")
        w = Writer().u16(self.call_id).u8(self.node_id).u8(self.op)
        if self.op == CALL_PARAM_GET_INDEX:
            w.uvarint(check_range(self.index, 0, PARAM_INDEX_MAX, "index"))
        elif self.op in (CALL_PARAM_GET_NAME, CALL_PARAM_SET):
            w.array(_name_bytes(self.name))
            if self.op == CALL_PARAM_SET:
                self.value.put(w)
        elif self.op == CALL_RESTART:
            w.raw(check_range(self.magic, 0, MAGIC_MAX, "magic").to_bytes(5, "little"))
            w.u8(1 if self.force else 0)
        elif self.op == CALL_FW_BEGIN:
            w.array(file_name(self.name))
        out = w.bytes()
        if len(out) > CALL_REQUEST_MAX:
            raise ValueError(
                f"the request takes {len(out)} bytes, at most {CALL_REQUEST_MAX} "
                "(a shorter name or value)"
            )
        return out

    @classmethod
    def decode(cls, payload) -> "NodeCall":
        r = Reader(payload)
        c = cls(r.u16("call_id"), r.u8("node_id"), r.u8("op"))
        if c.op == CALL_PARAM_GET_INDEX:
            c.index = r.uvarint("index")
        elif c.op in (CALL_PARAM_GET_NAME, CALL_PARAM_SET):
            c.name = r.array("name")
            if c.op == CALL_PARAM_SET:
                c.value = Value.get(r)
        elif c.op == CALL_RESTART:
            c.magic, force = _le(r, 5, "magic"), r.u8("force")
            if force > 1:
                raise PayloadError(f"force: {force}, must be 0 or 1")
            c.force = bool(force)
        elif c.op == CALL_FW_BEGIN:
            c.name = get_name(r, "file name")
        named = c.op in (CALL_PARAM_GET_NAME, CALL_PARAM_SET)
        if (
            not 1 <= c.node_id <= NODE_ID_MAX
            or c.op > CALL_OP_MAX
            or c.index > PARAM_INDEX_MAX
            or (named and not 1 <= len(c.name) <= PARAM_NAME_MAX)
        ):
            raise PayloadError(f"NODE_CALL: node {c.node_id} op {c.op}: a field out of range")
        return c

    def as_dict(self) -> dict:
        d = {"call_id": self.call_id, "node_id": self.node_id, "op": self.op}
        d["op_name"] = CALL_OP_NAMES[self.op] if self.op < len(CALL_OP_NAMES) else str(self.op)
        if self.op == CALL_PARAM_GET_INDEX:
            d["index"] = self.index
        elif self.op in (CALL_PARAM_GET_NAME, CALL_PARAM_SET):
            d["name"] = _text(self.name)
            if self.op == CALL_PARAM_SET:
                d.update(type=self.value.type_name, value=self.value.plain())
        elif self.op == CALL_RESTART:
            d.update(magic=f"0x{self.magic:X}", force=self.force)
        elif self.op == CALL_FW_BEGIN:
            d["file"] = _text(self.name)
        return d


@dataclass
class CallState:
    """NODE_CALL response: u16 call_id, u8 state, uv result_len when DONE."""

    call_id: int = 0
    state: int = CALL_PENDING
    result_len: int = 0

    def encode(self) -> bytes:
        w = Writer().u16(self.call_id).u8(self.state)
        if self.state == CALL_DONE:
            w.uvarint(self.result_len)
        return w.bytes()

    @classmethod
    def decode(cls, payload) -> "CallState":
        r = Reader(payload)
        s = cls(r.u16("call_id"), r.u8("state"))
        if s.state > CALL_BUSY:
            raise PayloadError(f"call state {s.state}")
        if s.state == CALL_DONE:
            s.result_len = r.uvarint("result_len")
        return s

    def as_dict(self) -> dict:
        return {
            "call_id": self.call_id,
            "state": CALL_STATE_NAMES[self.state],
            "result_len": self.result_len,
        }


# ---- CALL_RESULT (0x4F) ----


@dataclass
class CallResultRequest(Record):
    """u16 call_id, uv offset, u8 max."""

    call_id: int = 0
    offset: int = 0
    max: int = RESULT_CHUNK_MAX

    LAYOUT = (("call_id", "u16"), ("offset", "uvarint"), ("max", "u8"))


@dataclass
class CallResultResponse(Record):
    """u16 call_id, u8 state, uv result_len, uv offset, array data (<= 128;
    empty until DONE)."""

    call_id: int = 0
    state: int = CALL_PENDING
    result_len: int = 0
    offset: int = 0
    data: bytes = b""

    LAYOUT = (
        ("call_id", "u16"),
        ("state", "u8"),
        ("result_len", "uvarint"),
        ("offset", "uvarint"),
        ("data", "array"),
    )

    def encode(self) -> bytes:
        if len(self.data) > RESULT_CHUNK_MAX:
            raise ValueError(f"CALL_RESULT: at most {RESULT_CHUNK_MAX} data bytes")
        return super().encode()

    @classmethod
    def decode(cls, payload) -> "CallResultResponse":
        q = super().decode(payload)
        if q.state > CALL_BUSY or len(q.data) > RESULT_CHUNK_MAX:
            raise PayloadError(f"CALL_RESULT: state {q.state}, {len(q.data)} data bytes")
        return q

    def as_dict(self) -> dict:
        d = CallState.as_dict(self)  # call_id, state by name, result_len
        return {**d, "offset": self.offset, "data": self.data.hex()}


# ---- call results (the bytes CALL_RESULT reads) ----


@dataclass
class ParamResult:
    """PARAM_*: u8 present, value, [default], [max], [min] (max and min
    numeric), string name (empty: the node has no such parameter)."""

    value: Value = field(default_factory=Value)
    default: Value = None
    max: Value = None
    min: Value = None
    name: bytes = b""

    @property
    def present(self) -> int:
        return (
            (PARAM_HAS_DEFAULT if self.default is not None else 0)
            | (PARAM_HAS_MAX if self.max is not None else 0)
            | (PARAM_HAS_MIN if self.min is not None else 0)
        )

    @property
    def exists(self) -> bool:
        return bool(self.name)

    @property
    def name_text(self) -> str:
        return _text(self.name)

    def encode(self) -> bytes:
        if len(self.name) > PARAM_NAME_MAX:
            raise ValueError(f"parameter name: at most {PARAM_NAME_MAX} bytes")
        w = Writer().u8(self.present)
        self.value.put(w)
        for v in (self.default, self.max, self.min):
            if v is not None:
                v.put(w)
        return w.array(self.name).bytes()

    @classmethod
    def decode(cls, payload) -> "ParamResult":
        r = Reader(payload)
        present = r.u8("present")
        p = cls(Value.get(r))
        if present & PARAM_HAS_DEFAULT:
            p.default = Value.get(r, what="default")
        if present & PARAM_HAS_MAX:
            p.max = Value.get(r, True, "max")
        if present & PARAM_HAS_MIN:
            p.min = Value.get(r, True, "min")
        p.name = r.array("name")
        if len(p.name) > PARAM_NAME_MAX:
            raise PayloadError(f"name: {len(p.name)} bytes, at most {PARAM_NAME_MAX}")
        return p

    def as_dict(self) -> dict:
        d = {"name": self.name_text, "type": self.value.type_name, "value": self.value.plain()}
        for k in ("default", "min", "max"):
            v = getattr(self, k)
            if v is not None:
                d[k] = v.plain()
        return d


@dataclass
class OpcodeResult:
    """PARAM_SAVE, PARAM_ERASE: u8 ok, i48 argument (6 bytes LE). RESTART:
    u8 ok alone (argument 0)."""

    ok: bool = False
    argument: int = 0

    def encode(self) -> bytes:
        check_range(self.argument, -(1 << 47), (1 << 47) - 1, "argument")
        return bytes([int(self.ok)]) + (self.argument & (1 << 48) - 1).to_bytes(6, "little")

    @classmethod
    def decode(cls, payload) -> "OpcodeResult":
        r = Reader(payload)
        o = cls(bool(r.u8("ok")))
        if r.remaining():
            o.argument = _signed(_le(r, 6, "argument"), 48)
        return o

    def as_dict(self) -> dict:
        return {"ok": self.ok, "argument": self.argument}


# ---- HEALTH (0x52) ----


@dataclass
class Health:
    """u8 verdict, u8 reason, u8 subject (node ID or ESC index), u8 detail,
    u8 problems (how many reasons apply)."""

    verdict: int = HEALTH_OK
    reason: int = REASON_NONE
    subject: int = 0
    detail: int = 0
    problems: int = 0

    def encode(self) -> bytes:
        return bytes([self.verdict, self.reason, self.subject, self.detail, self.problems])

    @classmethod
    def decode(cls, payload) -> "Health":
        r = Reader(payload)
        return cls(*(r.u8(k) for k in ("verdict", "reason", "subject", "detail", "problems")))

    @property
    def ok(self) -> bool:
        return self.verdict == HEALTH_OK

    @property
    def verdict_name(self) -> str:
        return VERDICT_NAMES[self.verdict] if self.verdict < 2 else f"verdict {self.verdict}"

    def text(self) -> str:
        """ "OK", or "FAIL: unhealthy node 31 (detail 2), 3 problem(s)"."""
        if self.reason == REASON_NONE:
            return self.verdict_name
        what = {
            REASON_DUPLICATE: "node",
            REASON_UNHEALTHY: "node",
            REASON_OFFLINE: "node",
            REASON_DNA_CONFLICT: "allocator node",
            REASON_ESC_TELEMETRY: "ESC",
        }.get(self.reason)
        out = f"{self.verdict_name}: {reason_name(self.reason)}"
        if what:
            out += f" {what} {self.subject}"
        if self.reason == REASON_UNHEALTHY:
            out += f" (health {('OK', 'WARNING', 'ERROR', 'CRITICAL')[self.detail & 3]})"
        elif self.detail:
            out += f" (detail {self.detail})"
        return out + f", {self.problems} problem(s)"

    def as_dict(self) -> dict:
        return {
            "verdict": self.verdict_name,
            "ok": self.ok,
            "reason": reason_name(self.reason),
            "reason_code": self.reason,
            **attrs(self, "subject", "detail", "problems"),
        }


# ---- DNA (0x53) ----


@dataclass
class DnaEntry:
    node_id: int = 0
    unique_id: bytes = bytes(UNIQUE_ID_SIZE)

    def as_dict(self) -> dict:
        return {"node_id": self.node_id, "unique_id": self.unique_id.hex()}


@dataclass
class DnaPage:
    """u8 flags, u8 entries (in use), u8 capacity, u8 next (0xFF: end), u8
    count, count x (u8 node_id, 16 bytes unique_id)."""

    flags: int = 0
    entries: int = 0
    capacity: int = 0
    next: int = DNA_END
    items: list[DnaEntry] = field(default_factory=list)

    def encode(self) -> bytes:
        w = Writer().u8(self.flags).u8(self.entries).u8(self.capacity).u8(self.next)
        w.u8(len(self.items))
        for e in self.items:
            if len(e.unique_id) != UNIQUE_ID_SIZE:
                raise ValueError("unique_id must be 16 bytes")
            w.u8(e.node_id).raw(e.unique_id)
        return w.bytes()

    @classmethod
    def decode(cls, payload) -> "DnaPage":
        r = Reader(payload)
        p = cls(r.u8("flags"), r.u8("entries"), r.u8("capacity"), r.u8("next"))
        p.items = [
            DnaEntry(r.u8("node_id"), r.raw(UNIQUE_ID_SIZE, "unique_id"))
            for _ in range(r.u8("count"))
        ]
        return p

    @property
    def flag_names(self) -> list[str]:
        return dna_flag_names(self.flags)

    def as_dict(self) -> dict:
        return {
            "flags": self.flags,
            "server_on": bool(self.flags & DNA_ON),
            "loaded": bool(self.flags & DNA_LOADED),
            "store_error": bool(self.flags & DNA_STORE_ERROR),
            "entries": self.entries,
            "capacity": self.capacity,
            "next": self.next,
            "table": [e.as_dict() for e in self.items],
        }


def dna_flag_names(flags: int) -> list[str]:
    return [n for bit, n in DNA_FLAG_NAMES if flags & bit]
