"""danprobe sniff: decode a live DAN line (never transmitting) or a
dan-vbus capture file."""

from danprobe.commands.common import (
    DEFAULT_BAUD,
    EXIT_FAIL,
    EXIT_OK,
    CliError,
    UsageError,
    add_common_options,
    add_gap_option,
    positive_float,
    positive_int,
)
from danprobe.master import char_s
from danprobe.port import now
from danprobe.sniff import CaptureError, Sniffer, read_capture, sniff_capture

NAME = "sniff"
HELP = "decode the frames on a live line (listen only) or in a dan-vbus capture file"
DESCRIPTION = (
    "Prints every frame with its time, source (capture files know it), baud, gap since "
    "the previous frame, code name and decoded payload, plus decoder errors as they "
    "happen; the counters at the end. A live port is only read, never written. Stops "
    "after --count frames, --duration seconds, or Ctrl-C."
)


# --json: events, then the summary (as can.py's and nodes.py's JSON_EVENTS)
JSON_EVENTS = True


def add_arguments(p):
    add_common_options(
        p,
        port_required=False,
        baud_help="the live line's baud (default 9600)",
        timeout_default=None,
        timeout_help="live: fail if no frame was heard within S seconds",
    )
    g = p.add_argument_group("sniff options")
    g.add_argument("--capture", metavar="FILE", help="decode a dan-vbus capture file instead")
    g.add_argument("--count", type=positive_int, metavar="N", help="stop after N frames")
    g.add_argument("--duration", type=positive_float, metavar="S", help="stop after S seconds")
    add_gap_option(g)


def _fields_text(fields: dict) -> str:
    return " ".join(f"{k}={v!r}" if isinstance(v, str) else f"{k}={v}" for k, v in fields.items())


def _event_text(ev) -> str:
    src = "-" if ev.source is None else f"ep{ev.source}"
    head = f"{ev.time:12.6f} {src:>4} {ev.baud:>6}"
    if ev.kind != "frame":
        return f"{head} {'':>10}  !! {ev.kind.replace('_', ' ').rstrip('s')}"
    gap = "" if ev.gap is None else f"+{ev.gap * 1000:.2f}ms"
    name = ev.name if ev.name.endswith(f"0x{ev.code:02X}") else f"{ev.name} (0x{ev.code:02X})"
    text = f"{head} {gap:>10}  {name} {ev.role or ''}".rstrip()
    if ev.fields:
        text += "  " + _fields_text(ev.fields)
    elif ev.payload:
        text += f"  [{len(ev.payload)}] {ev.payload.hex()}"
    if ev.problem and ev.fields is None:
        text += f"  ({ev.problem})"
    return text


class _Printer:
    def __init__(self, ctx, sniffer: Sniffer):
        self.ctx, self.sniffer, self.frames = ctx, sniffer, 0

    def __call__(self, events) -> bool:
        """Prints events; False once --count frames were shown."""
        count = self.ctx.args.count
        for ev in events:
            if ev.kind == "frame":
                if count is not None and self.frames >= count:
                    return False
                self.frames += 1
            if self.ctx.args.json:
                self.ctx.emit_json(ev.as_dict())
            else:
                print(_event_text(ev), flush=True)
        return count is None or self.frames < count

    def summary(self) -> int:
        s = self.sniffer.summary()
        if self.ctx.args.json:
            self.ctx.reported = True
            self.ctx.emit_json({"event": "summary", **s})
        else:
            names = ", ".join(f"{k} {v}" for k, v in s.pop("frames_by_name").items())
            print(
                f"summary: {s.pop('frames')} frames"
                + (f" ({names})" if names else "")
                + "; "
                + ", ".join(f"{k.replace('_', ' ')} {v}" for k, v in s.items())
            )
        return EXIT_OK if self.frames else EXIT_FAIL


def _sniff_capture(ctx, printer: _Printer) -> int:
    a = ctx.args
    try:
        bursts = read_capture(a.capture)
    except OSError as e:
        raise UsageError(f"{a.capture}: {e.strerror}") from None
    except CaptureError as e:
        raise CliError(str(e)) from None
    start = bursts[0].time if bursts else 0.0
    for ev in sniff_capture(bursts, printer.sniffer):
        if a.duration is not None and ev.time - start > a.duration:
            break
        if not printer([ev]):
            break
    rc = printer.summary()
    if rc != EXIT_OK:
        ctx.error(f"no DAN frame in {a.capture}")
    return rc


def _sniff_live(ctx, printer: _Printer) -> int:
    a = ctx.args
    baud = a.baud or DEFAULT_BAUD
    c, gap = char_s(baud), a.gap_ms / 1000
    sniffer = printer.sniffer
    with ctx.open_port(baud) as port:
        ctx.progress(f"listening on {a.port} at {baud} baud (Ctrl-C to stop)")
        t0 = now()
        last_rx = prev_end = t0
        stop = None if a.duration is None else t0 + a.duration
        silent_until = None if a.timeout is None else t0 + a.timeout
        try:
            while True:
                t = now()
                if stop is not None and t >= stop:
                    break
                if silent_until is not None and not printer.frames and t >= silent_until:
                    printer.summary()
                    ctx.error(
                        f"no DAN frame heard on {a.port} in {a.timeout:g} s (wrong --baud? wiring?)"
                    )
                    return EXIT_FAIL
                wake = min(
                    x
                    for x in (
                        stop,
                        silent_until,
                        t + 0.5,
                        last_rx + gap if sniffer.busy() else None,
                    )
                    if x is not None
                )
                data = port.read(wake - t)
                t = now()
                if data:
                    # the last byte ended when it was read: its first one began n C earlier
                    first = max(t - len(data) * c, prev_end)
                    prev_end, last_rx = t, t
                    more = printer(sniffer.feed(data, first - t0, None, baud))
                elif sniffer.busy() and t - last_rx >= gap:
                    more = printer(sniffer.idle(last_rx - t0, baud))
                else:
                    continue
                if not more:
                    break
        except KeyboardInterrupt:
            pass
        printer(sniffer.idle(now() - t0, baud))
    rc = printer.summary()
    if rc != EXIT_OK:
        ctx.error(f"no DAN frame heard on {a.port}")
    return rc


def run(ctx) -> int:
    a = ctx.args
    if bool(a.capture) == bool(a.port):
        raise (
            UsageError("give --port (a live line) or --capture FILE, not both")
            if a.capture
            else UsageError("--port or --capture is required")
        )
    printer = _Printer(ctx, Sniffer())
    return _sniff_capture(ctx, printer) if a.capture else _sniff_live(ctx, printer)
