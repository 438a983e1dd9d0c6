"""danprobe lights: LightsCommand through the gateway."""

from danprobe import gateway_out as O
from danprobe.commands.common import (
    UsageError,
    add_gateway_options,
    flags_command,
    flat,
    id_list_option,
)

NAME = "lights"
HELP = "CAN gateway: set lights' colours (uavcan.equipment.indication.LightsCommand)"
DESCRIPTION = (
    "Sends uavcan.equipment.indication.LightsCommand through the gateway (LIGHTS): "
    "--light ID=RRGGBB per light (ID 0..255), a 24-bit RGB colour in hex, converted to "
    "the RGB565 the message carries by keeping each channel's high bits: red >> 3, "
    "green >> 2, blue >> 3 (ff0000 is 565:F800, 808080 is 565:8410); or "
    "ID=565:XXXX, the RGB565 value itself (4 hex digits: red << 11 | green << 5 | blue). "
    "Vertiq LED boards take their ESC index as the light ID. At most 20 lights."
)
EXAMPLES = (
    "danprobe lights --port /dev/ttyUSB0 --baud 115200 --light 0=ff0000",
    "danprobe lights --port /dev/ttyUSB0 --light 0=00ff00,1=0000ff --light 2=565:ffe0",
)


def parse_colour(light_id: int, spec: str) -> O.Light:
    """RRGGBB (optionally #, 0x) or 565:XXXX."""
    text = spec.lower()
    raw = text.startswith("565:")
    digits = text[4:] if raw else text.removeprefix("#").removeprefix("0x")
    if len(digits) != (4 if raw else 6) or not all(c in "0123456789abcdef" for c in digits):
        raise ValueError(f"colour {spec!r}: RRGGBB (6 hex digits) or 565:XXXX (4)")
    value = int(digits, 16)
    return O.Light(light_id, value if raw else O.rgb565_from_rgb(value))


def add_arguments(p):
    add_gateway_options(p, own="lights").add_argument(
        "--light",
        required=True,
        **id_list_option(parse_colour, "rrggbb", "ID=RRGGBB|ID=565:XXXX"),
        help="a light and its colour; repeat or comma-separate (at most 20)",
    )


def run(ctx) -> int:
    lights = flat(ctx.args.light)
    if len(lights) > O.LIGHTS_MAX:
        raise UsageError(f"at most {O.LIGHTS_MAX} lights ({len(lights)} given)")
    return flags_command(
        ctx,
        lambda gw: gw.lights(lights),
        {"lights": [x.as_dict() for x in lights]},
        lambda flags: "sent " + ", ".join(x.text() for x in lights),
    )
