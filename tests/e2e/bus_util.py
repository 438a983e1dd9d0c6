"""Helpers to start dan-vbus and DAN programs for the end-to-end tests."""

import json
import socket
import subprocess
import sys
from pathlib import Path

from conftest import BIN, PERIPH_WINDOW_MS


def ready(p, what):
    """The words after READY on p's first line (what: who, for the message)."""
    line = p.stdout.readline().decode()
    assert line.startswith("READY"), f"{what} did not start: {line!r}"
    return line.split()[1:]


def start_vbus(procs, tmp, n, *extra):
    """Starts dan-vbus with n endpoints; returns (proc, [endpoint links], control path)."""
    prefix = tmp / "dan"
    ctl = tmp / "vbus.ctl"
    p = procs.start(
        [
            BIN / "dan-vbus",
            "-n",
            str(n),
            "--link",
            prefix,
            "--control",
            ctl,
            "--capture",
            tmp / "bus.cap",
            *extra,
        ],
        name="dan-vbus",
    )
    ready(p, "dan-vbus")
    return p, [str(prefix) + str(i) for i in range(n)], ctl


def control(ctl, cmd):
    """One command line to a control socket (dan-vbus's or slcan_hub's: the
    same line protocol); its one-line answer."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.settimeout(10)
        s.connect(str(ctl))
        s.sendall((cmd + "\n").encode())
        buf = b""
        while not buf.endswith(b"\n"):
            chunk = s.recv(4096)
            if not chunk:
                break
            buf += chunk
    return buf.decode().strip()


def vbus_stats(ctl):
    return json.loads(control(ctl, "stats"))


def read_capture(tmp):
    """Bursts from the capture: list of (time, source, baud, bytes, flags)."""
    out = []
    path = tmp / "bus.cap"
    if not path.exists():
        return out
    for line in path.read_text().splitlines():
        if not line or line.startswith("#"):
            continue
        f = line.split()
        out.append((float(f[0]), int(f[1]), int(f[2]), bytes.fromhex(f[3]), f[4:]))
    return out


def start_periph(procs, port, types, mask="0x0F", *extra):
    if "--window-ms" not in extra:  # a loaded test host stalls replies (conftest)
        extra = ("--window-ms", PERIPH_WINDOW_MS, *extra)
    p = procs.start(
        [BIN / "dan-testperiph", "--port", port, "--types", types, "--mask", mask, *extra],
        name="dan-testperiph",
    )
    ready(p, "dan-testperiph")
    return p


def start_mixed_periphs(procs, eps):
    """Peripherals of three types on endpoints 1..3: test-a and test-b (every
    baud) and a can-gw without 57600 (mask 0x0B)."""
    return [
        start_periph(procs, eps[1], "test-a"),
        start_periph(procs, eps[2], "test-b"),
        start_periph(procs, eps[3], "can-gw", "0x0B"),
    ]


def periph_stats(procs, p):
    """Stops a dan-testperiph and returns its counters."""
    assert procs.stop(p) == 0
    return json.loads(p.stdout.read().decode().strip().splitlines()[-1])


def danprobe(*args, timeout=120):
    """Runs danprobe (this venv's); (exit code, stdout, stderr)."""
    return _run_python(["-m", "danprobe", *args], timeout)


def danprobe_with_fault(fault, *args, timeout=120):
    """danprobe(*args) with a fault injected (tests/e2e/danprobe_faults.py)."""
    return _run_python([Path(__file__).with_name("danprobe_faults.py"), fault, *args], timeout)


def _run_python(args, timeout):
    r = subprocess.run(
        [sys.executable, *map(str, args)],
        stdin=subprocess.DEVNULL,
        capture_output=True,
        timeout=timeout,
    )
    return r.returncode, r.stdout.decode(), r.stderr.decode()
