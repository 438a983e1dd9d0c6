"""End-to-end tests of the SLCAN side: host_tools/slcan_hub.py (a virtual
CAN bus of emulated Lawicel adapters on ptys), the gateway's C SLCAN backend
through tests/tools/dan-cantool, and pydronecan as the independent DroneCAN
peer."""

import json
import os
import pty
import re
import select
import signal
import sys
import threading
import time
import tty

import dronecan
import pytest

import pydronecan_nodes
from bus_util import control
from conftest import BIN, ROOT, read_line, wait_for

HUB = ROOT / "host_tools" / "slcan_hub.py"
CANTOOL = BIN / "dan-cantool"
LOGLINE = re.compile(r"^\((\d+\.\d{6})\) (\S+) ([0-9A-F]{3}|[0-9A-F]{8})#([0-9A-F]*|R\d?)$")


class Hub:
    def __init__(self, procs, tmp_path, n=4):
        self.prefix = str(tmp_path / "slcan")
        self.control = str(tmp_path / "hub.ctl")
        self.log = tmp_path / "bus.log"
        self.proc = procs.start(
            [
                sys.executable,
                HUB,
                "-n",
                n,
                "--link",
                self.prefix,
                "--control",
                self.control,
                "--log",
                self.log,
            ],
            name="slcan_hub",
        )
        line = read_line(self.proc.stdout.fileno(), 15)
        assert line.startswith("READY "), line
        self.ptys = line.split()[1:]
        assert len(self.ptys) == n
        self.links = [f"{self.prefix}{i}" for i in range(n)]
        for link, pts in zip(self.links, self.ptys):
            assert os.readlink(link) == pts

    def ctl(self, cmd):
        return control(self.control, cmd)

    def stats(self):
        return json.loads(self.ctl("stats"))["ports"]


@pytest.fixture
def hub(procs, tmp_path):
    return Hub(procs, tmp_path)


def make_node(path, node_id, **kw):
    return pydronecan_nodes.make_node(path, node_id, **kw)


def spin_until(nodes, pred, timeout=15.0, what="condition"):
    end = time.monotonic() + timeout
    while not pred():
        if time.monotonic() > end:
            raise AssertionError(f"timed out after {timeout}s waiting for {what}")
        for n in nodes:
            n.spin(0.02)
    return True


def cantool(args, timeout=20):
    import subprocess

    return subprocess.run(
        [str(CANTOOL)] + [str(a) for a in args],
        stdin=subprocess.DEVNULL,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


def parse_candump(text):
    out = []
    for line in text.splitlines():
        m = LOGLINE.match(line)
        assert m, f"not a candump log line: {line!r}"
        out.append((m.group(2), m.group(3), m.group(4)))
    return out


def open_raw(path):
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
    tty.setraw(fd)
    return fd


def exchange(fd, data, expect_end=(b"\r", b"\a"), timeout=5.0):
    """Writes data and reads until the reply ends with CR or BEL."""
    os.write(fd, data)
    end = time.monotonic() + timeout
    buf = b""
    while not buf or buf[-1:] not in expect_end:
        left = end - time.monotonic()
        assert left > 0, f"no reply to {data!r} (got {buf!r})"
        r, _, _ = select.select([fd], [], [], left)
        if r:
            buf += os.read(fd, 256)
    return buf


# ---------------------------------------------------------------------------


def test_dronecan_nodes_both_ways(hub):
    """Two pydronecan nodes on ports 0 and 1 see each other's broadcasts."""
    a = make_node(hub.links[0], 20)
    try:
        b = make_node(hub.links[1], 21)
        try:
            got_a, got_b = [], []

            def on_b(e):
                if e.transfer.source_node_id == 20:
                    got_b.append(e.message.vendor_specific_status_code)

            def on_a(e):
                if e.transfer.source_node_id == 21:
                    got_a.append(e.message.vendor_specific_status_code)

            b.add_handler(dronecan.uavcan.protocol.NodeStatus, on_b)
            a.add_handler(dronecan.uavcan.protocol.NodeStatus, on_a)
            a.broadcast(
                dronecan.uavcan.protocol.NodeStatus(
                    uptime_sec=5, vendor_specific_status_code=0xBEEF
                )
            )
            b.broadcast(
                dronecan.uavcan.protocol.NodeStatus(
                    uptime_sec=6, vendor_specific_status_code=0xCAFE
                )
            )
            spin_until(
                [a, b], lambda: 0xBEEF in got_b and 0xCAFE in got_a, what="NodeStatus both ways"
            )
        finally:
            b.close()
    finally:
        a.close()
    st = hub.stats()
    assert st[0]["frames_in"] >= 1 and st[1]["frames_in"] >= 1
    assert st[0]["errors"] == 0 and st[1]["errors"] == 0


def test_cantool_send_reaches_dronecan(hub):
    """A hand-made NodeStatus frame from dan-cantool (C SLCAN backend) on
    port 2 is decoded by a pydronecan node on port 1."""
    node = make_node(hub.links[1], 21)
    try:
        got = []

        def on_status(e):
            if e.transfer.source_node_id == 10:
                got.append(
                    (
                        e.message.uptime_sec,
                        e.message.vendor_specific_status_code,
                        e.message.health,
                        e.message.mode,
                    )
                )

        node.add_handler(dronecan.uavcan.protocol.NodeStatus, on_status)
        r = cantool(["--can", "slcan:" + hub.links[2], "send", "1401550A#01000000003412c0"])
        assert r.returncode == 0, r.stderr
        spin_until([node], lambda: got, what="NodeStatus from node 10")
        assert got[0] == (1, 0x1234, 0, 0)
    finally:
        node.close()
    log = hub.log.read_text()
    assert re.search(r"^\(\d+\.\d{6}\) hub2 1401550A#01000000003412C0$", log, re.M), log


def test_dronecan_broadcast_exact_frames_to_cantool(hub, procs):
    """pydronecan broadcasts a multi-frame LogMessage and a NodeStatus;
    dan-cantool recv prints exactly the frames pydronecan sent, in order."""
    from dronecan import transport

    log_msg = dronecan.uavcan.protocol.debug.LogMessage(
        level=dronecan.uavcan.protocol.debug.LogLevel(value=2),
        source="slcan",
        text="hello over the SLCAN hub",
    )
    status = dronecan.uavcan.protocol.NodeStatus(uptime_sec=77, vendor_specific_status_code=0x4242)
    n_frames = 0
    for msg in (log_msg, status):
        t = transport.Transfer(
            payload=msg, source_node_id=20, transfer_id=0, service_not_message=False
        )
        n_frames += len(t.to_frames())
    assert n_frames >= 4  # the LogMessage really is multi-frame

    rx = procs.start(
        [
            CANTOOL,
            "--can",
            "slcan:" + hub.links[2],
            "recv",
            "--count",
            n_frames,
            "--timeout-ms",
            20000,
        ],
        name="cantool-recv",
    )
    wait_for(lambda: hub.stats()[2]["open"], timeout=10, what="port 2 opened by dan-cantool")

    # No periodic NodeStatus: only the two broadcasts below go on the bus.
    node = make_node(hub.links[0], 20, node_status_interval=3600)
    sent = []
    try:
        node.can_driver.add_io_hook(lambda d, f: sent.append(f) if d == "tx" else None)
        node.broadcast(log_msg)
        node.broadcast(status)
        assert len(sent) == n_frames
        rc = rx.wait(20)
    finally:
        node.close()
    out = rx.stdout.read().decode()
    assert rc == 0, (out, rx.log_path.read_text())
    got = parse_candump(out)
    want = [("can0", "%08X" % f.id, bytes(f.data).hex().upper()) for f in sent]
    assert got == want


def test_malformed_lines_get_bel(hub):
    fd = open_raw(hub.links[3])
    try:
        assert exchange(fd, b"C\r") == b"\r"
        assert exchange(fd, b"V\r") == b"V1013\r"
        assert exchange(fd, b"N\r") == b"NA123\r"
        assert exchange(fd, b"t1230\r") == b"\a"  # not open yet
        assert exchange(fd, b"S8\r") == b"\r"
        assert exchange(fd, b"O\r") == b"\r"
        assert exchange(fd, b"O\r") == b"\a"  # already open
        assert exchange(fd, b"F\r") == b"F00\r"
        bad = [
            b"t12\r",
            b"tXYZ0\r",
            b"t8000\r",
            b"t1239" + b"00" * 9 + b"\r",
            b"t12330102\r",
            b"T2000000000\r",
            b"Q\r",
            b"x" * 200 + b"\r",
            b"Z7\r",
        ]
        for line in bad:
            assert exchange(fd, line) == b"\a", line
        assert exchange(fd, b"t1230\r") == b"z\r"
        assert exchange(fd, b"T1FFFFFFF2abcd\r") == b"Z\r"
        assert exchange(fd, b"r7FF2\r") == b"z\r"
        st = hub.stats()[3]
        assert st["errors"] == len(bad) + 2
        assert st["frames_in"] == 3

        # Timestamps: Z1 adds 4 hex digits of milliseconds to received frames.
        assert exchange(fd, b"Z1\r") == b"\r"
        r = cantool(["--can", "slcan:" + hub.links[0], "send", "12345678#0102"])
        assert r.returncode == 0, r.stderr
        line = b""
        while not line.endswith(b"\r"):
            sel, _, _ = select.select([fd], [], [], 10)
            assert sel, line
            line += os.read(fd, 64)
        assert re.fullmatch(rb"T1234567820102[0-9A-F]{4}\r", line), line
        assert int(line[-5:-1], 16) < 60000
    finally:
        os.close(fd)


def test_cantool_errors_exit_2(tmp_path):
    r = cantool(["--can", "slcan:" + str(tmp_path / "no-such-tty"), "recv"])
    assert r.returncode == 2
    assert "no such device" in r.stderr and "no-such-tty" in r.stderr
    r = cantool(["--can", "bogus:x", "recv"])
    assert r.returncode == 2 and "unknown CAN interface type" in r.stderr
    r = cantool(["--can", "slcan:/dev/null", "send", "123#zz"])
    assert r.returncode == 2 and "bad frame" in r.stderr
    r = cantool(["--can", "slcan:/dev/null", "recv"])
    assert r.returncode == 2 and "not a serial port" in r.stderr
    r = cantool(["--can", "socketcan:dancan0", "recv"])  # AF_CAN may be missing
    assert r.returncode == 2 and "socketcan:dancan0" in r.stderr
    # A tty where no adapter answers: a clear "no answer" within ~1 s.
    master, slave = pty.openpty()
    try:
        t0 = time.monotonic()
        r = cantool(["--can", "slcan:" + os.ttyname(slave), "recv"])
        assert r.returncode == 2 and "no answer from adapter" in r.stderr, r.stderr
        assert time.monotonic() - t0 < 5
    finally:
        os.close(master)
        os.close(slave)


def test_cantool_parser_against_fake_adapter():
    """The C backend through a scripted adapter: handshake, timestamps,
    z/Z ACKs, BEL, garbage and an overlong line, then valid frames."""
    master, slave = pty.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    seen = []
    stop = threading.Event()

    def adapter():
        buf = b""
        while not stop.is_set():
            r, _, _ = select.select([master], [], [], 0.05)
            if not r:
                continue
            try:
                buf += os.read(master, 256)
            except OSError:
                return
            while b"\r" in buf:
                line, buf = buf.split(b"\r", 1)
                seen.append(line)
                if line == b"O":
                    os.write(
                        master,
                        b"\r"
                        + b"z\rZ\r\a"
                        + b"garbage!\r"
                        + b"t" * 80
                        + b"\r"
                        + b"t1230\r"
                        + b"t12321122ABCD\r"
                        + b"T1ABCDEF08"
                        + b"00" * 8
                        + b"\r"
                        + b"r7FF3\r"
                        + b"R0000000100FFF\r\n"
                        + b"t12391122\r",
                    )
                else:
                    os.write(master, b"\r")

    th = threading.Thread(target=adapter, daemon=True)
    th.start()
    try:
        r = cantool(
            [
                "--can",
                "slcan:" + path,
                "--ifname",
                "slcan0",
                "recv",
                "--count",
                5,
                "--timeout-ms",
                10000,
            ]
        )
        assert r.returncode == 0, r.stderr
        assert parse_candump(r.stdout) == [
            ("slcan0", "123", ""),
            ("slcan0", "123", "1122"),
            ("slcan0", "1ABCDEF0", "0000000000000000"),
            ("slcan0", "7FF", "R3"),
            ("slcan0", "00000001", "R"),
        ]
        assert seen[:3] == [b"C", b"S8", b"O"]
        wait_for(lambda: seen[-1:] == [b"C"], timeout=5, what="C on close")
    finally:
        stop.set()
        th.join(5)
        os.close(master)
        os.close(slave)


def test_client_close_and_reopen(hub):
    """Clients come and go; the hub keeps serving every port."""
    for _ in range(3):
        r = cantool(["--can", "slcan:" + hub.links[2], "send", "123#01"])
        assert r.returncode == 0, r.stderr
    node = make_node(hub.links[1], 21)
    node.close()
    node = make_node(hub.links[1], 21)  # same pty, reopened
    try:
        got = []
        node.add_handler(
            dronecan.uavcan.protocol.NodeStatus,
            lambda e: got.append(e.message.uptime_sec) if e.transfer.source_node_id == 10 else None,
        )
        r = cantool(["--can", "slcan:" + hub.links[2], "send", "1401550A#09000000000000c0"])
        assert r.returncode == 0, r.stderr
        spin_until([node], lambda: 9 in got, what="NodeStatus after reopen")
    finally:
        node.close()
    assert hub.proc.poll() is None


def test_detach_attach(hub, procs):
    """detach K hangs the pty up (the C backend reports an I/O error) and
    removes the link; attach K brings a new pty behind the same link."""
    rx = procs.start(
        [CANTOOL, "--can", "slcan:" + hub.links[3], "recv", "--count", 1, "--timeout-ms", 20000],
        name="cantool-recv",
    )
    wait_for(lambda: hub.stats()[3]["open"], timeout=10, what="port 3 open")
    assert hub.ctl("detach 3") == "ok"
    assert rx.wait(10) == 1
    assert "receive failed" in rx.log_path.read_text()
    assert not os.path.lexists(hub.links[3])
    st = hub.stats()[3]
    assert st["attached"] is False and st["open"] is False
    assert hub.ctl("detach 3").startswith("error")
    assert hub.ctl("attach 3") == "ok"
    assert os.path.islink(hub.links[3])
    assert os.readlink(hub.links[3]).startswith("/dev/pts/")
    r = cantool(["--can", "slcan:" + hub.links[3], "send", "321#AA"])
    assert r.returncode == 0, r.stderr
    assert hub.ctl("bogus").startswith("error")


def test_hub_sigterm_and_quit(procs, tmp_path):
    h = Hub(procs, tmp_path, n=2)
    assert procs.stop(h.proc, signal.SIGTERM) == 0
    for link in h.links:
        assert not os.path.lexists(link)
    assert not os.path.exists(h.control)

    d = tmp_path / "q"
    d.mkdir()
    h2 = Hub(procs, d, n=1)
    assert h2.ctl("quit") == "ok"
    assert h2.proc.wait(10) == 0
    assert not os.path.lexists(h2.links[0])


def test_hub_help():
    import subprocess

    r = subprocess.run([sys.executable, HUB, "--help"], capture_output=True, text=True, timeout=20)
    assert r.returncode == 0
    assert "--control" in r.stdout and "detach K" in r.stdout
