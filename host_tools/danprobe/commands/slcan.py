"""danprobe slcan: the CAN bus behind the gateway as an SLCAN (Lawicel)
adapter on a local pseudo-terminal."""

from collections import deque

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
from danprobe.recv_clock import RecvClock, slcan_stamp_ms
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
    "open), and so do the frames the gateway itself sends (its NodeStatus, GetNodeInfo "
    "answers, ESC commands: filter bit 29), unless --no-own, so a DroneCAN GUI tool or an "
    "allocation server on this host sees the gateway's node too; the client's own frames "
    "are not handed back. With timestamps on (Z1) a frame's timestamp is its receive time "
    "at the gateway (milliseconds modulo 60000). pydronecan: "
    "dronecan.make_node('slcan:PTY', node_id=N, bitrate=1000000); the DroneCAN GUI tool: "
    "the interface 'slcan:PTY' or the /dev/pts path printed (not in its list), its local "
    "node ID set. The bus is DroneCAN's 1 Mbit/s: only S8 is accepted. Runs until Ctrl-C, "
    "SIGTERM or --duration."
)

IDLE_POLL_S = 0.005
TX_QUEUE_MAX = 64  # frames from the client not taken by the gateway yet
SENT_KEEP = 256  # our frames remembered until their copy (bit 29) comes back


# --json: events, then the summary (as can.py's and nodes.py's JSON_EVENTS)
JSON_EVENTS = True


def add_arguments(p):
    g = add_gateway_options(p, long_running=True, own="slcan")
    add_pty_options(g)
    g.add_argument(
        "--no-own",
        action="store_true",
        help="leave out the frames the gateway itself sends (default: they pass too)",
    )


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
    a = ctx.args
    res = {"pty": None, "link": a.link, "to_can": 0, "from_can": 0, "errors": 0, "lost": 0}
    res.update(own=not a.no_own, echoes=0)

    def op(m, gw):
        with bridge_pty(ctx, res, " is an SLCAN adapter on the CAN bus behind the gateway") as pty:
            Bridge(ctx, m, gw, pty, res).serve()

    m, failure, ms = gateway_operation(ctx, op)

    def human():
        print(
            f"slcan: stopped; {res['to_can']} frame(s) sent to CAN, {res['from_can']} received"
            + (f", {res['lost']} lost" if res["lost"] else "")
        )

    return gateway_report(ctx, m, failure, ms, {"event": "summary", **res}, human)


class Bridge:
    """The pty's client and the gateway: the client's frames out with
    CAN_SEND, the received ones back with CAN_RECV while the channel is
    open (with receive times when the client turned timestamps on)."""

    def __init__(self, ctx, m, gw, pty, res):
        self.ctx, self.m, self.gw, self.pty, self.res = ctx, m, gw, pty, res
        self.ad = Adapter()
        own = not ctx.args.no_own
        self.filters = gateway_can.PASS_ALL_OWN if own else gateway_can.PASS_ALL
        self.previous = None  # the gateway's filter table before we opened the channel
        self.filter_on = False  # ours is set
        self.resend = False  # the last CAN_SEND's transaction failed: repeat it
        self.out = bytearray()
        self.sent = deque(maxlen=SENT_KEEP)  # our frames, until the gateway's copy comes back
        self.clock = RecvClock()

    def serve(self):
        stop, dog = long_running(self.m, self.ctx)
        t0 = now()
        with stop:
            try:
                while not stop.stop and time_left(self.ctx, t0):
                    self._client()
                    try:
                        moved = self._gateway()
                    except OperationTimeout:
                        raise
                    except RemoteError:
                        raise
                    except DanError as e:
                        self.resend = self.gw.can_send_failed
                        dog.failed(e)
                        continue
                    dog.ok()
                    del self.out[: self.pty.write(self.out)]
                    if not moved:
                        self.pty.wait_readable(IDLE_POLL_S)
            finally:
                self.res["errors"], self.res["lost"] = self.ad.errors, self.gw.can_rx_lost
                if self.filter_on:
                    try:
                        self.gw.can_filter(gateway_msgs.FILTER_REPLACE, self.previous)
                    except DanError as e:
                        self.ctx.error(f"could not restore the gateway's filter: {e}")

    def _client(self):
        """The client's bytes in, the answers out."""
        was_open = self.ad.open
        answers = self.ad.feed(self.pty.read())
        if was_open and not self.ad.open:
            self.pty.discard_output()  # like an adapter: nothing stale after C
            self.out.clear()
            self.resend = False
        self.out += answers
        del self.out[: self.pty.write(self.out)]

    def _gateway(self) -> bool:
        """One round with the gateway; True if frames moved."""
        ad, gw = self.ad, self.gw
        if ad.open and not self.filter_on:
            listening = gw.can_listen(self.filters)
            self.previous = listening if self.previous is None else self.previous
            self.filter_on = True
            self.sent.clear()
            self.ctx.progress(
                "channel open: receiving every frame"
                + (", the gateway's own too" if self.filters[0].own else "")
            )
        elif not ad.open and self.filter_on:
            gw.can_filter(gateway_msgs.FILTER_REPLACE, self.previous)
            self.filter_on = False
            self.ctx.progress("channel closed")
        if not ad.open:
            return False
        return self._send() | self._recv()

    def _send(self) -> bool:
        ad, gw = self.ad, self.gw
        if not ad.tx:
            return False
        batch = ad.tx[: gateway_msgs.CAN_FRAMES_MAX]
        accepted = gw.can_send_again() if self.resend else gw.can_send(batch)
        self.resend = False
        for f in batch[:accepted]:
            self.out += tx_ack(f.ext)
            self.sent.append(f)
        del ad.tx[:accepted]
        self.res["to_can"] += accepted
        return accepted > 0

    def _echo(self, f) -> bool:
        """f is the gateway's copy of a frame our client sent (bit 29):
        an adapter does not hand a client its own frames back."""
        if not f.own:
            return False
        for k, s in enumerate(self.sent):
            if f.same_frame(s):
                for _ in range(k + 1):  # the ones before it never came back
                    self.sent.popleft()
                self.res["echoes"] += 1
                return True
        return False

    def _recv(self) -> bool:
        gw, ad = self.gw, self.ad
        resyncs = gw.can_rx_resyncs
        frames = gw.can_recv(opts=gateway_can.RECV_TIMES if ad.timestamps else 0)
        if gw.can_rx_resyncs != resyncs:
            self.clock.reset()  # the gateway restarted: another clock
        stamps = [None] * len(frames)
        if ad.timestamps:
            stamps = [slcan_stamp_ms(t) for t in self.clock.unwrap(gw.recv_times)]
        for f, stamp in zip(frames, stamps):
            if not self._echo(f):
                self.out += format_frame(f, stamp)
                self.res["from_can"] += 1
        return bool(frames)
