"""danprobe can dump / can send: raw CAN frames through the gateway, in
can-utils' formats."""

import argparse
import dataclasses
import time

from danprobe import gateway_can, gateway_msgs
from danprobe.commands.common import (
    EXIT_FAIL,
    UsageError,
    add_duration_option,
    add_gateway_options,
    append_option,
    gateway_operation,
    gateway_report,
    long_running,
    positive_int,
    stop_signals,
    time_left,
)
from danprobe.master import DanError, OperationTimeout, RemoteError
from danprobe.port import now
from danprobe.recv_clock import RecvClock

NAME = "can"
HELP = "CAN gateway: raw CAN frames: 'can dump' (candump log format), 'can send ID#DATA'"
DESCRIPTION = (
    "Raw CAN frames on the DroneCAN bus behind the gateway. 'can dump' sets the gateway's "
    "receive filter and prints every frame that passes in candump's log format, "
    "'(1700000000.123456) can0 1404060A#0001900C800B01C0', which can-utils (log2asc, "
    "canplayer) and cantools read; each frame's time is when the gateway received it (its "
    "clock, mapped onto this host's with one offset estimated from the responses), so the "
    "gaps between frames are the bus's, not the DAN wire's. --own adds the frames the "
    "gateway itself sends. 'can send' sends frames written as for cansend."
)

IDLE_POLL_S = 0.01


def JSON_EVENTS(a) -> bool:
    """`can dump --json` is frame events, then the summary."""
    return a.can_command == "dump"


def filter_spec(s: str) -> gateway_can.Filter:
    """ID:MASK[:ext] in hex; more than 3 ID digits also means extended."""
    parts = s.split(":")
    if len(parts) not in (2, 3) or (len(parts) == 3 and parts[2] not in ("ext", "std")):
        raise argparse.ArgumentTypeError(f"expected ID:MASK[:ext] (hex), not {s!r}")
    try:
        fid, mask = int(parts[0], 16), int(parts[1], 16)
    except ValueError:
        raise argparse.ArgumentTypeError(f"ID and MASK are hex numbers: {s!r}") from None
    ext = parts[2] == "ext" if len(parts) == 3 else len(parts[0]) > 3
    top = gateway_msgs.EFF_MASK if ext else gateway_msgs.SFF_MASK
    if not 0 <= fid <= top or not 0 <= mask <= gateway_msgs.EFF_MASK:
        raise argparse.ArgumentTypeError(
            f"{s!r}: ID or MASK out of range for a {'29' if ext else '11'}-bit filter"
        )
    return gateway_can.Filter(fid, mask, ext)


def frame_spec(s: str) -> gateway_can.CanFrame:
    try:
        return gateway_can.parse_cansend(s)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def add_arguments(p):
    sub = p.add_subparsers(dest="can_command", metavar="dump|send")
    sub.required = True
    d = sub.add_parser(
        "dump", help="print received frames in candump log format", description=DESCRIPTION
    )
    g = add_gateway_options(d, long_running=True, own="dump")
    g.add_argument(
        "--filter",
        **append_option(filter_spec, "ID:MASK[:ext]"),
        help="pass frames with (id & MASK) == (ID & MASK) (hex; repeatable, up to "
        f"{gateway_msgs.FILTERS_MAX}); default: every frame",
    )
    g.add_argument(
        "--own",
        action="store_true",
        help="also the frames the gateway itself sends (filter bit 29; marked in --json)",
    )
    g.add_argument("--count", type=positive_int, metavar="N", help="stop after N frames")
    add_duration_option(g)
    g.add_argument(
        "--ifname",
        default="can0",
        metavar="NAME",
        help="interface name in the log lines (default can0)",
    )
    s = sub.add_parser("send", help="send frames written as for cansend", description=DESCRIPTION)
    add_gateway_options(s)
    s.add_argument(
        "frames",
        type=frame_spec,
        nargs="+",
        metavar="ID#DATA",
        help="3 hex digits: 11-bit id, 4..8: 29-bit; data in hex, '.' allowed "
        "between bytes; ID#R or ID#Rn: remote frame",
    )


def log_line(t: float, ifname: str, f: gateway_can.CanFrame) -> str:
    return f"({t:.6f}) {ifname} {f.candump()}"


class Stamps:
    """Host-clock times of the frames of each CAN_RECV response, from the
    gateway's receive times (a new clock when the gateway restarted)."""

    def __init__(self):
        self.clock = RecvClock()
        self.resyncs = 0

    def of(self, gw, host_now: float) -> list[float]:
        if gw.can_rx_resyncs != self.resyncs:
            self.resyncs = gw.can_rx_resyncs
            self.clock.reset()
        return self.clock.host_times(self.clock.unwrap(gw.recv_times), host_now)


def _dump(ctx) -> int:
    a = ctx.args
    filters = a.filter or list(gateway_can.PASS_ALL)
    if a.own:
        filters = [dataclasses.replace(f, own=True) for f in filters]
    if len(filters) > gateway_msgs.FILTERS_MAX:
        raise UsageError(f"at most {gateway_msgs.FILTERS_MAX} filters")
    res = {"frames": 0, "lost": 0, "dropped": 0}
    halted = []

    stamps = Stamps()

    def op(m, gw):
        # Ctrl-C from here on only stops: the filter always goes back (a
        # can_listen() cut short puts it back itself)
        with stop_signals(ctx) as stop:
            previous = gw.can_listen(filters)
            try:
                ctx.progress(f"receiving {', '.join(f.text() for f in filters)} (Ctrl-C to stop)")
                _, dog = long_running(m, ctx)
                t0 = now()
                while (
                    not stop.stop
                    and (a.count is None or res["frames"] < a.count)
                    and time_left(ctx, t0)
                ):
                    try:
                        frames = gw.can_recv(opts=gateway_can.RECV_TIMES)
                    except OperationTimeout:
                        raise
                    except DanError as e:
                        dog.failed(e)
                        continue
                    dog.ok()
                    for f, stamp in zip(frames, stamps.of(gw, time.time())):
                        if a.count is not None and res["frames"] >= a.count:
                            break
                        res["frames"] += 1
                        if a.json:
                            ctx.emit_json(
                                {
                                    "event": "frame",
                                    "time": round(stamp, 6),
                                    "ifname": a.ifname,
                                    **f.as_dict(),
                                }
                            )
                        else:
                            print(log_line(stamp, a.ifname, f), flush=True)
                    if not frames:
                        time.sleep(IDLE_POLL_S)
            finally:
                halted.append(stop.stop)  # Ctrl-C: done, whatever --count said
                res["lost"], res["dropped"] = gw.can_rx_lost, gw.can_rx_dropped
                try:
                    gw.can_filter(gateway_msgs.FILTER_REPLACE, previous)
                except DanError as e:
                    ctx.error(f"could not restore the gateway's filter: {e}")

    m, failure, ms = gateway_operation(ctx, op)
    if res["lost"]:
        ctx.error(f"{res['lost']} frame(s) lost (the gateway's receive ring overflowed)")
    rc = gateway_report(
        ctx,
        m,
        failure,
        ms,
        {"event": "summary", **res},
        lambda: ctx.progress(f"{res['frames']} frame(s)"),
    )
    if rc == 0 and a.count is not None and res["frames"] < a.count and not any(halted):
        ctx.error(f"can dump: {res['frames']} of {a.count} frame(s) received")
        return EXIT_FAIL
    return rc


def _send(ctx) -> int:
    a = ctx.args
    res = {"sent": 0}

    def op(m, gw):
        frames = list(a.frames)
        while frames:
            batch = frames[: gateway_msgs.CAN_FRAMES_MAX]
            tries = 0
            accepted = None
            while accepted is None:
                try:
                    accepted = gw.can_send(batch) if tries == 0 else gw.can_send_again()
                except (OperationTimeout, RemoteError):
                    raise
                except DanError:
                    tries += 1
                    if tries > 3:
                        raise
            if accepted == 0:  # the gateway's queue is full: all or nothing, try again
                time.sleep(0.01)
                continue
            res["sent"] += accepted
            del frames[:accepted]

    m, failure, ms = gateway_operation(ctx, op)

    def human():
        print(f"can send: {res['sent']} frame(s) sent ({ms:.1f} ms)")

    return gateway_report(
        ctx, m, failure, ms, {"frames": [f.candump() for f in a.frames], "sent": res["sent"]}, human
    )


def run(ctx) -> int:
    return _dump(ctx) if ctx.args.can_command == "dump" else _send(ctx)
