"""The common DAN v1 payloads: identity, configure, ACK and error message
(docs/PROTOCOL.md section 3), and a bounds-checked reader and writer.

Decoders never read past the payload: a truncated or lying payload raises
PayloadError (a MalformedError). Bytes after the last known field are
ignored (later versions may append fields); reserved mask bits are kept
raw. Strings are decoded as UTF-8 with undecodable bytes escaped; unlike
libdan's fixed 32-byte buffers they are never truncated.
"""

import struct
from dataclasses import asdict, dataclass

from danprobe.codec import MalformedError, uvarint_decode, uvarint_encode

VERSION = 1

# DAN-PERIPHERAL-SUPPORTED-BAUDRATES-MASK-V1: bit i is MASK_BAUDS[i].
BASE_BAUD = 9600
MASK_BAUDS = (19200, 38400, 57600, 115200)
MASK_DEFINED = 0x000F

CONFIGURE_BPS = 0  # DAN-PERIPHERAL-CONFIGURATION-REQUEST-TYPE-ENUM-V1

ACK_OK = 0
ACK_FAIL = 1


class PayloadError(MalformedError):
    """A payload that does not follow its format."""


class UnsupportedRequest(ValueError):
    """A well-formed CONFIGURE with a request type v1 does not define."""

    def __init__(self, request_type: int):
        super().__init__(f"unknown configure request type {request_type}")
        self.request_type = request_type


def mask_bit_of_baud(baud: int) -> int:
    """Mask bit of a baud; 0 for 9600 or a baud with no bit."""
    return 1 << MASK_BAUDS.index(baud) if baud in MASK_BAUDS else 0


def bauds_of_mask(mask: int) -> list[int]:
    """Every baud a peripheral with this mask supports (9600 always),
    ascending; undefined bits are ignored."""
    return [BASE_BAUD] + [b for i, b in enumerate(MASK_BAUDS) if mask & (1 << i)]


def supports(mask: int, baud: int) -> bool:
    return baud == BASE_BAUD or bool(mask & MASK_DEFINED & mask_bit_of_baud(baud))


# ---- reader / writer ----


class Reader:
    """Reads fields from a received payload; any read past its end (or a
    bad uvarint, or an array longer than what remains) raises PayloadError
    naming the field."""

    def __init__(self, data):
        self.data = bytes(data)
        self.pos = 0

    def remaining(self) -> int:
        return len(self.data) - self.pos

    def raw(self, n: int, what: str = "bytes") -> bytes:
        if n > self.remaining():
            raise PayloadError(
                f"{what}: needs {n} byte(s) at offset {self.pos}, {self.remaining()} left"
            )
        out = self.data[self.pos : self.pos + n]
        self.pos += n
        return out

    def u8(self, what: str = "uint8") -> int:
        return self.raw(1, what)[0]

    def u16(self, what: str = "uint16") -> int:
        return struct.unpack("<H", self.raw(2, what))[0]

    def u24(self, what: str = "uint24") -> int:
        b = self.raw(3, what)
        return b[0] | b[1] << 8 | b[2] << 16

    def u32(self, what: str = "uint32") -> int:
        return struct.unpack("<I", self.raw(4, what))[0]

    def uvarint(self, what: str = "uvarint") -> int:
        try:
            v, n = uvarint_decode(self.data, self.pos)
        except MalformedError as e:
            raise PayloadError(f"{what}: {e} at offset {self.pos}") from None
        if n == 0:
            raise PayloadError(f"{what}: truncated uvarint at offset {self.pos}")
        self.pos += n
        return v

    def array(self, what: str = "array") -> bytes:
        n = self.uvarint(what + " length")
        return self.raw(n, what)

    def string(self, what: str = "string") -> str:
        return self.array(what).decode("utf-8", "backslashreplace")

    def items(self, get, what: str = "count") -> list:
        """A u8 count, then that many items, each get(reader)."""
        return [get(self) for _ in range(self.u8(what))]


class Writer:
    def __init__(self):
        self.buf = bytearray()

    def u8(self, v: int) -> "Writer":
        self.buf += struct.pack("<B", v)
        return self

    def u16(self, v: int) -> "Writer":
        self.buf += struct.pack("<H", v)
        return self

    def u24(self, v: int) -> "Writer":
        if not 0 <= v <= 0xFFFFFF:
            raise ValueError(f"uint24 out of range: {v}")
        self.buf += struct.pack("<I", v)[:3]
        return self

    def u32(self, v: int) -> "Writer":
        self.buf += struct.pack("<I", v)
        return self

    def uvarint(self, v: int) -> "Writer":
        self.buf += uvarint_encode(v)
        return self

    def raw(self, data) -> "Writer":
        self.buf += data
        return self

    def array(self, data) -> "Writer":
        return self.uvarint(len(data)).raw(data)

    def string(self, s: str) -> "Writer":
        return self.array(s.encode("utf-8"))

    def items(self, items) -> "Writer":
        """A u8 count, then each item's put(writer)."""
        self.u8(len(items))
        for x in items:
            x.put(self)
        return self

    def bytes(self) -> bytes:
        return bytes(self.buf)


# ---- DAN-PERIPHERAL-IDENTITY-PAYLOAD-V1 ----


def attrs(obj, *names) -> dict:
    """{name: obj.name} for each name, in order (as_dict's common part)."""
    return {n: getattr(obj, n) for n in names}


class Record:
    """A dataclass message that is a fixed list of fields: LAYOUT holds
    (attribute, kind) or (attribute, kind, what) with kind a Writer/Reader
    method (u8, u16, u24, u32, uvarint, array, string) and what the name a
    decode error gives (default: the attribute). Encode and decode follow
    the layout, so each layout is written once."""

    LAYOUT: tuple = ()

    def encode(self) -> bytes:
        w = Writer()
        for name, kind, *_ in self.LAYOUT:
            getattr(w, kind)(getattr(self, name))
        return w.bytes()

    @classmethod
    def decode(cls, payload):
        r = Reader(payload)
        # an error names the entry's label, else its attribute (not its kind)
        return cls(**{f[0]: getattr(r, f[1])(f[2] if len(f) > 2 else f[0]) for f in cls.LAYOUT})

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass
class Identity(Record):
    dan_version: int = VERSION
    manufacturer: str = ""
    model: str = ""
    hw_version: str = ""
    sw_version: str = ""
    baud_mask: int = 0  # raw, as on the wire
    capabilities: int = 0  # raw, as on the wire

    LAYOUT = (
        ("dan_version", "u8"),
        ("manufacturer", "string"),
        ("model", "string"),
        ("hw_version", "string"),
        ("sw_version", "string"),
        ("baud_mask", "u16"),
        ("capabilities", "u16"),
    )

    @property
    def bauds(self) -> list[int]:
        return bauds_of_mask(self.baud_mask)

    def as_dict(self) -> dict:
        d = asdict(self)
        d["bauds"] = self.bauds
        return d


# ---- DAN-PERIPHERAL-CONFIGURE-PAYLOAD-V1 ----


@dataclass
class Configure:
    request_type: int = CONFIGURE_BPS
    baud: int = BASE_BAUD

    def encode(self) -> bytes:
        w = Writer().u8(self.request_type)
        if self.request_type == CONFIGURE_BPS:
            w.uvarint(self.baud)
        return w.bytes()

    @classmethod
    def decode(cls, payload) -> "Configure":
        """PayloadError if truncated; UnsupportedRequest for a request type
        v1 does not define (a peripheral answers it with ACK-FAIL)."""
        r = Reader(payload)
        t = r.u8("request_type")
        if t != CONFIGURE_BPS:
            raise UnsupportedRequest(t)
        return cls(t, r.uvarint("baud"))

    def as_dict(self) -> dict:
        return asdict(self)


# ---- DAN-PERIPHERAL-ACK (our rule: one byte, 0 OK or 1 FAIL) ----


def encode_ack(value: int) -> bytes:
    if value not in (ACK_OK, ACK_FAIL):
        raise ValueError(f"ACK must be 0 or 1, not {value}")
    return bytes([value])


def decode_ack(payload) -> int:
    v = Reader(payload).u8("ack")
    if v not in (ACK_OK, ACK_FAIL):
        raise PayloadError(f"ack: {v} is neither 0 (OK) nor 1 (FAIL)")
    return v


# ---- DAN-ERROR-MESSAGE-V1 (payload of code 0) ----


@dataclass
class ErrorMessage(Record):
    code: int = 0  # the request code that caused the error
    error: int = 0  # reserved, 0 in v1
    text: str = ""

    LAYOUT = (
        ("code", "uvarint", "request_code"),
        ("error", "uvarint", "error_code"),
        ("text", "string", "description"),
    )
