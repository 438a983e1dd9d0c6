#!/usr/bin/env python3
"""Simulated DroneCAN ESCs, each a pydronecan node on its own SLCAN port.

    python host_tools/esc_sim.py --port /tmp/can1 --port /tmp/can2 ... [--log FILE]

ESC i (0-based, in --port order) has node ID --node-id-base + i and ESC
index i. It follows uavcan.equipment.esc.RawCommand: its RPM approaches
cmd[i] / 8191 * --max-rpm with a first-order lag (tau 0.15 s), current
grows with RPM squared, voltage sags with current, temperature rises with
current and cools toward ambient. Each publishes uavcan.equipment.esc.Status
at --status-hz, answers GetNodeInfo (name org.dan.esc_sim), and NodeStatus
at 1 Hz (pydronecan does this itself).

--log writes one JSON line per event: {"t", "esc", "event":
"cmd"|"arming"|"safety"|"status", ...} (safety: ardupilot.indication.SafetyState)
so tests and the demo can check exactly what arrived. Prints READY once all
nodes are up; exits 0 on SIGTERM/SIGINT.
"""

import argparse
import json
import math
import signal
import sys
import time

import dronecan

import pydronecan_nodes


class Esc:
    def __init__(self, idx, port, node_id, args, log):
        self.idx = idx
        self.args = args
        self.log = log
        info = dronecan.uavcan.protocol.GetNodeInfo.Response()
        info.name = "org.dan.esc_sim"
        info.software_version.major = 1
        info.hardware_version.major = 1
        info.hardware_version.unique_id = bytes([0xE5, idx] + [node_id] * 14)
        self.node = pydronecan_nodes.make_node(port, node_id, node_info=info)
        self.node.add_handler(dronecan.uavcan.equipment.esc.RawCommand, self.on_cmd)
        self.node.add_handler(dronecan.uavcan.equipment.safety.ArmingStatus, self.on_arming)
        self.node.add_handler(dronecan.ardupilot.indication.SafetyState, self.on_safety)
        self.node.health = dronecan.uavcan.protocol.NodeStatus().HEALTH_OK
        self.node.mode = dronecan.uavcan.protocol.NodeStatus().MODE_OPERATIONAL
        self.cmd = 0
        self.rpm = 0.0
        self.temp = 300.0
        self.errors = 0
        self.last = time.monotonic()
        self.node.periodic(1.0 / args.status_hz, self.publish)

    def emit(self, event, e=None, **kw):
        """A log line; t is when the transfer's first frame was read from
        the port (pydronecan's I/O process stamps it), so a handler running
        late on a loaded host does not move it; else now."""
        if self.log:
            t = getattr(e.transfer, "ts_monotonic", None) if e is not None else None
            t = time.monotonic() if t is None else t
            self.log.write(
                json.dumps({"t": round(t, 6), "esc": self.idx, "event": event, **kw}) + "\n"
            )
            self.log.flush()

    def on_cmd(self, e):
        cmd = list(e.message.cmd)
        self.emit("cmd", e, cmd=cmd, src=e.transfer.source_node_id)
        if self.idx < len(cmd):
            self.cmd = int(cmd[self.idx])
        return None

    def on_arming(self, e):
        self.emit("arming", e, status=int(e.message.status), src=e.transfer.source_node_id)
        return None

    def on_safety(self, e):
        self.emit("safety", e, status=int(e.message.status), src=e.transfer.source_node_id)
        return None

    def step(self):
        now = time.monotonic()
        dt = min(now - self.last, 0.5)
        self.last = now
        target = max(self.cmd, 0) / 8191.0 * self.args.max_rpm
        self.rpm += (target - self.rpm) * (1.0 - math.exp(-dt / 0.15))
        frac = self.rpm / self.args.max_rpm
        current = 0.3 + 28.0 * frac * frac
        self.temp += dt * (0.02 * current * current - 0.05 * (self.temp - 300.0))
        return current

    def publish(self):
        current = self.step()
        msg = dronecan.uavcan.equipment.esc.Status()
        msg.error_count = self.errors
        msg.voltage = 16.8 - 0.04 * current
        msg.current = current
        msg.temperature = self.temp
        msg.rpm = int(round(self.rpm))
        msg.power_rating_pct = max(0, min(100, int(round(self.cmd * 100 / 8191))))
        msg.esc_index = self.idx
        self.node.broadcast(msg)
        self.emit(
            "status",
            rpm=msg.rpm,
            voltage=round(msg.voltage, 3),
            current=round(current, 3),
            temperature=round(self.temp, 2),
            power_rating_pct=msg.power_rating_pct,
        )


def main():
    ap = argparse.ArgumentParser(description="Simulated DroneCAN ESCs on SLCAN ports (pydronecan).")
    ap.add_argument(
        "--port", action="append", required=True, help="SLCAN tty, one per ESC, in ESC index order"
    )
    ap.add_argument("--node-id-base", type=int, default=20)
    ap.add_argument("--max-rpm", type=float, default=12000.0)
    ap.add_argument("--status-hz", type=float, default=20.0)
    ap.add_argument("--log", help="JSON-lines event log")
    args = ap.parse_args()
    if not 1 <= args.node_id_base <= 127 - len(args.port):
        ap.error("--node-id-base out of range")
    stop = []
    signal.signal(signal.SIGTERM, lambda *a: stop.append(1))
    signal.signal(signal.SIGINT, lambda *a: stop.append(1))
    log = open(args.log, "a") if args.log else None
    escs = []
    try:
        for i, port in enumerate(args.port):
            escs.append(Esc(i, port, args.node_id_base + i, args, log))
        print("READY", flush=True)
        pydronecan_nodes.spin_until([e.node for e in escs], stop)
    finally:
        pydronecan_nodes.close_nodes([e.node for e in escs])
        if log:
            log.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
