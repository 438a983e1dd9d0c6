"""The chaos soak's checks on what the output devices and the two ends
logged (tests/bench/chaos.py): servo values, the arming and safety states
after each loss of the master, the tunnel streams, and the FC's counts
against the gateway's counters. Pure functions over the logs."""

import json
import re
from pathlib import Path

GW_NODE = 10
SERVO_FS_PWM = 1000.0  # actuator 1's failsafe value (actuator 2 holds)
PWM = 4  # command_type
RECORD = re.compile(rb"(r\d+):(\d{6}):([0-9a-f]{2})")
# faults that may lose tunnel bytes without a counter: the gateway's
# buffers die with it, the FC's with it, the CAN adapter's with it
LOSSY = ("gateway", "fc", "unplug")


def servo_values(k):
    """The servo commands of FC run k: actuators 1 and 2, PWM."""
    return (1100.0 + k, 1900.0 - k)


def read_jsonl(path):
    path = Path(path)
    if not path.exists():
        return []
    out = []
    for line in path.read_text().splitlines():
        try:
            out.append(json.loads(line))
        except ValueError:  # a line cut by a kill
            pass
    return out


class NodesLog:
    """chaos_nodes.py's log: servo commands, states, tunnel chunks."""

    def __init__(self, path):
        ev = read_jsonl(path)
        gw = [e for e in ev if e.get("src", GW_NODE) == GW_NODE]
        self.servo = [(e["t"], e["cmds"]) for e in gw if e["event"] == "servo"]
        self.arming = [(e["t"], e["status"]) for e in gw if e["event"] == "arming"]
        self.safety = [(e["t"], e["status"]) for e in gw if e["event"] == "safety"]
        self.rx = [(e["t"], bytes.fromhex(e["data"])) for e in ev if e["event"] == "tun_rx"]
        self.tx = [(e["t"], bytes.fromhex(e["data"])) for e in ev if e["event"] == "tun_tx"]


def check_servos(log, runs):
    """runs: [start, kill, values, superseded] as chaos.py keeps them (k =
    index). Every ArrayCommand: both actuators, PWM, either run k's values
    (k started before, not superseded at the servo by a later run) or
    actuator 1 at its failsafe with actuator 2 holding a run's value.
    Returns (wrong texts, first time each run's values reached the servo)."""
    first = {}
    for t, cmds in log.servo:
        pair = tuple(c[2] for c in sorted(cmds))
        for k in range(len(runs)):
            if pair == servo_values(k) and k not in first and t >= runs[k][0]:
                first[k] = t
    bad = []
    by_value = {servo_values(k)[1]: k for k in range(len(runs))}
    for t, cmds in log.servo:
        ids = sorted(c[0] for c in cmds)
        if ids != [1, 2] or any(c[1] != PWM for c in cmds):
            bad.append(f"t={t:.3f}: {cmds}: not actuators 1 and 2 in PWM")
            continue
        v1, v2 = (c[2] for c in sorted(cmds))
        k = by_value.get(v2)
        if k is None or v1 not in (servo_values(k)[0], SERVO_FS_PWM):
            bad.append(f"t={t:.3f}: {cmds} was never sent")
        elif t < runs[k][0]:
            bad.append(f"t={t:.3f}: {cmds} before its run started")
        elif k + 1 in first and t > first[k + 1]:
            bad.append(f"t={t:.3f}: {cmds} after a later run took over")
    return bad, first


def first_state(events, value, since, until):
    return next((t for t, s in events if since <= t <= until and s == value), None)


def esc_states(esc_path, event, nesc):
    """esc_sim's log: per ESC, [(t, status)] of event from the gateway."""
    per = {i: [] for i in range(nesc)}
    for e in read_jsonl(esc_path):
        if e["event"] == event and e.get("src") == GW_NODE:
            per[e["esc"]].append((e["t"], e["status"]))
    return per


def master_loss(kill, until, esc_arming, esc_safety, log):
    """After a kill: when DISARMED and safety ON had reached every ESC and
    the servo node, and the servo failsafe the servo node (None: not before
    until); and whether a device heard ARMED or safety OFF again after it
    had heard the failsafe (an ARM from nowhere: the FC is dead)."""
    out = {}
    for name, per, servo_ev in (
        ("disarmed", esc_arming, log.arming),
        ("safety_on", esc_safety, log.safety),
    ):
        devices = [*per.values(), servo_ev]
        ts = [first_state(ev, 0, kill, until) for ev in devices]
        out[name] = None if None in ts else max(ts) - kill
        out[name + "_undone"] = any(
            t0 is not None and any(t0 < t <= until and s != 0 for t, s in ev)
            for t0, ev in zip(ts, devices)
        )
    fs = next(
        (t for t, cmds in log.servo if kill <= t <= until and sorted(cmds)[0][2] == SERVO_FS_PWM),
        None,
    )
    out["servo_failsafe"] = None if fs is None else fs - kill
    return out


# ---- tunnel streams ----


def parse_stream(chunks):
    """chunks: [(t, bytes)] in order. Returns [(t, tag, seq)] of the good
    records (a line, or within a line where a loss joined the cut end of
    one record to the next: its sum tells) and [(t, nbytes, ngood)] of what
    is left of each line that is not a record (a record cut by a loss), t
    the time of the chunk that ended the line, ngood the good records
    before it."""
    good, broken, line = [], [], b""
    for t, data in chunks:
        parts = (line + data).split(b"\n")
        line = parts.pop()
        for p in parts:
            left = len(p) + 1
            for m in RECORD.finditer(p):
                head = m.group(0)[: m.start(3) - m.start(0)]
                if m.end() == len(p) and sum(head) % 256 == int(m.group(3), 16):
                    good.append((t, m.group(1).decode(), int(m.group(2))))
                    left -= len(m.group(0)) + 1
            if left > 0:
                broken.append((t, left, len(good)))
    return good, broken


def stream_losses(good, broken, tags):
    """Per tag, records must come in strictly increasing order (a repeat or
    a step back is a wrong byte: the tunnel duplicated or reordered); a
    jump is a loss, so is every broken line. tags: the known ones.
    Returns (wrong texts, losses [(t_prev_good, t, records or bytes, what)])."""
    wrong, losses, nxt, last_t = [], [], {}, {}
    for t, tag, seq in good:
        if tag not in tags:
            wrong.append(f"t={t:.3f}: record {tag}:{seq} of no run")
            continue
        want = nxt.get(tag, 0)
        if seq < want:
            wrong.append(f"t={t:.3f}: record {tag}:{seq} again or out of order (next {want})")
            continue
        if seq > want:
            losses.append((last_t.get(tag, t), t, seq - want, f"{tag} records {want}..{seq - 1}"))
        nxt[tag], last_t[tag] = seq + 1, t
    prev = 0.0
    marks = sorted(
        [(g[0], None) for g in good] + [(b[0], b[1]) for b in broken], key=lambda x: x[0]
    )
    for t, n in marks:
        if n is not None:
            losses.append((prev, t, n, "bytes of a cut record"))
        else:
            prev = t
    return wrong, losses


def explain(losses, timeline, slack_s=1.0, counted=None, keys=()):
    """Splits losses into those a lossy fault (LOSSY) whose span meets the
    time from the last good record to the loss explains, those a counter owns up to (counted(t0,
    t1, keys): the counter that rose around then, or None) and the rest."""
    # a fault's span, not only its start: an FC run killed loses its tunnel
    # when the next run opens it, up to the end of the fault (that run's
    # values at the ESCs)
    faults = [(t, t + dur, name) for t, name, dur in timeline if name in LOSSY]
    ok, owned, rest = [], [], []
    for t0, t1, n, what in losses:
        hit = next((name for a, b, name in faults if a <= t1 + slack_s and t0 - slack_s <= b), None)
        if hit:
            ok.append((t0, t1, n, what, hit))
            continue
        by = counted(t0 - slack_s, t1 + slack_s, keys) if counted else None
        (owned if by else rest).append((t0, t1, n, what, by))
    return ok, owned, rest


def far_to_fc(tmp, runs, tx):
    """The far end's bytes back to the FC: what each FC run read from the
    tunnel (fc<k>.tun, XORed back) against what the far end sent (tx:
    its chunks). Every good record read must be one the far end sent; per
    tag in strictly increasing order across the runs; a jump or a cut
    record is a loss, placed in time by the far end's send times of the
    records around it. Returns (wrong, losses, records read)."""
    sent, _ = parse_stream([(t, bytes(b ^ 0x5A for b in d)) for t, d in tx])
    t_sent = {(tag, seq): t for t, tag, seq in sent}
    good, broken, wrong = [], [], []
    for k, r in enumerate(runs):
        p = Path(tmp) / f"fc{k}.tun"
        data = bytes(b ^ 0x5A for b in p.read_bytes()) if p.exists() else b""
        g, b = parse_stream([(r[0], data)])
        times = [t_sent.get((tag, seq)) for _, tag, seq in g]
        for (_, tag, seq), t in zip(g, times):
            if t is None:
                wrong.append(f"run {k} read record {tag}:{seq}, which the far end never sent")
            else:
                good.append((t, tag, seq))
        # a cut record: the loss came after the far end sent the record before it
        before = [r[0]] + [t for t in times if t is not None]
        broken += [(before[len([t for t in times[:i] if t is not None])], n) for _, n, i in b]
    w, losses = stream_losses(good, broken, {tag for _, tag, _ in sent})
    return wrong + w, losses, len(good)


# ---- counters ----


def counter_windows(lines, timeline):
    """Between two stats steps of one FC run with no gateway restart in
    between, the gateway's counters against the FC's counts: esc_cmds
    against the ESC exchanges, servo_cmds against the SERVOs (each at
    least what succeeded, at most what succeeded plus what failed plus the
    retries). Returns the windows: dicts with the figures and ok."""
    restarts = [t for t, name, _ in timeline if name == "gateway"]
    out, prev, acc = [], None, None
    for line in lines:
        if line.get("step") == "stats" and line.get("ok"):
            if prev is not None and not any(prev["t"] - 0.5 <= t <= line["t"] for t in restarts):
                out.append(window(prev, line, acc))
            prev, acc = line, {"ex": 0, "err": 0, "sv": 0, "sverr": 0, "tun": 0, "tunerr": 0}
        elif line.get("step") == "esc" and acc is not None:
            acc["ex"] += line["exchanges"]
            acc["err"] += line["errors"]
            acc["sv"] += line.get("servo_cmds", 0)
            acc["sverr"] += line.get("servo_errors", 0)
            acc["tun"] += line.get("tun_xfers", 0)
            acc["tunerr"] += line.get("tun_errors", 0)
    return out


def window(a, b, acc):
    d = {k: b[k] - a[k] for k in ("esc_cmds", "servo_cmds", "master_retries", "tun_dropped")}
    d.update({k: b[k] - a[k] for k in ("dan_crc_errors", "failsafes", "dan_requests")})
    retries = d["master_retries"]
    w = {
        "t": round(a["t"], 2),
        "fc_exchanges": acc["ex"],
        "fc_esc_errors": acc["err"],
        "gw_esc_cmds": d["esc_cmds"],
        "fc_servo": acc["sv"],
        "fc_servo_errors": acc["sverr"],
        "gw_servo_cmds": d["servo_cmds"],
        "retries": retries,
        "gw_tun_dropped": d["tun_dropped"],
        "gw_crc_errors": d["dan_crc_errors"],
        "gw_failsafes": d["failsafes"],
    }
    w["ok"] = (
        acc["ex"] <= d["esc_cmds"] <= acc["ex"] + acc["err"] + retries
        and acc["sv"] <= d["servo_cmds"] <= acc["sv"] + acc["sverr"] + retries
        and d["dan_requests"] >= 0
    )
    return w
