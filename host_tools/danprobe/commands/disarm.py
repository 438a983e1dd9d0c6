"""danprobe disarm: make the gateway broadcast ArmingStatus disarmed."""

from danprobe import gateway_msgs
from danprobe.commands.arm import set_arming
from danprobe.commands.common import add_gateway_options

NAME = "disarm"
HELP = "CAN gateway: broadcast ArmingStatus DISARMED (0) to the ESCs"
DESCRIPTION = (
    "Sends ARM 0 to the CAN-over-DAN gateway, which broadcasts "
    "uavcan.equipment.safety.ArmingStatus DISARMED at once. Prints the gateway flags."
)


def add_arguments(p):
    add_gateway_options(p)


def run(ctx) -> int:
    return set_arming(ctx, gateway_msgs.ARM_DISARMED)
