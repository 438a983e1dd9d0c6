"""danprobe discover: which peripherals are on the bus, at which baud."""

from danprobe.commands.common import (
    DEFAULT_BAUD,
    add_bus_options,
    master_operation,
    peers_report,
)
from danprobe.master import DISCOVERY_BAUDS, NotFound

NAME = "discover"
HELP = "find the peripherals on the bus (at 9600, then at the other bauds)"
DESCRIPTION = (
    "IDENTIFY every type at 9600 baud, then the types that did not answer at "
    f"{', '.join(map(str, DISCOVERY_BAUDS[1:]))} (a bus configured earlier keeps its baud "
    "until power-cycled). Prints each peripheral's identity."
)


def add_arguments(p):
    add_bus_options(
        p,
        baud_help="the port's opening baud (default 9600); discovery itself always starts at 9600",
    )


def run(ctx) -> int:
    a = ctx.args
    m, failure, ms = master_operation(
        ctx, a.baud or DEFAULT_BAUD, lambda m: m.discover(), (NotFound,)
    )
    return peers_report(
        ctx,
        m,
        failure,
        ms,
        {"types": [t.name for t in a.types]},
        f"no peripheral answered (probed {', '.join(t.name for t in a.types)} at "
        f"{', '.join(map(str, DISCOVERY_BAUDS))} baud)",
        f"discover: {len(m.present())} peripheral(s) in {ms:.1f} ms, bus at {m.baud} baud",
    )
