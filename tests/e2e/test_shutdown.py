"""The long-running tools end promptly on SIGTERM whatever went away first:
esc_sim.py and param_node.py (pydronecan nodes) with their SLCAN hub gone
or still there, dan-gatewayd with its CAN adapter or its DAN UART gone,
danprobe slcan with its DAN port or its gateway gone.

SIGTERM goes to the process alone (`kill PID`), so the tool itself must
close its nodes' I/O processes; or to its whole process group (systemd,
procgroup, Ctrl-C in a terminal), which the I/O processes get too.

Before the fix in pydronecan_nodes.close_nodes, esc_sim with 2 nodes took
20.7 s to end after the hub, param_node 10.5 s; a group signal that killed
an I/O process before the tool's handler ran ended esc_sim with a
traceback and exit 1. The bound is generous (a loaded 2-core host) and
far below those.
"""

import os
import signal
import subprocess
import sys
import time

import pytest

from bus_util import ready
from conftest import ROOT, wait_for
from gw_rig import Rig, start_danprobe

BOUND_S = 8.0  # a prompt end; the defects took 10.5 s and 20.7 s
SETTLE_S = 1.5  # for the nodes' I/O processes to notice the hub is gone


def term(p, group=False):
    """SIGTERM to p (or its whole group, delivered while p itself is stopped,
    so its I/O processes die before its handler runs); p's exit code, after
    failing the test if p took longer than BOUND_S."""
    t0 = time.monotonic()
    if group:
        os.kill(p.pid, signal.SIGSTOP)
        os.killpg(p.pid, signal.SIGTERM)
        time.sleep(0.5)  # the I/O processes are gone now; p has SIGTERM pending
        t0 = time.monotonic()
        os.kill(p.pid, signal.SIGCONT)
    else:
        os.kill(p.pid, signal.SIGTERM)
    try:
        rc = p.wait(BOUND_S)
    except subprocess.TimeoutExpired:
        pytest.fail(f"{p.args[:2]} still running {BOUND_S} s after SIGTERM")
    name = p.log_path.name.split(".")[0]
    print(f"\n{name}: exit {rc} {time.monotonic() - t0:.2f} s after SIGTERM")
    return rc


def start_hub(procs, tmp, n):
    hub = procs.start(
        ["python3", ROOT / "host_tools" / "slcan_hub.py", "-n", str(n), "--link", tmp / "can"],
        name="slcan_hub",
    )
    ready(hub, "slcan_hub")
    return hub


def start_tool(procs, tmp, tool, link=None):
    """esc_sim with 2 ESCs on hub ports can0, can1, or param_node on can0
    (or on link)."""
    if tool == "esc_sim":
        args = [ROOT / "host_tools" / "esc_sim.py", "--port", tmp / "can0", "--port", tmp / "can1"]
    else:
        args = [ROOT / "tests" / "tools" / "param_node.py", "--port", link or tmp / "can0"]
    p = procs.start([sys.executable, *args], name=tool)
    ready(p, tool)
    return p


@pytest.mark.parametrize("tool", ["esc_sim", "param_node"])
def test_node_tool_after_the_hub(procs, tmp_path, tool):
    hub = start_hub(procs, tmp_path, 2)
    p = start_tool(procs, tmp_path, tool)
    assert procs.stop(hub) == 0
    time.sleep(SETTLE_S)
    assert p.poll() is None  # a lost adapter alone does not end it
    assert term(p) == 0, p.log_path.read_text()


@pytest.mark.parametrize("tool", ["esc_sim", "param_node"])
def test_node_tool_before_the_hub(procs, tmp_path, tool):
    hub = start_hub(procs, tmp_path, 2)
    p = start_tool(procs, tmp_path, tool)
    assert term(p) == 0, p.log_path.read_text()
    assert term(hub) == 0, hub.log_path.read_text()


@pytest.mark.parametrize("tool", ["esc_sim", "param_node"])
def test_node_tool_group_signal(procs, tmp_path, tool):
    start_hub(procs, tmp_path, 2)
    p = start_tool(procs, tmp_path, tool)
    assert term(p, group=True) == 0, p.log_path.read_text()


def gateway(procs, tmp):
    """A Rig without pydronecan nodes (dan-vbus, the hub with one port,
    dan-gatewayd), once the daemon runs."""
    r = Rig(procs, tmp, ncan=1)
    wait_for(lambda: b"DroneCAN node" in r.gwd.log_path.read_bytes(), 20, what="gateway start")
    return r


@pytest.mark.parametrize("first", ["hub", "none"])
def test_gatewayd(procs, tmp_path, first):
    r = gateway(procs, tmp_path)
    if first == "hub":
        assert procs.stop(r.hub) == 0
        wait_for(lambda: b"adapter lost" in r.gwd.log_path.read_bytes(), 20, what="adapter lost")
    assert term(r.gwd) == 0
    # the log says what happened: with the adapter gone nothing could be sent
    # (it said "failsafe sent" either way)
    want = "CAN down: failsafe not sent" if first == "hub" else "stopped (failsafe sent)"
    assert want in r.gwd.log_path.read_text()
    assert term(r.hub if first == "none" else r.vbus) == 0


def test_gatewayd_after_its_uart(procs, tmp_path):
    """Its DAN UART gone, the daemon ends by itself (failsafe sent, exit 1)."""
    r = gateway(procs, tmp_path)
    assert procs.stop(r.vbus) == 0
    assert r.gwd.wait(20) == 1
    log = r.gwd.log_path.read_text()
    assert "UART lost" in log and "failsafe sent" in log


@pytest.mark.parametrize("first", ["vbus", "gatewayd", "none"])
def test_danprobe_slcan(procs, tmp_path, first):
    """Without a client the channel is closed and danprobe slcan does not
    talk to the gateway: whatever went, SIGTERM ends it with exit 0."""
    r = gateway(procs, tmp_path)
    p, _ = start_danprobe(procs, "slcan", "--port", tmp_path / "dan0", "--link", tmp_path / "sl")
    if first != "none":
        assert procs.stop(r.vbus if first == "vbus" else r.gwd) in (0, 1)
        time.sleep(SETTLE_S)
    assert term(p) == 0, p.log_path.read_text()


def test_danprobe_slcan_with_a_client(procs, tmp_path):
    """A pydronecan node (param_node) on danprobe slcan's pty keeps the
    channel open: the DAN port gone ends danprobe by itself (exit 1); the
    node, its adapter gone, still ends promptly on SIGTERM."""
    r = gateway(procs, tmp_path)
    p, _ = start_danprobe(procs, "slcan", "--port", tmp_path / "dan0", "--link", tmp_path / "sl")
    node = start_tool(procs, tmp_path, "param_node", link=tmp_path / "sl")
    wait_for(lambda: b"channel open" in p.log_path.read_bytes(), 30, what="channel open")
    assert procs.stop(r.vbus) == 0
    assert p.wait(30) == 1
    assert "device disconnected" in p.log_path.read_text()
    time.sleep(SETTLE_S)
    assert term(node) == 0, node.log_path.read_text()
