#!/usr/bin/env python3
"""A hundred restarts (`make restarts [RESTARTS=100]
[RESTART_BAUDS=115200,1000000,2000000]`): the ESC stack of the benchmarks on
dan-vbus (dan-gatewayd, four esc_sim ESCs behind the SLCAN hub) with the FC
or the gateway killed (SIGKILL) at random moments, seeded.

  fc       dan-fcsim (the libdan master) runs discover, configure:BAUD, arm
           and an ESC loop with values of its own (unique per run). Each of
           the RESTARTS runs is timed from its start to its values at every
           ESC, then killed a random 0..1 s later (the bus running at
           BAUD); the next run starts after a random pause of 0..1.2 s. The
           gateway stays at BAUD through it all, as peripherals do after an
           FC's soft reboot. Besides these, before 30 % of them (--early) an
           extra run is killed at a random moment of its first 0.4 s (often
           mid-discovery or mid-configure), counted apart.
  gateway  one dan-fcsim --recover 3 runs the ESC loop; dan-gatewayd is
           killed a random 0.3..1.5 s after commands flow again and started
           after a random pause of 0..0.5 s (back at 9600, DISARMED).

Recovered: the run's (fc) or the loop's (gateway) values reach every ESC
again within 30 s; the recovery time runs from the process's start to the
first command at the last ESC (esc_sim's receive times, taken from the
whole log at the end: a starved host writes the log late). Checked all along, from esc_sim's log: every command an
ESC receives from the gateway is zeros (the failsafe) or values an FC sent,
and a run's values never arrive before it started or after a later run
reached the ESCs; after every loss of the master longer than the gateway's
ESC timeout, zeros at every ESC within the timeout plus a margin for the
SLCAN hub and the Python ESCs. Prints one summary per scenario; exit 1 if
an invariant failed or a restart did not recover.
"""

import argparse
import json
import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from run_bench import Stack, gw_rig, start_gwd  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
GW_NODE = 10
ESC_TIMEOUT_MS = 300
FAILSAFE_MARGIN_S = 0.25  # hub hop + Python ESC + log, on a loaded host
RECOVER_DEADLINE_S = 30.0
NESC = 4


class EscLog:
    """esc_sim's JSON lines, read as they grow."""

    def __init__(self, path):
        self.path, self.pos, self.cmds = Path(path), 0, []

    def poll(self):
        if not self.path.exists():
            return
        with open(self.path) as f:
            f.seek(self.pos)
            data = f.read()
        end = data.rfind("\n") + 1
        self.pos += len(data[:end].encode())
        for line in data[:end].splitlines():
            e = json.loads(line)
            if e["event"] == "cmd" and e["src"] == GW_NODE:
                self.cmds.append((e["t"], e["esc"], tuple(e["cmd"])))

    def first_at_all(self, values, since):
        """Time the last ESC first saw values after since, or None."""
        first = {}
        for t, esc, cmd in self.cmds:
            if t >= since and cmd == values and esc not in first:
                first[esc] = t
        return max(first.values()) if len(first) == NESC else None

    def zeros_at_all(self, since, until):
        first = {}
        for t, esc, cmd in self.cmds:
            if since <= t <= until and not any(cmd) and esc not in first:
                first[esc] = t
        return max(first.values()) if len(first) == NESC else None


def recoveries(log, starts):
    """starts: [(start, values)]: the times until values reached every ESC
    (within RECOVER_DEADLINE_S), and how many did not."""
    seen = [log.first_at_all(v, t) for t, v in starts]
    done = [
        x - t for x, (t, _) in zip(seen, starts) if x is not None and x - t <= RECOVER_DEADLINE_S
    ]
    return done, len(starts) - len(done)


def wait_until(fn, deadline, log):
    while time.monotonic() < deadline:
        log.poll()
        v = fn()
        if v is not None:
            return v
        time.sleep(0.02)
    return None


def start_fcsim(st, build, tmp, baud, values, name, recover=False):
    vals = ",".join(map(str, values))
    # 100 Hz: the Python ESCs behind the hub keep up (back to back at 1M
    # they fall seconds behind, and their log is the evidence)
    steps = ["discover", f"configure:{baud}", "arm", f"esc:{vals}@600000@100"]
    opts = ["--recover", "3"] if recover else []
    if baud > 115200:  # discovery scans the fast bauds only when the port may use them
        opts += ["--max-baud", str(baud)]
    return st.start(
        [build / "bin" / "dan-fcsim", "--port", tmp / "dan0", *opts, *steps],
        name,
        stdout=subprocess.DEVNULL,
    )


def check_values(log, runs):
    """runs: [(start, end, values)]; the wrong commands (list of text)."""
    bad = []
    known = {r[2]: r for r in runs}
    for t, esc, cmd in log.cmds:
        if not any(cmd):
            continue
        r = known.get(cmd)
        if r is None:
            bad.append(f"t={t:.3f} esc {esc}: {cmd} was never sent")
        elif t < r[0]:
            bad.append(f"t={t:.3f} esc {esc}: {cmd} before its run started")
        elif r[3] is not None and t > r[3]:
            bad.append(f"t={t:.3f} esc {esc}: {cmd} after a later run took over")
    return bad


def recovery_summary(rec, failed) -> dict:
    """The report's recovery keys, from recoveries()' result."""
    return {
        "recovered": len(rec),
        "not_recovered": failed,
        "recovery_worst_s": max(rec) if rec else None,
        "recovery_median_s": sorted(rec)[len(rec) // 2] if rec else None,
    }


def commands_summary(log, bad) -> dict:
    """The report's command keys: how many the ESC saw, and check_values()' misses."""
    return {
        "commands": len(log.cmds),
        "wrong_commands": len(bad),
        "wrong_examples": bad[:5],
    }


def fc_restarts(build, count, baud, rng, early_share=0.3):
    with tempfile.TemporaryDirectory(prefix="danrestart-") as tmp:
        tmp = Path(tmp)
        st = Stack(tmp)
        log = EscLog(tmp / "esc.log")
        runs, timed_runs, losses, early = [], [], [], 0

        def one_run(name, timed):
            """Starts a run, waits (timed) or not, kills it; then a pause."""
            k = len(runs)
            values = tuple(100 + 4 * k + i for i in range(NESC))
            t0 = time.monotonic()
            p = start_fcsim(st, build, tmp, baud, values, name)
            run = [t0, None, values, None]  # start, kill, values, superseded at
            runs.append(run)
            if not timed:
                time.sleep(rng.uniform(0, 0.4))
            else:
                timed_runs.append((t0, values))
                seen = wait_until(
                    lambda v=values, t=t0: log.first_at_all(v, t), t0 + RECOVER_DEADLINE_S, log
                )
                if seen is not None:
                    if len(runs) > 1:
                        runs[-2][3] = seen  # the older run's values end here
                    time.sleep(rng.uniform(0, 1.0))
            st.stop(p, signal.SIGKILL)
            kill = time.monotonic()
            run[1] = kill
            pause = rng.uniform(0, 1.2)
            time.sleep(pause)
            if pause > ESC_TIMEOUT_MS / 1000 + FAILSAFE_MARGIN_S + 0.1:
                losses.append((kill, kill + pause))

        try:
            gw_rig(st, build, tmp, gw_args=("--esc-timeout-ms", str(ESC_TIMEOUT_MS)))
            time.sleep(1.0)  # the ESCs join the node table
            for k in range(count):
                if rng.random() < early_share:
                    early += 1
                    one_run(f"early{early}", timed=False)
                one_run(f"fc{k}", timed=True)
            time.sleep(0.5)
            log.poll()
        finally:
            st.close()
    # the ESCs' log lines carry receive times, but a loaded host writes them
    # late: recoveries and zeros are looked for once every line is in
    rec, failed = recoveries(log, timed_runs)
    failsafe = [log.zeros_at_all(k, u) for k, u in losses]
    failsafe = [None if z is None else z - k for z, (k, _) in zip(failsafe, losses)]
    # a run killed early may never have been seen: its successor ends it
    for i in range(len(runs) - 1):
        if runs[i][3] is None:
            nxt = log.first_at_all(runs[i + 1][2], runs[i + 1][0])
            runs[i][3] = nxt
    bad = check_values(log, [(r[0], r[1], r[2], r[3]) for r in runs])
    bad_failsafe = [
        x for x in failsafe if x is None or x > ESC_TIMEOUT_MS / 1000 + FAILSAFE_MARGIN_S
    ]
    return {
        "scenario": "fc",
        "baud": baud,
        "restarts": count,
        "early_kills_besides": early,
        **recovery_summary(rec, failed),
        "failsafe_checks": len(failsafe),
        "failsafe_worst_s": max((x for x in failsafe if x is not None), default=None),
        "failsafe_late": len(bad_failsafe),
        **commands_summary(log, bad),
    }


def gateway_restarts(build, count, baud, rng):
    with tempfile.TemporaryDirectory(prefix="danrestart-") as tmp:
        tmp = Path(tmp)
        st = Stack(tmp)
        log = EscLog(tmp / "esc.log")
        gw_args = ("--esc-timeout-ms", str(ESC_TIMEOUT_MS))
        values = (11, -22, 333, -444)
        starts = []
        try:
            _, _, _, gwd = gw_rig(st, build, tmp, gw_args=gw_args)
            time.sleep(1.0)
            t0 = time.monotonic()
            fc = start_fcsim(st, build, tmp, baud, values, "fc", recover=True)
            first = wait_until(
                lambda v=values, t=t0: log.first_at_all(v, t), t0 + RECOVER_DEADLINE_S, log
            )
            if first is None:
                raise RuntimeError("the ESC loop never started: see " + str(tmp))
            for k in range(count):
                time.sleep(rng.uniform(0.3, 1.5))
                st.stop(gwd, signal.SIGKILL)
                time.sleep(rng.uniform(0, 0.5))
                g0 = time.monotonic()
                gwd = start_gwd(st, build, tmp, gw_args, name=f"dan-gatewayd{k}")
                starts.append((g0, values))
                wait_until(lambda t=g0: log.first_at_all(values, t), g0 + RECOVER_DEADLINE_S, log)
            st.stop(fc, signal.SIGKILL)
            log.poll()
        finally:
            st.close()
    rec, failed = recoveries(log, starts)  # on the whole log (see fc_restarts)
    bad = check_values(log, [(0.0, None, values, None)])
    return {
        "scenario": "gateway",
        "baud": baud,
        "restarts": count,
        **recovery_summary(rec, failed),
        **commands_summary(log, bad),
    }


def main():
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--build", default="build")
    ap.add_argument("--count", type=int, default=100, help="restarts per scenario and baud")
    ap.add_argument("--bauds", default="115200,1000000,2000000")
    ap.add_argument(
        "--early",
        type=float,
        default=0.3,
        help="fc: the share of restarts an extra run killed in its first 0.4 s precedes",
    )
    ap.add_argument("--scenarios", default="fc,gateway")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", help="write the results as JSON here")
    a = ap.parse_args()
    # SIGTERM (a timeout, make's Ctrl-C) unwinds: every process is stopped
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    if a.count < 1:
        ap.error("--count must be at least 1")
    try:
        bauds = [int(b) for b in a.bauds.split(",")]
    except ValueError:
        ap.error(f"--bauds must be a comma-separated list of numbers, not {a.bauds!r}")
    scen = a.scenarios.split(",")
    if not set(scen) <= {"fc", "gateway"}:
        ap.error("--scenarios takes fc and/or gateway")
    build = (ROOT / a.build).resolve()
    rng = random.Random(a.seed)
    results, ok = [], True
    for baud in bauds:
        for s in scen:
            print(f"restarts: {s} x{a.count} at {baud} ...", flush=True)
            if s == "fc":
                r = fc_restarts(build, a.count, baud, rng, a.early)
            else:
                r = gateway_restarts(build, a.count, baud, rng)
            results.append(r)
            print(json.dumps(r), flush=True)
            good = r["not_recovered"] == 0 and r["wrong_commands"] == 0
            good = good and r.get("failsafe_late", 0) == 0
            ok = ok and good
            print(
                f"  {r['recovered']} of {r['restarts']} restarts recovered, worst "
                f"{r['recovery_worst_s'] or 0:.2f} s "
                f"(median {r['recovery_median_s'] or 0:.2f} s); {r['commands']} commands at the "
                f"ESCs, {r['wrong_commands']} wrong"
                + (
                    f"; failsafe checked {r['failsafe_checks']}x, worst "
                    f"{r['failsafe_worst_s'] or 0:.3f} s, late {r['failsafe_late']}; "
                    f"{r['early_kills_besides']} early kills besides"
                    if s == "fc"
                    else ""
                ),
                flush=True,
            )
    if a.out:
        Path(a.out).write_text(json.dumps(results, indent=1))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
