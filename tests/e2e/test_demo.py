"""The README's run command: `make demo` runs host_tools/demo.py, which
starts the whole stack on virtual wires, drives it with danprobe and stops
everything. Here with a short ramp."""

import subprocess
import sys

from conftest import ROOT


def test_demo_runs_to_completion(tmp_path):
    plot = tmp_path / "esc.png"
    r = subprocess.run(
        [
            sys.executable,
            str(ROOT / "host_tools" / "demo.py"),
            "--ramp-seconds",
            "2",
            "--plot",
            str(plot),
        ],
        stdin=subprocess.DEVNULL,
        capture_output=True,
        timeout=300,
    )
    out = r.stdout.decode(errors="replace")
    assert r.returncode == 0, out[-3000:] + r.stderr.decode(errors="replace")[-2000:]
    assert "demo: done" in out
    for step in (
        "Discover",
        "Configure the bus to 115200",
        "Arm",
        "Throttle ramp",
        "node table",
        "Disarm",
    ):
        assert step in out, step
    assert "org.dan.esc_sim" in out  # the node table lists the ESCs
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # nothing left behind: every process of the demo was in its own group and stopped
    left = subprocess.run(["pgrep", "-f", "dan-demo-"], capture_output=True).stdout.decode()
    assert left.strip() == "", left
