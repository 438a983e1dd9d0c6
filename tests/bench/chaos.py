#!/usr/bin/env python3
"""Chaos soak (`make soak CHAOS=1 SOAK=<seconds>`): the ESC stack of the
benchmarks (dan-vbus with the FC, the gateway and a jammer endpoint;
the SLCAN hub with dan-gatewayd, four esc_sim ESCs, a flood port and a DNA
port) under a seeded random schedule of faults, one every 1.5..4 s:

  noise     the wire's bit error rate at 1e-3 for 0.5 s (dan-vbus ber)
  jammer    random bytes at 115200 from a third endpoint for 0.3 s
  gateway   dan-gatewayd killed (SIGKILL) and started again (at 9600)
  fc        dan-fcsim killed (SIGKILL) and started again after 0..1.2 s;
            it finds the gateway at the configured baud
  unplug    the gateway's CAN adapter detached for 1 s (slcan_hub detach)
  flood     29-bit frames as fast as the port takes them, for 0.2 s (the
            Python ESCs get them all: a longer flood only measures them)
  dna       anonymous Allocation requests (first stages) for 2 s
  escnode   the ESC nodes (esc_sim) killed and started again

The FC (dan-fcsim --recover 3) runs, after discover, configure and arm, a
cycle of ESC loops (values unique to each FC run), `nodes`, `health`,
`stats` and `candump` (raw frames) steps; a run that ends by itself is
replaced. Checked along the way and reported at the end (exit 1 if one
fails): no wrong command ever reached an ESC (esc_sim's log: zeros or the
values of an FC run, only while that run was the latest); after each loss
of the master longer than the ESC timeout, zeros at every ESC within the
timeout plus a margin; every FC and gateway restart recovered (count, worst
time); the daemon's RSS and open file descriptors sampled per instance
(growth reported); the gateway's counters at the end. Left out: tunnel
traffic (the soak's FC runs no tunnel transfers) and servo values (no
servo simulator checks them).
"""

import argparse
import json
import os
import random
import signal
import sys
import tempfile
import time
import tty
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "e2e"))
from restarts import (  # noqa: E402
    ESC_TIMEOUT_MS,
    FAILSAFE_MARGIN_S,
    NESC,
    RECOVER_DEADLINE_S,
    EscLog,
    check_values,
)
from run_bench import PY, Stack, rss_kb, start_gwd  # noqa: E402

from bus_util import control  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
BAUD = 115200
FAULTS = ("noise", "jammer", "gateway", "fc", "unplug", "flood", "dna", "escnode")
CAN_FLOOD = ROOT / "tests" / "tools" / "can_flood.py"


def fd_count(pid):
    try:
        return len(os.listdir(f"/proc/{pid}/fd"))
    except OSError:
        return None


class Chaos:
    def __init__(self, build, tmp, seconds, rng):
        self.build, self.tmp, self.seconds, self.rng = build, Path(tmp), seconds, rng
        self.st = Stack(self.tmp)
        self.log = EscLog(self.tmp / "esc.log")
        self.runs = []  # [start, kill, values, superseded]
        self.fc = None
        self.fc_recover, self.gw_recover, self.failsafe = [], [], []
        self.fc_failed = self.gw_failed = 0
        self.counts = {f: 0 for f in FAULTS}
        self.gw_samples = []  # (instance, t, rss_kb, fds)
        self.gw_instance = 0
        self.fc_steps_failed = 0
        self.timeline = []  # (s since the start, fault, s it took incl. recovery)
        self.t_start = time.monotonic()
        self.faults = FAULTS

    # ---- the stack ----

    def start(self):
        st, tmp = self.st, self.tmp
        st.ready(
            st.start(
                [self.build / "bin" / "dan-vbus", "-n", "3", "--link", tmp / "dan"]
                + ["--control", tmp / "vbus.ctl", "--seed", str(self.rng.randrange(1 << 30))],
                "dan-vbus",
            )
        )
        st.ready(
            st.start(
                [PY, ROOT / "host_tools" / "slcan_hub.py", "-n", "7", "--link", tmp / "can"]
                + ["--control", tmp / "hub.ctl"],
                "slcan_hub",
            )
        )
        self.start_escs()
        self.gwd = start_gwd(st, self.build, tmp, self.gw_args(), name="gwd0")
        time.sleep(1.0)
        self.start_fc()

    def gw_args(self):
        return ("--esc-timeout-ms", str(ESC_TIMEOUT_MS))

    def start_escs(self):
        ports = sum([["--port", self.tmp / f"can{k}"] for k in range(1, 1 + NESC)], [])
        self.esc = self.st.start(
            [PY, ROOT / "host_tools" / "esc_sim.py", *ports, "--log", self.tmp / "esc.log"],
            f"esc_sim{self.counts['escnode']}",
        )
        self.st.ready(self.esc)

    def start_fc(self):
        k = len(self.runs)
        values = tuple(100 + 4 * k + i for i in range(NESC))
        vals = ",".join(map(str, values))
        # 100 Hz: the Python ESCs behind the hub must keep up on a loaded
        # host, or their log (the invariants' evidence) falls behind
        cycle = [f"esc:{vals}@3000@100", "nodes", "health", f"esc:{vals}@2000@100", "stats"]
        cycle += ["candump:50:200"]
        steps = ["discover", f"configure:{BAUD}", "arm"] + cycle * 200
        t0 = time.monotonic()
        self.fc = self.st.start(
            [self.build / "bin" / "dan-fcsim", "--port", self.tmp / "dan0", "--recover", "3"]
            + ["--latency-ms", "100", *steps],
            f"fc{k}",
            stdout=open(self.tmp / f"fc{k}.out", "wb"),
        )
        self.runs.append([t0, None, values, None])
        seen = self.wait(lambda: self.log.first_at_all(values, t0), RECOVER_DEADLINE_S)
        if seen is None:
            self.fc_failed += 1
        else:
            self.fc_recover.append(seen - t0)
            if len(self.runs) > 1 and self.runs[-2][3] is None:
                self.runs[-2][3] = seen

    def wait(self, fn, seconds):
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.log.poll()
            v = fn()
            if v is not None:
                return v
            time.sleep(0.02)
        return None

    # ---- faults ----

    def fault(self, name):
        self.counts[name] += 1
        t = time.monotonic()
        getattr(self, "f_" + name)()
        self.timeline.append((round(t - self.t_start, 2), name, round(time.monotonic() - t, 2)))

    def f_noise(self):
        control(self.tmp / "vbus.ctl", "ber 0.001")
        time.sleep(0.5)
        control(self.tmp / "vbus.ctl", "ber 0")

    def f_jammer(self):
        fd = os.open(self.tmp / "dan2", os.O_RDWR | os.O_NOCTTY)
        try:
            tty.setraw(fd)
            import termios

            a = termios.tcgetattr(fd)
            a[4] = a[5] = termios.B115200
            termios.tcsetattr(fd, termios.TCSANOW, a)
            end = time.monotonic() + 0.3
            while time.monotonic() < end:
                os.write(fd, self.rng.randbytes(16))
                time.sleep(0.002)
        finally:
            os.close(fd)

    def f_gateway(self):
        self.sample_gw()
        self.st.stop(self.gwd, signal.SIGKILL)
        time.sleep(self.rng.uniform(0, 0.5))
        self.gw_instance += 1
        g0 = time.monotonic()
        self.gwd = start_gwd(
            self.st, self.build, self.tmp, self.gw_args(), f"gwd{self.gw_instance}"
        )
        values = self.runs[-1][2]
        seen = self.wait(lambda: self.log.first_at_all(values, g0), RECOVER_DEADLINE_S)
        if seen is None:
            self.gw_failed += 1
        else:
            self.gw_recover.append(seen - g0)

    def f_fc(self):
        self.st.stop(self.fc, signal.SIGKILL)
        kill = time.monotonic()
        self.runs[-1][1] = kill
        pause = self.rng.uniform(0, 1.2)
        time.sleep(pause)
        if pause > ESC_TIMEOUT_MS / 1000 + FAILSAFE_MARGIN_S + 0.1:
            self.log.poll()
            z = self.log.zeros_at_all(kill, kill + pause)
            self.failsafe.append(None if z is None else z - kill)
        self.start_fc()

    def f_unplug(self):
        control(self.tmp / "hub.ctl", "detach 0")
        time.sleep(1.0)
        control(self.tmp / "hub.ctl", "attach 0")

    def f_flood(self):
        p = self.st.start([PY, CAN_FLOOD, self.tmp / f"can{1 + NESC}", "0.2"], "flood")
        p.wait(30)
        # the Python ESCs behind the hub get every flood frame too (real ESCs
        # filter in hardware): let them work through the backlog, so that
        # the times in their log are the commands' times again
        time.sleep(3.0)

    def f_dna(self):
        from danprobe.slcan_codec import Frame, format_frame
        from gw_rig import allocation_request, anonymous_can_id

        fd = os.open(self.tmp / f"can{2 + NESC}", os.O_RDWR | os.O_NOCTTY)
        try:
            tty.setraw(fd)
            os.write(fd, b"C\rS8\rO\r")
            end, tid = time.monotonic() + 2.0, 0
            while time.monotonic() < end:
                uid = self.rng.randbytes(6)
                data = allocation_request(uid, 0, True, tid)
                f = Frame(anonymous_can_id(1, self.rng.randrange(1 << 14)), True, False, 8, data)
                f = f._replace(dlc=len(data))
                os.write(fd, format_frame(f))
                tid += 1
                time.sleep(0.02)
                try:
                    os.set_blocking(fd, False)
                    os.read(fd, 4096)
                except BlockingIOError:
                    pass
        finally:
            os.close(fd)

    def f_escnode(self):
        self.st.stop(self.esc, signal.SIGKILL)
        time.sleep(0.2)
        self.start_escs()

    def sample_gw(self):
        pid = self.gwd.pid
        self.gw_samples.append((self.gw_instance, time.monotonic(), rss_kb(pid), fd_count(pid)))

    def fc_alive(self):
        if self.fc.poll() is not None:  # ended by itself (a step failed for good)
            self.fc_steps_failed += 1
            self.runs[-1][1] = time.monotonic()
            self.start_fc()

    # ---- the run ----

    def run(self):
        self.start()
        end = time.monotonic() + self.seconds
        next_sample = 0.0
        while time.monotonic() < end:
            time.sleep(self.rng.uniform(1.5, 4.0))
            self.fc_alive()
            if time.monotonic() >= next_sample:
                self.sample_gw()
                next_sample = time.monotonic() + 5.0
            self.fault(self.rng.choice(self.faults))
        time.sleep(1.0)
        self.sample_gw()
        self.log.poll()
        stats_path = self.tmp / "gw.stats"
        gw_stats = json.loads(stats_path.read_text()) if stats_path.exists() else {}
        return gw_stats

    def growth(self):
        """Per gateway instance: (rss, fds) at its first and last sample."""
        per = {}
        for inst, _, rss, fds in self.gw_samples:
            if rss is None:
                continue
            first, last = per.get(inst, ((rss, fds), (rss, fds)))
            per[inst] = (first, (rss, fds))
        rss_growth = max((b[0] - a[0] for a, b in per.values()), default=0)
        fd_growth = max((b[1] - a[1] for a, b in per.values()), default=0)
        longest = max(
            (
                (max(t for i, t, *_ in self.gw_samples if i == k))
                - min(t for i, t, *_ in self.gw_samples if i == k),
                k,
            )
            for k in per
        )
        return rss_growth, fd_growth, longest

    def close(self):
        self.st.close()


def summary(c, gw_stats, seconds):
    for i in range(len(c.runs) - 1):
        if c.runs[i][3] is None:
            c.runs[i][3] = c.log.first_at_all(c.runs[i + 1][2], c.runs[i + 1][0])
    bad = check_values(c.log, [tuple(r) for r in c.runs])
    late = [x for x in c.failsafe if x is None or x > ESC_TIMEOUT_MS / 1000 + FAILSAFE_MARGIN_S]
    rss_g, fd_g, (longest_s, _) = c.growth()
    return {
        "seconds": seconds,
        "faults": c.counts,
        "fc_runs": len(c.runs),
        "fc_recovered": len(c.fc_recover),
        "fc_not_recovered": c.fc_failed,
        "fc_recovery_worst_s": max(c.fc_recover, default=None),
        "fc_runs_ended_by_themselves": c.fc_steps_failed,
        "gateway_restarts": c.counts["gateway"],
        "gateway_recovered": len(c.gw_recover),
        "gateway_not_recovered": c.gw_failed,
        "gateway_recovery_worst_s": max(c.gw_recover, default=None),
        "failsafe_checks": len(c.failsafe),
        "failsafe_worst_s": max((x for x in c.failsafe if x is not None), default=None),
        "failsafe_late": len(late),
        "esc_commands": len(c.log.cmds),
        "wrong_commands": len(bad),
        "wrong_examples": bad[:5],
        "gateway_rss_growth_kb": rss_g,
        "gateway_fd_growth": fd_g,
        "gateway_longest_instance_s": round(longest_s, 1),
        "timeline": c.timeline,
        "gateway_counters_last_instance": gw_stats,
    }


def main():
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--build", default="build")
    ap.add_argument("--seconds", type=float, default=60)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", help="write the summary as JSON here")
    ap.add_argument("--keep", help="run in this directory and keep the logs")
    ap.add_argument("--faults", default=",".join(FAULTS), help="the faults to draw from")
    a = ap.parse_args()
    # SIGTERM (a timeout, make's Ctrl-C) unwinds: every process is stopped
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    if a.seconds <= 0:
        ap.error("--seconds must be positive")
    faults = a.faults.split(",")
    if not faults or not set(faults) <= set(FAULTS):
        ap.error(f"--faults takes a comma-separated list of {', '.join(FAULTS)}")
    build = (ROOT / a.build).resolve()
    with tempfile.TemporaryDirectory(prefix="danchaos-") as tmp:
        if a.keep:
            tmp = Path(a.keep)
            tmp.mkdir(parents=True, exist_ok=True)
        c = Chaos(build, tmp, a.seconds, random.Random(a.seed))
        c.faults = tuple(faults)
        try:
            gw_stats = c.run()
        finally:
            c.close()
        s = summary(c, gw_stats, a.seconds)
    print(json.dumps(s, indent=1))
    if a.out:
        Path(a.out).write_text(json.dumps(s, indent=1))
    ok = (
        s["wrong_commands"] == 0
        and s["failsafe_late"] == 0
        and s["fc_not_recovered"] == 0
        and s["gateway_not_recovered"] == 0
        and s["gateway_fd_growth"] <= 0
    )
    print(
        f"chaos {a.seconds:.0f} s: {sum(s['faults'].values())} faults {s['faults']}; "
        f"{s['esc_commands']} ESC commands, {s['wrong_commands']} wrong; FC restarts "
        f"{s['fc_recovered']}/{s['fc_runs']} recovered (worst {s['fc_recovery_worst_s'] or 0:.2f} s); "
        f"gateway restarts {s['gateway_recovered']}/{s['gateway_restarts']} "
        f"(worst {s['gateway_recovery_worst_s'] or 0:.2f} s); failsafe {s['failsafe_checks']}x, "
        f"worst {s['failsafe_worst_s'] or 0:.3f} s, late {s['failsafe_late']}; gateway RSS growth "
        f"{s['gateway_rss_growth_kb']} kB, fd growth {s['gateway_fd_growth']} "
        f"(longest instance {s['gateway_longest_instance_s']} s): {'OK' if ok else 'FAILED'}"
    )
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
