#!/usr/bin/env python3
"""A pydronecan node with parameters, for tests and benchmarks: the
independent peer of the gateway's service calls.

    .venv/bin/python tests/tools/param_node.py --port /tmp/can3 [--node-id 50]
        [--count 100] [--log FILE]

It serves --count parameters (params() below: integers, reals, booleans and
strings, in turn, with names, defaults and, for the numbers, min and max)
through uavcan.protocol.param.GetSet, by index and by name; a request with
a value of the parameter's type sets it (a number is clamped to its
range; a value of another type changes nothing), and the answer carries
the value then held. An index or name it does not have gets an empty
answer (empty name), as the specification says. param.ExecuteOpcode
(SAVE, ERASE: ERASE restores the defaults) and RestartNode (any magic:
the node only records it, and answers ok when the magic is RestartNode's)
are recorded.

--log writes one JSON line per request: {"t", "event": "getset" | "opcode"
| "restart", ...}. Prints READY when the node is up; exits 0 on SIGTERM or
SIGINT. Standard pydronecan; its I/O child starts with spawn
(host_tools/pydronecan_nodes.py).
"""

import argparse
import json
import signal
import struct
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host_tools"))
import pydronecan_nodes  # noqa: E402

KINDS = ("integer", "real", "boolean", "string")
PREFIX = {"integer": "int", "real": "real", "boolean": "bool", "string": "str"}


def f32(x: float) -> float:
    return struct.unpack("<f", struct.pack("<f", x))[0]


def params(count: int) -> list[dict]:
    """The node's parameters, in index order: name, type, value (the
    default), and min and max for the numbers."""
    out = []
    for i in range(count):
        kind = KINDS[i % 4]
        p = {"index": i, "name": f"{PREFIX[kind]}_{i:03d}", "type": kind}
        if kind == "integer":
            p.update(value=i * 10 - 50, min=-1000, max=1000 + i)
        elif kind == "real":
            p.update(value=f32(i * 0.25 - 3.5), min=f32(-100.0), max=f32(100.0 + i))
        elif kind == "boolean":
            p.update(value=i % 8 == 2)
        else:
            p.update(value=f"text {i}")
        p["default"] = p["value"]
        out.append(p)
    return out


class ParamNode:
    def __init__(self, port, node_id, count, log):
        import dronecan

        self.dc = dronecan
        self.P = dronecan.uavcan.protocol.param
        self.log = log
        self.params = params(count)
        self.by_name = {p["name"]: p for p in self.params}
        info = dronecan.uavcan.protocol.GetNodeInfo.Response()
        info.name = "org.dan.param_node"
        info.software_version.major = 1
        info.hardware_version.unique_id = bytes([0x9A, node_id] + [0x55] * 14)
        self.node = pydronecan_nodes.make_node(port, node_id, node_info=info)
        self.node.health = dronecan.uavcan.protocol.NodeStatus().HEALTH_OK
        self.node.mode = dronecan.uavcan.protocol.NodeStatus().MODE_OPERATIONAL
        self.node.add_handler(self.P.GetSet, self.on_getset)
        self.node.add_handler(self.P.ExecuteOpcode, self.on_opcode)
        self.node.add_handler(dronecan.uavcan.protocol.RestartNode, self.on_restart)

    def emit(self, event, **kw):
        if self.log:
            self.log.write(json.dumps({"t": round(time.monotonic(), 6), "event": event, **kw}))
            self.log.write("\n")
            self.log.flush()

    # ---- values ----

    def value(self, p, v):
        P = self.P
        if p["type"] == "integer":
            return P.Value(integer_value=v)
        if p["type"] == "real":
            return P.Value(real_value=v)
        if p["type"] == "boolean":
            return P.Value(boolean_value=1 if v else 0)
        return P.Value(string_value=v)

    def numeric(self, p, v):
        field = "integer_value" if p["type"] == "integer" else "real_value"
        return self.P.NumericValue(**{field: v})

    def assign(self, p, v) -> bool:
        """Sets p from a request's Value if it is of p's type."""
        field = self.dc.get_active_union_field(v)
        want = {
            "integer": "integer_value",
            "real": "real_value",
            "boolean": "boolean_value",
            "string": "string_value",
        }[p["type"]]
        if field != want:
            return False
        x = getattr(v, field)
        if p["type"] in ("integer", "real"):
            x = min(max(x, p["min"]), p["max"])
            p["value"] = int(x) if p["type"] == "integer" else f32(x)
        elif p["type"] == "boolean":
            p["value"] = bool(x)
        else:
            p["value"] = bytes(x).decode("utf-8", "replace")
        return True

    # ---- services ----

    def on_getset(self, e):
        q = e.request
        name = bytes(q.name).decode("utf-8", "replace")
        p = self.by_name.get(name) if name else None
        if not name and q.index < len(self.params):
            p = self.params[q.index]
        setting = self.dc.get_active_union_field(q.value) not in (None, "empty")
        changed = p is not None and setting and self.assign(p, q.value)
        self.emit(
            "getset",
            index=q.index,
            name=name,
            found=p["name"] if p else None,
            set=setting,
            changed=changed,
            value=p["value"] if p else None,
        )
        if p is None:
            return self.P.GetSet.Response()
        r = self.P.GetSet.Response(
            value=self.value(p, p["value"]),
            default_value=self.value(p, p["default"]),
            name=p["name"],
        )
        if "max" in p:
            r.max_value = self.numeric(p, p["max"])
            r.min_value = self.numeric(p, p["min"])
        return r

    def on_opcode(self, e):
        op = e.request.opcode
        if op == e.request.OPCODE_ERASE:
            for p in self.params:
                p["value"] = p["default"]
        self.emit("opcode", opcode=op, name={0: "save", 1: "erase"}.get(op, str(op)))
        return self.P.ExecuteOpcode.Response(ok=op in (0, 1), argument=e.request.argument)

    def on_restart(self, e):
        magic = int(e.request.magic_number)
        ok = magic == e.request.MAGIC_NUMBER
        self.emit("restart", magic=magic, ok=ok)
        return self.dc.uavcan.protocol.RestartNode.Response(ok=ok)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--port", required=True, help="SLCAN tty")
    ap.add_argument("--node-id", type=int, default=50)
    ap.add_argument("--count", type=int, default=100, help="parameters (default 100)")
    ap.add_argument("--log", help="JSON-lines request log")
    a = ap.parse_args()
    if not 1 <= a.node_id <= 125 or not 0 <= a.count <= 8192:
        ap.error("--node-id 1..125, --count 0..8192")
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    signal.signal(signal.SIGINT, lambda *_: stop.append(1))
    log = open(a.log, "a") if a.log else None
    node = None
    try:
        node = ParamNode(a.port, a.node_id, a.count, log)
        print("READY", flush=True)
        pydronecan_nodes.spin_until([node.node], stop, 0.005)
    finally:
        if node:
            pydronecan_nodes.close_nodes([node.node])
        if log:
            log.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
