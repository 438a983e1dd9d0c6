"""The subcommands. To add one, write a module with NAME, HELP,
add_arguments(parser) and run(ctx) (see common.py for the shared options
and helpers) and list it here."""

from danprobe.commands import (
    arm,
    can,
    configure,
    disarm,
    discover,
    dna,
    esc,
    health,
    nodes,
    param,
    restart,
    slcan,
    sniff,
    stats,
    telemetry,
    tunnel,
)

COMMANDS = (
    discover,
    configure,
    sniff,
    # the CAN-over-DAN gateway
    esc,
    arm,
    disarm,
    telemetry,
    stats,
    nodes,
    health,
    dna,
    param,
    restart,
    tunnel,
    can,
    slcan,
)
