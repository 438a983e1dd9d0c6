"""danprobe beep: BeepCommand through the gateway."""

from danprobe import gateway_out as O
from danprobe.commands.common import add_gateway_options, flags_command, int_range

NAME = "beep"
HELP = "CAN gateway: sound the buzzers (uavcan.equipment.indication.BeepCommand)"
DESCRIPTION = (
    "Sends uavcan.equipment.indication.BeepCommand through the gateway (BEEP): every "
    "buzzer on the bus beeps at --hz for --ms. The message carries both as float16 (the "
    "gateway converts, rounding to nearest: Hz and seconds)."
)
EXAMPLES = ("danprobe beep --port /dev/ttyUSB0 --baud 115200 --hz 2000 --ms 100",)


def add_arguments(p):
    g = add_gateway_options(p, own="beep")
    # (option, what, unit, lo, hi, default): whole numbers the message carries as float16
    for flag, what, unit, lo, hi, default in (
        ("--hz", "frequency", "Hz", 1, O.BEEP_HZ_MAX, 2000),
        ("--ms", "duration", "ms", 0, O.BEEP_MS_MAX, 100),
    ):
        g.add_argument(
            flag,
            type=int_range(lo, hi, flag),
            default=default,
            metavar="N",
            help=f"{what}, {lo}..{hi} {unit} (default {default})",
        )


def run(ctx) -> int:
    a = ctx.args
    return flags_command(
        ctx,
        lambda gw: gw.beep(a.hz, a.ms),
        {"frequency_hz": a.hz, "duration_ms": a.ms},
        lambda flags: f"{a.hz} Hz for {a.ms} ms",
    )
