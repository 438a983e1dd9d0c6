"""The gateway end-to-end rigs' shared parts (test_gateway, test_danprobe_gateway):
Rig (dan-vbus, an SLCAN hub, dan-gatewayd, pydronecan nodes) and the far
end of a Targetted serial tunnel."""

import json
import threading
import time

import dronecan
import pytest

import pydronecan_nodes
from bus_util import ready
from conftest import BIN, ROOT

U = dronecan.uavcan

GW_NODE = 10


class Rig:
    def __init__(self, procs, tmp, ncan=3, gw_args=()):
        for b in ("dan-vbus", "dan-gatewayd", "dan-fcsim", "dan-cantool"):
            if not (BIN / b).exists():
                pytest.fail(f"{b} not built: run make test (it builds everything)")
        self.procs, self.tmp = procs, tmp
        self.start_wires(ncan)
        # Generous reply windows (here and in fcsim): a loaded 2-core host
        # can stall a process that long; these tests check behaviour, not speed.
        self.gwd = procs.start(
            [
                BIN / "dan-gatewayd",
                "--uart",
                tmp / "dan1",
                "--can",
                f"slcan:{tmp / 'can0'}",
                "--verbose",
                "--reply-window-ms",
                "200",
                *gw_args,
            ],
            stdout=None,
        )
        self.nodes = []
        self.stop = threading.Event()
        self.threads = []

    def start_wires(self, ncan, vbus_extra=(), hub_extra=()):
        """dan-vbus with 2 endpoints (tmp/dan0, dan1) and slcan_hub with ncan
        ports (tmp/can0..), run by the system python3 as users run it."""
        self.vbus = self.procs.start(
            [BIN / "dan-vbus", "-n", "2", "--link", self.tmp / "dan", *vbus_extra]
        )
        ready(self.vbus, "dan-vbus")
        self.hub = self.procs.start(
            ["python3", ROOT / "host_tools" / "slcan_hub.py", "-n", str(ncan)]
            + ["--link", self.tmp / "can", *hub_extra],
            name="slcan_hub",
        )
        ready(self.hub, "slcan_hub")

    def node(self, k, node_id, name):
        info = U.protocol.GetNodeInfo.Response()
        info.name = name
        info.software_version.major = 2
        info.software_version.minor = 7
        info.hardware_version.major = 1
        n = pydronecan_nodes.make_node(self.tmp / f"can{k}", node_id, node_info=info)
        self.nodes.append(n)
        return n

    def spin(self, node, periodic=None, period=0.05):
        def loop():
            last = 0.0
            while not self.stop.is_set():
                try:
                    node.spin(0.01)
                except Exception:  # a malformed frame must not kill the thread
                    pass
                if periodic and time.monotonic() - last >= period:
                    last = time.monotonic()
                    periodic()

        t = threading.Thread(target=loop, daemon=True)
        t.start()
        self.threads.append(t)

    def fcsim(self, *steps, timeout=120):
        p = self.procs.start(
            [BIN / "dan-fcsim", "--port", self.tmp / "dan0", "--latency-ms", "250", *steps]
        )
        out, _ = p.communicate(timeout=timeout)
        lines = [json.loads(line) for line in out.decode().splitlines() if line.strip()]
        return p.returncode, lines

    def close(self):
        self.stop.set()
        for t in self.threads:
            t.join(5)
        pydronecan_nodes.close_nodes(self.nodes)


class TunnelFarEnd:
    """The device's end of a Targetted tunnel on a pydronecan node: the
    gateway's bytes (to node_id, serial_id) collect in .got, and the far end
    answers them XORed with 0x5A, up to 120 bytes a message from pump()
    (give pump to Rig.spin)."""

    def __init__(self, node, node_id, serial_id):
        self.node, self.node_id, self.serial_id = node, node_id, serial_id
        self.got = bytearray()
        self.outq = bytearray()
        self.lock = threading.Lock()
        node.add_handler(U.tunnel.Targetted, self._on_targetted)

    def _on_targetted(self, e):
        m = e.message
        if (
            m.target_node != self.node_id
            or e.transfer.source_node_id != GW_NODE
            or m.serial_id != self.serial_id
        ):
            return
        data = bytes(m.buffer)
        with self.lock:
            self.got.extend(data)
            self.outq.extend(bytes(b ^ 0x5A for b in data))  # a transformed stream back

    def pump(self):
        with self.lock:
            chunk = bytes(self.outq[:120])
            del self.outq[:120]
        if chunk:
            self.node.broadcast(
                U.tunnel.Targetted(
                    protocol=U.tunnel.Protocol(protocol=255),
                    target_node=GW_NODE,
                    serial_id=self.serial_id,
                    options=0,
                    baudrate=0,
                    buffer=list(chunk),
                )
            )
