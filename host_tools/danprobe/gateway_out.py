"""The gateway's output messages besides ESCs (docs/PROTOCOL.md section 7,
"Outputs"; libdan's dan/can_gw/msgs_out.h): the safety state (SAFETY
0x54, ardupilot.indication.SafetyState), servos (SERVO 0x55,
uavcan.equipment.actuator.ArrayCommand) and their failsafe table
(SERVO_FAILSAFE 0x56), lights (LIGHTS 0x57, LightsCommand) and the buzzer
(BEEP 0x58, BeepCommand).

Same rules as gateway_msgs.py: inner payloads (the client seals them),
decoders never read past the payload, raise PayloadError for a truncated
payload or a field out of range and ignore trailing bytes;
tests/vectors/gateway.txt pins every layout. Servo values stay IEEE
binary16 bits, as on the wire; f16_bits() makes them from a number.
"""

import math
import struct
from collections.abc import Sequence
from dataclasses import dataclass, field

from danprobe.gateway_msgs import check_range, f16_to_float
from danprobe.payloads import PayloadError, Reader, Writer, attrs

CODE_SAFETY = 0x54
CODE_SERVO = 0x55
CODE_SERVO_FAILSAFE = 0x56
CODE_LIGHTS = 0x57
CODE_BEEP = 0x58

# SafetyState.status: the only two values the gateway takes
SAFETY_ON, SAFETY_OFF = 0, 255

# servos
SERVO_MAX = 32  # commands in one SERVO, entries in the failsafe table
# actuator.Command.command_type
TYPE_UNITLESS, TYPE_POSITION, TYPE_FORCE, TYPE_SPEED, TYPE_PWM = range(5)
TYPE_NAMES = ("unitless", "position", "force", "speed", "pwm")
TYPE_MAX = TYPE_PWM
# failsafe modes (kind bit 7)
SERVO_HOLD, SERVO_VALUE = 0, 1
MODE_NAMES = ("hold", "value")
_KIND_MODE = 0x80
_KIND_TYPE = 0x0F
_KIND_RESERVED = 0x70

LIGHTS_MAX = 20
BEEP_HZ_MAX = 65504  # the largest float16
BEEP_MS_MAX = 65504000
F16_MAX = 65504.0


def f16_bits(value: float) -> int:
    """IEEE binary16 bits of value, rounded to nearest (even); ValueError
    for what rounds beyond +-65504, and for infinities and NaN."""
    try:
        if math.isfinite(value):
            return struct.unpack("<H", struct.pack("<e", value))[0]
    except (OverflowError, struct.error):
        pass
    raise ValueError(f"{value} does not fit a float16 (at most {F16_MAX:g})")


def type_name(command_type: int) -> str:
    return TYPE_NAMES[command_type] if command_type < len(TYPE_NAMES) else str(command_type)


def rgb565(red: int, green: int, blue: int) -> int:
    """RGB565 from its fields: red 5 bits << 11, green 6 bits << 5, blue 5 bits."""
    check_range(red, 0, 31, "red")
    check_range(green, 0, 63, "green")
    check_range(blue, 0, 31, "blue")
    return red << 11 | green << 5 | blue


def rgb565_from_rgb(rgb: int) -> int:
    """24-bit 0xRRGGBB to RGB565, keeping each channel's high bits: red >> 3,
    green >> 2, blue >> 3 (0xFF0000 -> 0xF800, 0xFFFFFF -> 0xFFFF)."""
    check_range(rgb, 0, 0xFFFFFF, "RGB colour")
    return rgb565((rgb >> 16) >> 3, ((rgb >> 8) & 0xFF) >> 2, (rgb & 0xFF) >> 3)


def rgb565_fields(c: int) -> tuple[int, int, int]:
    return c >> 11, (c >> 5) & 0x3F, c & 0x1F


# ---- SAFETY (0x54): u8 status (0 on, 255 off); response u8 flags ----


def _safety(status: int) -> int:
    if status not in (SAFETY_ON, SAFETY_OFF):
        raise ValueError(f"safety status {status}: 0 (on) or 255 (off)")
    return status


def encode_safety(status: int) -> bytes:
    return bytes([_safety(status)])


def decode_safety(payload) -> int:
    status = Reader(payload).u8("status")
    if status not in (SAFETY_ON, SAFETY_OFF):
        raise PayloadError(f"safety status {status}: 0 or 255")
    return status


def safety_dict(status: int) -> dict:
    return {"status": status, "safety_off": status == SAFETY_OFF}


class _ItemList:
    """A list message: u8 n (MIN..MAX), then n items, each written by its
    class's put() and read by get(). FIELD names the list attribute, KEY its
    as_dict() key."""

    NAME, FIELD, KEY = "", "", ""
    MIN, MAX = 1, SERVO_MAX
    ITEM = None

    def encode(self) -> bytes:
        items = getattr(self, self.FIELD)
        if not self.MIN <= len(items) <= self.MAX:
            raise ValueError(f"{self.NAME}: {self.MIN}..{self.MAX} {self.KEY}, not {len(items)}")
        return Writer().items(items).bytes()

    @classmethod
    def decode(cls, payload):
        r = Reader(payload)
        n = r.u8("count")
        if not cls.MIN <= n <= cls.MAX:
            raise PayloadError(f"count: {n} is outside {cls.MIN}..{cls.MAX}")
        return cls([cls.ITEM.get(r) for _ in range(n)])

    def as_dict(self) -> dict:
        return {self.KEY: [x.as_dict() for x in getattr(self, self.FIELD)]}


# ---- SERVO (0x55) ----


@dataclass
class ServoCommand:
    """One actuator.Command: actuator_id, command_type (TYPE_*), value as
    binary16 bits."""

    actuator_id: int = 0
    command_type: int = TYPE_UNITLESS
    value_f16: int = 0

    @classmethod
    def make(cls, actuator_id: int, command_type: int, value: float) -> "ServoCommand":
        check_range(actuator_id, 0, 255, "actuator_id")
        check_range(command_type, 0, TYPE_MAX, "command_type")
        return cls(actuator_id, command_type, f16_bits(value))

    def put(self, w: Writer):
        check_range(self.command_type, 0, TYPE_MAX, "command_type")
        w.u8(self.actuator_id).u8(self.command_type).u16(self.value_f16)

    @classmethod
    def get(cls, r: Reader) -> "ServoCommand":
        c = cls(r.u8("actuator_id"), r.u8("command_type"), r.u16("value"))
        if c.command_type > TYPE_MAX:
            raise PayloadError(f"command_type {c.command_type}: at most {TYPE_MAX}")
        return c

    @property
    def value(self) -> float:
        return f16_to_float(self.value_f16)

    def text(self) -> str:
        return f"{self.actuator_id}={self.value:g} {type_name(self.command_type)}"

    def as_dict(self) -> dict:
        d = attrs(self, "actuator_id", "command_type")
        return {**d, "type": type_name(self.command_type), **attrs(self, "value", "value_f16")}


@dataclass
class ServoRequest(_ItemList):
    """u8 n (1..32), n x (u8 actuator_id, u8 command_type 0..4, u16 value f16)."""

    commands: list[ServoCommand] = field(default_factory=list)

    NAME, FIELD, KEY, ITEM = "SERVO", "commands", "servos", ServoCommand


# ---- SERVO_FAILSAFE (0x56) ----


@dataclass
class ServoFailsafe:
    """One entry of the failsafe table: HOLD (keep the last command) or
    VALUE (send this command_type and value instead). On the wire: u8
    actuator_id, u8 kind (bits 0-3 command_type, bit 7 mode, bits 4-6
    zero), u16 value f16."""

    actuator_id: int = 0
    mode: int = SERVO_HOLD
    command_type: int = TYPE_UNITLESS
    value_f16: int = 0

    @classmethod
    def hold(cls, actuator_id: int) -> "ServoFailsafe":
        return cls(check_range(actuator_id, 0, 255, "actuator_id"))

    @classmethod
    def value_of(cls, actuator_id: int, command_type: int, value: float) -> "ServoFailsafe":
        c = ServoCommand.make(actuator_id, command_type, value)
        return cls(c.actuator_id, SERVO_VALUE, c.command_type, c.value_f16)

    def put(self, w: Writer):
        check_range(self.mode, SERVO_HOLD, SERVO_VALUE, "failsafe mode")
        check_range(self.command_type, 0, TYPE_MAX, "command_type")
        w.u8(self.actuator_id).u8(self.command_type | self.mode << 7).u16(self.value_f16)

    @classmethod
    def get(cls, r: Reader) -> "ServoFailsafe":
        aid, kind, v = r.u8("actuator_id"), r.u8("kind"), r.u16("value")
        if kind & _KIND_RESERVED or (kind & _KIND_TYPE) > TYPE_MAX:
            raise PayloadError(f"kind 0x{kind:02X}: reserved bits or command_type > {TYPE_MAX}")
        return cls(aid, kind >> 7, kind & _KIND_TYPE, v)

    @property
    def value(self) -> float:
        return f16_to_float(self.value_f16)

    def text(self) -> str:
        if self.mode == SERVO_HOLD:
            return f"{self.actuator_id}=hold"
        return f"{self.actuator_id}={self.value:g} {type_name(self.command_type)}"

    def as_dict(self) -> dict:
        d = {"actuator_id": self.actuator_id, "mode": MODE_NAMES[self.mode & 1]}
        if self.mode == SERVO_VALUE:
            d.update(
                command_type=self.command_type,
                type=type_name(self.command_type),
                value=self.value,
                value_f16=self.value_f16,
            )
        return d


@dataclass
class ServoFailsafeTable(_ItemList):
    """u8 n (0..32), n x ServoFailsafe. Replaces the gateway's table."""

    entries: list[ServoFailsafe] = field(default_factory=list)

    NAME, FIELD, KEY, ITEM, MIN = "SERVO_FAILSAFE", "entries", "failsafe", ServoFailsafe, 0


# ---- LIGHTS (0x57) ----


@dataclass
class Light:
    light_id: int = 0
    rgb565: int = 0

    def put(self, w: Writer):
        w.u8(self.light_id).u16(self.rgb565)

    @classmethod
    def get(cls, r: Reader) -> "Light":
        return cls(r.u8("light_id"), r.u16("rgb565"))

    def text(self) -> str:
        return f"{self.light_id}=565:{self.rgb565:04X}"

    def as_dict(self) -> dict:
        r, g, b = rgb565_fields(self.rgb565)
        return {"light_id": self.light_id, "rgb565": self.rgb565, "red": r, "green": g, "blue": b}


@dataclass
class LightsRequest(_ItemList):
    """u8 n (1..20), n x (u8 light_id, u16 rgb565)."""

    lights: list[Light] = field(default_factory=list)

    NAME, FIELD, KEY, ITEM, MAX = "LIGHTS", "lights", "lights", Light, LIGHTS_MAX


# ---- BEEP (0x58): uv frequency_hz (1..65504), uv duration_ms (0..65504000) ----


@dataclass
class Beep:
    frequency_hz: int = 1
    duration_ms: int = 0

    def encode(self) -> bytes:
        check_range(self.frequency_hz, 1, BEEP_HZ_MAX, "frequency_hz")
        check_range(self.duration_ms, 0, BEEP_MS_MAX, "duration_ms")
        return Writer().uvarint(self.frequency_hz).uvarint(self.duration_ms).bytes()

    @classmethod
    def decode(cls, payload) -> "Beep":
        r = Reader(payload)
        b = cls(r.uvarint("frequency_hz"), r.uvarint("duration_ms"))
        if not 1 <= b.frequency_hz <= BEEP_HZ_MAX or b.duration_ms > BEEP_MS_MAX:
            raise PayloadError(f"beep {b.frequency_hz} Hz {b.duration_ms} ms: out of range")
        return b

    def as_dict(self) -> dict:
        return {"frequency_hz": self.frequency_hz, "duration_ms": self.duration_ms}


def servo_commands(items: Sequence) -> list[ServoCommand]:
    """ServoCommands from ServoCommand objects or (actuator_id,
    command_type, value) tuples (value a number)."""
    return [c if isinstance(c, ServoCommand) else ServoCommand.make(*c) for c in items]
