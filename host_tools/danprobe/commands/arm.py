"""danprobe arm: make the gateway broadcast ArmingStatus armed (and, with
--safety-off, SafetyState off first)."""

from typing import Optional

from danprobe import gateway_msgs, gateway_out
from danprobe.commands.common import (
    UsageError,
    add_gateway_options,
    flags_command,
    non_negative_int,
)

NAME = "arm"
HELP = "CAN gateway: broadcast ArmingStatus FULLY_ARMED (255) to the ESCs"
DESCRIPTION = (
    "Sends ARM to the CAN-over-DAN gateway, which broadcasts "
    "uavcan.equipment.safety.ArmingStatus at once and then at its arming rate. "
    "--safety-off first sends SAFETY 255 (SafetyState OFF, as ArduPilot's safety switch "
    "must be off before arming), so AP_Periph ESCs that wait for it spin. "
    "Prints the gateway flags."
)
EXAMPLES = (
    "danprobe arm --port /dev/ttyUSB0 --baud 115200",
    "danprobe arm --port /dev/ttyUSB0 --baud 115200 --safety-off",
)


def add_arguments(p):
    g = add_gateway_options(p, own="arm")
    g.add_argument(
        "--status",
        type=non_negative_int,
        default=gateway_msgs.ARM_FULLY_ARMED,
        metavar="N",
        help="ArmingStatus value to send: 255 (default) or 0 (the gateway refuses others)",
    )
    g.add_argument(
        "--safety-off",
        action="store_true",
        help="send SAFETY 255 (SafetyState OFF) before arming",
    )


def set_arming(ctx, status: Optional[int], safety_off: Optional[bool] = None) -> int:
    """ARM with status (None: none) and SAFETY (None: none; off before
    arming, on after disarming); the result is reported for arm, disarm and
    safety alike."""
    if status is not None and status > 255:
        raise UsageError("--status must be 0..255")

    def send(gw):
        if safety_off:
            flags = gw.safety(True)
        if status is not None:
            flags = gw.arm(status)
        if safety_off is False:
            flags = gw.safety(False)
        return flags

    def what(flags):
        did = []
        if status is not None:
            state = "armed" if flags & gateway_msgs.FLAG_ARMED else "disarmed"
            did.append(f"gateway {state} (ArmingStatus {status})")
        if safety_off is not None:
            did.append(f"safety {'OFF (255)' if safety_off else 'ON (0)'}")
        return ", ".join(did)

    fields = {} if status is None else {"status": status}
    if safety_off is not None:
        fields["safety"] = gateway_out.SAFETY_OFF if safety_off else gateway_out.SAFETY_ON
    return flags_command(ctx, send, fields, what)


def run(ctx) -> int:
    return set_arming(ctx, ctx.args.status, True if ctx.args.safety_off else None)
