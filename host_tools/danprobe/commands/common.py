"""What every subcommand shares: options, exit codes, the port, the master,
progress and output. A subcommand module defines NAME, HELP,
add_arguments(parser) and run(ctx) -> exit code (see commands/__init__.py).
"""

import argparse
import json
import math
import os
import signal
import sys
import time
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from typing import Callable, Optional

from danprobe import gateway_client, gateway_msgs, registry
from danprobe.master import (
    DanError,
    DanTimeout,
    Master,
    MasterConfig,
    NotFound,
    OperationTimeout,
)
from danprobe.payloads import MASK_BAUDS
from danprobe.port import PortError, SerialPort, now
from danprobe.ptyport import Pty

EXIT_OK = 0
EXIT_FAIL = 1  # the operation failed: no answer, configure failed, port I/O error
EXIT_USAGE = 2  # bad arguments, or the port cannot be opened (missing, busy, not a tty)
EXIT_INTERRUPTED = 130  # Ctrl-C ended a command that does not take it for "stop"

DEFAULT_BAUD = 9600
DEFAULT_TYPES = "vtx,can-gw"


class CliError(Exception):
    """Ends the command with a one-line message on stderr and exit_code."""

    def __init__(self, message: str, exit_code: int = EXIT_FAIL):
        super().__init__(message)
        self.exit_code = exit_code


class UsageError(CliError):
    """A CliError for bad arguments or a port that cannot be opened: exit
    code EXIT_USAGE."""

    def __init__(self, message: str):
        super().__init__(message, EXIT_USAGE)


# ---- argument types ----


def int_range(lo: int, hi: Optional[int] = None, what: str = "the value"):
    """An argument type: an integer (0x.. for hex) of lo.. (or lo..hi)."""

    def parse(s: str) -> int:
        try:
            v = int(s, 0)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number: {s!r}") from None
        if hi is None and v < lo:
            raise argparse.ArgumentTypeError(f"must be at least {lo}: {s!r}")
        if hi is not None and not lo <= v <= hi:
            raise argparse.ArgumentTypeError(f"{what} must be {lo}..{hi}, not {s}")
        return v

    return parse


positive_int = int_range(1)
non_negative_int = int_range(0)


def positive_float(s: str) -> float:
    try:
        v = float(s)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {s!r}") from None
    if not v > 0:
        raise argparse.ArgumentTypeError(f"must be positive: {s!r}")
    return v


def assignments(parse_one: Callable[[int, str], object], what: str, id_max: int = 255):
    """An argument type: comma-separated ID=SPEC items (ID 0..id_max), each
    parse_one(id, spec) (a ValueError says why not); a list. With
    action="append", flat() joins the lists of repeated options."""

    def parse(s: str) -> list:
        out = []
        for item in filter(None, (x.strip() for x in s.split(","))):
            ident, sep, spec = item.partition("=")
            try:
                if not sep or not spec:
                    raise ValueError("expected ID=" + what.upper())
                try:
                    i = int(ident, 0)
                except ValueError:
                    raise ValueError(f"{ident!r} is not an ID") from None
                if not 0 <= i <= id_max:
                    raise ValueError(f"ID {i} is outside 0..{id_max}")
                out.append(parse_one(i, spec.strip()))
            except ValueError as e:
                raise argparse.ArgumentTypeError(f"{item!r}: {e}") from None
        if not out:
            raise argparse.ArgumentTypeError(f"no ID={what.upper()} given")
        return out

    return parse


def append_option(parse: Callable[[str], object], metavar: str) -> dict:
    """The add_argument() keywords of an option that may be given several
    times: the list of its values, each parse(text) (None if never given)."""
    return {"action": "append", "type": parse, "metavar": metavar}


def id_list_option(parse_one: Callable[[int, str], object], what: str, metavar: str) -> dict:
    """append_option() of ID=SPEC lists (assignments(parse_one, what)):
    flat() joins them."""
    return append_option(assignments(parse_one, what), metavar)


def flat(groups) -> list:
    """The items of an append option's lists, in order ([] if never given)."""
    return [x for g in groups or () for x in g]


def type_list(s: str) -> list[registry.PeripheralType]:
    out = []
    for name in filter(None, (x.strip() for x in s.split(","))):
        t = registry.lookup(name)
        if t is None:
            names = ", ".join(t.name for t in registry.TYPES)
            raise argparse.ArgumentTypeError(f"unknown type {name!r} ({names} or a first code)")
        if t not in out:
            out.append(t)
    if not out:
        raise argparse.ArgumentTypeError("no type given")
    return out


# ---- shared options ----


def add_common_options(
    p: argparse.ArgumentParser,
    *,
    port_required: bool = True,
    baud_help: str = "the line's baud rate (default 9600)",
    timeout_default: Optional[float] = 30.0,
    timeout_help: str = "give up after S seconds (default 30)",
):
    g = p.add_argument_group("common options")
    g.add_argument(
        "--port",
        required=port_required,
        metavar="TTY",
        help="serial port: a USB-serial adapter on the DAN wire, or a dan-vbus endpoint",
    )
    g.add_argument("--baud", type=positive_int, metavar="N", help=baud_help)
    g.add_argument("--json", action="store_true", help="machine-readable output on stdout")
    g.add_argument(
        "--timeout", type=positive_float, default=timeout_default, metavar="S", help=timeout_help
    )
    g.add_argument("-q", "--quiet", action="store_true", help="no progress messages on stderr")


def add_gap_option(g):
    g.add_argument(
        "--gap-ms",
        type=positive_int,
        default=20,
        metavar="N",
        help="idle time that ends a partial frame (default 20: USB adapters, ptys)",
    )


def add_duration_option(g):
    g.add_argument("--duration", type=positive_float, metavar="S", help="stop after S seconds")


def add_pty_options(g):
    """--link and --duration of a command that bridges to a local pty."""
    g.add_argument("--link", metavar="PATH", help="also make PATH a symlink to the pty")
    add_duration_option(g)


LATENCY_ENV = "DANPROBE_LATENCY_MS"


def env_latency_ms() -> int:
    """--latency-ms's default: $DANPROBE_LATENCY_MS (set once for a slow
    adapter or a loaded host) or 50."""
    v = os.environ.get(LATENCY_ENV)
    if v is None:
        return 50
    try:
        return positive_int(v)
    except argparse.ArgumentTypeError as e:  # while the parser is built: no command yet
        sys.stderr.write(f"danprobe: ${LATENCY_ENV}: {e}\n")
        sys.exit(EXIT_USAGE)


def add_master_options(p: argparse.ArgumentParser, *, types_default: str = DEFAULT_TYPES):
    """Options of every command that talks on the bus as its master."""
    g = p.add_argument_group("bus options")
    g.add_argument(
        "--types",
        type=type_list,
        default=type_list(types_default),
        metavar="LIST",
        help=f"peripheral types to probe, comma-separated names or first codes "
        f"(default {types_default}; known: "
        f"{', '.join(t.name for t in registry.TYPES)})",
    )
    g.add_argument(
        "--no-echo",
        action="store_true",
        help="the adapter does not echo our bytes (default: single wire, echo checked)",
    )
    g.add_argument(
        "--latency-ms",
        type=positive_int,
        default=env_latency_ms(),
        metavar="N",
        help="reply start window after our request (default 50: USB adapters, ptys; "
        f"or ${LATENCY_ENV} for a slow adapter or host)",
    )
    add_gap_option(g)
    g.add_argument(
        "--max-baud",
        type=positive_int,
        default=0,
        metavar="N",
        help="the fastest baud the adapter can do: discovery also looks at the fast bauds "
        "up to N and configure offers them, highest first (default: the draft's bauds only)",
    )
    g.add_argument(
        "--retries",
        type=non_negative_int,
        default=2,
        metavar="N",
        help="extra attempts per transaction (default 2)",
    )


def port_max_baud(a: argparse.Namespace) -> int:
    """--max-baud; else a fast --baud says the adapter does that much;
    else 0 (no limit within the draft's bauds, no fast bauds)."""
    baud = getattr(a, "baud", None) or 0
    return a.max_baud or (baud if baud > MASK_BAUDS[-1] else 0)


# ---- the run-time context ----


class Context:
    def __init__(self, args: argparse.Namespace):
        self.args = args
        self.t0 = now()
        self.bus: Optional[Master] = None  # the command's master, once made
        self.reported = False  # report() printed its final JSON document

    def progress(self, msg: str):
        if not self.args.quiet:
            print(f"danprobe: {msg}", file=sys.stderr, flush=True)

    def error(self, msg: str):
        print(f"danprobe: {msg}", file=sys.stderr, flush=True)

    def open_port(self, baud: int) -> SerialPort:
        if not self.args.port:
            raise UsageError("--port is required")
        try:
            return SerialPort(self.args.port, baud)
        except PortError as e:
            raise UsageError(str(e)) from None

    def master(self, port: SerialPort, baud: int) -> Master:
        a = self.args
        cfg = MasterConfig(
            resp_latency_s=a.latency_ms / 1000,
            gap_s=a.gap_ms / 1000,
            retries=a.retries,
            max_baud=port_max_baud(a),
        )
        m = Master(port, a.types, baud, cfg, echo=not a.no_echo, progress=self.progress)
        m.set_time_limit(a.timeout)
        self.bus = m
        return m

    def emit_json(self, obj: dict):
        print(json.dumps(json_safe(obj), allow_nan=False), flush=True)

    def cut_short(self, e: DanError, message: str, exit_code: int) -> int:
        """The end of a command that an exception ended (--timeout, Ctrl-C,
        a port or bus error): message on stderr, exit_code, and with --json
        the document a script waits for, unless the command printed its own:
        command, result, error, detail (as report()'s), ms, port, baud and
        peers (what the master knew), "event": "summary" for a command
        whose --json is a stream of events."""
        a, m = self.args, self.bus
        if getattr(a, "json", False) and not self.reported:
            self.emit_json(
                {
                    "command": a.command,
                    **error_fields(e),
                    "ms": round((now() - self.t0) * 1000, 1),
                    "port": getattr(a, "port", None),
                    "baud": m.baud if m else None,
                    **({"event": "summary"} if self.json_events() else {}),
                    "peers": [p.as_dict() for p in m.present()] if m else [],
                }
            )
        self.error(message)
        return exit_code

    def json_events(self) -> bool:
        """The command's --json is a stream of events that ends with a
        summary: its module's JSON_EVENTS (True, or a function of the
        arguments: `can dump` does, `can send` not)."""
        ev = getattr(self.args, "json_events", False)
        return bool(ev(self.args) if callable(ev) else ev)


def json_safe(v):
    """v with every NaN or infinity as None: float16 telemetry is NaN for
    "unknown" (DroneCAN ESCs send it), and JSON has no NaN (json.dumps would
    write one that jq and strict parsers refuse)."""
    if isinstance(v, float):
        return v if math.isfinite(v) else None
    if isinstance(v, dict):
        return {k: json_safe(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [json_safe(x) for x in v]
    return v


def error_fields(e: Optional[DanError]) -> dict:
    """result / error / detail of a JSON document, as dan-master names them."""
    if e is None:
        return {"result": 0, "error": "", "detail": ""}
    return {"result": e.code, "error": e.reason, "detail": str(e)}


def format_table(rows) -> str:
    """Left-aligned columns: rows[0] is the header; every cell a string."""
    widths = [max(len(r[c]) for r in rows) for c in range(len(rows[0]))]
    return "\n".join("  ".join(v.ljust(w) for v, w in zip(r, widths)).rstrip() for r in rows)


def peers_table(peers) -> str:
    rows = [("type", "code", "baud", "manufacturer", "model", "hw", "sw", "bauds")]
    for p in peers:
        i = p.identity
        rows.append(
            (
                p.type.name,
                f"0x{p.type.first:02X}",
                str(p.baud),
                i.manufacturer,
                i.model,
                i.hw_version,
                i.sw_version,
                ",".join(map(str, i.bauds)),
            )
        )
    return format_table(rows)


def master_operation(
    ctx: Context,
    baud: int,
    op: Callable[[Master], None],
    expected: tuple[type[DanError], ...] = (DanError,),
):
    """Opens the port, runs op(master) and returns (master, failure, ms):
    failure is the expected DanError op raised, or None. OperationTimeout
    and other errors propagate (cli.main reports them)."""
    with ctx.open_port(baud) as port:
        m = ctx.master(port, baud)
        t0 = now()
        failure = None
        try:
            op(m)
        except OperationTimeout:
            raise
        except expected as e:
            failure = e
        return m, failure, (now() - t0) * 1000


def add_bus_options(p: argparse.ArgumentParser, baud_help: str):
    """The common and the bus options of a command on the whole bus
    (discover, configure)."""
    add_common_options(p, baud_help=baud_help)
    add_master_options(p)


def peers_report(ctx: Context, m: Master, failure, ms: float, fields, failure_text, headline):
    """report() of a command that ends with the peers found: the human text
    is headline and the peers table."""

    def human():
        print(headline)
        print(peers_table(m.present()))

    return report(ctx, m, failure, ms, fields, failure_text, human)


def report(
    ctx: Context,
    m: Master,
    failure: Optional[DanError],
    ms: float,
    fields: dict,
    failure_text: str,
    human: Callable[[], None],
) -> int:
    """The end of a bus command: the JSON document (command, result, error,
    detail, ms, port, baud, the command's fields, peers), or the human
    text; failure_text on stderr and EXIT_FAIL on failure."""
    a = ctx.args
    if a.json:
        ctx.reported = True
        ctx.emit_json(
            {
                "command": a.command,
                **error_fields(failure),
                "ms": round(ms, 1),
                "port": a.port,
                "baud": m.baud,
                **fields,
                "peers": [p.as_dict() for p in m.present()],
            }
        )
    if failure is not None:
        ctx.error(failure_text)
        return EXIT_FAIL
    if not a.json:
        human()
    return EXIT_OK


# ---- the CAN-over-DAN gateway commands ----

GATEWAY_TYPE = registry.lookup("can-gw")


def add_gateway_options(
    p: argparse.ArgumentParser,
    *,
    long_running: bool = False,
    timeout_default: float = 30.0,
    timeout_help: Optional[str] = None,
    own: Optional[str] = None,
):
    """The options of every gateway command: the common and bus options
    (--types defaults to can-gw alone), --bus-baud and --configure. With own
    (the command's name), returns the group "<own> options" for its own."""
    add_common_options(
        p,
        baud_help="the baud the bus is at, if known: the gateway is tried there first "
        "(one IDENTIFY), then by discovery from 9600 (default: discovery)",
        timeout_default=timeout_default,
        timeout_help=timeout_help
        or (
            "give up finding the gateway after S seconds; then fail once it has "
            "not answered for S seconds (default 30)"
            if long_running
            else "give up after S seconds (default 30)"
        ),
    )
    add_master_options(p, types_default=GATEWAY_TYPE.name)
    g = p.add_argument_group("gateway options")
    g.add_argument(
        "--bus-baud", dest="baud", type=positive_int, metavar="N", help="the same as --baud"
    )
    g.add_argument(
        "--configure",
        action="store_true",
        help="first move the bus to the best baud of every peripheral found "
        "(--types; 115200 for the gateway alone, or up to --max-baud)",
    )
    return p.add_argument_group(f"{own} options") if own else None


def gateway_actions(p: argparse.ArgumentParser, command: str, helps: dict, description: str):
    """The actions of a gateway command (`param list|get|...`): a subparser
    per key of helps (dest COMMAND_command), each with the gateway options;
    yields (action, its "COMMAND ACTION options" group)."""
    sub = p.add_subparsers(dest=f"{command}_command", metavar="|".join(helps))
    sub.required = True
    for name, text in helps.items():
        s = sub.add_parser(name, help=text, description=description)
        yield name, add_gateway_options(s, own=f"{command} {name}")


def find_gateway(ctx: Context, m: Master):
    """The gateway's Peer: IDENTIFY at --baud if given, else (or if it did
    not answer there) discovery; then --configure. The bus is left at the
    gateway's baud. Raises NotFound if no gateway answered."""
    a = ctx.args
    peer = next(p for p in m.peers if p.type == GATEWAY_TYPE)
    if a.baud:
        m.probe(a.baud)
    if not peer.present:
        try:
            m.discover()
        except NotFound:
            pass
    if not peer.present:
        others = ", ".join(f"{p.type.name} at {p.baud}" for p in m.present())
        raise NotFound(
            "no CAN gateway answered"
            + (f" ({others} did)" if others else "")
            + " at "
            + ", ".join(map(str, sorted({a.baud or 9600, *m.scan_bauds()})))
            + " baud"
        )
    m.switch_baud(peer.baud)
    if a.configure:
        m.configure()
    ctx.progress(
        f"gateway at {m.baud} baud ({peer.identity.manufacturer} {peer.identity.model} "
        f"{peer.identity.sw_version})"
    )
    return peer


def gateway_operation(ctx: Context, op: Callable[[Master, gateway_client.GatewayClient], None]):
    """Opens the port, finds the gateway and runs op(master, client); returns
    (master, failure, ms) like master_operation()."""
    a = ctx.args
    if GATEWAY_TYPE not in a.types:
        a.types = [*a.types, GATEWAY_TYPE]

    def run(m: Master):
        find_gateway(ctx, m)
        op(m, gateway_client.GatewayClient(m))

    return master_operation(ctx, a.baud or DEFAULT_BAUD, run)


def gateway_reads(ctx: Context, **reads: Callable):
    """gateway_operation() of calls that only read: each keyword's function
    of the client gives one result. Returns (master, failure, ms, results:
    a dict by keyword, of the calls that returned)."""
    got = {}

    def op(m, gw):
        for name, read in reads.items():
            got[name] = read(gw)

    return (*gateway_operation(ctx, op), got)


def gateway_report(
    ctx: Context,
    m: Master,
    failure: Optional[DanError],
    ms: float,
    fields: dict,
    human: Callable[[], None],
) -> int:
    """report() for a one-shot gateway command."""
    return report(ctx, m, failure, ms, fields, f"{ctx.args.command}: {failure}", human)


def flags_command(ctx: Context, send: Callable, fields, what: Callable[[int], str]) -> int:
    """A one-shot gateway command: send(gw) makes its calls and returns the
    gateway flags of the last response (None: no call returns them). Prints
    "COMMAND: ok, what(flags); flags ... (N ms)", or the JSON document:
    fields (a dict, or a function giving it after the calls) and the flags."""
    flags = None

    def op(m, gw):
        nonlocal flags
        flags = send(gw)

    m, failure, ms = gateway_operation(ctx, op)

    def human():
        names = ",".join(gateway_msgs.flags_names(flags)) or "none" if flags is not None else None
        print(
            f"{ctx.args.command}: ok, {what(flags)}"
            + (f"; flags {names}" if names is not None else "")
            + f" ({ms:.1f} ms)"
        )

    doc = fields() if callable(fields) else dict(fields)
    if flags is not None:
        doc.update(gateway_msgs.flags_dict(flags))
    return gateway_report(ctx, m, failure, ms, doc, human)


class StopSignals:
    """While active, SIGINT and SIGTERM only set .stop: a long-running
    command ends its loop and cleans up (tunnel closed, zero throttle sent,
    filter restored) before it exits."""

    def __init__(self):
        self.stop = False
        self._old = {}
        self._depth = 0

    def _handler(self, signum, frame):
        self.stop = True

    def __enter__(self) -> "StopSignals":
        # nested use (announced "ready", then the loop): installed once, so
        # a signal in between is not lost
        self._depth += 1
        if self._depth == 1:
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._old[sig] = signal.signal(sig, self._handler)
        return self

    def __exit__(self, *exc):
        self._depth -= 1
        if self._depth == 0:
            for sig, old in self._old.items():
                signal.signal(sig, old)


def stop_signals(ctx: "Context") -> StopSignals:
    """The command's one StopSignals (made on first use)."""
    if getattr(ctx, "_stop_signals", None) is None:
        ctx._stop_signals = StopSignals()
    return ctx._stop_signals


class Watchdog:
    """Counts failed transactions of a long-running command; raises once the
    gateway has not answered for `seconds`."""

    def __init__(self, seconds: Optional[float]):
        self.seconds = seconds
        self.last_ok = now()
        self.failures = 0

    def ok(self):
        self.last_ok = now()

    def failed(self, e: DanError):
        self.failures += 1
        if self.seconds is not None and now() - self.last_ok > self.seconds:
            raise DanTimeout(f"the gateway has not answered for {self.seconds:g} s (last: {e})")


def long_running(m: Master, ctx: Context) -> tuple[StopSignals, Watchdog]:
    """After the gateway was found: no overall time limit any more."""
    m.set_time_limit(None)
    return stop_signals(ctx), Watchdog(ctx.args.timeout)


def sleep_until(due: float, stop, step: float = 0.05, clock=now, sleep=None) -> None:
    """Sleeps until the clock reaches `due` or stop.stop is set, in steps of
    at most `step` s (so a signal is seen). The clock is read once per pass:
    reading it again for the length gave a negative sleep (ValueError) when
    the loop ran late on a loaded machine."""
    sleep = sleep or time.sleep
    while not stop.stop:
        left = due - clock()
        if left <= 0:
            return
        sleep(min(left, step))


def time_left(ctx: Context, t0: float) -> bool:
    """--duration has not run out since t0 (without it, never)."""
    d = ctx.args.duration
    return d is None or now() - t0 < d


@contextmanager
def bridge_pty(ctx: Context, res: dict, what: str, **ready) -> Iterator[Pty]:
    """The local pty of a bridging command (--link), closed at the end. Its
    path goes into res["pty"] and is announced: a "ready" event (with the
    ready fields) for --json, else the line "COMMAND: PATH (link L)WHAT"."""
    a = ctx.args
    try:
        pty = Pty(a.link)
    except PortError as e:
        raise UsageError(str(e)) from None
    res["pty"] = pty.path
    # SIGTERM right after "ready" (a supervisor that waited for it) must
    # still end the command cleanly: the handlers go in before the news
    with pty, stop_signals(ctx):
        if a.json:
            ctx.emit_json({"event": "ready", "pty": pty.path, "link": a.link, **ready})
        else:
            print(
                f"{a.command}: {pty.path}" + (f" (link {a.link})" if a.link else "") + what,
                flush=True,
            )
        yield pty


def _kelvin_text(k: float) -> str:
    return f"{k - 273.15:.1f} C"


def telemetry_table(records: Iterable[gateway_msgs.TelemRecord]) -> str:
    """One row per ESC; a "dev temp" column (the node's device.Temperature)
    when some record carries one."""
    records = sorted(records, key=lambda r: r.esc_index)
    device = any(t.flags & gateway_msgs.TELEM_DEVICE for t in records)
    rows = [("esc", "node", "rpm", "voltage", "current", "temp", "power", "errors", "age")]
    rows[0] += ("dev temp",) if device else ()
    for t in records:
        if t.flags & gateway_msgs.TELEM_STATUS:
            row = (
                str(t.esc_index),
                str(t.node_id),
                str(t.rpm),
                f"{t.voltage:.2f} V",
                f"{t.current:.2f} A",
                _kelvin_text(t.temperature),
                f"{t.power_pct} %",
                str(t.error_count),
                f"{t.age_ms} ms",
            )
        else:
            row = (str(t.esc_index), str(t.node_id)) + ("-",) * 7
        if device:
            row += (dev_temp_text(t) or "-",)
        rows.append(row)
    return format_table(rows)


def dev_temp_text(t: gateway_msgs.TelemRecord) -> str:
    """ "44.9 C" (with "overheating" / "overcooling"), or "" without one."""
    if not t.flags & gateway_msgs.TELEM_DEVICE:
        return ""
    warn = [
        n
        for bit, n in (
            (gateway_msgs.DEV_OVERHEATING, "overheating"),
            (gateway_msgs.DEV_OVERCOOLING, "overcooling"),
        )
        if t.dev_flags & bit
    ]
    return _kelvin_text(t.dev_temperature) + (f" {','.join(warn)}" if warn else "")
