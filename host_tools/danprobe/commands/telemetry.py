"""danprobe telemetry: every ESC's newest telemetry, as the gateway keeps it."""

from danprobe import gateway_msgs
from danprobe.commands.common import (
    add_gateway_options,
    gateway_operation,
    gateway_report,
    telemetry_table,
)

NAME = "telemetry"
HELP = "CAN gateway: the newest esc.Status of every ESC (paged ESC_TELEM)"
DESCRIPTION = (
    "Reads the gateway's telemetry table page by page (ESC_TELEM) and prints one line per "
    "ESC: node, RPM, voltage, current, temperature, power, error count and the age of the "
    "newest esc.Status."
)


def add_arguments(p):
    add_gateway_options(p)


def run(ctx) -> int:
    records, client = [], []

    def op(m, gw):
        client.append(gw)
        records.extend(gw.telemetry())

    m, failure, ms = gateway_operation(ctx, op)
    flags = client[0].flags if client else 0

    def human():
        print(
            f"telemetry: {len(records)} ESC(s); gateway flags "
            f"{','.join(gateway_msgs.flags_names(flags)) or 'none'} ({ms:.1f} ms)"
        )
        if records:
            print(telemetry_table(records))

    return gateway_report(
        ctx,
        m,
        failure,
        ms,
        {**gateway_msgs.flags_dict(flags), "esc": [r.as_dict() for r in records]},
        human,
    )
