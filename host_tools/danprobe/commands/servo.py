"""danprobe servo: actuator commands (ArrayCommand) and their failsafe."""

from danprobe import gateway_out as O
from danprobe.commands.common import (
    UsageError,
    add_gateway_options,
    flags_command,
    flat,
    id_list_option,
)

NAME = "servo"
HELP = "CAN gateway: servo commands (actuator ArrayCommand) and the servo failsafe table"
DESCRIPTION = (
    "Sends uavcan.equipment.actuator.ArrayCommand through the gateway (SERVO): "
    "--set ID=VALUE[:TYPE] per actuator, TYPE one of unitless (the default, -1..1), "
    "position, force, speed or pwm (microseconds); the value travels as a float16 "
    "(rounded to nearest: the value sent is printed). The gateway keeps each actuator's "
    "latest command and sends them all with every SERVO. When SERVO requests stop for "
    "its esc_timeout_ms (or at any failsafe) it sends each commanded actuator its "
    "failsafe: --failsafe ID=hold (keep the last command, the default for every actuator) "
    "or ID=VALUE[:TYPE] (send this instead); --failsafe replaces the whole table, "
    "--failsafe-clear empties it (all hold). The table is sent before the commands. "
    "Lists may be comma-separated or the option repeated."
)
EXAMPLES = (
    "danprobe servo --port /dev/ttyUSB0 --baud 115200 --set 3=0.5 --set 7=1500:pwm",
    "danprobe servo --port /dev/ttyUSB0 --set 0=-1,1=-0.25:position,2=1100:pwm",
    "danprobe servo --port /dev/ttyUSB0 --failsafe 3=hold --failsafe 7=1100:pwm --set 7=1500:pwm",
    "danprobe servo --port /dev/ttyUSB0 --failsafe-clear",
)


def parse_command(spec: str) -> tuple[float, int]:
    """VALUE[:TYPE] -> (value, command_type)."""
    text, _, kind = spec.partition(":")
    kind = kind.strip().lower() or "unitless"
    if kind in O.TYPE_NAMES:
        ctype = O.TYPE_NAMES.index(kind)
    elif kind.isdigit() and int(kind) <= O.TYPE_MAX:
        ctype = int(kind)
    else:
        raise ValueError(f"command type {kind!r}: {', '.join(O.TYPE_NAMES)} (or 0..4)")
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{text!r} is not a number") from None
    if ctype == O.TYPE_UNITLESS and not -1.0 <= value <= 1.0:
        raise ValueError(f"unitless values are -1..1, not {text} (PWM? write {text}:pwm)")
    O.f16_bits(value)  # a ValueError if it does not fit
    return value, ctype


def servo_item(actuator: int, spec: str) -> O.ServoCommand:
    value, ctype = parse_command(spec)
    return O.ServoCommand.make(actuator, ctype, value)


def failsafe_item(actuator: int, spec: str) -> O.ServoFailsafe:
    if spec.lower() == "hold":
        return O.ServoFailsafe.hold(actuator)
    value, ctype = parse_command(spec)
    return O.ServoFailsafe.value_of(actuator, ctype, value)


def add_arguments(p):
    g = add_gateway_options(p, own="servo")
    g.add_argument(
        "--set",
        **id_list_option(servo_item, "value[:type]", "ID=VALUE[:TYPE]"),
        help="command actuator ID (0..255); TYPE unitless (default), position, force, "
        "speed or pwm; repeat or comma-separate (at most 32)",
    )
    fs = g.add_mutually_exclusive_group()
    fs.add_argument(
        "--failsafe",
        **id_list_option(failsafe_item, "hold|value[:type]", "ID=hold|VALUE[:TYPE]"),
        help="the failsafe table (replaced as a whole): hold the last command, or send "
        "VALUE; actuators not listed hold",
    )
    fs.add_argument(
        "--failsafe-clear",
        action="store_true",
        help="empty the failsafe table: every actuator holds",
    )


def run(ctx) -> int:
    a = ctx.args
    commands, table = flat(a.set), flat(a.failsafe)
    send_table = bool(table) or a.failsafe_clear
    if not commands and not send_table:
        raise UsageError("give --set ID=VALUE[:TYPE], --failsafe or --failsafe-clear")
    if len(commands) > O.SERVO_MAX or len(table) > O.SERVO_MAX:
        raise UsageError(f"at most {O.SERVO_MAX} actuators per --set / --failsafe")
    kept = []

    def send(gw):
        if send_table:
            kept.append(gw.servo_failsafe(table))
            if kept[0] < len(table):
                ctx.error(f"the gateway kept {kept[0]} of {len(table)} failsafe entries")
        return gw.servo(commands) if commands else None

    def what(flags):
        parts = []
        if send_table:
            listed = ", ".join(e.text() for e in table) or "empty (every actuator holds)"
            parts.append(f"failsafe table {listed}: {kept[0]} kept")
        if commands:
            parts.append("sent " + ", ".join(c.text() for c in commands))
        return "; ".join(parts)

    def fields():
        return {
            "servos": [c.as_dict() for c in commands],
            "failsafe": [e.as_dict() for e in table] if send_table else None,
            "kept": kept[0] if kept else None,
        }

    return flags_command(ctx, send, fields, what)
