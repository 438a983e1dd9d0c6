"""Two DAN buses in one FC process (dan-fc2bus: two masters, two gateway
clients, one poll loop): two dan-vbus wires, two gateways, two CAN buses
with four esc_sim ESCs each. Bus 1's gateway is killed mid-flight and
started again; bus 0 never sees an error, and every ESC gets only its own
bus's values. Nothing here asserts a speed."""

import json
import signal
import subprocess
import time

import pytest

from conftest import BIN, MASTER_WAIT_MS, closing_factory, wait_for
from gw_rig import GW_NODE, Stack, gatewayd_cmd


@pytest.fixture
def stack(procs, tmp_path):
    def make(name):
        (tmp_path / name).mkdir()
        return Stack(procs, tmp_path / name)

    yield from closing_factory(make)


def test_one_bus_failing_leaves_the_other_unaffected(stack, procs):
    a, b = stack("a"), stack("b")
    a.wait_gateway_sees(4)
    b.wait_gateway_sees(4)
    fc = procs.start(
        [BIN / "dan-fc2bus", "--port", a.dan, "--port", b.dan, "--seconds", "300"]
        + ["--latency-ms", MASTER_WAIT_MS, "--values", "10,20,30,40"],
        stdout=subprocess.PIPE,
    )

    wait_for(lambda: bus_cmds(b, [11, 21, 31, 41]), 120, 0.1, what="bus 1 running")
    time.sleep(1.0)
    g = restart_gateway_midflight(procs, b, [11, 21, 31, 41])
    fc.send_signal(signal.SIGTERM)  # ends the run: one summary per bus
    out, _ = fc.communicate(timeout=120)
    lines = [json.loads(x) for x in out.decode().splitlines()]
    summary = {x["bus"]: x for x in lines if x.get("summary")}
    windows = [x for x in lines if not x.get("summary")]
    assert fc.returncode == 0, lines
    check_one_failing(summary, windows, a, b)
    procs.stop(g)


def bus_cmds(s, values):
    """The RawCommands with values the ESCs of stack s heard from the gateway."""
    return [e for e in s.esc_events("cmd") if e["src"] == GW_NODE and e["cmd"] == values]


def restart_gateway_midflight(procs, b, values, timeout=30):
    """Kills bus b's gateway, starts it again (at 9600) 3 s later and waits
    until b's ESCs hear values through it; returns the new gateway."""
    procs.stop(b.gwd, signal.SIGKILL)  # bus 1 fails ...
    time.sleep(3.0)
    restart_t = time.monotonic()
    g = procs.start(  # ... and its gateway comes back (at 9600)
        gatewayd_cmd(b.tmp),
        name="gwd-b-again",
        stdout=None,
    )
    wait_for(
        lambda: (
            len(bus_cmds(b, values)) > 0 and max(e["t"] for e in bus_cmds(b, values)) > restart_t
        ),
        timeout,
        0.2,
        what="bus 1's ESCs commanded through the restarted gateway",
    )
    return g


def check_one_failing(summary, windows, a, b):
    """summary: bus -> its summary line; windows: the per-second lines
    ("bus", "exchanges", "errors"); a, b: the two buses' stacks."""
    # bus 0: exchanges in every second after it started, not one error
    a_win = [w for w in windows if w["bus"] == 0]
    assert summary[0]["errors"] == 0 and summary[0]["recoveries"] == 0, summary
    started = next(i for i, w in enumerate(a_win) if w["exchanges"])
    assert all(w["exchanges"] > 0 and w["errors"] == 0 for w in a_win[started:]), a_win
    # bus 1: failed while its gateway was gone, then recovered
    assert summary[1]["errors"] > 0 and summary[1]["recoveries"] >= 1, (summary, windows)
    # every ESC got its own bus's values only (and the failsafe's zeros)
    for s, mine in ((a, [10, 20, 30, 40]), (b, [11, 21, 31, 41])):
        seen = {tuple(e["cmd"]) for e in s.esc_events("cmd") if e["src"] == GW_NODE}
        assert seen <= {tuple(mine), (0, 0, 0, 0)} and tuple(mine) in seen, seen
