"""danprobe configure: move the bus to a faster baud and verify it."""

from danprobe.commands.common import (
    DEFAULT_BAUD,
    add_bus_options,
    master_operation,
    peers_report,
)

NAME = "configure"
HELP = "discover, then move every peripheral to a baud (default: the best common one)"
DESCRIPTION = (
    "Discovers the bus, sends CONFIGURE to every peripheral not at the target baud, "
    "switches and verifies each one with IDENTIFY at the target. If anything fails the "
    "bus is recovered to 9600 baud and the command fails."
)


def add_arguments(p):
    add_bus_options(
        p,
        baud_help="the target baud, any value the adapter can do (default: the fastest "
        "every peripheral accepts, up to --max-baud)",
    )


def run(ctx) -> int:
    a = ctx.args
    target = a.baud or 0

    def op(m):
        nonlocal target
        m.discover()
        target = m.configure(target)

    m, failure, ms = master_operation(ctx, DEFAULT_BAUD, op)
    recovered = f"; bus recovered at {m.baud} baud" if m.stats.recoveries else ""
    return peers_report(
        ctx,
        m,
        failure,
        ms,
        {"target": target, "recoveries": m.stats.recoveries, "retries": m.stats.retries},
        f"configure failed: {failure}{recovered}",
        f"configure: ok, bus at {m.baud} baud, {len(m.present())} peripheral(s) "
        f"verified ({ms:.1f} ms)",
    )
