"""The subcommands. To add one, write a module with NAME, HELP,
add_arguments(parser) and run(ctx) (see common.py for the shared options
and helpers) and list it here. Optional: DESCRIPTION, EXAMPLES, and
JSON_EVENTS (True, or a function of the arguments) when its --json is a
stream of events ending with a summary (the document a command cut short
prints is then a summary event too)."""

from danprobe.commands import (
    arm,
    beep,
    can,
    configure,
    disarm,
    discover,
    dna,
    esc,
    files,
    fw_update,
    health,
    lights,
    nodes,
    param,
    restart,
    safety,
    servo,
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
    safety,
    servo,
    lights,
    beep,
    telemetry,
    stats,
    nodes,
    health,
    dna,
    param,
    restart,
    files,
    fw_update,
    tunnel,
    can,
    slcan,
)
