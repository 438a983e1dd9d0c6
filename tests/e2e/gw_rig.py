"""The gateway end-to-end rigs' shared parts (test_gateway,
test_danprobe_gateway, test_danprobe_outputs, test_bus_mgmt): Rig (dan-vbus,
an SLCAN hub, dan-gatewayd, pydronecan nodes), Stack (the same with
esc_sim, for danprobe's commands) and the far end of a Targetted serial
tunnel."""

import json
import os
import random
import select
import struct
import sys
import threading
import time
import tty

import dronecan
import pytest

import pydronecan_nodes
from bus_util import control, danprobe, ready
from conftest import BIN, MASTER_WAIT_MS, PERIPH_WINDOW_MS, ROOT, wait_for

U = dronecan.uavcan

GW_NODE = 10

# The ESC loop the gateway tests run: 4 and 8 channels with the extreme
# values at 50 Hz, then 4 channels back to back (its rate is printed).
ESC_LOOP = (
    "esc:0,100,-8192,8191@1500@50",
    "esc:1,2,3,4,5,6,7,-8@1000@50",
    "esc:0,100,200,300@3000@0",
)


def f16(x):
    """x rounded to float16, as it travels in esc.Status."""
    return struct.unpack("<e", struct.pack("<e", x))[0]


def step(lines, name):
    """The JSON lines of dan-fcsim's steps called name."""
    return [line for line in lines if line["step"] == name]


def gatewayd_cmd(tmp, *extra):
    """dan-gatewayd on tmp/dan1 (the vbus's endpoint 1) and tmp/can0 (the
    hub's port 0). The reply window is PERIPH_WINDOW_MS, not the 50 ms
    default: a loaded 2-core host stalls a process that long (conftest),
    and a reply dropped as late is a failure the master would not have seen
    (these tests check behaviour, not speed)."""
    return [
        BIN / "dan-gatewayd",
        "--uart",
        tmp / "dan1",
        "--can",
        f"slcan:{tmp / 'can0'}",
        "--reply-window-ms",
        PERIPH_WINDOW_MS,
        *extra,
    ]


class Rig:
    def __init__(self, procs, tmp, ncan=3, gw_args=()):
        for b in ("dan-vbus", "dan-gatewayd", "dan-fcsim", "dan-cantool"):
            if not (BIN / b).exists():
                pytest.fail(f"{b} not built: run make test (it builds everything)")
        self.procs, self.tmp = procs, tmp
        self.start_wires(ncan)
        self.gwd = procs.start(gatewayd_cmd(tmp, "--verbose", *gw_args), stdout=None)
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

    def fcsim(self, *steps, timeout=120, opts=()):
        p = self.procs.start(
            [
                BIN / "dan-fcsim",
                "--port",
                self.tmp / "dan0",
                "--latency-ms",
                MASTER_WAIT_MS,
                *opts,
                *steps,
            ]
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
    (give pump to Rig.spin), with reply_serial_id (default: the
    same; AP_Periph answers a request for -1 with the port it chose).
    .heard lists (protocol, serial_id, options, baudrate) of every message
    the gateway sent to node_id, keepalives included."""

    # The far end is a serial device: it sends at a steady rate, not in the
    # bursts a starved test process would make of its backlog. The rate is
    # low enough that what the SLCAN hub (Python too) holds back while it
    # is starved and then delivers at once stays within the gateway's
    # 4096-byte tunnel buffer: 1.3 s of stall (a tunnel has no flow
    # control: a far end faster than the FC reads loses bytes, counted in
    # tun_dropped, as with a real device that fast). Bytes a second, and
    # the most sent at once after a pause.
    RATE = 3000.0
    BURST = 240

    def __init__(self, node, node_id, serial_id, reply_serial_id=None):
        self.node, self.node_id, self.serial_id = node, node_id, serial_id
        self.reply_serial_id = serial_id if reply_serial_id is None else reply_serial_id
        self.got = bytearray()
        self.outq = bytearray()
        self.heard = []
        self.lock = threading.Lock()
        self.tokens, self.t_last = float(self.BURST), time.monotonic()
        node.add_handler(U.tunnel.Targetted, self._on_targetted)

    def _on_targetted(self, e):
        m = e.message
        if m.target_node != self.node_id or e.transfer.source_node_id != GW_NODE:
            return
        with self.lock:
            self.heard.append((m.protocol.protocol, m.serial_id, m.options, m.baudrate))
        if m.serial_id != self.serial_id:
            return
        data = bytes(m.buffer)
        with self.lock:
            self.got.extend(data)
            self.outq.extend(bytes(b ^ 0x5A for b in data))  # a transformed stream back

    def pump(self):
        t = time.monotonic()
        self.tokens = min(self.BURST, self.tokens + (t - self.t_last) * self.RATE)
        self.t_last = t
        n = min(120, int(self.tokens))
        with self.lock:
            chunk = bytes(self.outq[:n])
            del self.outq[:n]
        self.tokens -= len(chunk)
        if chunk:
            self.node.broadcast(
                U.tunnel.Targetted(
                    protocol=U.tunnel.Protocol(protocol=255),
                    target_node=GW_NODE,
                    serial_id=self.reply_serial_id,
                    options=0,
                    baudrate=0,
                    buffer=list(chunk),
                )
            )


def start_danprobe(procs, *args, name="danprobe"):
    """A long-running danprobe command (--json added) in its own process
    group; returns (proc, its "ready" event)."""
    args = [*map(str, args)]
    if "--latency-ms" not in args:  # generous: a loaded test host stalls replies
        args += ["--latency-ms", MASTER_WAIT_MS]
    p = procs.start([sys.executable, "-m", "danprobe", *args, "--json"], name=name)
    line = p.stdout.readline().decode()
    assert line, f"{name} ended: {p.log_path.read_text()}"
    ev = json.loads(line)
    assert ev.get("event") == "ready", ev
    return p, ev


def finish_danprobe(procs, p):
    """Stops a long-running danprobe command (SIGTERM): exit 0 and its
    summary document, returned."""
    assert procs.stop(p, timeout=30) == 0, p.log_path.read_text()
    lines = [json.loads(x) for x in p.stdout.read().decode().splitlines() if x.strip()]
    assert lines and lines[-1]["event"] == "summary" and lines[-1]["result"] == 0, lines
    return lines[-1]


def danprobe_json(*args):
    rc, out, err = danprobe(*args, "--json")
    assert rc == 0, (rc, out, err)
    return json.loads(out.splitlines()[-1])


def esc_run(out):
    """The JSON lines of a danprobe esc --json run: (its exchange events, the
    summary, which must be the last line)."""
    lines = [json.loads(x) for x in out.splitlines()]
    assert lines[-1]["event"] == "summary"
    return [line for line in lines if line.get("event") == "exchange"], lines[-1]


def hub_stats(ctl):
    return json.loads(control(ctl, "stats"))


class Stack(Rig):
    """dan-vbus (ep 0: danprobe, ep 1: the gateway), slcan_hub (port 0: the
    gateway, 1..escs: esc_sim, the rest for the test), dan-gatewayd and
    esc_sim with `escs` ESCs (node ids 20..). Rig's node(k, ...) (a
    pydronecan node on tmp/can<k>), spin() and close() serve here too."""

    def __init__(self, procs, tmp, escs=4, ncan=8, vbus_extra=()):
        for b in ("dan-vbus", "dan-gatewayd", "dan-cantool"):
            if not (BIN / b).exists():
                pytest.fail(f"{b} not built: run make test (it builds everything)")
        import dronecan  # noqa: F401

        self.procs, self.tmp = procs, tmp
        self.dan = str(tmp / "dan0")
        self.ctl = tmp / "hub.ctl"
        self.hub_log = tmp / "hub.log"
        self.start_wires(
            ncan,
            vbus_extra=("--capture", tmp / "bus.cap", *vbus_extra),
            hub_extra=("--log", self.hub_log, "--control", self.ctl),
        )
        self.gwd = procs.start(gatewayd_cmd(tmp), stdout=None)
        self.esc_log = tmp / "esc.log"
        if escs:
            ports = sum((["--port", tmp / f"can{1 + i}"] for i in range(escs)), [])
            self.esc = procs.start(
                [sys.executable, ROOT / "host_tools" / "esc_sim.py", *ports, "--log", self.esc_log],
                name="esc_sim",
            )
            ready(self.esc, "esc_sim")
        self.free = escs + 1  # first hub port for the test
        self.nodes, self.threads = [], []
        self.stop = threading.Event()

    def can(self, k):
        return str(self.tmp / f"can{k}")

    def wait_gateway_sees(self, n):
        wait_for(
            lambda: danprobe_json("stats", "--port", self.dan, "-q")["stats"]["nodes"] >= n,
            60,
            0.5,
            what=f"{n} node(s) in the gateway's table",
        )

    def esc_events(self, event):
        if not self.esc_log.exists():
            return []
        return [
            e for e in map(json.loads, self.esc_log.read_text().splitlines()) if e["event"] == event
        ]

    def hub_frames(self, port):
        """(id, data hex) of every frame the hub port's client sent."""
        out = []
        for line in self.hub_log.read_text().splitlines():
            f = line.split()
            if len(f) == 3 and f[1] == f"hub{port}":
                ident, data = f[2].split("#")
                out.append((int(ident, 16), data))
        return out

    def start_danprobe(self, *args, name="danprobe"):
        """A long-running danprobe command (--json); returns (proc, ready event)."""
        return start_danprobe(self.procs, *args, name=name)

    def finish(self, p):
        """SIGTERM, exit 0, and the summary document."""
        return finish_danprobe(self.procs, p)

    def close(self):
        super().close()
        self.threads, self.nodes = [], []


def pty_open(path):
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    tty.setraw(fd)
    return fd


def pump_pty(fd, data, want, timeout=90):
    """Writes data to fd while reading until `want` bytes came back."""
    got = bytearray()
    pos = 0
    end = time.monotonic() + timeout
    while len(got) < want and time.monotonic() < end:
        w = [fd] if pos < len(data) else []
        r, wr, _ = select.select([fd], w, [], 0.1)
        if wr:
            try:
                pos += os.write(fd, data[pos : pos + 256])
            except BlockingIOError:
                pass
        if r:
            try:
                got += os.read(fd, 4096)
            except BlockingIOError:
                pass
    return bytes(got), pos


# ---- dynamic node ID allocation: an allocatee from the specification ----

ALLOCATION_DTID = 1  # uavcan.protocol.dynamic_node_id.Allocation
ANON_PRIORITY = 30  # any priority will do; a low one, as a request is not urgent


def anonymous_can_id(dtid, discriminator, priority=ANON_PRIORITY):
    """The 29-bit CAN ID of an anonymous message transfer: priority (bits
    24-28), a 14-bit discriminator (10-23), the data type ID's two low bits
    (8-9), message (bit 7 clear), source node 0 (0-6)."""
    return (priority & 0x1F) << 24 | (discriminator & 0x3FFF) << 10 | (dtid & 3) << 8


def allocation_request(uid_part, preferred, first, transfer_id):
    """An anonymous Allocation request as the data of one CAN frame: node_id
    (uint7) and first_part_of_unique_id (bool) in the first byte, most
    significant bit first; the unique ID bytes (a tail array: no length);
    the tail byte (start and end of transfer, toggle 0, transfer ID). At
    most 6 bytes of unique ID, so always one frame, without a transfer CRC."""
    assert 0 < len(uid_part) <= 6
    head = (preferred & 0x7F) << 1 | (1 if first else 0)
    return bytes([head]) + bytes(uid_part) + bytes([0xC0 | transfer_id & 0x1F])


class Allocatee:
    """A dynamic node ID allocatee written from the DroneCAN specification
    (the comments of uavcan.protocol.dynamic_node_id.Allocation, rules A-E)
    as a state machine: send(can_id, data) puts a raw 29-bit frame on the
    bus (pydronecan cannot send anonymous transfers); the caller calls
    poll() often (every 10 ms) and on_allocation() for every Allocation
    message heard, all from one thread (AllocateeHost does this).

    Rule A: the request timer starts at 600-1000 ms (random each time).
    B: when it expires, it restarts and the first stage goes out (6 bytes,
    first_part_of_unique_id set, node_id = the preferred ID or 0). C: any
    Allocation message restarts the timer. D: an Allocation from a
    non-anonymous node whose unique_id (under 16 bytes) is the start of
    ours: after 0-400 ms, unless another Allocation arrives meanwhile, the
    next stage (up to 6 bytes from the offset the answer reached). E: one
    with all 16 bytes of ours and a node ID other than 0: granted
    (.node_id; .granted is set); it reacts to nothing after that.

    .answers lists every Allocation heard (source node, node_id, unique ID
    bytes); .stages counts the requests sent."""

    REQUEST_PERIOD = (0.6, 1.0)
    FOLLOWUP_DELAY = (0.0, 0.4)

    def __init__(self, send, unique_id, preferred=0, seed=0):
        assert len(unique_id) == 16
        self.send, self.uid, self.preferred = send, bytes(unique_id), preferred
        self.rng = random.Random(seed)
        self.discriminator = self.rng.getrandbits(14)
        self.node_id = None
        self.granted = threading.Event()
        self.answers = []
        self.stages = 0
        self._tid = 0
        self._followup = None  # (due, offset) of a pending rule D
        self._request_due = self._later(self.REQUEST_PERIOD)  # rule A

    def _later(self, span):
        return time.monotonic() + self.rng.uniform(*span)

    def _send(self, offset, first):
        data = allocation_request(self.uid[offset : offset + 6], self.preferred, first, self._tid)
        self._tid = (self._tid + 1) & 0x1F
        self.send(anonymous_can_id(ALLOCATION_DTID, self.discriminator), data)
        self.stages += 1

    def poll(self):
        if self.node_id is not None:
            return
        now = time.monotonic()
        if self._followup is not None and now >= self._followup[0]:
            offset = self._followup[1]
            self._followup = None
            self._send(offset, first=False)
        if now >= self._request_due:  # rule B
            self._request_due = self._later(self.REQUEST_PERIOD)
            self._send(0, first=True)

    def on_allocation(self, src, node_id, uid):
        self.answers.append((src, node_id, uid))
        if self.node_id is not None:
            return
        self._request_due = self._later(self.REQUEST_PERIOD)  # rule C
        self._followup = None  # rule D.1: another Allocation ends the wait
        if not src:
            return  # another allocatee's request
        if uid == self.uid and node_id:  # rule E
            self.node_id = node_id
            self.granted.set()
        elif len(uid) < 16 and self.uid.startswith(uid):  # rule D
            self._followup = (self._later(self.FOLLOWUP_DELAY), len(uid))

    def wait(self, timeout=30):
        """The node ID granted; fails the test after timeout seconds."""
        if not self.granted.wait(timeout):
            pytest.fail(f"no node ID for {self.uid.hex()} in {timeout} s: heard {self.answers}")
        return self.node_id


class AllocateeHost:
    """A pydronecan node without a node ID on hub port k of a Rig, in a spin
    thread of the rig, running the Allocatees added to it (as devices
    behind one adapter): their requests leave through the node's driver as
    raw frames, and the Allocation messages it hears go to each of them."""

    def __init__(self, rig, k):
        self.node = pydronecan_nodes.make_node(rig.tmp / f"can{k}", None)
        rig.nodes.append(self.node)
        self.lock = threading.Lock()
        self.allocatees = []
        self.node.add_handler(U.protocol.dynamic_node_id.Allocation, self._on_allocation)
        rig.spin(self.node, self._poll, 0.01)

    def _send(self, can_id, data):
        self.node.can_driver.send(can_id, data, extended=True)

    def _each(self):
        with self.lock:
            return list(self.allocatees)

    def _poll(self):
        for a in self._each():
            a.poll()

    def _on_allocation(self, e):
        m = e.message
        for a in self._each():
            a.on_allocation(e.transfer.source_node_id, m.node_id, bytes(m.unique_id))

    def add(self, unique_id, preferred=0, seed=0):
        """A new Allocatee for unique_id (16 bytes), preferring node ID
        preferred (0: none); seed makes its random intervals repeatable."""
        a = Allocatee(self._send, unique_id, preferred, seed)
        with self.lock:
            self.allocatees.append(a)
        return a
