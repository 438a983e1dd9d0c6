"""libdan inside flight-controller firmware: examples/fc_firmware runs the
master engine on a Cortex-M4 under QEMU (mps2-an386), its UART0 on a
dan-vbus endpoint, with dan-testperiph peripherals on the other endpoints.

The host owns the pty (dan-vbus keeps the master side; QEMU gets the slave
path), so the firmware's baud-divisor writes reach the pty's termios and
dan-vbus paces the wire at the firmware's baud. The firmware reports over
semihosting (QEMU writes it to stderr) and ends QEMU with its exit code.
"""

import json
import os
import shutil
import subprocess

import pytest

import pydronecan_nodes
from bus_util import (
    periph_stats,
    read_capture,
    start_mixed_periphs,
    start_periph,
    start_vbus,
    vbus_stats,
)
from conftest import PERIPH_WINDOW_MS, ROOT, wait_for

FW_ELF = os.environ.get("DAN_FW_ELF", str(ROOT / "build" / "fw" / "fc_firmware.elf"))
QEMU = shutil.which("qemu-system-arm")
RUN_TIMEOUT = 180  # seconds: QEMU on a loaded 2-core machine


def need_qemu():
    """Fails the test unless QEMU and the firmware are there."""
    if QEMU is None or not os.path.exists(FW_ELF):
        pytest.fail(f"needs qemu-system-arm and {FW_ELF}: make test installs and builds both")


@pytest.fixture(autouse=True)
def need_firmware():
    need_qemu()


def qemu_command(serials, append=None):
    """QEMU running the firmware, UART k on serials[k] (pty paths)."""
    args = [
        QEMU,
        "-M",
        "mps2-an386",
        "-display",
        "none",
        "-monitor",
        "none",
        "-semihosting-config",
        "enable=on,target=native",
        "-kernel",
        FW_ELF,
    ]
    for path in serials:
        args += ["-serial", path]
    if append:
        args += ["-append", append]
    return args


def run_firmware(procs, tmp_path, endpoint, append=None):
    """Boots the firmware on a vbus endpoint; returns (exit code, JSON lines)."""
    pty = os.path.realpath(endpoint)  # /dev/pts/N: QEMU's tty backend
    assert pty.startswith("/dev/pts/")
    args = qemu_command([pty], append)
    with open(tmp_path / "qemu.stdout", "wb") as out:
        p = procs.start(args, name="qemu", stdout=out)
        try:
            rc = p.wait(RUN_TIMEOUT)
        except subprocess.TimeoutExpired:
            procs.stop(p)
            pytest.fail(f"firmware did not finish in {RUN_TIMEOUT}s:\n{p.log_path.read_text()}")
    p.log_file.flush()
    text = p.log_path.read_text()  # semihosting console (stderr)
    lines = []
    for line in text.splitlines():
        if line.startswith("{"):
            lines.append(json.loads(line))
    assert lines, f"no output from the firmware:\n{text}"
    return rc, {d["step"]: d for d in lines if "step" in d}, text


def firmware_bus(procs, tmp_path):
    """dan-vbus: endpoint 0 for the firmware, then test-a, test-b and a
    can-gw without 57600 (mask 0x0B). Returns (endpoints, vbus control,
    peripherals)."""
    vbus, eps, ctl = start_vbus(procs, tmp_path, 4)
    ps = start_mixed_periphs(procs, eps)
    return eps, ctl, ps


@pytest.fixture
def fc_bus(procs, tmp_path):
    return firmware_bus(procs, tmp_path)


def test_firmware_discovers_configures_and_transacts(fc_bus, procs, tmp_path):
    eps, ctl, ps = fc_bus
    rc, steps, text = run_firmware(procs, tmp_path, eps[0])
    assert rc == 0, text

    disc = steps["discover"]
    assert disc["result"] == 0
    peers = {p["type"]: p for p in disc["peers"]}
    assert set(peers) == {"test-a", "test-b", "can-gw"}
    assert all(p["baud"] == 9600 and p["dan_version"] == 1 for p in peers.values())
    assert peers["test-a"]["manufacturer"] == "DAN Project"
    assert peers["test-b"]["model"] == "test-b"
    assert peers["can-gw"]["baud_mask"] == 0x0B

    conf = steps["configure"]
    assert conf["result"] == 0 and conf["baud"] == 115200
    assert conf["uart_baud"] == 115207  # 25 MHz / 217: the divisor it wrote

    txn = steps["transactions"]
    assert txn["ok"] == txn["count"] == 40 and txn["bad"] == 0 and txn["baud"] == 115200
    assert steps["identify"]["result"] == 0 and steps["identify"]["model"] == "test-b"

    # dan-testperiph's can-gw answers IDENTIFY/CONFIGURE only: the gateway
    # phase (default gw=try) reports the timeout without failing the run.
    gw = steps["gateway"]
    assert gw.get("skipped") or (gw["result"] == -4 and gw["required"] is False)

    st = steps["stats"]
    assert st["exit"] == 0
    assert st["uart_overruns"] == 0 and st["ring_dropped"] == 0
    assert st["collisions"] == 0 and st["baud_changes"] == 1

    # The host saw the baud change: the firmware's divisor write reached the
    # pty's termios, so dan-vbus put its bytes on the wire at 115200.
    bursts = read_capture(tmp_path)
    configures = [  # frames that start a burst ('D'): a burst may also be a frame's tail
        b
        for b in bursts
        if b[1] == 0 and len(b[3]) > 1 and b[3][0] == 0x44 and b[3][1] in (0x41, 0x61, 0x71)
    ]
    assert len(configures) == 3 and all(b[2] == 9600 for b in configures)
    after = [b for b in bursts if b[1] == 0 and b[0] > configures[-1][0] + 0.005]
    assert len(after) >= 40 and all(b[2] == 115200 for b in after)
    assert {b[1] for b in bursts if b[2] == 115200} == {0, 1, 2, 3}
    assert vbus_stats(ctl)["endpoints"][0]["baud"] == 115200
    for p in ps:
        s = periph_stats(procs, p)
        assert s["baud"] == 115200 and s["baud_changes"] == 1 and s["collisions"] == 0


def test_firmware_exit_code_when_nothing_answers(procs, tmp_path):
    vbus, eps, ctl = start_vbus(procs, tmp_path, 2)
    rc, steps, text = run_firmware(procs, tmp_path, eps[0], append="gw=off")
    assert rc == 1, text
    assert steps["discover"]["result"] == -9 and steps["discover"]["peers"] == []
    assert "configure" not in steps
    assert steps["stats"]["exit"] == 1
    # it probed every type at every discovery baud
    assert {b[2] for b in read_capture(tmp_path)} == {9600, 115200, 57600, 38400, 19200}


def test_firmware_gateway_required_fails_without_gateway(fc_bus, procs, tmp_path):
    eps, ctl, ps = fc_bus
    rc, steps, text = run_firmware(procs, tmp_path, eps[0], append="gw=require")
    assert rc == 1, text
    assert steps["boot"]["gw_mode"] == "require"
    assert steps["transactions"]["bad"] == 0
    gw = steps["gateway"]
    assert gw.get("skipped") or (
        gw["result"] == -4 and gw["at"] == "arm" and gw["required"] is True
    )


def test_firmware_gateway_arm_esc_ramp_telemetry(procs, tmp_path):
    """The gateway phase against the real gateway: dan-gatewayd on the bus,
    an SLCAN hub as the CAN bus and a pydronecan ESC node that publishes
    esc.Status for ESC 0..3 and records what reaches CAN."""
    import threading
    import time

    import dronecan

    from conftest import BIN

    U = dronecan.uavcan
    for b in ("dan-gatewayd", "dan-testperiph"):
        if not (BIN / b).exists():
            pytest.fail(f"{b} not built: run make test (it builds everything)")
    vbus, eps, ctl = start_vbus(procs, tmp_path, 3)
    hub = procs.start(
        ["python3", ROOT / "host_tools" / "slcan_hub.py", "-n", "2", "--link", tmp_path / "can"],
        name="slcan_hub",
    )
    assert hub.stdout.readline().decode().startswith("READY")
    procs.start(
        [BIN / "dan-gatewayd", "--uart", eps[1], "--can", f"slcan:{tmp_path / 'can0'}"]
        + ["--reply-window-ms", PERIPH_WINDOW_MS],  # a loaded test host stalls (conftest)
        name="dan-gatewayd",
        stdout=subprocess.DEVNULL,
    )
    start_periph(procs, eps[2], "test-a,test-b")

    esc = pydronecan_nodes.make_node(tmp_path / "can1", 20)
    raw, arming = [], []
    esc.add_handler(U.equipment.esc.RawCommand, lambda e: raw.append(list(e.message.cmd)))
    esc.add_handler(U.equipment.safety.ArmingStatus, lambda e: arming.append(e.message.status))
    stop = threading.Event()

    def spin():
        last = 0.0
        while not stop.is_set():
            try:
                esc.spin(0.01)
            except Exception:  # a malformed frame must not end the thread
                pass
            if time.monotonic() - last >= 0.05:
                last = time.monotonic()
                for idx in range(4):
                    esc.broadcast(
                        U.equipment.esc.Status(
                            voltage=16.0,
                            current=1.5 + idx,
                            temperature=300.0,
                            rpm=1000 * (idx + 1),
                            power_rating_pct=idx,
                            esc_index=idx,
                        )
                    )

    t = threading.Thread(target=spin, daemon=True)
    t.start()
    try:
        time.sleep(0.5)  # the gateway sees the ESC node before the FC boots
        rc, steps, text = run_firmware(procs, tmp_path, eps[0], append="gw=require")
        # the disarm's ArmingStatus may still be on its way to this node (a
        # loaded host): keep listening until it came (the gateway repeats it)
        wait_for(lambda: arming and arming[-1] == 0, 10, what="DISARMED after the run")
    finally:
        stop.set()
        t.join(5)
        esc.close()
    assert rc == 0, text
    assert {p["type"] for p in steps["discover"]["peers"]} == {"test-a", "test-b", "can-gw"}
    assert steps["configure"]["baud"] == 115200
    gw = steps["gateway"]
    assert gw["result"] == 0 and gw["at"] == "done" and gw["esc_commands_ok"] == 40
    tel = {e["esc"]: e for e in gw["telemetry"]}
    assert set(tel) == {0, 1, 2, 3}
    for idx, e in tel.items():
        assert e["rpm"] == 1000 * (idx + 1) and e["mV"] == 16000 and e["node"] == 20
    # the ramp reached CAN: four channels, up to 2000 and back to 0
    fours = [c for c in raw if len(c) == 4]
    assert [2000] * 4 in fours and max(c[0] for c in fours) == 2000
    assert 255 in arming and arming[-1] == 0  # armed, then disarmed
