"""The code registry (include/dan/codes.h, src/types.c): peripheral types,
message names and payload describers for tools.

Each type owns a block of 16 codes starting with IDENTIFY (first) and
CONFIGURE (first + 1); code 0 is the error message. Other modules name
their messages with register_message(), e.g. the gateway's:

    register_message(0x42, "ESC_COMMAND", request=decode_esc_command)

Until then such a code shows as "can-gw 0x42".
"""

from dataclasses import dataclass
from typing import Callable, Optional

from danprobe import payloads
from danprobe.codec import MalformedError

BLOCK_SIZE = 16
CODE_ERROR = 0


@dataclass(frozen=True)
class PeripheralType:
    name: str  # short name for command lines ("can-gw")
    first: int  # first code of the block (IDENTIFY)
    title: str
    more_blocks: tuple[int, ...] = ()  # first codes of further blocks (their first two unused)

    @property
    def identify(self) -> int:
        return self.first

    @property
    def configure(self) -> int:
        return self.first + 1


TYPES = (
    PeripheralType("vtx", 0x20, "video transmitter (DAN draft)"),
    PeripheralType("can-gw", 0x40, "CAN-over-DAN gateway", (0x50,)),
    PeripheralType("test-a", 0x60, "test type A"),
    PeripheralType("test-b", 0x70, "test type B"),
)


def lookup(name_or_code: str) -> Optional[PeripheralType]:
    """A type by short name or by its first code as a number ("0x40")."""
    for t in TYPES:
        if t.name == name_or_code:
            return t
    try:
        v = int(name_or_code, 0)
    except ValueError:
        return None
    return next((t for t in TYPES if t.first == v), None)


def type_of_code(code: int) -> Optional[PeripheralType]:
    """The type whose block (or further block) holds code."""
    return next(
        (t for t in TYPES if any(0 <= code - b < BLOCK_SIZE for b in (t.first, *t.more_blocks))),
        None,
    )


# ---- messages ----

# A payload describer: payload bytes -> dict of fields; raises
# MalformedError (or ValueError) when the payload does not fit.
Describer = Callable[[bytes], dict]


@dataclass(frozen=True)
class Message:
    name: str
    request: Optional[Describer] = None  # payload sent by the master
    response: Optional[Describer] = None  # payload sent back


_MESSAGES: dict[int, Message] = {}


def register_message(
    code: int, name: str, request: Optional[Describer] = None, response: Optional[Describer] = None
):
    """Names a code (its type prefix is added by code_name()) and, optionally,
    how to show its request and response payloads."""
    _MESSAGES[code] = Message(name, request, response)


def code_name(code: int) -> str:
    """ "ERROR", "test-a IDENTIFY", "can-gw 0x42", or "0x50" outside any type."""
    if code == CODE_ERROR:
        return _MESSAGES[CODE_ERROR].name
    t = type_of_code(code)
    m = _MESSAGES.get(code)
    if t is None:
        return m.name if m else f"0x{code:02X}"
    return f"{t.name} {m.name if m else f'0x{code:02X}'}"


def describe_empty(payload: bytes) -> dict:
    if payload:
        raise MalformedError(f"expected an empty payload, got {len(payload)} byte(s)")
    return {}


def _identity(payload: bytes) -> dict:
    return payloads.Identity.decode(payload).as_dict()


def _configure(payload: bytes) -> dict:
    try:
        return payloads.Configure.decode(payload).as_dict()
    except payloads.UnsupportedRequest as e:
        return {"request_type": e.request_type, "unsupported": True}


def _ack(payload: bytes) -> dict:
    v = payloads.decode_ack(payload)
    return {"ack": "OK" if v == payloads.ACK_OK else "FAIL"}


def _error(payload: bytes) -> dict:
    e = payloads.ErrorMessage.decode(payload)
    return {
        "request_code": e.code,
        "request": code_name(e.code),
        "error_code": e.error,
        "description": e.text,
    }


register_message(CODE_ERROR, "ERROR", response=_error)
for _t in TYPES:
    register_message(_t.identify, "IDENTIFY", request=describe_empty, response=_identity)
    register_message(_t.configure, "CONFIGURE", request=_configure, response=_ack)

REQUEST, RESPONSE = "request", "response"


def describe(
    code: int, payload: bytes, role: Optional[str]
) -> tuple[Optional[str], Optional[dict], str]:
    """Decodes a payload for display: (role, fields, problem). The guessed
    role's format is tried first, then the other one (a retried request
    looks like a response to a sniffer); fields is None when neither fits
    or the code has no describer, and problem says why."""
    m = _MESSAGES.get(code)
    if m is None:
        return role, None, ""
    tries = [(RESPONSE, m.response), (REQUEST, m.request)]
    if role != RESPONSE:
        tries.reverse()
    problem = ""
    for r, fn in tries:
        if fn is None:
            continue
        try:
            return r, fn(payload), ""
        except (MalformedError, ValueError) as e:
            problem = problem or str(e)
    return role, None, problem or "no describer"
