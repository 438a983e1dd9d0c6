"""Two DAN buses in the QEMU firmware (examples/fc_firmware, buses=2): the
Cortex-M4 runs a master on UART0 and one on UART1, each on its own dan-vbus
wire with a gateway, a CAN bus and four esc_sim ESCs; UART2 is the test's
control line ('q' ends the run). Bus 1's gateway is killed mid-flight and
started again; bus 0 never sees an error, and every ESC gets only its own
bus's values (as test_two_buses.py shows for dan-fc2bus). Nothing here
asserts a speed."""

import json
import os
import subprocess
import time

import pytest

import test_two_buses
from conftest import wait_for
from test_firmware import FW_ELF, QEMU, RUN_TIMEOUT, qemu_command
from test_two_buses import bus_cmds, check_one_failing, restart_gateway_midflight

stack = test_two_buses.stack  # the fixture: stack(name) makes a gateway stack


@pytest.fixture
def control_line():
    """A pty the test owns for UART2: (the master fd, the slave's path)."""
    master, slave = os.openpty()
    yield master, os.ttyname(slave)
    os.close(master)
    os.close(slave)


def qemu_args(a, b, ctl):
    paths = [os.path.realpath(a.dan), os.path.realpath(b.dan), ctl]
    assert all(p.startswith("/dev/pts/") for p in paths)  # the host owns each pty
    return qemu_command(paths, "buses=2")


def test_firmware_two_buses_one_failing(
    stack,
    procs,
    control_line,
    tmp_path,
):
    if QEMU is None or not os.path.exists(FW_ELF):
        pytest.fail(f"needs qemu-system-arm and {FW_ELF}: make test installs and builds both")
    a, b = stack("a"), stack("b")
    a.wait_gateway_sees(4)
    b.wait_gateway_sees(4)
    ctl, ctl_path = control_line
    with open(tmp_path / "qemu.stdout", "wb") as out:
        fw = procs.start(qemu_args(a, b, ctl_path), name="qemu", stdout=out)

    wait_for(lambda: bus_cmds(a, [10, 20, 30, 40]), 120, 0.1, what="bus 0 running")
    wait_for(lambda: bus_cmds(b, [11, 21, 31, 41]), 120, 0.1, what="bus 1 running")
    time.sleep(1.0)
    g = restart_gateway_midflight(procs, b, [11, 21, 31, 41], timeout=60)
    os.write(ctl, b"q")  # ends the run: one summary per bus
    try:
        rc = fw.wait(RUN_TIMEOUT)
    except subprocess.TimeoutExpired:
        pytest.fail(f"the firmware did not stop:\n{fw.log_path.read_text()[-2000:]}")
    fw.log_file.flush()
    text = fw.log_path.read_text()  # semihosting console (stderr)
    lines = [json.loads(x) for x in text.splitlines() if x.startswith("{")]
    assert rc == 0, text[-2000:]
    summary = {x["bus"]: x for x in lines if x.get("step") == "bus_summary"}
    windows = [x for x in lines if x.get("step") == "bus"]
    check_one_failing(summary, windows, a, b)
    assert summary[0]["values"] == [10, 20, 30, 40] and summary[0]["baud"] == 115200
    assert summary[1]["values"] == [11, 21, 31, 41]
    procs.stop(g)
