"""danprobe slcan: the CAN bus behind the gateway as an SLCAN (Lawicel)
adapter on a local pseudo-terminal."""

import time

from danprobe import gateway_can, gateway_msgs
from danprobe.commands.common import (
    add_gateway_options,
    add_pty_options,
    bridge_pty,
    gateway_operation,
    gateway_report,
    long_running,
    time_left,
)
from danprobe.master import DanError, OperationTimeout, RemoteError
from danprobe.port import now
from danprobe.slcan_codec import (
    ACK,
    BEL,
    FRAME_KINDS,
    LINE_MAX,
    format_frame,
    is_hex,
    parse_frame,
    tx_ack,
)

NAME = "slcan"
HELP = "CAN gateway: an SLCAN (Lawicel) adapter on a pty, for pydronecan and the DroneCAN GUI"
DESCRIPTION = (
    "Emulates a Lawicel/SLCAN USB-CAN adapter on a new pseudo-terminal whose CAN bus is the "
    "one behind the gateway: frames the client sends (t/T/r/R) go out with CAN_SEND and are "
    "acknowledged (z/Z) once the gateway took them; every frame the gateway receives comes "
    "back as a t/T line (CAN_RECV, the filter set to pass everything while the channel is "
    "open). pydronecan: dronecan.make_node('slcan:PTY', node_id=N, bitrate=1000000). The bus "
    "is DroneCAN's 1 Mbit/s: only S8 is accepted. Runs until Ctrl-C, SIGTERM or --duration."
)

IDLE_POLL_S = 0.005
TX_QUEUE_MAX = 64  # frames from the client not taken by the gateway yet


def add_arguments(p):
    add_gateway_options(p, long_running=True)
    g = p.add_argument_group("slcan options")
    add_pty_options(g)


def can_frame(line: bytes):
    """A t/T/r/R line (no CR) as the gateway's CanFrame, or None if malformed."""
    f = parse_frame(line)
    if f is None:
        return None
    return gateway_can.CanFrame(f.id, f.data, f.ext, f.rtr, f.dlc if f.rtr else 0)


class Adapter:
    """The Lawicel command set, one client line at a time."""

    def __init__(self):
        self.open = False
        self.listen_only = False
        self.timestamps = False
        self.tx = []  # CanFrames waiting for the gateway
        self._line = bytearray()
        self._overlong = False
        self.errors = 0

    def feed(self, data: bytes) -> bytes:
        """Handles the client's bytes; returns the answers."""
        out = bytearray()
        for c in data:
            if c in (0x0D, 0x0A):
                if self._overlong:
                    self._overlong = False
                    out += BEL
                elif self._line or c == 0x0D:
                    out += self.command(bytes(self._line))
                self._line.clear()
            elif len(self._line) >= LINE_MAX:
                self._overlong = True
                self._line.clear()
                self.errors += 1
            elif not self._overlong:
                self._line.append(c)
        return bytes(out)

    def command(self, line: bytes) -> bytes:
        c, arg = line[:1], line[1:]
        if not line:
            return ACK
        if c in FRAME_KINDS:
            f = can_frame(line)
            if f is None or not self.open or self.listen_only or len(self.tx) >= TX_QUEUE_MAX:
                return self._error()
            self.tx.append(f)
            return b""  # z / Z once the gateway took it
        if c == b"S":
            return ACK if arg == b"8" and not self.open else self._error()
        if c == b"s":
            return ACK if not self.open else self._error()
        if c in (b"O", b"L") and not arg:
            if self.open:
                return self._error()
            self.open, self.listen_only = True, c == b"L"
            return ACK
        if c == b"C" and not arg:
            self.open = False
            self.tx.clear()
            return ACK
        if line in (b"V", b"v"):
            return c + b"1013" + ACK
        if line == b"N":
            return b"NDAN1" + ACK
        if line == b"F":
            return b"F00" + ACK
        if line in (b"Z0", b"Z1"):
            self.timestamps = line == b"Z1"
            return ACK
        if c in (b"M", b"m") and len(arg) == 8 and is_hex(arg):
            return ACK
        return self._error()

    def _error(self) -> bytes:
        self.errors += 1
        return BEL


def run(ctx) -> int:
    res = {"pty": None, "link": ctx.args.link, "to_can": 0, "from_can": 0, "errors": 0, "lost": 0}

    def op(m, gw):
        with bridge_pty(ctx, res, " is an SLCAN adapter on the CAN bus behind the gateway") as pty:
            _serve(ctx, m, gw, pty, res)

    m, failure, ms = gateway_operation(ctx, op)

    def human():
        print(
            f"slcan: stopped; {res['to_can']} frame(s) sent to CAN, {res['from_can']} received"
            + (f", {res['lost']} lost" if res["lost"] else "")
        )

    return gateway_report(ctx, m, failure, ms, {"event": "summary", **res}, human)


def _serve(ctx, m, gw, pty, res):
    stop, dog = long_running(m, ctx)
    ad = Adapter()
    previous = None  # the gateway's filter table before we opened the channel
    filter_on = False  # ours (pass everything) is set
    resend = False  # the last CAN_SEND's transaction failed: repeat it
    out = bytearray()
    t0 = now()
    with stop:
        try:
            while not stop.stop and time_left(ctx, t0):
                was_open = ad.open
                answers = ad.feed(pty.read())
                if was_open and not ad.open:
                    pty.discard_output()  # like an adapter: nothing stale after C
                    out.clear()
                    resend = False
                out += answers
                del out[: pty.write(out)]
                moved = False
                try:
                    if ad.open and not filter_on:
                        listening = gw.can_listen(gateway_can.PASS_ALL)
                        previous = listening if previous is None else previous
                        filter_on = True
                        ctx.progress("channel open: receiving every frame")
                    elif not ad.open and filter_on:
                        gw.can_filter(gateway_msgs.FILTER_REPLACE, previous)
                        filter_on = False
                        ctx.progress("channel closed")
                    if ad.open and ad.tx:
                        batch = ad.tx[: gateway_msgs.CAN_FRAMES_MAX]
                        accepted = gw.can_send_again() if resend else gw.can_send(batch)
                        resend = False
                        for f in batch[:accepted]:
                            out += tx_ack(f.ext)
                        del ad.tx[:accepted]
                        res["to_can"] += accepted
                        moved = moved or accepted > 0
                    if ad.open:
                        frames = gw.can_recv()
                        stamp = int(time.time() * 1000) if ad.timestamps else None
                        for f in frames:
                            out += format_frame(f, stamp)
                        res["from_can"] += len(frames)
                        moved = moved or bool(frames)
                except OperationTimeout:
                    raise
                except RemoteError:
                    raise
                except DanError as e:
                    resend = gw.can_send_failed
                    dog.failed(e)
                    continue
                dog.ok()
                del out[: pty.write(out)]
                if not moved:
                    pty.wait_readable(IDLE_POLL_S)
        finally:
            res["errors"], res["lost"] = ad.errors, gw.can_rx_lost
            if filter_on:
                try:
                    gw.can_filter(gateway_msgs.FILTER_REPLACE, previous)
                except DanError as e:
                    ctx.error(f"could not restore the gateway's filter: {e}")
