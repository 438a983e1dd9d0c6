"""The README's run command: `make demo` runs host_tools/demo.py, which
starts the whole stack on virtual wires, drives it with danprobe and stops
everything. Here with a short ramp."""

import subprocess

import procgroup  # host_tools, on sys.path by conftest


def test_demo_runs_to_completion(tmp_path):
    plot = tmp_path / "esc.png"
    r = subprocess.run(
        procgroup.host_tool("demo.py", "--ramp-seconds", "2", "--plot", str(plot)),
        stdin=subprocess.DEVNULL,
        capture_output=True,
        timeout=300,
    )
    out = r.stdout.decode(errors="replace")
    assert r.returncode == 0, out[-3000:] + r.stderr.decode(errors="replace")[-2000:]
    assert "demo: done" in out
    steps = (
        "Discover",
        "Configure the bus to 115200",
        "Safety off",
        "Arm",
        "Throttle ramp",
        "node table",
        "Disarm",
        "Safety on",
    )
    titles = [line for line in out.splitlines() if line.startswith("=== ")]
    at = [next((i for i, t in enumerate(titles) if step in t), -1) for step in steps]
    assert -1 not in at and at == sorted(at), (titles, at)  # all, in this order
    assert "safety: ok, safety OFF (255); flags can-up,safety-off" in out
    on = [line for line in out.splitlines() if line.startswith("safety: ok, safety ON (0)")]
    assert len(on) == 1 and "safety-off" not in on[0], on
    # what the ESCs heard: safety ON from power-up, OFF for the ramp, ON again
    assert "ESC 0 heard safety ON (0) -> OFF (255) -> ON (0)\n" in out
    assert "org.dan.esc_sim" in out  # the node table lists the ESCs
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # nothing left behind: every process of the demo was in its own group and stopped
    left = subprocess.run(["pgrep", "-f", "dan-demo-"], capture_output=True).stdout.decode()
    assert left.strip() == "", left
