"""danprobe esc: drive ESCs through the gateway and watch their telemetry."""

import argparse

from danprobe import gateway_msgs
from danprobe.commands.common import (
    UsageError,
    add_gateway_options,
    dev_temp_text,
    gateway_operation,
    gateway_report,
    long_running,
    positive_float,
    positive_int,
    sleep_until,
    telemetry_table,
)
from danprobe.master import DanError, OperationTimeout
from danprobe.port import now

NAME = "esc"
HELP = "CAN gateway: send ESC commands (fixed values or a ramp) and show live telemetry"
DESCRIPTION = (
    "Sends uavcan.equipment.esc.RawCommand values through the gateway (ESC_CMD) at --rate "
    "exchanges per second for --duration seconds; every exchange brings one ESC's newest "
    "telemetry back (round robin), shown once a second (--json: every exchange as a JSON "
    "line). Values are raw (-8192..8191) or percent of full "
    "throttle with a '%' suffix (100% = 8191). At the end one command of zeros stops the "
    "motors at once (the gateway's failsafe would after its timeout). Negative values "
    "(reversible ESCs) are written as they are: --values -8192,-1,0,8191. --fast sends the "
    "compact ESC_FAST instead (13 bytes for 4 ESCs, the response 7) and asks for a telemetry "
    "record (ESC_FAST_T) every --telem-every N-th exchange only: the rate an FC loop needs."
)
EXAMPLES = (
    "danprobe esc --port /dev/ttyUSB0 --configure --values 0,100,200,300 --duration 3",
    "danprobe esc --port /dev/ttyUSB0 --baud 115200 --values -8192,-1,0,8191",
    "danprobe esc --port /dev/ttyUSB0 --baud 115200 --ramp -10%:10% --duration 5 --arm",
    "danprobe esc --port /dev/ttyUSB0 --baud 115200 --throttle -5 --count 2 --json",
    "danprobe esc --port /dev/ttyUSB0 --baud 115200 --values 0,0,0,0 --fast --telem-every 4 "
    "--rate 400",
)


# --json: events, then the summary (as can.py's and nodes.py's JSON_EVENTS)
JSON_EVENTS = True


def command_value(s: str) -> int:
    """A raw value (-8192..8191) or a throttle percent ('50%')."""
    s = s.strip()
    try:
        if s.endswith("%"):
            return gateway_msgs.throttle_to_raw(float(s[:-1]))
        v = int(s, 0)
    except ValueError as e:
        raise argparse.ArgumentTypeError(f"bad ESC value {s!r}: {e}") from None
    if not gateway_msgs.RAW_MIN <= v <= gateway_msgs.RAW_MAX:
        raise argparse.ArgumentTypeError(
            f"ESC value {v} outside {gateway_msgs.RAW_MIN}..{gateway_msgs.RAW_MAX}"
        )
    return v


def value_list(s: str):
    vals = [command_value(x) for x in s.split(",") if x.strip()]
    if not 1 <= len(vals) <= gateway_msgs.ESC_MAX:
        raise argparse.ArgumentTypeError(f"1..{gateway_msgs.ESC_MAX} values, not {len(vals)}")
    return vals


def ramp(s: str):
    a, sep, b = s.partition(":")
    if not sep:
        raise argparse.ArgumentTypeError(f"expected FROM:TO, not {s!r}")
    return command_value(a), command_value(b)


def throttle(s: str) -> int:
    return command_value(s.rstrip("%") + "%")


def add_arguments(p):
    g = add_gateway_options(p, long_running=True, own="esc")
    what = g.add_mutually_exclusive_group(required=True)
    what.add_argument(
        "--values",
        type=value_list,
        metavar="LIST",
        help="one value per ESC, comma-separated: raw or N%% (0,100,200,300 or -8192,-1,0,8191)",
    )
    what.add_argument(
        "--throttle",
        type=throttle,
        metavar="PCT",
        help="the same throttle percent for --count ESCs (100 = raw 8191)",
    )
    what.add_argument(
        "--ramp",
        type=ramp,
        metavar="FROM:TO",
        help="every ESC from FROM to TO (raw or N%%) over --duration",
    )
    g.add_argument(
        "--count",
        type=positive_int,
        default=4,
        metavar="N",
        help="ESCs for --throttle and --ramp (default 4)",
    )
    g.add_argument(
        "--rate",
        type=positive_float,
        default=50.0,
        metavar="HZ",
        help="exchanges per second (default 50)",
    )
    g.add_argument(
        "--duration",
        type=positive_float,
        default=3.0,
        metavar="S",
        help="seconds to run (default 3)",
    )
    g.add_argument(
        "--arm", action="store_true", help="ARM before the first command, disarm after the last"
    )
    g.add_argument(
        "--fast",
        action="store_true",
        help="compact exchanges (ESC_FAST, ESC_FAST_T): telemetry only every --telem-every N-th",
    )
    g.add_argument(
        "--telem-every",
        type=int,
        default=1,
        metavar="N",
        help="with --fast: a telemetry record every N-th exchange (default 1; 0: never)",
    )
    g.add_argument(
        "--plot",
        metavar="FILE.png",
        help="write RPM, current, voltage and temperature over time "
        "(needs matplotlib: pip install 'danprobe[plot]')",
    )


def _plot_module():
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise UsageError("--plot needs matplotlib (pip install 'danprobe[plot]')") from None
    return plt


def write_plot(plt, path: str, samples, title: str):
    """samples: (t, TelemRecord) with the sample's time on our clock."""
    fig, axes = plt.subplots(4, 1, sharex=True, figsize=(9, 10))
    series = (
        ("RPM", lambda r: r.rpm),
        ("current (A)", lambda r: r.current),
        ("voltage (V)", lambda r: r.voltage),
        ("temperature (C)", lambda r: r.temperature - 273.15),
    )
    escs = sorted({r.esc_index for _, r in samples})
    for ax, (label, get) in zip(axes, series):
        for e in escs:
            pts = sorted({(t, get(r)) for t, r in samples if r.esc_index == e})
            ax.plot([t for t, _ in pts], [v for _, v in pts], label=f"ESC {e}")
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[0].set_title(title)
    axes[0].legend(loc="upper left", fontsize="small", ncol=max(1, len(escs)))
    axes[-1].set_xlabel("time (s)")
    fig.tight_layout()
    fig.savefig(path, format="png")
    plt.close(fig)


def _live_line(t: float, values, gw, rate: float) -> str:
    parts = []
    for i in sorted(gw.esc):
        r = gw.esc[i]
        if r.flags & gateway_msgs.TELEM_STATUS:
            parts.append(
                f"esc{i} {r.rpm} rpm {r.voltage:.1f} V {r.current:.1f} A "
                f"{r.temperature - 273.15:.0f} C"
                + (f" (dev {dev_temp_text(r)})" if r.flags & gateway_msgs.TELEM_DEVICE else "")
            )
    return (
        f"{t:6.1f} s  cmd {','.join(map(str, values))}  "
        + (" | ".join(parts) or "no telemetry")
        + f"  ({rate:.0f}/s)"
    )


def _values_function(a):
    """values_at(t): the command values t seconds into the run."""
    if a.values is not None:
        return lambda t: a.values
    if a.throttle is not None:
        return lambda t: [a.throttle] * a.count
    lo, hi = a.ramp
    return lambda t: [int(round(lo + (hi - lo) * min(t / a.duration, 1.0)))] * a.count


def run(ctx) -> int:
    a = ctx.args
    values_at = _values_function(a)
    if a.count > gateway_msgs.ESC_MAX:
        raise UsageError(f"--count: at most {gateway_msgs.ESC_MAX} ESCs")
    if a.telem_every < 0:
        raise UsageError("--telem-every: 0 or more")
    plt = _plot_module() if a.plot else None
    res = {"exchanges": 0, "failed": 0, "seconds": 0.0, "samples": [], "client": None}

    def op(m, gw):
        res["client"] = gw
        _drive(ctx, m, gw, values_at, res)

    m, failure, ms = gateway_operation(ctx, op)
    return _summary(ctx, plt, res, m, failure, ms)


def _drive(ctx, m, gw, values_at, res):
    """Exchanges at --rate for --duration (arming first with --arm), then
    zero throttle (and disarm) however the loop ended: an ARM whose answer
    was lost may still have armed the gateway, so its failure is inside."""
    a = ctx.args
    stop, dog = long_running(m, ctx)
    period = 1.0 / a.rate
    n_values = len(values_at(0.0))
    with stop:
        t0 = now()

        def exchange_event(t, values, ok, **more):
            ctx.emit_json(
                {"event": "exchange", "t": round(t - t0, 6), "values": values, "ok": ok, **more}
            )

        try:
            if a.arm:
                gw.arm(gateway_msgs.ARM_FULLY_ARMED)
                ctx.progress("armed")
            t0 = now()
            due = last_line = t0
            count_at_line = 0
            while not stop.stop:
                t = now()
                if t - t0 >= a.duration:
                    break
                values = values_at(t - t0)
                try:
                    rec = _exchange(gw, a, values, res["exchanges"] + res["failed"])
                except OperationTimeout:
                    raise
                except DanError as e:
                    res["failed"] += 1
                    dog.failed(e)
                    if a.json:
                        exchange_event(t, values, False, error=str(e))
                    continue
                dog.ok()
                res["exchanges"] += 1
                t_rx = now()
                if rec is not None:
                    if rec.flags & gateway_msgs.TELEM_STATUS:
                        res["samples"].append((t_rx - t0 - rec.age_ms / 1000.0, rec))
                if a.json:
                    exchange_event(
                        t,
                        values,
                        True,
                        **gateway_msgs.flags_dict(gw.flags),
                        escs_known=_known(gw),
                        telemetry=rec.as_dict() if rec else None,
                    )
                elif t_rx - last_line >= 1.0:
                    rate = (res["exchanges"] - count_at_line) / (t_rx - last_line)
                    print(_live_line(t_rx - t0, values, gw, rate), flush=True)
                    last_line, count_at_line = t_rx, res["exchanges"]
                due = max(due + period, now() - period)
                sleep_until(min(due, t0 + a.duration), stop)  # a low --rate keeps --duration
        finally:
            res["seconds"] = now() - t0
            _stop_motors(ctx, gw, n_values, a.arm)


def _known(gw) -> int:
    """ESCs the gateway knows: ESC_CMD says; ESC_FAST does not, so at least
    those whose telemetry came back."""
    return max(gw.escs_known, len(gw.esc))


def _exchange(gw, a, values, i):
    """One exchange: ESC_CMD, or with --fast ESC_FAST (ESC_FAST_T on every
    --telem-every-th). Returns the telemetry record that came back, as the
    client keeps it (a TelemRecord), or None."""
    if not a.fast:
        return gw.esc_command(values)
    rec = gw.esc_fast(values, telem=a.telem_every > 0 and i % a.telem_every == 0)
    return gw.esc[rec.esc_index] if rec is not None else None


def _summary(ctx, plt, res, m, failure, ms) -> int:
    """The plot (--plot) and the report of the run."""
    a = ctx.args
    gw = res["client"]
    records = list(gw.esc.values()) if gw else []
    rate = res["exchanges"] / res["seconds"] if res["seconds"] > 0 else 0.0
    plotted = None
    if plt is not None and res["samples"]:
        write_plot(
            plt,
            a.plot,
            res["samples"],
            f"danprobe esc on {a.port}: {res['exchanges']} exchanges at {rate:.0f}/s",
        )
        plotted = a.plot
        ctx.progress(f"plot written to {a.plot}")
    elif plt is not None and failure is None:
        ctx.error("no telemetry came back: no plot written")

    def human():
        print(
            f"esc: {res['exchanges']} exchanges in {res['seconds']:.1f} s ({rate:.1f}/s), "
            f"{res['failed']} failed; {_known(gw)} ESC(s) known; flags "
            f"{','.join(gateway_msgs.flags_names(gw.flags)) or 'none'}"
        )
        if records:
            print(telemetry_table(records))
        else:
            print("no telemetry came back")

    fields = {
        "event": "summary",
        "exchanges": res["exchanges"],
        "failed": res["failed"],
        "seconds": round(res["seconds"], 3),
        "rate": round(rate, 1),
        "escs_known": _known(gw) if gw else 0,
        "esc": [r.as_dict() for r in sorted(records, key=lambda r: r.esc_index)],
        "plot": plotted,
    }
    return gateway_report(ctx, m, failure, ms, fields, human)


def _stop_motors(ctx, gw, n: int, disarm: bool):
    """Zero throttle (and disarm) at the end, however the loop ended."""
    for what, call in (
        ("zero throttle", lambda: gw.esc_command([0] * n)),
        ("disarm", lambda: gw.arm(gateway_msgs.ARM_DISARMED)),
    ):
        if what == "disarm" and not disarm:
            break
        try:
            call()
            ctx.progress(f"{what} sent")
        except DanError as e:
            ctx.error(f"could not send {what}: {e} (the gateway's failsafe stops the motors)")
