"""A daemon that dies is noticed (docs/SECURITY.md, dan-gatewayd.service):
dan-gatewayd speaks systemd's notify protocol (READY=1, WATCHDOG=1 at half
of WATCHDOG_USEC from its poll loop, STOPPING=1), so systemd restarts a
daemon whose loop hangs; and a daemon killed mid-flight (SIGKILL: no
failsafe of its own) comes back DISARMED with safety on before any
command. Here a datagram socket stands in for systemd."""

import os
import signal
import socket
import subprocess
import time

import pytest

from conftest import BIN, MASTER_WAIT_MS, closing_factory, wait_for
from gw_rig import GW_NODE, Stack, gatewayd_cmd

PING_US = 200_000  # WATCHDOG_USEC: a ping every 100 ms


@pytest.fixture
def stack(procs, tmp_path):
    yield from closing_factory(lambda **kw: Stack(procs, tmp_path, **kw))


def notify_socket(tmp):
    s = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    s.bind(str(tmp / "notify"))
    s.settimeout(0.2)
    return s


def messages(sock, seconds):
    got, end = [], time.monotonic() + seconds
    while time.monotonic() < end:
        try:
            got.append(sock.recv(4096).decode())
        except socket.timeout:
            pass
    return got


def gateway(s, procs, env, name):
    return procs.start(
        gatewayd_cmd(s.tmp),
        name=name,
        env={**os.environ, **env},
        stdout=None,
    )


def test_ready_watchdog_pings_and_a_hung_loop_stops_them(stack, procs):
    s = stack(escs=0)
    procs.stop(s.gwd)
    sock = notify_socket(s.tmp)
    env = {"NOTIFY_SOCKET": str(s.tmp / "notify"), "WATCHDOG_USEC": str(PING_US)}
    g = gateway(s, procs, env, "gwd-notify")
    first = messages(sock, 1.5)
    assert first and first[0] == "READY=1", first
    assert first[1:].count("WATCHDOG=1") >= 5, first
    # a hung loop (stopped process): no more pings, so systemd would kill it
    os.kill(g.pid, signal.SIGSTOP)
    messages(sock, 0.3)  # what was sent before the stop
    assert messages(sock, 1.0) == []
    os.kill(g.pid, signal.SIGCONT)
    assert "WATCHDOG=1" in messages(sock, 1.0)
    procs.stop(g)
    assert g.returncode == 0
    assert "STOPPING=1" in messages(sock, 0.5)
    # pings are for the process systemd named in WATCHDOG_PID only
    g2 = gateway(s, procs, {**env, "WATCHDOG_PID": "1"}, "gwd-other-pid")
    got = messages(sock, 1.0)
    assert got == ["READY=1"], got
    procs.stop(g2)
    sock.close()


def test_no_notify_socket_and_a_bad_one(stack, procs):
    s = stack(escs=0)
    procs.stop(s.gwd)
    g = gateway(s, procs, {"NOTIFY_SOCKET": "relative/path", "WATCHDOG_USEC": "1000"}, "gwd-bad")
    wait_for(lambda: "NOTIFY_SOCKET unusable" in g.log_path.read_text(), 20, 0.1, what="warning")
    assert g.poll() is None  # it runs on
    procs.stop(g)
    assert g.returncode == 0


def test_sigkill_mid_flight_what_the_escs_see(stack, procs):
    s = stack()
    s.wait_gateway_sees(4)
    # the FC recovers a gateway that came back at 9600 (--recover)
    p = procs.start(
        [BIN / "dan-fcsim", "--port", s.dan, "--latency-ms", MASTER_WAIT_MS, "--recover", "3"]
        + ["discover", "configure:115200", "esc:300,300,300,300@120000@100"],
        stdout=subprocess.DEVNULL,
    )
    wait_for(
        lambda: any(e["cmd"] == [300] * 4 for e in s.esc_events("cmd")), 60, 0.1, what="commands"
    )
    t_kill = time.monotonic()
    procs.stop(s.gwd, signal.SIGKILL)

    def drained():
        # commands already on their way (hub, Python ESCs) are logged late on
        # a loaded host: wait until the log has been quiet for a second
        cmds = [e["t"] for e in s.esc_events("cmd") if e["src"] == GW_NODE]
        return time.monotonic() - max(cmds) > 1.0

    wait_for(drained, 60, 0.2, what="the ESCs' backlog")
    # nothing from a dead gateway: its last command was the running value,
    # the ESCs' own command timeout is what stops the motors now
    last = max(e["t"] for e in s.esc_events("cmd") if e["src"] == GW_NODE)
    assert [e["cmd"] for e in s.esc_events("cmd") if e["src"] == GW_NODE][-1] == [300] * 4
    # "systemd" restarts it: DISARMED and safety on go out first
    t_start = time.monotonic()
    g = gateway(s, procs, {}, "gwd-restarted")

    def first(kind, status):
        ev = [
            e
            for e in s.esc_events(kind)
            if e["src"] == GW_NODE and e["t"] > t_start and e["status"] == status
        ]
        return min(ev, key=lambda e: e["t"]) if ev else None

    arming = wait_for(lambda: first("arming", 0), 30, 0.1, what="ArmingStatus DISARMED")
    safety = wait_for(lambda: first("safety", 0), 30, 0.1, what="SafetyState ON")

    def moving():
        return [
            e
            for e in s.esc_events("cmd")
            if e["src"] == GW_NODE and e["t"] > t_start and any(e["cmd"])
        ]

    wait_for(moving, 60, 0.1, what="commands through the restarted gateway")
    assert all(e["t"] > arming["t"] for e in moving())
    print(
        f"\nSIGKILL: last command logged {1000 * (last - t_kill):+.0f} ms from the kill; restarted "
        f"{1000 * (t_start - t_kill):.0f} ms later, DISARMED after {1000 * (arming['t'] - t_start):.0f} ms, "
        f"safety ON after {1000 * (safety['t'] - t_start):.0f} ms, commands again after {1000 * (moving()[0]['t'] - t_start):.0f} ms"
    )
    procs.stop(p)
    procs.stop(g)
