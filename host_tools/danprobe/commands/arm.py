"""danprobe arm: make the gateway broadcast ArmingStatus armed."""

from danprobe import gateway_msgs
from danprobe.commands.common import (
    EXIT_USAGE,
    CliError,
    add_gateway_options,
    gateway_operation,
    gateway_report,
    non_negative_int,
)

NAME = "arm"
HELP = "CAN gateway: broadcast ArmingStatus FULLY_ARMED (255) to the ESCs"
DESCRIPTION = (
    "Sends ARM to the CAN-over-DAN gateway, which broadcasts "
    "uavcan.equipment.safety.ArmingStatus at once and then at its arming rate. "
    "Prints the gateway flags."
)


def add_arguments(p):
    add_gateway_options(p)
    g = p.add_argument_group("arm options")
    g.add_argument(
        "--status",
        type=non_negative_int,
        default=gateway_msgs.ARM_FULLY_ARMED,
        metavar="N",
        help="ArmingStatus value to send, 0..255 (default 255)",
    )


def set_arming(ctx, status: int) -> int:
    """ARM with status; the result is reported for arm and disarm alike."""
    if status > 255:
        raise CliError("--status must be 0..255", EXIT_USAGE)
    flags = None

    def op(m, gw):
        nonlocal flags
        flags = gw.arm(status)

    m, failure, ms = gateway_operation(ctx, op)

    def human():
        state = "armed" if flags & gateway_msgs.FLAG_ARMED else "disarmed"
        print(
            f"{ctx.args.command}: ok, gateway {state} (ArmingStatus {status}); flags "
            f"{','.join(gateway_msgs.flags_names(flags)) or 'none'} ({ms:.1f} ms)"
        )

    return gateway_report(
        ctx,
        m,
        failure,
        ms,
        {"status": status, **(gateway_msgs.flags_dict(flags) if flags is not None else {})},
        human,
    )


def run(ctx) -> int:
    return set_arming(ctx, ctx.args.status)
