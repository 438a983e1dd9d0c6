#!/usr/bin/env python3
"""The chaos soak's output devices (tests/bench/chaos.py), pydronecan nodes
on SLCAN ports of the hub, each logging what it heard as JSON lines:

    chaos_nodes.py --servo-port P --tunnel-port P --log FILE
                   [--servo-id 40] [--tunnel-id 41] [--serial-id 0]

servo   a servo node: uavcan.equipment.actuator.ArrayCommand ("servo": cmds
        [[actuator_id, command_type, value], ...]), ArmingStatus ("arming":
        status) and ardupilot SafetyState ("safety": status), with src
tunnel  the far end of a Targetted serial tunnel (TunnelFarEnd of
        tests/e2e/gw_rig.py: it answers the bytes XORed with 0x5A at a
        steady 3000 B/s): "tun_rx" (the bytes to it, hex) and "tun_tx" (the
        bytes it sent back, hex)

t is when the transfer's first frame was read from the port (pydronecan's
I/O process stamps it), else the time of the log line. Prints READY once
both nodes are up; exits 0 on SIGTERM/SIGINT.
"""

import argparse
import json
import signal
import sys
import time
from pathlib import Path

import dronecan

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host_tools"))
sys.path.insert(0, str(ROOT / "tests" / "e2e"))
import pydronecan_nodes  # noqa: E402
from gw_rig import TunnelFarEnd  # noqa: E402

U = dronecan.uavcan


class Log:
    def __init__(self, path):
        self.f = open(path, "a")

    def emit(self, event, e=None, **kw):
        t = getattr(e.transfer, "ts_monotonic", None) if e is not None else None
        t = time.monotonic() if t is None else t
        self.f.write(json.dumps({"t": round(t, 6), "event": event, **kw}) + "\n")
        self.f.flush()


class LoggedFarEnd(TunnelFarEnd):
    """TunnelFarEnd with every chunk in and out logged."""

    def __init__(self, node, node_id, serial_id, log):
        self.log = log
        super().__init__(node, node_id, serial_id)

    def _on_targetted(self, e):
        before = len(self.got)
        super()._on_targetted(e)
        if len(self.got) > before:
            self.log.emit("tun_rx", e, data=bytes(self.got[before:]).hex())
            del self.got[:]  # the log holds it

    def pump(self):
        before = bytes(self.outq)  # one thread: handlers and pump alternate
        super().pump()
        sent = before[: len(before) - len(self.outq)]
        if sent:
            self.log.emit("tun_tx", data=sent.hex())


def servo_node(port, node_id, log):
    info = U.protocol.GetNodeInfo.Response()
    info.name = "org.dan.chaos_servo"
    node = pydronecan_nodes.make_node(port, node_id, node_info=info)

    def on_array(e):
        cmds = [
            [int(c.actuator_id), int(c.command_type), float(c.command_value)]
            for c in e.message.commands
        ]
        log.emit("servo", e, cmds=cmds, src=e.transfer.source_node_id)

    def on_state(event):
        return lambda e: log.emit(
            event, e, status=int(e.message.status), src=e.transfer.source_node_id
        )

    node.add_handler(U.equipment.actuator.ArrayCommand, on_array)
    node.add_handler(U.equipment.safety.ArmingStatus, on_state("arming"))
    node.add_handler(dronecan.ardupilot.indication.SafetyState, on_state("safety"))
    return node


def main():
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--servo-port", required=True)
    ap.add_argument("--tunnel-port", required=True)
    ap.add_argument("--log", required=True)
    ap.add_argument("--servo-id", type=int, default=40)
    ap.add_argument("--tunnel-id", type=int, default=41)
    ap.add_argument("--serial-id", type=int, default=0)
    a = ap.parse_args()
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    signal.signal(signal.SIGINT, lambda *_: stop.append(1))
    log = Log(a.log)
    nodes = []
    try:
        nodes.append(servo_node(a.servo_port, a.servo_id, log))
        info = U.protocol.GetNodeInfo.Response()
        info.name = "org.dan.chaos_tunnel"
        far = pydronecan_nodes.make_node(a.tunnel_port, a.tunnel_id, node_info=info)
        nodes.append(far)
        end = LoggedFarEnd(far, a.tunnel_id, a.serial_id, log)
        far.periodic(0.01, end.pump)
        print("READY", flush=True)
        pydronecan_nodes.spin_until(nodes, stop)
    finally:
        pydronecan_nodes.close_nodes(nodes)
    return 0


if __name__ == "__main__":
    sys.exit(main())
