#!/usr/bin/env python3
"""Chaos soak (`make soak CHAOS=1 SOAK=<seconds>`): the ESC stack of the
benchmarks (dan-vbus with the FC, the gateway and a jammer endpoint;
the SLCAN hub with dan-gatewayd, four esc_sim ESCs, a flood port, a DNA
port, a servo node and a tunnel's far end (tests/bench/chaos_nodes.py))
under a seeded random schedule of faults, one every 1.5..4 s:

  noise     the wire's bit error rate at 1e-3 for 0.5 s (dan-vbus ber)
  jammer    random bytes at the bus's baud from a third endpoint for 0.3 s
  gateway   dan-gatewayd killed (SIGKILL) and started again (at 9600)
  fc        dan-fcsim killed (SIGKILL) and started again after 0..1.2 s;
            it finds the gateway at the configured baud
  unplug    the gateway's CAN adapter detached for 1 s (slcan_hub detach)
  flood     29-bit frames as fast as the port takes them, for 0.2 s (the
            Python ESCs get them all: a longer flood only measures them)
  dna       anonymous Allocation requests (first stages) for 2 s
  escnode   the ESC nodes (esc_sim) killed and started again

Each FC run (dan-fcsim --recover 3 --restore --max-baud 2000000) configures
a baud drawn from 115200, 1000000 and 2000000, arms, sets safety off and a
servo failsafe table (actuator 1 to PWM 1000, actuator 2 holds), opens a
Targetted tunnel to the far end, then runs a cycle of ESC loops (values
unique to each run) that carry, between their exchanges, SERVO commands
(PWM values unique to the run) and a tunnel stream of numbered, summed
records at 400 B/s (--mix-servo, --mix-tunnel), and `nodes`, `health`,
`stats` and `candump` (raw frames) steps; a run that ends by itself is
replaced. Checked, reported at the end (exit 1 if one fails):

- no wrong value ever reached an ESC or the servo: zeros or the values of
  an FC run, only while that run was the latest; the servo's failsafe
  value, or the held one
- after each loss of the master longer than the ESC timeout: zeros,
  DISARMED and safety ON at every ESC and the servo node, and the servo
  failsafe, within the timeout plus a margin; nothing armed again before
  the next FC run
- every FC and gateway restart recovered (count, worst time); a restarted
  gateway is heard DISARMED before the FC recovers
- tunnel bytes exact both ways (a record repeated, reordered or never sent
  is wrong), or each loss explained by a fault that loses buffers (gateway,
  fc, unplug) or owned up to by a counter that rose around it (sampled
  every 0.5 s: the hub's drops toward the gateway's or the far end's port,
  a reader that lags like an adapter's overflow; the gateway's tun_dropped,
  can_tx_dropped)
- no growth of the daemon's RSS over 1 MiB, and none of its open file
  descriptors, over any instance's life
- counters consistent between the two ends: between two `stats` steps of
  one FC run (no gateway restart between), the gateway's esc_cmds and
  servo_cmds against the FC's exchanges and SERVOs (at least what
  succeeded, at most that plus the failures and the retries)
"""

import argparse
import json
import os
import random
import signal
import sys
import tempfile
import threading
import time
import tty
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "e2e"))
import chaos_checks as cc  # noqa: E402
from restarts import (  # noqa: E402
    ESC_TIMEOUT_MS,
    FAILSAFE_MARGIN_S,
    NESC,
    RECOVER_DEADLINE_S,
    EscLog,
    check_values,
    recoveries,
)
from run_bench import PY, Stack, rss_kb, start_gwd  # noqa: E402

from bus_util import control  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
BAUDS = (115200, 1000000, 2000000)  # each FC run configures one of these
RSS_GROWTH_MAX_KB = 1024
BOUND_S = ESC_TIMEOUT_MS / 1000 + FAILSAFE_MARGIN_S  # the failsafe's, at the devices
SERVO_NODE, TUNNEL_NODE, TUNNEL_SERIAL = 40, 41, 0
# B/s the FC writes to the tunnel: every hub port (the Python ESCs too) gets its frames
TUNNEL_RATE = 400
FAULTS = ("noise", "jammer", "gateway", "fc", "unplug", "flood", "dna", "escnode")
CAN_FLOOD = ROOT / "tests" / "tools" / "can_flood.py"


class DropSampler(threading.Thread):
    """Every 0.5 s, with the time: the counters that own up to dropped
    tunnel bytes. The hub's drops toward the gateway's port and the far
    end's (a reader that lags, like an adapter's overflow), the gateway's
    tun_dropped and can_tx_dropped (per instance: a new one starts at 0)."""

    KEYS_OUT = ("hub_far_end", "gw_tun_dropped", "gw_can_tx_dropped")  # FC -> far end
    KEYS_BACK = ("hub_gateway", "gw_tun_dropped")  # far end -> FC

    def __init__(self, chaos):
        super().__init__(daemon=True)
        self.chaos, self.samples, self.halt = chaos, [], threading.Event()

    def sample(self):
        c = self.chaos
        x = {"t": time.monotonic(), "inst": c.gw_instance}
        try:
            ports = json.loads(control(c.tmp / "hub.ctl", "stats"))["ports"]
            x["hub_gateway"], x["hub_far_end"] = ports[0]["dropped"], ports[4 + NESC]["dropped"]
            gw = json.loads((c.tmp / "gw.stats").read_text())
            x["gw_tun_dropped"], x["gw_can_tx_dropped"] = gw["tun_dropped"], gw["can_tx_dropped"]
        except (OSError, ValueError, KeyError, IndexError):
            pass  # a gateway starting, a file being replaced: the next one
        return x

    def run(self):
        while not self.halt.wait(0.5):
            self.samples.append(self.sample())

    def counted(self, t0, t1, keys):
        """The first of keys that rose between two samples around [t0, t1]."""
        s = self.samples
        for a, b in zip(s, s[1:]):
            if b["t"] < t0 or a["t"] > t1:
                continue
            for k in keys:
                same = not k.startswith("gw_") or a["inst"] == b["inst"]
                if same and k in a and k in b and b[k] > a[k]:
                    return k
        return None


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
        self.failsafe = []
        self.counts = {f: 0 for f in FAULTS}
        self.gw_samples = []  # (instance, t, rss_kb, fds)
        self.gw_instance = 0
        self.fc_steps_failed = 0
        self.timeline = []  # (s since the start, fault, s it took incl. recovery)
        self.events = []  # (monotonic start, fault, s)
        self.losses = []  # (kill, end of the pause) of each loss of the master checked
        self.gw_starts = []  # (start, the values the FC was sending)
        self.gw_counters = []  # the stats file of each instance, read before its kill
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
                [
                    PY,
                    ROOT / "host_tools" / "slcan_hub.py",
                    "-n",
                    str(NESC + 5),
                    "--link",
                    tmp / "can",
                ]
                + ["--control", tmp / "hub.ctl"],
                "slcan_hub",
            )
        )
        self.start_escs()
        self.nodes = st.start(
            [PY, ROOT / "tests" / "bench" / "chaos_nodes.py", "--log", tmp / "nodes.log"]
            + ["--servo-port", tmp / f"can{3 + NESC}", "--tunnel-port", tmp / f"can{4 + NESC}"]
            + ["--servo-id", str(SERVO_NODE), "--tunnel-id", str(TUNNEL_NODE)],
            "chaos_nodes",
        )
        st.ready(self.nodes)
        self.gwd = start_gwd(st, self.build, tmp, self.gw_args(), name="gwd0")
        time.sleep(1.0)
        self.start_fc()

    def gw_args(self):
        return ("--esc-timeout-ms", str(ESC_TIMEOUT_MS))

    def start_escs(self, attempts=3):
        ports = sum([["--port", self.tmp / f"can{k}"] for k in range(1, 1 + NESC)], [])
        for a in range(attempts):
            self.esc = self.st.start(
                [PY, ROOT / "host_tools" / "esc_sim.py", *ports, "--log", self.tmp / "esc.log"],
                f"esc_sim{self.counts['escnode']}.{a}",
            )
            try:
                self.st.ready(self.esc)
                return
            except RuntimeError:
                # pydronecan's I/O process can miss its start-up deadline on
                # a starved host: the harness tries again, the soak goes on
                self.st.stop(self.esc, signal.SIGKILL)
                if a == attempts - 1:
                    raise

    def start_fc(self):
        k = len(self.runs)
        values = tuple(100 + 4 * k + i for i in range(NESC))
        vals = ",".join(map(str, values))
        baud = self.rng.choice(BAUDS)
        s1, s2 = cc.servo_values(k)
        # 100 Hz: the Python ESCs behind the hub must keep up on a loaded
        # host, or their log (the invariants' evidence) falls behind
        cycle = [f"esc:{vals}@3000@100", "nodes", "health", f"esc:{vals}@2000@100", "stats"]
        cycle += ["candump:50:200"]
        steps = ["discover", f"configure:{baud}", "arm", "safety:off"]
        steps += [f"servo-fs:1={cc.SERVO_FS_PWM:.0f}:{cc.PWM}"]
        steps += [f"tunnel:0:targetted:{TUNNEL_NODE}:{TUNNEL_SERIAL}"] + cycle * 200
        opts = ["--recover", "3", "--restore", "--max-baud", str(max(BAUDS))]
        opts += ["--mix-servo", f"1={s1:.0f}:{cc.PWM},2={s2:.0f}:{cc.PWM}"]
        opts += ["--mix-tunnel", f"0:r{k}:{self.tmp / f'fc{k}.tun'}:{TUNNEL_RATE}"]
        t0 = time.monotonic()
        self.fc = self.st.start(
            [self.build / "bin" / "dan-fcsim", "--port", self.tmp / "dan0", *opts]
            + ["--latency-ms", "100", *steps],
            f"fc{k}",
            stdout=open(self.tmp / f"fc{k}.out", "wb"),
        )
        self.runs.append([t0, None, values, None, baud])
        # paces the schedule; the recovery is timed at the end, on the whole log
        seen = self.wait(lambda: self.log.first_at_all(values, t0), RECOVER_DEADLINE_S)
        if seen is not None and len(self.runs) > 1 and self.runs[-2][3] is None:
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
        self.events.append((t, name, time.monotonic() - t))

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
            a[4] = a[5] = getattr(termios, f"B{self.runs[-1][4]}")  # the bus's baud
            termios.tcsetattr(fd, termios.TCSANOW, a)
            end = time.monotonic() + 0.3
            while time.monotonic() < end:
                os.write(fd, self.rng.randbytes(16))
                time.sleep(0.002)
        finally:
            os.close(fd)

    def f_gateway(self):
        self.sample_gw()
        self.read_counters()
        self.st.stop(self.gwd, signal.SIGKILL)
        time.sleep(self.rng.uniform(0, 0.5))
        self.gw_instance += 1
        g0 = time.monotonic()
        self.gwd = start_gwd(
            self.st, self.build, self.tmp, self.gw_args(), f"gwd{self.gw_instance}"
        )
        values = self.runs[-1][2]
        self.gw_starts.append((g0, values))
        # paces the schedule; the recovery is timed at the end, on the whole log
        self.wait(lambda: self.log.first_at_all(values, g0), RECOVER_DEADLINE_S)

    def f_fc(self):
        self.st.stop(self.fc, signal.SIGKILL)
        kill = time.monotonic()
        self.runs[-1][1] = kill
        pause = self.rng.uniform(0, 1.2)
        time.sleep(pause)
        if pause > BOUND_S + 0.1:  # checked at the end, on the whole logs
            self.losses.append((kill, kill + pause))
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

    def read_counters(self):
        p = self.tmp / "gw.stats"
        try:
            self.gw_counters.append(json.loads(p.read_text()))
        except (OSError, ValueError):
            pass

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
        self.drops = DropSampler(self)
        self.drops.start()
        end = time.monotonic() + self.seconds
        next_sample = 0.0
        while time.monotonic() < end:
            time.sleep(self.rng.uniform(1.5, 4.0))
            self.fc_alive()
            if time.monotonic() >= next_sample:
                self.sample_gw()
                next_sample = time.monotonic() + 5.0
            self.fault(self.rng.choice(self.faults))
        time.sleep(1.5)  # the stats file is rewritten once a second
        self.drops.halt.set()
        self.drops.join()
        self.sample_gw()
        self.read_counters()
        self.log.poll()
        return self.gw_counters[-1] if self.gw_counters else {}

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


def worst(xs):
    return max((x for x in xs if x is not None), default=None)


def outputs_summary(c, nodes):
    """Servo values, the failsafe states after each loss of the master, and
    what a restarted gateway says first."""
    bad_servo, _ = cc.check_servos(nodes, c.runs)
    esc_arming = cc.esc_states(c.tmp / "esc.log", "arming", NESC)
    esc_safety = cc.esc_states(c.tmp / "esc.log", "safety", NESC)
    loss = [cc.master_loss(k, u, esc_arming, esc_safety, nodes) for k, u in c.losses]
    fields = ("disarmed", "safety_on", "servo_failsafe")
    late = {f: sum(1 for x in loss if x[f] is None or x[f] > BOUND_S) for f in fields}
    undone = sum(1 for x in loss if x["disarmed_undone"] or x["safety_on_undone"])
    # a restarted gateway starts DISARMED with safety ON: heard before the FC is back
    gw_start_bad = 0
    for g0, values in c.gw_starts:
        seen = c.log.first_at_all(values, g0)
        if seen is not None and (
            cc.first_state(nodes.arming, 0, g0, seen) is None
            or cc.first_state(nodes.safety, 0, g0, seen) is None
        ):
            gw_start_bad += 1
    return {
        "servo_commands": len(nodes.servo),
        "wrong_servo": len(bad_servo),
        "wrong_servo_examples": bad_servo[:5],
        "master_losses_checked": len(loss),
        **{f"{f}_worst_s": worst(x[f] for x in loss) for f in fields},
        **{f"{f}_late": late[f] for f in fields},
        "armed_again_without_fc": undone,
        "gateway_starts_checked": len(c.gw_starts),
        "gateway_start_not_disarmed": gw_start_bad,
    }


def loss_detail(c, x, way, around_s=5.0):
    """An unexplained tunnel loss for the report: its direction, when
    (seconds into the soak: the last good record, the loss), what, and
    the faults that started within around_s of it (the next thing to look
    at)."""
    t0, t1, _, what, _ = x
    base = c.runs[0][0] if c.runs else 0.0
    near = [
        f"{name} at {t - base:.1f}"
        for t, name, _ in c.events
        if t0 - around_s <= t <= t1 + around_s
    ]
    return f"{way}: {what}, {t0 - base:.2f}..{t1 - base:.2f} s; faults near: {near}"


def tunnel_summary(c, nodes):
    """Both directions of the tunnel."""
    good, broken = cc.parse_stream(nodes.rx)
    tags = {f"r{k}" for k in range(len(c.runs))}
    wrong_out, loss_out = cc.stream_losses(good, broken, tags)
    d = c.drops
    ok_out, own_out, rest_out = cc.explain(loss_out, c.events, 1.0, d.counted, d.KEYS_OUT)
    wrong_back, loss_back, read_back = cc.far_to_fc(c.tmp, c.runs, nodes.tx)
    ok_back, own_back, rest_back = cc.explain(loss_back, c.events, 5.0, d.counted, d.KEYS_BACK)
    rest = rest_out + rest_back
    return {
        "tunnel_records_to_far_end": len(good),
        "tunnel_records_back": read_back,
        "tunnel_bytes_to_far_end": sum(len(d) for _, d in nodes.rx),
        "tunnel_bytes_back_sent": sum(len(d) for _, d in nodes.tx),
        "tunnel_wrong": len(wrong_out) + len(wrong_back),
        "tunnel_wrong_examples": (wrong_out + wrong_back)[:5],
        "tunnel_losses_explained": {
            "to_far_end": len(ok_out),
            "back": len(ok_back),
            "by": sorted({x[4] for x in ok_out + ok_back}),
        },
        "tunnel_losses_counted": {
            "to_far_end": len(own_out),
            "back": len(own_back),
            "by": sorted({x[4] for x in own_out + own_back}),
        },
        "tunnel_losses_unexplained": len(rest),
        "tunnel_losses_unexplained_examples": [
            loss_detail(c, x, way)
            for way, xs in (("to far end", rest_out), ("back", rest_back))
            for x in xs[:5]
        ],
    }


def fc_summary(c):
    """The FC runs' own lines: counter windows against the gateway's, and
    the tunnel drops the FC counted."""
    windows, rd = [], {"rd_dropped": 0, "rd_lost": 0}
    exchanges = errors = 0
    for k in range(len(c.runs)):
        lines = cc.read_jsonl(c.tmp / f"fc{k}.out")
        windows += cc.counter_windows(lines, c.events)
        for line in lines:
            if line.get("step") == "esc":
                exchanges += line["exchanges"]
                errors += line["errors"]
                for f in rd:  # the port's counts since it was last opened
                    rd[f] = max(rd[f], line.get(f, 0))
    bad = [w for w in windows if not w["ok"]]
    return windows, bad, rd, exchanges, errors


def summary(c, gw_stats, seconds):
    for i in range(len(c.runs) - 1):
        if c.runs[i][3] is None:
            c.runs[i][3] = c.log.first_at_all(c.runs[i + 1][2], c.runs[i + 1][0])
    bad = check_values(c.log, [tuple(r) for r in c.runs])
    # the ESCs' log lines carry receive times, but a loaded host writes
    # them late: recoveries and zeros are looked for once every line is in
    c.fc_recover, c.fc_failed = recoveries(c.log, [(r[0], r[2]) for r in c.runs])
    c.gw_recover, c.gw_failed = recoveries(c.log, c.gw_starts)
    zeros = [c.log.zeros_at_all(k, u) for k, u in c.losses]
    c.failsafe = [None if z is None else z - k for z, (k, _) in zip(zeros, c.losses)]
    late = [x for x in c.failsafe if x is None or x > BOUND_S]
    rss_g, fd_g, (longest_s, _) = c.growth()
    nodes = cc.NodesLog(c.tmp / "nodes.log")
    windows, bad_windows, rd, fc_ex, fc_err = fc_summary(c)
    gw_total = {
        f: sum(x.get(f, 0) for x in c.gw_counters)
        for f in ("esc_cmds", "servo_cmds", "failsafes", "tun_dropped", "can_tx_dropped")
    }
    return {
        "seconds": seconds,
        "faults": c.counts,
        "fc_runs": len(c.runs),
        "fc_bauds": {b: sum(1 for r in c.runs if r[4] == b) for b in BAUDS},
        "fc_recovered": len(c.fc_recover),
        "fc_not_recovered": c.fc_failed,
        "fc_recovery_worst_s": max(c.fc_recover, default=None),
        "fc_runs_ended_by_themselves": c.fc_steps_failed,
        "gateway_restarts": c.counts["gateway"],
        "gateway_recovered": len(c.gw_recover),
        "gateway_not_recovered": c.gw_failed,
        "gateway_recovery_worst_s": max(c.gw_recover, default=None),
        "failsafe_checks": len(c.failsafe),
        "failsafe_worst_s": worst(c.failsafe),
        "failsafe_late": len(late),
        "esc_commands": len(c.log.cmds),
        "wrong_commands": len(bad),
        "wrong_examples": bad[:5],
        **outputs_summary(c, nodes),
        **tunnel_summary(c, nodes),
        "counter_windows": len(windows),
        "counter_windows_inconsistent": len(bad_windows),
        "counter_inconsistent_examples": bad_windows[:5],
        "counter_windows_sum": {
            k: sum(w[k] for w in windows)
            for k in ("fc_exchanges", "gw_esc_cmds", "fc_servo", "gw_servo_cmds", "retries")
        },
        "fc_exchanges_reported": fc_ex,
        "fc_esc_errors_reported": fc_err,
        "gateway_counters_all_instances": gw_total,
        "fc_tunnel_drops_max": rd,  # rd_dropped, rd_lost of one run at most
        "gateway_rss_growth_kb": rss_g,
        "gateway_fd_growth": fd_g,
        "gateway_longest_instance_s": round(longest_s, 1),
        "timeline": c.timeline,
        "gateway_counters_last_instance": gw_stats,
    }


def verdict(s):
    """The failed invariants (empty: all held)."""
    checks = {
        "wrong ESC commands": s["wrong_commands"],
        "wrong servo commands": s["wrong_servo"],
        "zeros late": s["failsafe_late"],
        "DISARMED late": s["disarmed_late"],
        "safety ON late": s["safety_on_late"],
        "servo failsafe late": s["servo_failsafe_late"],
        "armed again without an FC": s["armed_again_without_fc"],
        "gateway started armed": s["gateway_start_not_disarmed"],
        "FC restarts not recovered": s["fc_not_recovered"],
        "gateway restarts not recovered": s["gateway_not_recovered"],
        "wrong tunnel bytes": s["tunnel_wrong"],
        "tunnel loss neither explained nor counted": s["tunnel_losses_unexplained"],
        "RSS growth over 1 MiB": s["gateway_rss_growth_kb"] > RSS_GROWTH_MAX_KB,
        "fd growth": s["gateway_fd_growth"] > 0,
        "counters inconsistent": s["counter_windows_inconsistent"],
    }
    return [k for k, v in checks.items() if v]


def report(s):
    w = s["counter_windows_sum"]
    return (
        f"chaos {s['seconds']:.0f} s: {sum(s['faults'].values())} faults {s['faults']}\n"
        f"  values: {s['esc_commands']} ESC commands, {s['wrong_commands']} wrong; "
        f"{s['servo_commands']} servo commands, {s['wrong_servo']} wrong\n"
        f"  restarts: FC {s['fc_recovered']}/{s['fc_runs']} recovered (worst "
        f"{s['fc_recovery_worst_s'] or 0:.2f} s, bauds {s['fc_bauds']}); gateway "
        f"{s['gateway_recovered']}/{s['gateway_restarts']} (worst "
        f"{s['gateway_recovery_worst_s'] or 0:.2f} s), started DISARMED "
        f"{s['gateway_starts_checked'] - s['gateway_start_not_disarmed']}/"
        f"{s['gateway_starts_checked']}\n"
        f"  failsafe after {s['master_losses_checked']} losses of the master (bound "
        f"{BOUND_S:.2f} s): zeros worst {s['failsafe_worst_s'] or 0:.3f} s late "
        f"{s['failsafe_late']}; DISARMED {s['disarmed_worst_s'] or 0:.3f} s late "
        f"{s['disarmed_late']}; safety ON {s['safety_on_worst_s'] or 0:.3f} s late "
        f"{s['safety_on_late']}; servo failsafe {s['servo_failsafe_worst_s'] or 0:.3f} s late "
        f"{s['servo_failsafe_late']}; armed again without an FC {s['armed_again_without_fc']}\n"
        f"  tunnel: {s['tunnel_records_to_far_end']} records to the far end, "
        f"{s['tunnel_records_back']} back, {s['tunnel_wrong']} wrong; losses explained by a "
        f"fault {s['tunnel_losses_explained']}, counted {s['tunnel_losses_counted']}, "
        f"neither {s['tunnel_losses_unexplained']}\n"
        f"  counters: {s['counter_windows']} windows, {s['counter_windows_inconsistent']} "
        f"inconsistent: FC {w['fc_exchanges']} exchanges / gateway {w['gw_esc_cmds']} esc_cmds, "
        f"FC {w['fc_servo']} SERVOs / gateway {w['gw_servo_cmds']} servo_cmds, "
        f"{w['retries']} retries\n"
        f"  daemon: RSS growth {s['gateway_rss_growth_kb']} kB (max {RSS_GROWTH_MAX_KB}), "
        f"fd growth {s['gateway_fd_growth']} (longest instance "
        f"{s['gateway_longest_instance_s']} s)"
    )


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
        if a.keep:  # what the checks ran on, for a second look
            state = {k: getattr(c, k) for k in ("runs", "events", "losses", "gw_starts")}
            (tmp / "state.json").write_text(json.dumps(state))
        s = summary(c, gw_stats, a.seconds)
        s["failed"] = verdict(s)
    print(json.dumps(s, indent=1))
    if a.out:
        Path(a.out).write_text(json.dumps(s, indent=1))
    print(report(s))
    print("chaos: " + ("OK" if not s["failed"] else "FAILED: " + ", ".join(s["failed"])))
    return 0 if not s["failed"] else 1


if __name__ == "__main__":
    sys.exit(main())
