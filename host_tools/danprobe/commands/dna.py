"""danprobe dna: the gateway's dynamic node ID allocation table."""

from danprobe import gateway_msgs
from danprobe.commands.common import (
    add_gateway_options,
    format_table,
    gateway_operation,
    gateway_report,
)
from danprobe.gateway_mgmt import dna_flag_names

NAME = "dna"
HELP = "CAN gateway: the dynamic node ID allocation table (node ID, unique ID) and its flags"
DESCRIPTION = (
    "Reads the gateway's allocation table (DNA, page by page): each node ID it handed out "
    "and the unique ID it went to; the flags say whether its allocation server runs, whether "
    "the table came from storage and whether storage failed. --server on|off switches the "
    "allocation server (CONFIG; until the gateway restarts)."
)


def add_arguments(p):
    g = add_gateway_options(p, own="dna")
    g.add_argument(
        "--server",
        choices=("on", "off"),
        help="first switch the gateway's allocation server on or off",
    )


def run(ctx) -> int:
    a = ctx.args
    got = {}

    def op(m, gw):
        if a.server:
            req = gateway_msgs.ConfigRequest(gateway_msgs.CFG_DNA, dna=int(a.server == "on"))
            gw.read_config(req)
        got["page"], got["entries"] = gw.dna()

    m, failure, ms = gateway_operation(ctx, op)
    page, entries = got.get("page"), got.get("entries", [])

    def human():
        flags = ", ".join(dna_flag_names(page.flags)) or "server off"
        print(f"dna: {flags}; {page.entries} of {page.capacity} entries")
        if entries:
            rows = [("node", "unique id")]
            rows += [(str(e.node_id), e.unique_id.hex()) for e in entries]
            print(format_table(rows))

    fields = {}
    if page:
        fields = page.as_dict()
        fields["table"] = [e.as_dict() for e in entries]
    return gateway_report(ctx, m, failure, ms, fields, human)
