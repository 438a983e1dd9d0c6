"""danprobe disarm: make the gateway broadcast ArmingStatus disarmed (and,
with --safety-on, SafetyState on after it)."""

from danprobe import gateway_msgs
from danprobe.commands.arm import set_arming
from danprobe.commands.common import add_gateway_options

NAME = "disarm"
HELP = "CAN gateway: broadcast ArmingStatus DISARMED (0) to the ESCs"
DESCRIPTION = (
    "Sends ARM 0 to the CAN-over-DAN gateway, which broadcasts "
    "uavcan.equipment.safety.ArmingStatus DISARMED at once; --safety-on then sends "
    "SAFETY 0 (SafetyState ON: outputs locked). Prints the gateway flags."
)
EXAMPLES = ("danprobe disarm --port /dev/ttyUSB0 --baud 115200 --safety-on",)


def add_arguments(p):
    add_gateway_options(p, own="disarm").add_argument(
        "--safety-on", action="store_true", help="then send SAFETY 0 (SafetyState ON)"
    )


def run(ctx) -> int:
    return set_arming(ctx, gateway_msgs.ARM_DISARMED, False if ctx.args.safety_on else None)
