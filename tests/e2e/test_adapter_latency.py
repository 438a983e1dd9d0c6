"""USB-serial adapters between the wire and the FC (dan-vbus --latency,
docs/VBUS.md "Adapter latency"): bytes reach the FC late and in bursts,
its own echo too. danprobe and the libdan master (dan-fcsim) with the
documented settings (docs/PROTOCOL.md section 6, host_tools/README.md) work
through an FTDI chip at its default 16 ms latency timer, and exactly the
values sent reach the ESCs.

Deadlines are generous and catch hangs; nothing here asserts a speed
(`make bench` measures the rates through each adapter kind).
"""

import os
import random
import select
import subprocess
import termios
import time

import pytest

from bus_util import control, danprobe, start_vbus, vbus_stats
from conftest import BIN, MASTER_WAIT_MS, closing_factory
from gw_rig import GW_NODE, Stack, pty_open
from test_esc_fast import fcsim_fast_run, gateway_cmds, only_values_then_zeros

FTDI_DEFAULT = ("--latency", "0:16:1")  # ep 0 is the FC's (danprobe, dan-fcsim)


@pytest.fixture
def stack(procs, tmp_path):
    yield from closing_factory(lambda **kw: Stack(procs, tmp_path, **kw))


def set_baud(fd, baud):
    attr = termios.tcgetattr(fd)
    speed = getattr(termios, f"B{baud}")
    attr[4] = attr[5] = speed
    termios.tcsetattr(fd, termios.TCSANOW, attr)


def read_exactly(fd, n, timeout=30):
    got = b""
    until = time.monotonic() + timeout
    while len(got) < n and time.monotonic() < until:
        if select.select([fd], [], [], 0.5)[0]:
            got += os.read(fd, 4096)
    return got


def test_latency_model_delivers_every_byte_in_order(procs, tmp_path):
    _, eps, ctl = start_vbus(procs, tmp_path, 3, "--latency", "0:16:2", "--latency", "2:4:0:8")
    fds = [pty_open(p) for p in eps]
    for fd in fds:
        set_baud(fd, 115200)
    data = random.Random(7).randbytes(3000)
    for i in range(0, len(data), 100):  # paced below the wire's rate
        os.write(fds[1], data[i : i + 100])
        time.sleep(0.01)
    # behind the adapters (0: FTDI-like, 2: 4 ms and 8-byte packets), the
    # writer's own echo without one: every byte, in order, unchanged
    for k in (0, 1, 2):
        assert read_exactly(fds[k], len(data)) == data, k
    st = vbus_stats(ctl)
    eps_st = st["endpoints"]
    assert [e["latency_ms"] for e in eps_st] == [16, 0, 4]
    assert [e["jitter_ms"] for e in eps_st] == [2, 0, 0]
    assert [e["bytes_out"] for e in eps_st] == [3000] * 3 and st["dropped"] == 0
    # at run time: set, switch off, refuse what is not a setting
    assert control(ctl, "latency 1:8:1") == "ok"
    assert control(ctl, "latency all:0") == "ok"
    assert [e["latency_ms"] for e in vbus_stats(ctl)["endpoints"]] == [0, 0, 0]
    for bad in ("latency 3:16", "latency 0:x", "latency 0:16:1:0", "latency 0:2000", "latency"):
        assert control(ctl, bad).startswith("error:"), bad
    for fd in fds:
        os.close(fd)


def test_vbus_refuses_bad_latency_options(procs, tmp_path):
    for bad in ("2:16", "0", "0:-1", "0:16:1:5000", "x:16", "0:16:1:62:9"):
        r = subprocess.run(
            [BIN / "dan-vbus", "-n", "2", "--latency", bad], capture_output=True, timeout=10
        )
        assert r.returncode == 2, bad
        assert b"--latency must be" in r.stderr and b"Traceback" not in r.stderr


def test_danprobe_through_an_ftdi_at_its_default_latency(stack):
    s = stack(vbus_extra=FTDI_DEFAULT)
    s.wait_gateway_sees(4)
    # The documented rule: --latency-ms above the adapter's timer plus the
    # host's jitter. The default 50 ms covers 16 ms on an idle host; a test
    # host running three test workers on two cores stalls danprobe, the
    # gateway and dan-vbus for hundreds of ms more, so the window is the
    # tests' generous one (conftest: MASTER_WAIT_MS, above the gateway's).
    rc, out, err = danprobe(
        "esc",
        "--port",
        s.dan,
        "--configure",
        "--latency-ms",
        MASTER_WAIT_MS,
        "--values",
        "0,100,200,300",
        "--duration",
        "2.5",
    )
    assert rc == 0, err
    head = next(line for line in out.splitlines() if line.startswith("esc:"))
    exchanges = int(head.split()[1])
    assert exchanges > 20, out
    cmds = {tuple(e["cmd"]) for e in s.esc_events("cmd") if e["src"] == GW_NODE}
    assert cmds <= {(0, 100, 200, 300), (0, 0, 0, 0)} and (0, 100, 200, 300) in cmds


@pytest.mark.parametrize("baud", [115200, 1000000])
def test_libdan_master_through_an_ftdi_at_its_default_latency(stack, baud):
    s = stack(vbus_extra=FTDI_DEFAULT)
    s.wait_gateway_sees(4)
    _, run = fcsim_fast_run(s, baud, 2000)
    assert run["baud"] == baud and run["exchanges"] > 20, run
    print(f"\nESC_FAST at {baud} behind a 16 ms adapter: {run['rate']:.0f} exchanges/s")
    gateway_cmds(s, [11, -22, 8191, -8192], 10)
    only_values_then_zeros(s, [11, -22, 8191, -8192])
