"""Helpers to start dan-vbus and DAN programs for the end-to-end tests."""

import json
import socket

from conftest import BIN


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
    line = p.stdout.readline().decode()
    assert line.startswith("READY"), f"dan-vbus did not start: {line!r}"
    return p, [str(prefix) + str(i) for i in range(n)], ctl


def vbus_cmd(ctl, cmd):
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
    return json.loads(vbus_cmd(ctl, "stats"))


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
    p = procs.start(
        [BIN / "dan-testperiph", "--port", port, "--types", types, "--mask", mask, *extra],
        name="dan-testperiph",
    )
    line = p.stdout.readline().decode()
    assert line.startswith("READY"), f"dan-testperiph did not start: {line!r}"
    return p


def periph_stats(procs, p):
    """Stops a dan-testperiph and returns its counters."""
    assert procs.stop(p) == 0
    return json.loads(p.stdout.read().decode().strip().splitlines()[-1])
