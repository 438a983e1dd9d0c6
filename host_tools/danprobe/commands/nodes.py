"""danprobe nodes: the DroneCAN nodes the gateway has seen."""

import time

from danprobe import gateway_msgs
from danprobe.commands.common import (
    add_gateway_options,
    format_table,
    gateway_operation,
    gateway_report,
    long_running,
    positive_float,
)
from danprobe.master import DanError, OperationTimeout, RemoteError
from danprobe.port import now

NAME = "nodes"
HELP = "CAN gateway: the DroneCAN node table (NodeStatus and GetNodeInfo of every node)"
DESCRIPTION = (
    "Reads the gateway's node table (NODES, page by page) and each node's GetNodeInfo data "
    "(NODE_INFO): id, health, mode, uptime, name, software and hardware versions, unique "
    "id, and the gateway's flags of the node (duplicate: two nodes use its ID; offline: "
    "seen, then silent over 3 s; allocated: its ID came from the gateway's allocator); with "
    "the gateway's health verdict (HEALTH, as 'danprobe health'). --watch refreshes it every "
    "second until Ctrl-C or --duration."
)


def JSON_EVENTS(a) -> bool:
    """With --watch, --json is one document per refresh, then the summary."""
    return a.watch


def add_arguments(p):
    g = add_gateway_options(p, long_running=True, own="nodes")
    g.add_argument(
        "--watch",
        action="store_true",
        help="refresh every second (--json: one document per refresh)",
    )
    g.add_argument(
        "--duration", type=positive_float, metavar="S", help="with --watch: stop after S seconds"
    )


def _uptime(s: int) -> str:
    d, s = divmod(s, 86400)
    h, s = divmod(s, 3600)
    m, s = divmod(s, 60)
    return (f"{d}d" if d else "") + f"{h:02d}:{m:02d}:{s:02d}"


class NodeTable:
    """The node list plus GetNodeInfo data, asked again only for new nodes,
    nodes whose info was not valid yet, and nodes that restarted."""

    def __init__(self, gw):
        self.gw = gw
        self.entries = []
        self.info = {}  # node id -> (uptime when read, NodeInfo)
        self.health = None  # the verdict (None: a gateway without HEALTH)

    def refresh(self):
        try:
            self.health = self.gw.health()
        except RemoteError:
            self.health = None
        self.entries = self.gw.nodes()
        for e in self.entries:
            known = self.info.get(e.node_id)
            if (
                known is None
                or known[1].info_state != gateway_msgs.INFO_VALID
                or e.uptime_sec < known[0]
            ):
                self.info[e.node_id] = (e.uptime_sec, self.gw.node_info(e.node_id))

    def rows(self):
        out = []
        for e in self.entries:
            d = e.as_dict()
            i = self.info.get(e.node_id)
            d.update(i[1].as_dict() if i else {})
            d["info_state_name"] = (
                gateway_msgs.INFO_STATE_NAMES[d["info_state"]]
                if d["info_state"] < len(gateway_msgs.INFO_STATE_NAMES)
                else str(d["info_state"])
            )
            out.append(d)
        return out

    def text(self) -> str:
        rows = [
            ("id", "health", "mode", "uptime", "name", "sw", "hw", "unique id", "info", "flags")
        ]
        for d in self.rows():
            valid = d["info_state"] == gateway_msgs.INFO_VALID
            rows.append(
                (
                    str(d["node_id"]),
                    d["health_name"],
                    d["mode_name"],
                    _uptime(d["uptime_sec"]),
                    d["name"] if valid else "",
                    "%d.%d" % tuple(d["sw"]) if valid else "",
                    "%d.%d" % tuple(d["hw"]) if valid else "",
                    d["unique_id"] if valid else "",
                    d["info_state_name"],
                    ",".join(n for _, n in gateway_msgs.NODE_FLAG_NAMES if d[n]),
                )
            )
        return format_table(rows)

    def verdict(self) -> str:
        return f"health {self.health.text()}" if self.health else "health unknown"


def run(ctx) -> int:
    a = ctx.args
    state = {}

    def op(m, gw):
        table = state["table"] = NodeTable(gw)
        if not a.watch:
            table.refresh()
            return
        stop, dog = long_running(m, ctx)
        t0 = now()
        refreshes = 0
        with stop:
            while not stop.stop and (a.duration is None or now() - t0 < a.duration):
                t = now()
                try:
                    table.refresh()
                except OperationTimeout:
                    raise
                except DanError as e:
                    dog.failed(e)
                    ctx.progress(f"refresh failed: {e}")
                else:
                    dog.ok()
                    refreshes += 1
                    if a.json:
                        ctx.emit_json(
                            {
                                "event": "nodes",
                                "time": round(t - t0, 3),
                                "nodes": table.rows(),
                                "health": table.health.as_dict() if table.health else None,
                            }
                        )
                    else:
                        print(
                            f"--- {time.strftime('%H:%M:%S')}  {len(table.entries)} node(s), "
                            + table.verdict()
                        )
                        print(table.text(), flush=True)
                while (
                    not stop.stop
                    and now() < t + 1.0
                    and (a.duration is None or now() - t0 < a.duration)
                ):
                    time.sleep(0.05)
        state["refreshes"] = refreshes

    m, failure, ms = gateway_operation(ctx, op)
    table = state.get("table")
    rows = table.rows() if table else []

    def human():
        if not a.watch:
            print(
                f"nodes: {len(rows)} DroneCAN node(s) seen by the gateway; {table.verdict()} "
                f"({ms:.1f} ms)"
            )
            if rows:
                print(table.text())

    health = table.health if table else None
    fields = {"nodes": rows, "health": health.as_dict() if health else None}
    if a.watch:
        fields.update(event="summary", refreshes=state.get("refreshes", 0))
    return gateway_report(ctx, m, failure, ms, fields, human)
