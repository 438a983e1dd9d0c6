#!/usr/bin/env python3
"""DAN benchmarks (`make bench`): every figure is measured in this run and
printed as a ratio against a bound computed from the same bytes.

    run_bench.py [--build build] [--out build/bench] [--soak SECONDS] [--quick]

Rows:
  esc        ESC exchanges/s (4-ESC command + telemetry) through dan-gatewayd on
             dan-vbus at 115200, esc_sim ESCs behind the SLCAN hub; bounds from
             the bytes in the vbus capture (8N1), with and without the mandatory
             gaps (turnaround 2 C + listen-before-talk 3 C per exchange)
  esc_fast   the same loop with dan-fcsim --fast (ESC_FAST, a record by
             ESC_FAST_T every N-th exchange) at 115200 (4 ESCs, N 4), 1000000
             and 2000000 (4 and 8 ESCs, N 1; 8 ESCs at 115200 too), bounds the
             same way, and each against a bare round trip of the same bytes
             between two processes on dan-vbus (tests/bench/bench_pty_rtt.c:
             what the host's ptys allow; 1.0 means the daemon adds nothing)
  esc_sim    ESC loops in simulated time through the real engines on the unit
             tests' simulated wire (tests/bench/bench_esc_sim.c): 4 and 8 ESCs at
             115200, 1000000 and 2000000; ESC_CMD, ESC_FAST, ESC_FAST_T every N-th
             exchange (the largest N keeping every ESC at >= 25 Hz on the bound)
             and every exchange; exchanges/s against the bound of the same bytes
             with the gaps, telemetry records per ESC per second (the slowest
             ESC). Goals: >= 0.97 of the bound; 4 ESCs at 115200 >= 400/s with
             >= 25 Hz per ESC; 8 ESCs at 1000000 with a record every exchange
             >= 1800/s
  raw_can    raw CAN frames/s drained with CAN_RECV from a frame source on the
             hub, against the DAN wire bound of the same messages, and against
             SLCAN and MAVLink2 CAN_FRAME at 115200
  discovery  discover + configure of 3 dan-testperiph (test-a, test-b, can-gw)
             by dan-master against the wire time of its bytes in the capture
  parser     callgrind instructions/byte of dan_decoder_feed and of crc8 alone
  gateway    callgrind instructions per ESC exchange, gateway side and FC side
  latency    ESC_CMD last byte on the wire -> RawCommand out of the hub, against
             a bare vbus pty hop plus a bare hub hop measured the same way
  files      a 256 KiB firmware image uploaded through DAN (danprobe's client,
             dan-vbus, dan-gatewayd --file-dir) at 115200 and 2000000, against
             the wire bound of its FILE_* frames with the gaps (goal >= 0.8), and
             the time tests/e2e/fw_bootloader.py takes to read it through the
             gateway behind the SLCAN hub (tests/bench/bench_files.py)
  params     listing the 100 parameters of tests/tools/param_node.py (pydronecan,
             behind the hub) with danprobe's client through the DAN wire at
             115200 (NODE_CALL / CALL_RESULT, 5 calls in flight), against the
             goal of 3 s
  chaos      the chaos soak (tests/bench/chaos.py) for 60 s: faults survived,
             wrong values (0), worst recovery, the daemon's RSS growth; OK
             when every invariant held (tests/bench/bench_reliability.py)
  hostile    tests/e2e/test_hostile_can.py with $DAN_HOSTILE_OUT: the ESC
             exchange rate under hostile CAN traffic against the clean rate
             (goal >= 0.9)
Results: OUT/results.json (+ results-YYYYmmdd-HHMMSS.json); the delta against
the previous results.json is printed. --soak N: the ESC loop for N seconds
with dan-gatewayd's RSS and counters sampled (also in the JSON).
"""

import argparse
import datetime
import json
import os
import re
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host_tools"))  # this checkout's danprobe, whatever the venv's
import bench_files  # noqa: E402  (tests/bench, the script's own directory)
import bench_reliability  # noqa: E402

import procgroup  # noqa: E402
from danprobe import gateway_calls, registry  # noqa: E402
from danprobe.codec import encode_frame  # noqa: E402  (the host tool's codec)
from danprobe.gateway_client import GatewayClient  # noqa: E402
from danprobe.gateway_msgs import REQUEST, seal  # noqa: E402
from danprobe.master import Master  # noqa: E402
from danprobe.port import SerialPort  # noqa: E402

CAN_FLOOD = ROOT / "tests" / "tools" / "can_flood.py"
PARAM_NODE = ROOT / "tests" / "tools" / "param_node.py"
PARAMS_GOAL_S = 3.0

BAUD = 115200
C_US = (10_000_000 + BAUD - 1) // BAUD  # one character, as libdan rounds it
PY = sys.executable


class Stack:
    """Processes of one scenario; every one in its own process group, all
    killed on close whatever happened."""

    def __init__(self, tmp):
        self.tmp = Path(tmp)
        self.procs = []

    def start(self, args, name, stdout=subprocess.PIPE):
        log = open(self.tmp / f"{name}.log", "wb")
        p = procgroup.start(args, log, stdout)
        p.name, p.log_file = name, log
        self.procs.append(p)
        return p

    def ready(self, p):
        line = p.stdout.readline().decode()
        if not line.startswith("READY"):
            raise RuntimeError(
                f"{p.name} did not start: {line!r}: "
                + (self.tmp / f"{p.name}.log").read_text()[-500:]
            )
        return line.split()[1:]

    def stop(self, p, sig=signal.SIGTERM):
        return procgroup.stop(p, sig)

    def close(self):
        procgroup.close_all(self.procs)


def read_capture(path):
    out = []
    for line in Path(path).read_text().splitlines():
        if line and not line.startswith("#"):
            f = line.split()
            out.append((float(f[0]), int(f[1]), int(f[2]), bytes.fromhex(f[3]), f[4:]))
    return out


def frame_code(b):
    """Code of a DAN frame starting at b[0] == 'D' (first uvarint)."""
    v, s = 0, 0
    for x in b[1:6]:
        v |= (x & 0x7F) << s
        s += 7
        if x < 0x80:
            return v
    return None


def fcsim(stack, build, port, steps, name="fcsim", timeout=300, stamps=None):
    """Runs dan-fcsim; returns (rc, [json lines]); stamps gets each line's
    arrival time (monotonic)."""
    p = stack.start([build / "bin" / "dan-fcsim", "--port", port, *steps], name)
    lines = []
    end = time.monotonic() + timeout
    for raw in p.stdout:
        if raw.strip():
            lines.append(json.loads(raw))
            if stamps is not None:
                stamps.append(time.monotonic())
        if time.monotonic() > end:
            break
    p.wait(30)
    return p.returncode, lines


def step(lines, name):
    return [line for line in lines if line.get("step") == name]


def gw_rig(stack, build, tmp, n_esc=4, extra_can=1, gw_args=(), vbus_args=()):
    """vbus (2 endpoints) + hub (1 + n_esc + extra_can ports) + esc_sim + dan-gatewayd."""
    vbus = stack.start(
        [
            build / "bin" / "dan-vbus",
            "-n",
            "2",
            "--link",
            tmp / "dan",
            "--capture",
            tmp / "bus.cap",
            "--control",
            tmp / "vbus.ctl",
            *vbus_args,
        ],
        "dan-vbus",
    )
    stack.ready(vbus)
    nports = 1 + n_esc + extra_can
    hub = stack.start(
        [
            PY,
            ROOT / "host_tools" / "slcan_hub.py",
            "-n",
            nports,
            "--link",
            tmp / "can",
            "--log",
            tmp / "hub.log",
            "--control",
            tmp / "hub.ctl",
        ],
        "slcan_hub",
    )
    stack.ready(hub)
    esc = None
    if n_esc:
        esc = stack.start(
            [
                PY,
                ROOT / "host_tools" / "esc_sim.py",
                *sum([["--port", tmp / f"can{k}"] for k in range(1, 1 + n_esc)], []),
                "--log",
                tmp / "esc.log",
            ],
            "esc_sim",
        )
        stack.ready(esc)
    return vbus, hub, esc, start_gwd(stack, build, tmp, gw_args)


def start_gwd(stack, build, tmp, gw_args=(), name="dan-gatewayd"):
    """dan-gatewayd on the rig's endpoint 1 and hub port 0 (again after a kill)."""
    gwd = stack.start(
        [
            build / "bin" / "dan-gatewayd",
            "--uart",
            tmp / "dan1",
            "--can",
            f"slcan:{tmp / 'can0'}",
            "--stats-file",
            tmp / "gw.stats",
            *gw_args,
        ],
        name,
        stdout=subprocess.DEVNULL,
    )
    time.sleep(0.5)
    if gwd.poll() is not None:
        raise RuntimeError(f"{name} exited: " + (tmp / f"{name}.log").read_text()[-500:])
    return gwd


# ---- rows --------------------------------------------------------------------


def bench_esc(build, seconds, fast_every=None, baud=BAUD, n_esc=4, vbus_args=()):
    """The ESC loop through dan-gatewayd on dan-vbus with n_esc esc_sim ESCs:
    ESC_CMD, or with fast_every=N the compact ESC_FAST with ESC_FAST_T every
    N-th; the bus configured to baud; vbus_args e.g. an adapter model."""
    opts = ["--fast", "--telem-every", str(fast_every)] if fast_every else []
    codes = (0x59, 0x5A) if fast_every else (0x42,)
    values = ",".join(str(100 * k) for k in range(n_esc))
    c_us = (10_000_000 + baud - 1) // baud
    with tempfile.TemporaryDirectory(prefix="danbench-") as tmp:
        tmp = Path(tmp)
        st = Stack(tmp)
        try:
            gwd = gw_rig(st, build, tmp, n_esc=n_esc, vbus_args=vbus_args)[3]
            rc, out = fcsim(
                st,
                build,
                tmp / "dan0",
                [
                    *opts,
                    "discover",
                    f"configure:{baud}",
                    "arm",
                    f"esc:{values}@1000@50",
                    f"esc:{values}@{int(seconds * 1000)}@0",
                    "disarm",
                ],
            )
            runs = step(out, "esc")
            if len(runs) < 2:  # a failed exchange on a loaded host is counted, not fatal
                raise RuntimeError(f"dan-fcsim failed ({rc}): {out}")
            run = runs[1]
            gw_cpu = cpu_seconds(gwd.pid)  # its whole life: an upper bound
        finally:
            st.close()
        cap = [
            b
            for b in read_capture(tmp / "bus.cap")
            if b[2] == baud and b[3][:1] == b"D" and frame_code(b[3]) in codes
        ]
    req = [len(b[3]) for b in cap if b[1] == 0]
    rsp = [len(b[3]) for b in cap if b[1] == 1]
    nbytes = statistics.mean(req) + statistics.mean(rsp)
    gw_turn, fc_turn = turnarounds(cap, c_us)
    bound = baud / 10 / nbytes
    bound_gaps = 1e6 / ((nbytes + 2 + 3) * c_us)
    return {
        "baud": baud,
        "escs": n_esc,
        "telem_every": fast_every or 1,
        "rate": run["rate"],
        "exchanges": run["exchanges"],
        "errors": run["errors"],
        "telemetry_records": run["telemetry_records"],
        "telem_hz_per_esc": run["telemetry_records"] / run["seconds"] / n_esc,
        "req_bytes": statistics.mean(req),
        "rsp_bytes": statistics.mean(rsp),
        "bound": bound,
        "bound_gaps": bound_gaps,
        "ratio": run["rate"] / bound,
        "ratio_gaps": run["rate"] / bound_gaps,
        # where an exchange's time goes beyond its bytes (median us, from the
        # capture): the gateway's answer after the request's last byte (the
        # rule: 2 C), the FC's next request after the answer's (3 C)
        "gw_turnaround_us": gw_turn,
        "fc_turnaround_us": fc_turn,
        "rule_gw_us": 2 * c_us,
        "rule_fc_us": 3 * c_us,
        # the daemon's CPU per exchange (setup and the warm-up run included):
        # far below the exchange's period, it is not what limits the rate
        "gw_cpu_us_per_exchange": (
            gw_cpu * 1e6 / (runs[0]["exchanges"] + run["exchanges"]) if gw_cpu else None
        ),
    }


def turnarounds(cap, c_us):
    """Median idle time (us) on the wire between a request's last byte and
    its answer (the gateway's turnaround), and between an answer's last byte
    and the next request (the FC's), from capture bursts in order."""
    gw, fc = [], []
    for a, b in zip(cap, cap[1:]):
        idle = (b[0] - a[0]) * 1e6 - len(a[3]) * c_us
        if (a[1], b[1]) == (0, 1):
            gw.append(idle)
        elif (a[1], b[1]) == (1, 0):
            fc.append(idle)
    return (statistics.median(gw) if gw else None, statistics.median(fc) if fc else None)


# dan-vbus rows of the fast loop: (ESCs, baud, a record every N-th exchange)
VBUS_FAST = [
    (4, 115200, 4),
    (8, 115200, 4),
    (4, 1000000, 1),
    (4, 2000000, 1),
    (8, 1000000, 1),
    (8, 2000000, 1),
]


def bare_round_trip(build, baud, req, rsp, seconds):
    """Exchanges/s of the same bytes between two bare processes on dan-vbus
    (tests/bench/bench_pty_rtt.c: no DAN engine, no gaps): what the host's
    ptys allow, against which the daemon's loop is compared."""
    with tempfile.TemporaryDirectory(prefix="danbench-") as tmp:
        tmp = Path(tmp)
        st = Stack(tmp)
        try:
            st.ready(
                st.start([build / "bin" / "dan-vbus", "-n", "2", "--link", tmp / "dan"], "vbus")
            )
            p = subprocess.run(
                [build / "bench" / "bench_pty_rtt", tmp / "dan0", tmp / "dan1"]
                + [str(x) for x in (baud, round(req), round(rsp), seconds)],
                capture_output=True,
                text=True,
                timeout=seconds + 30,
            )
        finally:
            st.close()
    if p.returncode != 0:
        raise RuntimeError(f"bench_pty_rtt failed: {p.stderr[-300:]}")
    return json.loads(p.stdout)["rate"]


def with_bare(build, row, seconds):
    """row (a bench_esc result) with the bare round trip of its bytes."""
    row["bare_rate"] = bare_round_trip(
        build, row["baud"], row["req_bytes"], row["rsp_bytes"], seconds
    )
    row["vs_bare"] = row["rate"] / row["bare_rate"]
    return row


def bench_esc_fast_vbus(build, seconds):
    return {
        "rows": [
            with_bare(
                build, bench_esc(build, seconds, fast_every=every, baud=baud, n_esc=n), seconds
            )
            for n, baud, every in VBUS_FAST
        ]
    }


# dan-vbus --latency models of the FC's USB-serial adapter (docs/VBUS.md):
# (name, --latency of endpoint 0, baud, a telemetry record every N-th)
ADAPTERS = [
    ("FTDI, latency timer 16 ms (default)", "0:16:1", 115200, 4),
    ("FTDI, latency timer 16 ms (default)", "0:16:1", 1000000, 1),
    ("FTDI, latency timer 4 ms", "0:4:1", 115200, 4),
    ("FTDI, latency timer 1 ms (low_latency)", "0:1:0.5", 115200, 4),
    ("FTDI, latency timer 1 ms (low_latency)", "0:1:0.5", 1000000, 1),
]


def bench_adapters(build, seconds):
    rows = []
    for name, lat, baud, every in ADAPTERS:
        r = bench_esc(build, seconds, fast_every=every, baud=baud, vbus_args=("--latency", lat))
        r["adapter"], r["latency"] = name, lat
        rows.append(r)
    return {"rows": rows}


def bench_esc_sim(build):
    p = subprocess.run(
        [str(build / "bench" / "bench_esc_sim"), "1"], capture_output=True, text=True, timeout=600
    )
    rows = [json.loads(line) for line in p.stdout.splitlines() if line.startswith("{")]
    if p.returncode != 0 or not rows:
        raise RuntimeError(f"bench_esc_sim failed: {p.stderr[-500:]}")

    def find(escs, baud, mode, every=None):
        return next(
            r
            for r in rows
            if (r["escs"], r["baud"], r["mode"]) == (escs, baud, mode)
            and (every is None or r["every"] == every)
        )

    t4 = [r for r in rows if (r["escs"], r["baud"], r["mode"]) == (4, 115200, "fast_t")]
    goals = {
        "ratio_min": min(r["ratio"] for r in rows),
        "esc4_115200_rate": t4[0]["rate"],
        "esc4_115200_telem_hz": t4[0]["telem_hz_min"],
        "esc8_1000000_telem_every_rate": find(8, 1000000, "fast_t", 1)["rate"],
    }
    goals["met"] = (
        goals["ratio_min"] >= 0.97
        and goals["esc4_115200_rate"] >= 400
        and goals["esc4_115200_telem_hz"] >= 25
        and goals["esc8_1000000_telem_every_rate"] >= 1800
    )
    return {"rows": rows, **goals}


def esc_sim_rows(e):
    out = []
    for r in e["rows"]:
        mode = {"cmd": "ESC_CMD", "fast": "ESC_FAST"}.get(r["mode"], f"FAST_T 1/{r['every']}")
        telem = "" if r["mode"] == "fast" else f", {r['telem_hz_min']:.1f} Hz/ESC"
        out.append(
            (
                f"  sim {r['escs']} ESC {r['baud']} {mode}",
                f"{r['rate']:.1f}/s{telem}",
                f"bound {r['bound']:.1f}/s ({r['bytes_per_exchange']:.2f} B + 5 C)",
                f"{r['ratio']:.3f}",
            )
        )
    goal = "met" if e["met"] else "NOT met"
    out.insert(
        0,
        (
            "ESC loops, simulated time",
            f"min ratio {e['ratio_min']:.3f}",
            f"goals {goal}: 4 ESC 115200 {e['esc4_115200_rate']:.0f}/s "
            f"{e['esc4_115200_telem_hz']:.1f} Hz; 8 ESC 1M telem {e['esc8_1000000_telem_every_rate']:.0f}/s",
            "",
        ),
    )
    return out


def bench_raw(build, seconds):
    with tempfile.TemporaryDirectory(prefix="danbench-") as tmp:
        tmp = Path(tmp)
        st = Stack(tmp)
        try:
            gw_rig(st, build, tmp, n_esc=0, extra_can=1)
            rc, out = fcsim(
                st, build, tmp / "dan0", ["discover", "configure", "filter:00000000/00000000"]
            )
            if rc != 0:
                raise RuntimeError(f"dan-fcsim failed: {out}")
            src = st.start([PY, CAN_FLOOD, tmp / "can1", seconds + 30], "blast")
            st.ready(src)
            time.sleep(0.5)
            stamps = []
            want = int(seconds * 300)
            rc, out = fcsim(
                st,
                build,
                tmp / "dan0",
                ["discover", "sleep:1", f"candump:{want}:{int(seconds * 4000)}"],
                name="fcsim2",
                stamps=stamps,
            )
            st.stop(src)
            dump = step(out, "candump")[0]
            secs = stamps[2] - stamps[1]
            got = len(dump["frames"])
        finally:
            st.close()
        cap = [
            b
            for b in read_capture(tmp / "bus.cap")
            if b[2] == BAUD and b[3][:1] == b"D" and frame_code(b[3]) == 0x4C and b[0] > 0
        ]
    rsp = [b for b in cap if b[1] == 1]
    req = [b for b in cap if b[1] == 0]
    # frames per response: count byte after the two uvarints (seq, dropped)
    per = []
    for b in rsp:
        body = b[3]
        i = 1 + len(bytes([0x4C]))  # 'D' + 1-byte code
        i += 1 if body[i] < 0x80 else 2  # length uvarint
        for _ in range(2):
            while body[i] & 0x80:
                i += 1
            i += 1
        per.append(body[i])
    full = [(len(r[3]), c) for r, c in zip(rsp, per) if c > 0]
    # the wire bound of the same messages: a full CAN_RECV exchange
    req_b = statistics.mean(len(b[3]) for b in req)
    rsp_b = max(n for n, _ in full) if full else 0
    fpm = max(c for _, c in full) if full else 0
    bound = fpm * BAUD / 10 / (req_b + rsp_b) if fpm else 0.0
    bound_gaps = fpm * 1e6 / ((req_b + rsp_b + 5) * C_US) if fpm else 0.0
    rate = got / secs
    slcan_bytes = 1 + 8 + 1 + 16 + 1  # T iiiiiiii l dd*8 \r
    mav_bytes = 12 + 16  # v2 header 10 + crc 2; CAN_FRAME payload 16
    return {
        "rate": rate,
        "frames": got,
        "seconds": secs,
        "dropped": dump.get("dropped"),
        "frames_per_msg_mean": statistics.mean(per) if per else 0,
        "frames_per_msg_max": fpm,
        "req_bytes": req_b,
        "rsp_bytes_full": rsp_b,
        "bound": bound,
        "bound_gaps": bound_gaps,
        "ratio": rate / bound if bound else 0,
        "slcan_rate": BAUD / 10 / slcan_bytes,
        "mavlink_rate": BAUD / 10 / mav_bytes,
        "vs_slcan": rate / (BAUD / 10 / slcan_bytes),
        "vs_mavlink": rate / (BAUD / 10 / mav_bytes),
        "bound_vs_slcan": bound / (BAUD / 10 / slcan_bytes),
    }


def bench_discovery(build, runs=3):
    res = []
    for _ in range(runs):
        with tempfile.TemporaryDirectory(prefix="danbench-") as tmp:
            tmp = Path(tmp)
            st = Stack(tmp)
            try:
                vbus = st.start(
                    [
                        build / "bin" / "dan-vbus",
                        "-n",
                        "4",
                        "--link",
                        tmp / "dan",
                        "--capture",
                        tmp / "bus.cap",
                    ],
                    "dan-vbus",
                )
                st.ready(vbus)
                for k, t in enumerate(("test-a", "test-b", "can-gw"), 1):
                    p = st.start(
                        [
                            build / "bin" / "dan-testperiph",
                            "--port",
                            tmp / f"dan{k}",
                            "--types",
                            t,
                            "--mask",
                            "0x0F",
                        ],
                        f"periph{k}",
                    )
                    st.ready(p)
                m = st.start(
                    [
                        build / "bin" / "dan-master",
                        "--port",
                        tmp / "dan0",
                        "--types",
                        "test-a,test-b,can-gw",
                        "--json",
                        "discover",
                        "configure",
                    ],
                    "dan-master",
                )
                out, _ = m.communicate(timeout=120)
                lines = [json.loads(line) for line in out.decode().splitlines() if line.strip()]
                if m.returncode != 0:
                    raise RuntimeError(f"dan-master failed: {lines}")
            finally:
                st.close()
            cap = read_capture(tmp / "bus.cap")
        ms = sum(line["ms"] for line in lines)
        wire_s = sum(len(b[3]) * 10 / b[2] for b in cap)
        res.append((ms / 1000, wire_s, len(cap), lines[-1]["baud"]))
    secs = statistics.median(r[0] for r in res)
    wire = statistics.median(r[1] for r in res)
    return {
        "seconds": secs,
        "wire_seconds": wire,
        "ratio": wire / secs,
        "bursts": res[0][2],
        "baud": res[0][3],
        "runs": [r[0] for r in res],
    }


def callgrind(args, toggle):
    with tempfile.NamedTemporaryFile(prefix="cg-", suffix=".out", delete=False) as f:
        outf = f.name
    try:
        p = subprocess.run(
            [
                "valgrind",
                "--tool=callgrind",
                f"--toggle-collect={toggle}",
                f"--callgrind-out-file={outf}",
                *map(str, args),
            ],
            capture_output=True,
            timeout=600,
        )
        if p.returncode != 0:
            raise RuntimeError(p.stderr.decode()[-500:])
        total = int(re.search(r"^totals:\s*(\d+)", Path(outf).read_text(), re.M).group(1))
        return total, json.loads(p.stdout.decode().strip().splitlines()[-1])
    finally:
        os.unlink(outf)


def bench_parser(build):
    b = build / "bench"
    dec, info = callgrind([b / "bench_parser", "decode", 200], "bench_run_decode")
    crc, _ = callgrind([b / "bench_parser", "crc", 200], "bench_run_crc")
    n = info["bytes"]
    return {
        "decode_ipb": dec / n,
        "crc_ipb": crc / n,
        "bytes": n,
        "frames": info["frames"],
        "mix_bytes": info["mix_bytes"],
        "ratio": crc / dec,
    }


def bench_gateway_instr(build):
    b = build / "bench" / "bench_gateway"
    n = 2000
    gw, info = callgrind([b, n], "gwside_*")
    fc, _ = callgrind([b, n], "fcside_*")
    return {
        "gw_instr": gw / n,
        "fc_instr": fc / n,
        "exchanges": info["exchanges"],
        "sim_rate": info["exchanges"] / info["virtual_seconds"],
        "ratio": fc / gw,
    }


PROBE_ESC = bytes.fromhex("04000019800cb004")  # 4 channels 0,100,200,300


def open_raw(path, baud):
    import serial  # pyserial from the venv

    return serial.Serial(str(path), baud, timeout=0)


def read_until(ser, pred, timeout=2.0):
    buf = b""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        d = ser.read(4096)
        if d:
            buf += d
            if pred(buf):
                return time.monotonic(), buf
        else:
            time.sleep(0.0001)
    return None, buf


def slcan_open(path):
    s = open_raw(path, 115200)
    s.write(b"C\rS8\rO\r")
    time.sleep(0.2)
    s.read(65536)
    return s


def bench_latency(build, samples=60):
    with tempfile.TemporaryDirectory(prefix="danbench-") as tmp:
        tmp = Path(tmp)
        st = Stack(tmp)
        try:
            gw_rig(st, build, tmp, n_esc=0, extra_can=2)
            rc, out = fcsim(st, build, tmp / "dan0", ["discover", "configure"])
            if rc != 0:
                raise RuntimeError(f"dan-fcsim failed: {out}")
            fc = open_raw(tmp / "dan0", BAUD)
            mon = slcan_open(tmp / "can1")
            src = slcan_open(tmp / "can2")
            req = encode_frame(0x42, seal(0x42, REQUEST, PROBE_ESC))
            gw_lat, vbus_hop, hub_hop = [], [], []
            for _ in range(samples):
                # gateway: the request's last byte leaves the wire -> RawCommand read from the hub
                # (includes the vbus hop to the gateway and the hub hop out: compare with those bare)
                mon.read(65536)
                fc.read(65536)
                ta = time.monotonic()
                fc.write(req)
                t0 = ta + len(req) * C_US / 1e6  # the last byte has left the wire
                read_until(fc, lambda b: len(b) >= len(req))
                t1, _ = read_until(
                    mon, lambda b: re.search(rb"T[0-9A-F]{2}04060A[0-9A-F]*\r", b) is not None
                )
                if t0 and t1:
                    gw_lat.append((t1 - t0) * 1e6)
                time.sleep(0.03)
                # bare vbus hop: one byte; its echo arrives after its wire time + one hop
                fc.read(65536)
                ta = time.monotonic()
                fc.write(b"\x00")
                tb, _ = read_until(fc, lambda b: len(b) >= 1)
                if tb:
                    vbus_hop.append((tb - ta) * 1e6 - C_US)
                # bare hub hop: a frame from one SLCAN port to another
                mon.read(65536)
                ta = time.monotonic()
                src.write(b"T1ABCDE0180102030405060708\r")
                tb, _ = read_until(mon, lambda b: b"T1ABCDE01" in b and b.endswith(b"\r"))
                if tb:
                    hub_hop.append((tb - ta) * 1e6)
                time.sleep(0.02)
            fc.close()
            mon.close()
            src.close()
        finally:
            st.close()
    g = statistics.median(gw_lat)
    v = statistics.median(vbus_hop)
    h = statistics.median(hub_hop)
    return {
        "gw_us": g,
        "gw_p90_us": sorted(gw_lat)[int(0.9 * len(gw_lat))],
        "vbus_hop_us": v,
        "hub_hop_us": h,
        "bare_us": v + h,
        "ratio": g / (v + h),
        "samples": len(gw_lat),
    }


def bench_params(build, runs=3, count=100):
    """param list of a 100-parameter pydronecan node: the median of runs."""
    with tempfile.TemporaryDirectory(prefix="danbench-") as tmp:
        tmp = Path(tmp)
        st = Stack(tmp)
        try:
            gw_rig(st, build, tmp, n_esc=0, extra_can=1)
            node = st.start(
                [PY, PARAM_NODE, "--port", tmp / "can1", "--node-id", 50, "--count", count],
                "param_node",
            )
            st.ready(node)
            with SerialPort(str(tmp / "dan0"), 9600) as port:
                m = Master(port, [registry.lookup("can-gw")])
                m.discover()
                m.configure()
                if m.baud != BAUD:
                    raise RuntimeError(f"the bus is at {m.baud}, not {BAUD}")
                gw = GatewayClient(m)
                gateway_calls.param_list(gw, 50)  # warm: the node's first answers
                times, n, tx = [], 0, 0
                for _ in range(runs):
                    before = m.stats.transactions
                    t0 = time.monotonic()
                    n = len(gateway_calls.param_list(gw, 50))
                    times.append(time.monotonic() - t0)
                    tx = m.stats.transactions - before
                    if n != count:
                        raise RuntimeError(f"listed {n} of {count} parameters")
                retries = m.stats.retries
        finally:
            st.close()
    secs = statistics.median(times)
    return {
        "seconds": secs,
        "params": n,
        "transactions": tx,
        "retries": retries,
        "goal_s": PARAMS_GOAL_S,
        "ratio": secs / PARAMS_GOAL_S,
        "runs": times,
    }


def cpu_seconds(pid):
    """User + system CPU time a process has used so far (/proc/PID/stat)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return None


def rss_kb(pid):
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    except OSError:
        pass
    return None


def soak(build, seconds):
    with tempfile.TemporaryDirectory(prefix="dansoak-") as tmp:
        tmp = Path(tmp)
        st = Stack(tmp)
        samples = []
        try:
            _, _, _, gwd = gw_rig(st, build, tmp)
            chunk = 10
            n = max(1, int(seconds // chunk))
            steps = (
                ["discover", "configure", "arm"]
                + [f"esc:0,300,600,900@{chunk * 1000}@0"] * n
                + ["disarm", "stats"]
            )
            p = st.start([build / "bin" / "dan-fcsim", "--port", tmp / "dan0", *steps], "fcsim")
            t0 = time.monotonic()
            while p.poll() is None:
                samples.append((round(time.monotonic() - t0, 1), rss_kb(gwd.pid)))
                time.sleep(1.0)
            lines = [
                json.loads(line) for line in p.stdout.read().decode().splitlines() if line.strip()
            ]
            stats = json.loads((tmp / "gw.stats").read_text())
        finally:
            st.close()
    escs = step(lines, "esc")
    rss = [r for _, r in samples if r]
    return {
        "seconds": seconds,
        "exchanges": sum(e["exchanges"] for e in escs),
        "errors": sum(e["errors"] for e in escs),
        "rate": statistics.mean(e["rate"] for e in escs),
        "rss_start_kb": rss[0] if rss else None,
        "rss_end_kb": rss[-1] if rss else None,
        "rss_max_kb": max(rss) if rss else None,
        "rss_samples": samples,
        "gateway": stats,
        "fc_stats": (step(lines, "stats") or [{}])[0],
    }


# ---- report ------------------------------------------------------------------


def table(r):
    rows = []
    e = r.get("esc")
    if e:
        rows.append(
            (
                "ESC exchange (4 ESC + telem)",
                f"{e['rate']:.1f}/s",
                f"wire {e['bound']:.0f}/s ({e['req_bytes']:.0f}+{e['rsp_bytes']:.1f} B); +gaps {e['bound_gaps']:.0f}/s",
                f"{e['ratio']:.2f} / {e['ratio_gaps']:.2f}",
            )
        )
    for e in (r.get("esc_fast") or {}).get("rows", []):
        rows.append(
            (
                f"vbus ESC_FAST {e['escs']} ESC {e['baud']} T 1/{e['telem_every']}",
                f"{e['rate']:.1f}/s, {e['telem_hz_per_esc']:.1f} Hz/ESC",
                f"wire {e['bound']:.0f}/s ({e['req_bytes']:.0f}+{e['rsp_bytes']:.1f} B); +gaps {e['bound_gaps']:.0f}/s",
                f"{e['ratio']:.2f} / {e['ratio_gaps']:.2f}",
            )
        )
        if e.get("gw_turnaround_us") is not None:
            rows.append(
                (
                    "  idle on the wire per exchange (median)",
                    f"gateway {e['gw_turnaround_us']:.0f} us, FC {e['fc_turnaround_us']:.0f} us",
                    f"rules {e['rule_gw_us']} us + {e['rule_fc_us']} us",
                    "",
                )
            )
        if "bare_rate" in e:
            cpu = e.get("gw_cpu_us_per_exchange")
            rows.append(
                (
                    "  vs a bare pty round trip (same bytes)",
                    f"{e['rate']:.1f}/s"
                    + (f", daemon CPU {cpu:.0f} us/exch" if cpu is not None else ""),
                    f"bare {e['bare_rate']:.0f}/s",
                    f"{e['vs_bare']:.2f}",
                )
            )
    for e in (r.get("adapters") or {}).get("rows", []):
        rows.append(
            (
                f"adapter {e['adapter']}, ESC_FAST 4 ESC {e['baud']} T 1/{e['telem_every']}",
                f"{e['rate']:.1f}/s, {e['telem_hz_per_esc']:.1f} Hz/ESC",
                f"no adapter: wire {e['bound']:.0f}/s; +gaps {e['bound_gaps']:.0f}/s",
                f"{e['ratio']:.2f} / {e['ratio_gaps']:.2f}",
            )
        )
    if r.get("esc_sim"):
        rows += esc_sim_rows(r["esc_sim"])
    w = r.get("raw_can")
    if w:
        rows.append(
            (
                "raw CAN frames via CAN_RECV",
                f"{w['rate']:.0f} fr/s",
                f"wire {w['bound']:.0f} fr/s ({w['frames_per_msg_max']}/msg, {w['req_bytes']:.0f}+{w['rsp_bytes_full']} B)",
                f"{w['ratio']:.2f}",
            )
        )
        rows.append(
            (
                "  vs SLCAN (27 B/frame)",
                f"{w['rate']:.0f} fr/s",
                f"{w['slcan_rate']:.0f} fr/s",
                f"{w['vs_slcan']:.2f} (bound {w['bound_vs_slcan']:.2f})",
            )
        )
        rows.append(
            (
                "  vs MAVLink2 CAN_FRAME (28 B)",
                f"{w['rate']:.0f} fr/s",
                f"{w['mavlink_rate']:.0f} fr/s",
                f"{w['vs_mavlink']:.2f}",
            )
        )
    d = r.get("discovery")
    if d:
        rows.append(
            (
                "discover+configure 3 periph",
                f"{d['seconds'] * 1000:.0f} ms",
                f"wire {d['wire_seconds'] * 1000:.0f} ms ({d['bursts']} bursts)",
                f"{d['ratio']:.3f}",
            )
        )
    p = r.get("parser")
    if p:
        rows.append(
            (
                "parser (callgrind)",
                f"{p['decode_ipb']:.1f} instr/B",
                f"crc8 alone {p['crc_ipb']:.1f} instr/B",
                f"{p['ratio']:.2f}",
            )
        )
    g = r.get("gateway")
    if g:
        rows.append(
            (
                "gateway per ESC exchange",
                f"{g['gw_instr']:.0f} instr",
                f"FC side {g['fc_instr']:.0f} instr",
                f"{g['ratio']:.2f}",
            )
        )
    lat = r.get("latency")
    if lat:
        rows.append(
            (
                "latency req end -> CAN out",
                f"{lat['gw_us']:.0f} us (p90 {lat['gw_p90_us']:.0f})",
                f"bare hops {lat['bare_us']:.0f} us (vbus {lat['vbus_hop_us']:.0f} + hub {lat['hub_hop_us']:.0f})",
                f"{lat['ratio']:.2f}",
            )
        )
    pr = r.get("params")
    if pr:
        rows.append(
            (
                f"param list ({pr['params']} params)",
                f"{pr['seconds']:.2f} s",
                f"goal {pr['goal_s']:.0f} s ({pr['transactions']} transactions)",
                f"{pr['ratio']:.2f}",
            )
        )
    rows += bench_files.files_rows(r.get("files") or {})
    rows += bench_reliability.rows(r)
    w0 = max(len(x[0]) for x in rows)
    w1 = max(len(x[1]) for x in rows)
    w2 = max(len(x[2]) for x in rows)
    out = [
        f"{'benchmark':<{w0}}  {'measured':<{w1}}  {'against':<{w2}}  ratio",
        "-" * (w0 + w1 + w2 + 13),
    ]
    out += [f"{a:<{w0}}  {b:<{w1}}  {c:<{w2}}  {d}" for a, b, c, d in rows]
    return "\n".join(out)


KEYS = [
    ("esc", "rate"),
    ("esc", "ratio"),
    ("esc_sim", "ratio_min"),
    ("esc_sim", "esc4_115200_rate"),
    ("esc_sim", "esc8_1000000_telem_every_rate"),
    ("raw_can", "rate"),
    ("raw_can", "ratio"),
    ("discovery", "seconds"),
    ("discovery", "ratio"),
    ("parser", "decode_ipb"),
    ("parser", "crc_ipb"),
    ("gateway", "gw_instr"),
    ("gateway", "fc_instr"),
    ("latency", "gw_us"),
    ("latency", "ratio"),
    ("params", "seconds"),
    ("files", "ratio_min"),
    ("chaos", "faults"),
    ("chaos", "rss_growth_kb"),
    ("hostile", "ratio"),
]


def delta(prev, cur):
    lines = []
    for sec, k in KEYS:
        a = prev.get(sec, {}).get(k)
        b = cur.get(sec, {}).get(k)
        if isinstance(a, (int, float)) and isinstance(b, (int, float)) and a:
            lines.append(f"  {sec}.{k}: {a:.4g} -> {b:.4g} ({(b - a) / a * 100:+.1f}%)")
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--build", default="build")
    ap.add_argument("--out", default="build/bench")
    ap.add_argument("--soak", type=float, default=0)
    ap.add_argument("--seconds", type=float, default=5.0, help="length of the rate runs")
    ap.add_argument(
        "--only",
        help="comma-separated rows (esc,esc_fast,adapters,esc_sim,raw_can,discovery,parser,"
        "gateway,latency,params,files,chaos,hostile)",
    )
    a = ap.parse_args()
    build = (ROOT / a.build).resolve()
    out = (ROOT / a.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    only = set(a.only.split(",")) if a.only else None
    res = {
        "time": datetime.datetime.now().isoformat(timespec="seconds"),
        "baud": BAUD,
        "git": subprocess.run(
            ["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True, text=True
        ).stdout.strip(),
    }
    if a.soak:
        print(f"soak: the ESC loop for {a.soak:.0f} s ...", flush=True)
        res["soak"] = s = soak(build, a.soak)
        print(
            f"soak: {s['exchanges']} exchanges ({s['rate']:.1f}/s), {s['errors']} failed; "
            f"dan-gatewayd RSS {s['rss_start_kb']} -> {s['rss_end_kb']} kB (max {s['rss_max_kb']}); "
            f"gateway esc_cmds {s['gateway'].get('esc_cmds')}, crc errors {s['gateway'].get('dan_crc_errors')}, "
            f"can_tx_dropped {s['gateway'].get('can_tx_dropped')}, failsafes {s['gateway'].get('failsafes')}"
        )
        print(
            "  RSS samples (s, kB): "
            + " ".join(
                f"{t:.0f}:{r}" for t, r in s["rss_samples"][:: max(1, len(s["rss_samples"]) // 12)]
            )
        )
    else:
        todo = [
            ("esc", lambda: bench_esc(build, a.seconds)),
            ("esc_fast", lambda: bench_esc_fast_vbus(build, min(a.seconds, 3.0))),
            ("adapters", lambda: bench_adapters(build, min(a.seconds, 3.0))),
            ("esc_sim", lambda: bench_esc_sim(build)),
            ("raw_can", lambda: bench_raw(build, a.seconds)),
            ("discovery", lambda: bench_discovery(build)),
            ("parser", lambda: bench_parser(build)),
            ("gateway", lambda: bench_gateway_instr(build)),
            ("latency", lambda: bench_latency(build)),
            ("params", lambda: bench_params(build)),
            (
                "files",
                lambda: bench_files.bench_files(
                    build, Stack, gw_rig, read_capture, frame_code, bare_round_trip
                ),
            ),
            ("chaos", lambda: bench_reliability.bench_chaos(build)),
            ("hostile", lambda: bench_reliability.bench_hostile(PY)),
        ]
        for name, fn in todo:
            if only and name not in only:
                continue
            print(f"bench: {name} ...", flush=True)
            res[name] = fn()
        print()
        print(table(res))
    prev = out / "results.json"
    if prev.exists():
        try:
            d = delta(json.loads(prev.read_text()), res)
            if d:
                print("\nchange against the previous results.json:\n" + d)
        except (ValueError, OSError):
            pass
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    name = "soak" if a.soak else "results"
    (out / f"{name}-{stamp}.json").write_text(json.dumps(res, indent=1))
    if not a.soak:
        shutil.copy(out / f"{name}-{stamp}.json", prev)
    print(f"\nwritten: {out / (name + '-' + stamp + '.json')}" + ("" if a.soak else f" and {prev}"))


if __name__ == "__main__":
    main()
