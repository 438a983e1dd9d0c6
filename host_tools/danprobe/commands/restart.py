"""danprobe restart: RestartNode to a DroneCAN node, through the gateway."""

from danprobe import gateway_calls, gateway_mgmt
from danprobe.commands.common import (
    add_gateway_options,
    gateway_operation,
    gateway_report,
    int_range,
)
from danprobe.commands.param import Kept, add_node_option
from danprobe.gateway_mgmt import NodeCall
from danprobe.master import DanError, RemoteError

NAME = "restart"
HELP = "CAN gateway: restart a DroneCAN node (uavcan.protocol.RestartNode)"
DESCRIPTION = (
    "Asks a node to restart with uavcan.protocol.RestartNode and its magic number "
    f"0x{gateway_mgmt.RESTART_MAGIC:X}. The gateway refuses any other magic before anything "
    "is sent, unless --force (some bootloaders use their own, e.g. 0xBEEFCAFE). Exit 0 when "
    "the node answered ok."
)


def add_arguments(p):
    g = add_gateway_options(p, own="restart")
    add_node_option(g, "the node to restart")
    g.add_argument(
        "--magic",
        type=int_range(0, gateway_mgmt.MAGIC_MAX, "--magic (40 bits)"),
        default=gateway_mgmt.RESTART_MAGIC,
        metavar="0x...",
        help=f"the magic number (default RestartNode's 0x{gateway_mgmt.RESTART_MAGIC:X})",
    )
    g.add_argument(
        "--force", action="store_true", help="send a magic other than RestartNode's anyway"
    )


class Refused(DanError):
    code, reason = -6, "refused by the gateway"


def run(ctx) -> int:
    a = ctx.args
    res = {"node": a.node, "magic": f"0x{a.magic:X}", "force": a.force}

    def op(m, gw):
        call = NodeCall(0, a.node, gateway_mgmt.CALL_RESTART, magic=a.magic, force=a.force)
        try:
            r = gateway_calls.opcode_result(gw, call)
        except RemoteError as e:
            hint = "" if a.force else "; --force sends it anyway"
            raise Refused(
                f"the gateway refused magic 0x{a.magic:X} for node {a.node} and sent nothing "
                f"({e.message.text}){hint}"
            ) from None
        res["ok"] = r.ok
        if not r.ok:
            raise Kept(f"node {a.node} answered RestartNode: not ok (it does not restart)")

    m, failure, ms = gateway_operation(ctx, op)

    def human():
        print(f"restart: node {a.node} accepted RestartNode (magic 0x{a.magic:X})")

    return gateway_report(ctx, m, failure, ms, res, human)
