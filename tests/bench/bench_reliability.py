"""make bench's reliability rows (tests/bench/run_bench.py):

chaos    the chaos soak (tests/bench/chaos.py) for 60 s: faults survived,
         wrong values at the ESCs and the servo (0), the worst FC and
         gateway recovery, the daemon's RSS growth; every invariant held
hostile  tests/e2e/test_hostile_can.py (a node forging, replaying,
         flooding, claiming the gateway's ID, sending malformed and
         oversized transfers), which writes its figures to
         $DAN_HOSTILE_OUT: the ESC exchange rate under attack against the
         clean rate (goal >= 0.9)
"""

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
CHAOS_SECONDS = 60
HOSTILE_GOAL = 0.9


def bench_chaos(build, seconds=CHAOS_SECONDS, seed=1):
    with tempfile.TemporaryDirectory(prefix="danbench-") as tmp:
        out = Path(tmp) / "chaos.json"
        p = subprocess.run(
            [sys.executable, ROOT / "tests" / "bench" / "chaos.py", "--build", build]
            + ["--seconds", str(seconds), "--seed", str(seed), "--out", out],
            capture_output=True,
            text=True,
            timeout=seconds * 10 + 300,
        )
        if not out.exists():
            raise RuntimeError(f"chaos.py failed ({p.returncode}): {p.stderr[-1000:]}")
        s = json.loads(out.read_text())
    return {
        "seconds": seconds,
        "seed": seed,
        "faults": sum(s["faults"].values()),
        "faults_by_kind": s["faults"],
        "wrong": s["wrong_commands"] + s["wrong_servo"] + s["tunnel_wrong"],
        "esc_commands": s["esc_commands"],
        "servo_commands": s["servo_commands"],
        "fc_recovery_worst_s": s["fc_recovery_worst_s"],
        "gateway_recovery_worst_s": s["gateway_recovery_worst_s"],
        "rss_growth_kb": s["gateway_rss_growth_kb"],
        "fd_growth": s["gateway_fd_growth"],
        "failed": s["failed"],
        "ok": not s["failed"],
    }


def bench_hostile(python):
    with tempfile.TemporaryDirectory(prefix="danbench-") as tmp:
        out = Path(tmp) / "hostile.json"
        env = dict(os.environ, DAN_HOSTILE_OUT=str(out))
        p = subprocess.run(
            [python, "-m", "pytest", "-q", "-p", "no:cacheprovider"]
            + [str(ROOT / "tests" / "e2e" / "test_hostile_can.py")],
            cwd=ROOT,
            env=env,
            capture_output=True,
            text=True,
            timeout=900,
        )
        if not out.exists():
            raise RuntimeError(
                f"test_hostile_can.py wrote nothing ({p.returncode}): {p.stdout[-1500:]}"
            )
        f = json.loads(out.read_text())
    f["test_passed"] = p.returncode == 0
    f["goal"] = HOSTILE_GOAL
    f["met"] = f["ratio"] >= HOSTILE_GOAL and f["test_passed"]
    return f


def rows(r):
    out = []
    c = r.get("chaos")
    if c:
        fc, gw = c["fc_recovery_worst_s"] or 0.0, c["gateway_recovery_worst_s"] or 0.0
        out.append(
            (
                f"chaos soak {c['seconds']} s (seed {c['seed']})",
                f"{c['faults']} faults survived, {c['wrong']} wrong values",
                f"worst recovery FC {fc:.2f} s, gateway {gw:.2f} s; RSS growth "
                f"{c['rss_growth_kb']} kB, fds {c['fd_growth']}",
                "OK" if c["ok"] else "FAILED: " + ", ".join(c["failed"]),
            )
        )
    h = r.get("hostile")
    if h:
        out.append(
            (
                "ESC loop under hostile CAN",
                f"{h['attacked_rate']:.1f}/s ({h['hostile_frames']} hostile frames)",
                f"clean {h['clean_rate']:.1f}/s, goal >= {h['goal']}"
                + ("" if h["test_passed"] else " (the test FAILED)"),
                f"{h['ratio']:.2f}",
            )
        )
    return out
