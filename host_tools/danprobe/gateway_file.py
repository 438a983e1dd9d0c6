"""The gateway's file store and firmware updates (docs/PROTOCOL.md section 7,
"Files and firmware updates"): FILE_OPEN 0x5B, FILE_WRITE 0x5C, FILE_COMMIT
0x5D, FILE_LIST 0x5E, FILE_REMOVE 0x5F, the result of NODE_CALL op 6
FW_BEGIN (uavcan.protocol.file.BeginFirmwareUpdate) and the fields NODE_INFO
appends to follow an update.

Same rules as gateway_msgs.py: inner payloads (the client seals them),
decoders never read past the payload, raise PayloadError for a truncated
payload or a field out of range and ignore trailing bytes. This module
imports only payloads.py, so gateway_msgs.py (NODE_INFO) and
gateway_mgmt.py (NODE_CALL) can use it. Names stay bytes, as on the wire.
"""

import zlib
from dataclasses import dataclass, field
from typing import Optional, Union

from danprobe.payloads import PayloadError, Reader, Record, Writer

CODE_FILE_OPEN = 0x5B
CODE_FILE_WRITE = 0x5C
CODE_FILE_COMMIT = 0x5D
CODE_FILE_LIST = 0x5E
CODE_FILE_REMOVE = 0x5F

NAME_MAX = 32
NAME_CHARS = frozenset(b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789._-")
WRITE_MAX = 150  # data bytes of one FILE_WRITE
SIZE_MAX = 0xFFFFFFFF  # u32 on the wire (the store's cap is lower: TOO_LARGE)
OPEN_RESTART = 0x01  # FILE_OPEN flags bit0
LIST_END = 0xFF

# results of the file messages
(
    FILE_OK,
    FILE_NO_UPLOAD,
    FILE_GAP,
    FILE_TOO_LARGE,
    FILE_SHORT,
    FILE_CRC,
    FILE_NOT_FOUND,
    FILE_IO_ERROR,
    FILE_NO_STORE,
    FILE_IN_USE,
    FILE_NO_SPACE,
) = range(11)
RESULT_NAMES = (
    "ok",
    "no upload open",
    "gap (offset beyond the bytes held)",
    "too large",
    "short (not every byte uploaded)",
    "crc mismatch",
    "not found",
    "i/o error in the store",
    "no file store",
    "in use (a node is reading the file it would replace)",
    "no space (the store is full: remove files)",
)

# FW_BEGIN result: uavcan.protocol.file.BeginFirmwareUpdate.Response error
FW_OK, FW_INVALID_MODE, FW_IN_PROGRESS, FW_UNKNOWN = 0, 1, 2, 255
FW_ERROR_NAMES = {0: "ok", 1: "invalid mode", 2: "in progress", 255: "unknown"}
FW_MESSAGE_MAX = 127

# NODE_INFO follow fields
STATUS_NONE = 0xFF  # no NodeStatus heard
FW_BEGUN = 0x01  # file flags bit0: a BeginFirmwareUpdate was answered OK
FW_READING = 0x02  # bit1: it has read since
NEVER_READ = 0xFFFFFFFF
MODE_SOFTWARE_UPDATE = 3
MODE_OPERATIONAL = 0


def result_name(result: int) -> str:
    return RESULT_NAMES[result] if result < len(RESULT_NAMES) else f"result {result}"


def fw_error_name(error: int) -> str:
    return FW_ERROR_NAMES.get(error, f"error {error}")


def crc32(data: bytes, crc: int = 0) -> int:
    """zlib's CRC-32 (IEEE 802.3), the one FILE_COMMIT carries; crc: the
    value so far, to continue over more bytes."""
    return zlib.crc32(data, crc) & 0xFFFFFFFF


def name_problem(name: bytes) -> Optional[str]:
    """Why name is not a store name (1..32 bytes of A-Z a-z 0-9 . _ -, not
    starting with '.'), or None."""
    if not 1 <= len(name) <= NAME_MAX:
        return f"{len(name)} bytes, must be 1..{NAME_MAX}"
    if name[0] == ord("."):
        return "starts with '.'"
    bad = next((b for b in name if b not in NAME_CHARS), None)
    if bad is not None:
        return f"byte 0x{bad:02x} ({chr(bad)!r}) is not one of A-Z a-z 0-9 . _ -"
    return None


def file_name(name: Union[str, bytes]) -> bytes:
    """name as wire bytes; ValueError (saying why) if it is no store name."""
    b = name.encode("utf-8") if isinstance(name, str) else bytes(name)
    why = name_problem(b)
    if why:
        raise ValueError(f"file name {b!r}: {why}")
    return b


def get_name(r: Reader, what: str = "name") -> bytes:
    b = r.array(what)
    why = name_problem(b)
    if why:
        raise PayloadError(f"{what}: {why}")
    return b


def _text(b: bytes) -> str:
    return b.decode("utf-8", "backslashreplace")


def _u32(v: int, what: str) -> int:
    if not 0 <= v <= SIZE_MAX:
        raise ValueError(f"{what}: {v} is outside 0..{SIZE_MAX}")
    return v


# ---- FILE_OPEN (0x5B) ----


@dataclass
class FileOpen:
    """string name, u32 size, u8 flags (bit0 restart)."""

    name: bytes = b""
    size: int = 0
    flags: int = 0

    @property
    def restart(self) -> bool:
        return bool(self.flags & OPEN_RESTART)

    def encode(self) -> bytes:
        if self.flags & ~OPEN_RESTART:
            raise ValueError(f"FILE_OPEN: flags 0x{self.flags:02x}, only bit0 (restart)")
        w = Writer().array(file_name(self.name)).u32(_u32(self.size, "size"))
        return w.u8(self.flags).bytes()

    @classmethod
    def decode(cls, payload) -> "FileOpen":
        r = Reader(payload)
        o = cls(get_name(r), r.u32("size"), r.u8("flags"))
        if o.flags & ~OPEN_RESTART:
            raise PayloadError(f"FILE_OPEN: flags 0x{o.flags:02x}, only bit0 (restart) is defined")
        return o

    def as_dict(self) -> dict:
        return {"name": _text(self.name), "size": self.size, "restart": self.restart}


@dataclass
class FileState(Record):
    """FILE_OPEN and FILE_WRITE response: u8 result, uv have (the bytes the
    upload holds, contiguous from 0: where to go on)."""

    result: int = FILE_OK
    have: int = 0

    LAYOUT = (("result", "u8"), ("have", "uvarint"))

    def as_dict(self) -> dict:
        return {"result": result_name(self.result), "have": self.have}


# ---- FILE_WRITE (0x5C) ----


@dataclass
class FileWrite:
    """uv offset, array data (1..150)."""

    offset: int = 0
    data: bytes = b""

    def encode(self) -> bytes:
        if not 1 <= len(self.data) <= WRITE_MAX:
            raise ValueError(f"FILE_WRITE: {len(self.data)} data bytes, must be 1..{WRITE_MAX}")
        return Writer().uvarint(_u32(self.offset, "offset")).array(self.data).bytes()

    @classmethod
    def decode(cls, payload) -> "FileWrite":
        r = Reader(payload)
        w = cls(r.uvarint("offset"), r.array("data"))
        if not 1 <= len(w.data) <= WRITE_MAX:
            raise PayloadError(f"FILE_WRITE: {len(w.data)} data bytes, must be 1..{WRITE_MAX}")
        return w

    def as_dict(self) -> dict:
        return {"offset": self.offset, "length": len(self.data)}


# ---- FILE_COMMIT (0x5D) ----


@dataclass
class FileCommit:
    """Request: u32 crc32 (of the whole file). Response: u8 result, u32 the
    crc32 of the bytes the gateway holds (the request's crc absent: 0)."""

    result: int = FILE_OK
    crc: int = 0

    def encode_request(self) -> bytes:
        return Writer().u32(_u32(self.crc, "crc32")).bytes()

    def encode(self) -> bytes:
        return Writer().u8(self.result).u32(_u32(self.crc, "crc32")).bytes()

    @classmethod
    def decode_request(cls, payload) -> "FileCommit":
        return cls(FILE_OK, Reader(payload).u32("crc32"))

    @classmethod
    def decode(cls, payload) -> "FileCommit":
        r = Reader(payload)
        return cls(r.u8("result"), r.u32("crc32"))

    def as_dict(self) -> dict:
        return {"result": result_name(self.result), "crc32": f"0x{self.crc:08x}"}


# ---- FILE_LIST (0x5E) ----


@dataclass
class FileEntry:
    name: bytes = b""
    size: int = 0

    @property
    def name_text(self) -> str:
        return _text(self.name)

    def as_dict(self) -> dict:
        return {"name": self.name_text, "size": self.size}


@dataclass
class FileListPage:
    """u8 next (0xFF end), u8 count, count x (string name, uv size); the
    request is u8 first index."""

    next: int = LIST_END
    entries: list[FileEntry] = field(default_factory=list)

    def encode(self) -> bytes:
        w = Writer().u8(self.next).u8(len(self.entries))
        for e in self.entries:
            w.array(file_name(e.name)).uvarint(e.size)
        return w.bytes()

    @classmethod
    def decode(cls, payload) -> "FileListPage":
        r = Reader(payload)
        p = cls(r.u8("next"))
        p.entries = [FileEntry(get_name(r), r.uvarint("size")) for _ in range(r.u8("count"))]
        return p

    def as_dict(self) -> dict:
        return {"next": self.next, "files": [e.as_dict() for e in self.entries]}


# ---- FILE_REMOVE (0x5F): request string name, response u8 result ----


def encode_name(name: Union[str, bytes]) -> bytes:
    return Writer().array(file_name(name)).bytes()


def decode_name(payload) -> bytes:
    return get_name(Reader(payload))


def decode_result(payload) -> int:
    return Reader(payload).u8("result")


# ---- FW_BEGIN (NODE_CALL op 6): the result CALL_RESULT reads ----


@dataclass
class FwBeginResult:
    """u8 error (0 OK, 1 INVALID_MODE, 2 IN_PROGRESS, 255 UNKNOWN), string
    optional_error_message (<= 127)."""

    error: int = FW_OK
    message: bytes = b""

    @property
    def ok(self) -> bool:
        return self.error == FW_OK

    def encode(self) -> bytes:
        if len(self.message) > FW_MESSAGE_MAX:
            raise ValueError(f"error message: at most {FW_MESSAGE_MAX} bytes")
        return Writer().u8(self.error).array(self.message).bytes()

    @classmethod
    def decode(cls, payload) -> "FwBeginResult":
        r = Reader(payload)
        f = cls(r.u8("error"), r.array("message"))
        if len(f.message) > FW_MESSAGE_MAX:
            raise PayloadError(f"message: {len(f.message)} bytes, at most {FW_MESSAGE_MAX}")
        return f

    def text(self) -> str:
        msg = f" ({_text(self.message)})" if self.message else ""
        return fw_error_name(self.error) + msg

    def as_dict(self) -> dict:
        return {
            "error": self.error,
            "name": fw_error_name(self.error),
            "message": _text(self.message),
        }


# ---- NODE_INFO's appended fields ----


@dataclass
class FwFollow:
    """After NODE_INFO's info (or its info_state when there is none): u8
    status (health | mode<<2 | sub_mode<<5, 0xFF none), u8 file flags (bit0
    begun, bit1 reading), uv bytes_read, uv file_size (0 none), u32 ms since
    the node's last read (0xFFFFFFFF never)."""

    status: int = STATUS_NONE
    file_flags: int = 0
    bytes_read: int = 0
    file_size: int = 0
    since_read_ms: int = NEVER_READ

    def put(self, w: Writer):
        w.u8(self.status).u8(self.file_flags).uvarint(self.bytes_read).uvarint(self.file_size)
        w.u32(self.since_read_ms)

    @classmethod
    def get(cls, r: Reader) -> "FwFollow":
        return cls(
            r.u8("status"),
            r.u8("file flags"),
            r.uvarint("bytes_read"),
            r.uvarint("file_size"),
            r.u32("ms since read"),
        )

    @property
    def has_status(self) -> bool:
        return self.status != STATUS_NONE

    @property
    def health(self) -> int:
        return self.status & 3

    @property
    def mode(self) -> int:
        return (self.status >> 2) & 7

    @property
    def sub_mode(self) -> int:
        return self.status >> 5

    @property
    def begun(self) -> bool:
        return bool(self.file_flags & FW_BEGUN)

    @property
    def reading(self) -> bool:
        return bool(self.file_flags & FW_READING)

    def as_dict(self) -> dict:
        d = {"status": self.status}
        if self.has_status:
            d.update(health=self.health, mode=self.mode, sub_mode=self.sub_mode)
        d.update(
            begun=self.begun,
            reading=self.reading,
            bytes_read=self.bytes_read,
            file_size=self.file_size,
            since_read_ms=None if self.since_read_ms == NEVER_READ else self.since_read_ms,
        )
        return d
