"""danprobe safety: the safety state the gateway broadcasts (SafetyState)."""

from danprobe.commands.arm import set_arming
from danprobe.commands.common import add_gateway_options

NAME = "safety"
HELP = "CAN gateway: broadcast SafetyState ON (0, outputs locked) or OFF (255)"
DESCRIPTION = (
    "Sends SAFETY to the CAN-over-DAN gateway, which broadcasts "
    "ardupilot.indication.SafetyState at once and then at its arming rate: 'on' (0, "
    "STATUS_SAFETY_ON) locks the outputs, 'off' (255, STATUS_SAFETY_OFF) lets them move. "
    "ArduPilot's peripherals built with safety-switch support (AP_Periph ESCs and servos) "
    "drive nothing until they hear 255. The gateway starts with safety ON and goes back "
    "to ON in its failsafe. Prints the gateway flags (safety-off)."
)
EXAMPLES = (
    "danprobe safety off --port /dev/ttyUSB0 --baud 115200",
    "danprobe safety on --port /dev/ttyUSB0 --json",
)


def add_arguments(p):
    p.add_argument("state", choices=("on", "off"), help="on: outputs locked; off: they may move")
    add_gateway_options(p)


def run(ctx) -> int:
    return set_arming(ctx, None, safety_off=ctx.args.state == "off")
