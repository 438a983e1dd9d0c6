"""The master and peripheral engines over a virtual half-duplex bus:
dan-master (libdan master) and dan-testperiph processes on dan-vbus ptys."""

import json
import os
import subprocess
import threading
import time

import pytest

from bus_util import (
    control,
    periph_stats,
    read_capture,
    start_mixed_periphs,
    start_vbus,
    vbus_stats,
)
from conftest import BIN, MASTER_WAIT_MS

TYPES = "test-a,test-b,can-gw,vtx"


def master(port, *steps, types=TYPES, timeout=120, check=True, opts=()):
    """Runs dan-master with --json; returns (exit code, list of step results).
    The reply window is generous (MASTER_WAIT_MS): a loaded 2-core host can
    stall a process that long, and these tests check behaviour, not speed."""
    r = subprocess.run(
        [
            str(BIN / "dan-master"),
            "--port",
            port,
            "--types",
            types,
            "--json",
            "--latency-ms",
            MASTER_WAIT_MS,
            *opts,
            *steps,
        ],
        stdin=subprocess.DEVNULL,
        capture_output=True,
        timeout=timeout,
    )
    out = [json.loads(line) for line in r.stdout.decode().splitlines() if line.startswith("{")]
    if check:
        assert r.returncode == 0, (r.returncode, out, r.stderr.decode())
    return r.returncode, out


@pytest.fixture
def bus3(procs, tmp_path):
    """dan-vbus with a master endpoint and three peripherals of different
    types: test-a (all bauds), test-b (all bauds), can-gw (no 57600)."""
    vbus, eps, ctl = start_vbus(procs, tmp_path, 5)
    ps = start_mixed_periphs(procs, eps)
    return eps, ctl, ps


def test_discovery_identities_and_configure(bus3, procs, tmp_path):
    eps, ctl, ps = bus3
    rc, out = master(eps[0], "discover", "configure", "request:0x62:616263", "stats")
    disc, conf, req, stats = out
    peers = {p["type"]: p for p in disc["peers"]}
    assert set(peers) == {"test-a", "test-b", "can-gw"}  # no VTX on this bus
    assert peers["test-a"]["manufacturer"] == "DAN Project"
    assert peers["test-b"]["model"] == "test-b"
    assert peers["can-gw"]["baud_mask"] == 0x0B
    assert peers["can-gw"]["dan_version"] == 1
    assert all(p["baud"] == 9600 for p in peers.values())
    assert conf["result"] == 0 and conf["baud"] == 115200
    assert bytes.fromhex(req["payload"]) == b"cba"
    # The capture shows the bus really moved: CONFIGURE and its ACKs at 9600,
    # then IDENTIFY verification and the request at 115200 from every talker.
    bursts = read_capture(tmp_path)
    configures = [b for b in bursts if b[1] == 0 and b[3][1] in (0x41, 0x61, 0x71)]
    assert len(configures) == 3 and all(b[2] == 9600 for b in configures)
    fast = [b for b in bursts if b[2] == 115200]
    assert {b[1] for b in fast} == {0, 1, 2, 3}
    assert all(b[2] == 115200 for b in bursts if b[0] > configures[-1][0] + 0.2)
    for p in ps:
        s = periph_stats(procs, p)
        assert s["baud"] == 115200 and s["baud_changes"] == 1 and s["collisions"] == 0


def test_unknown_code_ignored_and_malformed_answered(bus3, procs):
    eps, ctl, ps = bus3
    rc, out = master(
        eps[0],
        "discover",
        "request:0x64",
        "request:0x62",
        "request:0x61",
        "request:0x62:0001",
        check=False,
    )
    assert rc == 1
    disc, unknown, malformed, bad_conf, ok = out
    assert unknown["result"] == -4 and unknown["error"] == "timeout"  # ignored: no reply at all
    assert malformed["result"] == -6 and malformed["error"] == "empty payload"
    assert bad_conf["result"] == -6 and "CONFIGURE" in bad_conf["error"]
    assert ok["result"] == 0 and ok["payload"] == "0100"
    s = periph_stats(procs, ps[0])
    assert s["unknown"] >= 3  # 0x64 and its two retries were heard and ignored
    assert s["errors_sent"] == 2
    assert s["replies"] >= 3


def test_master_restart_finds_configured_bus(bus3, procs, tmp_path):
    eps, ctl, ps = bus3
    master(eps[0], "discover", "configure:38400")
    # A new master process starts at 9600 like a rebooted FC: nothing answers
    # there, so it must find the peripherals at their configured baud.
    rc, out = master(eps[0], "discover", "configure", "request:0x62:0102")
    disc, conf, req = out
    assert {p["baud"] for p in disc["peers"]} == {38400}
    assert len(disc["peers"]) == 3
    assert conf["baud"] == 115200
    assert req["payload"] == "0201"


def test_collisions_detected_and_recovered(bus3, procs, tmp_path):
    """A second talker jams part of the traffic: whoever talks over it sees its
    echo differ, backs off and retries; every exchange completes correctly."""
    eps, ctl, ps = bus3
    stop = threading.Event()
    jams = []

    def jammer():
        fd = os.open(eps[4], os.O_RDWR | os.O_NOCTTY)
        try:
            os.set_blocking(fd, False)
            seen, prev = 0, None
            while not stop.is_set():
                try:
                    data = os.read(fd, 256)
                except BlockingIOError:
                    time.sleep(0.0005)
                    continue
                # On every 7th frame of code 0x62 heard (the repeat step's,
                # not discovery's), talk at once over it. An exchange has
                # at most 2 such frames, so a transaction's next attempt is
                # not jammed too, and with 4 retries even a jam that a
                # loaded host delays onto the next attempt leaves three.
                for b in data:
                    if prev == 0x44 and b == 0x62:
                        seen += 1
                        if seen % 7 == 0:
                            os.write(fd, b"\x13\x37\x13")
                            jams.append(time.monotonic())
                    prev = b
        finally:
            os.close(fd)

    t = threading.Thread(target=jammer, daemon=True)
    t.start()
    try:
        rc, out = master(
            eps[0],
            "discover",
            "repeat:60:0x62:a1b2c3d4",
            "request:0x62:0a0b",
            "stats",
            types="test-a,test-b,can-gw",
            opts=("--retries", "4"),
        )
    finally:
        stop.set()
        t.join(5)
    disc, rep, req, stats = out
    assert len(disc["peers"]) == 3
    assert rep["done"] == 60 and rep["result"] == 0
    assert req["payload"] == "0b0a"
    assert len(jams) >= 3
    assert stats["collisions"] >= 1 and stats["retries"] >= 1
    assert vbus_stats(ctl)["collisions"] >= 1


def test_noise_recovered(bus3, procs):
    """Bit errors on the wire: frames are dropped by the CRC, the master
    retries, and no wrong payload is ever returned; once noise stops the
    link is clean."""
    eps, ctl, ps = bus3

    def at_ber(ber, repeats, last, **kw):
        """discover, the same request `repeats` times, then `last`, at this bit error rate."""
        assert control(ctl, f"ber {ber}") == "ok"
        repeat = f"repeat:{repeats}:0x62:00112233445566778899"
        return master(eps[0], "discover", repeat, last, types="test-a", **kw)

    master(eps[0], "discover", "configure")
    rc, out = at_ber("0.002", 40, "stats", check=False)
    disc, rep, stats = out
    noisy = vbus_stats(ctl)
    assert noisy["noise_flips"] > 0
    # Damaged frames were retried; the repeat step stops at the first
    # failure, which is allowed under noise ("done" counts the exchanges
    # that succeeded: it counted the failing one too).
    assert stats["retries"] >= 1
    assert rep["done"] <= 40 and (rep["done"] == 40) == (rep["result"] == 0)
    rc, out = at_ber("0", 30, "request:0x62:cafe", opts=("--retries", "4"))
    assert out[1]["done"] == 30 and out[2]["payload"] == "feca"


def test_bad_arguments_and_missing_port(tmp_path):
    def dan_master(*args):
        return subprocess.run(
            [str(BIN / "dan-master"), *args],
            capture_output=True,
            stdin=subprocess.DEVNULL,
            timeout=30,
        )

    r = dan_master("--port", str(tmp_path / "nope"), "discover")
    assert r.returncode == 2 and b"No such file" in r.stderr
    r = dan_master("--port", "/dev/null", "--bogus")
    assert r.returncode == 2 and b"unknown option" in r.stderr
    r = dan_master("--port", "/dev/null", "discover")
    assert r.returncode == 2 and b"not a serial port" in r.stderr
    # every step is checked whole before the port is touched (a bad one ran
    # the steps before it, or an automatic configure, and exited 1)
    for step in (
        "configurefoo",
        "configure:abc",
        "configure:0",
        "request:0x60:zz",
        "request:0x60:-1",
        "request:0x60:00:junk",
        "repeat:0:0x60",
        "repeat:2:0x60:00:x",
    ):
        r = dan_master("--port", str(tmp_path / "nope"), "discover", step)
        assert r.returncode == 2 and b"bad step" in r.stderr, (step, r.stderr)
    r = subprocess.run([str(BIN / "dan-master"), "--help"], capture_output=True, timeout=30)
    assert r.returncode == 0 and b"steps:" in r.stdout
