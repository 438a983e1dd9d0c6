"""A DAN master over a serial port, with libdan's rules (docs/PROTOCOL.md
section 6; src/link.c, src/master.c): listen before talk, echo check on a
single wire, response deadline, retries with random backoff, discovery at
9600 then the other bauds, configure with verification and recovery.

Unlike libdan's non-blocking engine this one blocks the calling thread for
the length of an operation; it keeps reading the line whenever it waits, so
its view of the line (idle time, partial frames) is always current.
"""

import os
import random
import time
from collections import deque
from contextlib import contextmanager
from dataclasses import asdict, dataclass
from typing import Callable, Optional

from danprobe import payloads
from danprobe.codec import MAX_FRAME, Decoder, encode_frame
from danprobe.payloads import (
    ACK_OK,
    BASE_BAUD,
    MASK_BAUDS,
    MASK_DEFINED,
    Configure,
    ErrorMessage,
    Identity,
    PayloadError,
)
from danprobe.port import now
from danprobe.registry import CODE_ERROR, PeripheralType

# 9600 first (the spec's start), then the mask bauds from the highest down:
# where a bus configured by a master that restarted most likely is.
DISCOVERY_BAUDS = (9600, 115200, 57600, 38400, 19200)
# Bauds above the draft's mask, offered only to a port that can do them
# (MasterConfig.max_baud) and negotiated with plain CONFIGURE: a peripheral
# that cannot answers ACK-FAIL (docs/PROTOCOL.md section 6, "Fast bauds").
FAST_BAUDS = (230400, 460800, 921600, 1000000, 1500000, 2000000)
TURNAROUND_CHARS = 2  # a peripheral replies no sooner than this after our last byte
GAP_CHARS = 10  # libdan's inter-byte gap: max(10 C, 2 ms)
GAP_MIN_S = 0.002
ECHO_WAKE_CHARS = 4  # send() sleeps until this many characters before its echo's end
ECHO_LATE_HOLD_S = 1.0  # after an echo timeout or a collision, a copy of our frame is our echo
RECOVER_S = 10.0  # to recover from a configure (or a filter) cut short: --timeout, Ctrl-C


def char_s(baud: int) -> float:
    """One character time (10 bits, 8N1) in seconds, rounded up to whole
    microseconds as libdan does."""
    return ((10_000_000 + baud - 1) // baud) / 1e6


# ---- errors: libdan's codes (include/dan/common.h), so JSON results match dan-master ----


class DanError(Exception):
    code = -10
    reason = "port I/O error"

    def __init__(self, detail: str = ""):
        super().__init__(detail or self.reason)


class Malformed(DanError):
    code, reason = -3, "malformed payload"


class DanTimeout(DanError):
    code, reason = -4, "timeout"


class OperationTimeout(DanError):
    """The whole operation ran past its time limit (--timeout). Not a
    DanTimeout (those are retried), but libdan's code and reason are the
    same."""

    code, reason = DanTimeout.code, DanTimeout.reason


class Busy(DanError):
    code, reason = -5, "busy"


class RemoteError(DanError):
    code, reason = -6, "peer answered with an error frame"

    def __init__(self, msg: ErrorMessage):
        super().__init__(f"peer answered with an error frame: {msg.text}")
        self.message = msg


class Collision(DanError):
    code, reason = -7, "collision"


class EchoTimeout(Collision):
    """Our bytes did not come back: counted as a failed attempt like a
    collision (libdan does the same)."""


class BadReply(Malformed):
    """A reply the reply check refused (the gateway's seal did not match):
    the attempt fails and is retried, as for a collision."""


class Unsupported(DanError):
    code, reason = -8, "unsupported"


class NotFound(DanError):
    code, reason = -9, "not found"


class Nack(DanError):
    code, reason = -11, "peer answered ACK-FAIL"


# ---- the link: echo, idle line, frames ----


@dataclass
class LinkStats:
    tx_frames: int = 0
    tx_bytes: int = 0
    rx_bytes: int = 0
    collisions: int = 0  # echo differed from what we sent
    echo_timeouts: int = 0  # echo never came back


class Link:
    """The half-duplex line as one talker sees it. pump() reads whatever
    arrives until a time, matches our echo, decodes frames into .frames and
    drops a partial frame after an idle gap."""

    def __init__(
        self,
        port,
        baud: int,
        echo: bool = True,
        gap_s: Optional[float] = None,
        echo_timeout_s: float = 0.0,
    ):
        self.port = port
        self.echo = echo
        self.gap_cfg = gap_s
        self.echo_timeout_cfg = echo_timeout_s
        self.decoder = Decoder()
        self.frames = deque()
        self.stats = LinkStats()
        self.deadline: Optional[float] = None  # of the current operation
        self._tx: Optional[bytes] = None  # our frame while its echo is pending
        self.last_tx = b""  # the last frame we sent
        self.echo_late_at: Optional[float] = None  # when our echo last went missing or broke
        self._echo_pos = 0
        self._tx_failed = False
        self._tx_end = 0.0
        self.baud = baud
        self.char = char_s(baud)
        self.last_rx = now()
        # Every byte that arrived before this time has been handled: time
        # decisions are taken at it, so a pause of this process (a loaded
        # machine) never turns bytes waiting in the port into a timeout.
        self.polled = self.last_rx

    @property
    def gap(self) -> float:
        return self.gap_cfg or max(GAP_CHARS * self.char, GAP_MIN_S)

    @property
    def echo_timeout(self) -> float:
        """The echo must be complete this long after our frame's expected
        end: it travels the same path as replies, so it gets the same
        latency allowance (never less than the gap)."""
        return max(self.gap, self.echo_timeout_cfg)

    def is_late_echo(self, frame, t: float) -> bool:
        """A copy of our last frame shortly after its echo went missing is
        that echo arriving late (slow adapter, stalled host), not a reply."""
        return (
            self.echo
            and self.echo_late_at is not None
            and t - self.echo_late_at <= ECHO_LATE_HOLD_S
            and encode_frame(frame.code, frame.payload) == self.last_tx
        )

    def set_baud(self, baud: int):
        self.port.set_baud(baud)
        self.baud = baud
        self.char = char_s(baud)
        self.decoder.reset()
        self.last_rx = now()

    def idle(self, t: float) -> float:
        """Seconds the line has been idle at t (0 while a frame is on it)."""
        if self._tx is not None or self.decoder.busy() or t < self.last_rx:
            return 0.0
        return t - self.last_rx

    def next_idle(self, chars: int) -> float:
        """When the line will have been idle chars character times, if
        nothing more arrives."""
        if self.decoder.busy():
            return self.last_rx + self.gap  # the partial frame is dropped then
        return self.last_rx + chars * self.char

    def pump(self, until: float = 0.0):
        """Handles the bytes waiting in the port, waiting for some until
        `until` at the latest (pump() only reads what is there). Raises
        OperationTimeout past the operation's deadline."""
        t = now()
        if self.deadline is not None and t >= self.deadline:
            raise OperationTimeout("operation timed out")
        wake = until
        if self.decoder.busy():
            wake = min(wake, self.last_rx + self.gap)
        if self.deadline is not None:
            wake = min(wake, self.deadline)
        self.polled = t
        data = self.port.read(wake - t)
        t = now()
        if data:
            self._rx(data, t)
        if self.decoder.busy() and t >= self.last_rx + self.gap:
            self.frames.extend(self.decoder.abort())  # the line went quiet mid-frame

    def _rx(self, data: bytes, t: float):
        self.stats.rx_bytes += len(data)
        self.last_rx = t
        i = 0
        if self._tx is not None and self.echo:
            # compared as slices: a byte loop in Python costs a third of a
            # 2 Mbit/s transaction (measured on 160-byte FILE_WRITE frames)
            n = min(len(data), len(self._tx) - self._echo_pos)
            want = self._tx[self._echo_pos : self._echo_pos + n]
            if data[:n] == want:
                self._echo_pos += n
                i = n
            else:
                i = next(k for k in range(n) if data[k] != want[k])
                self._echo_pos += i
                self.stats.collisions += 1  # someone else drove the wire
                self.echo_late_at = t  # the rest of our frame may still come
                self._end_tx(failed=True)
            if self._tx is not None and self._echo_pos == len(self._tx):
                self._tx_end = t
                self._end_tx(failed=False)
        if i < len(data):
            self.frames.extend(self.decoder.feed(data[i:]))

    def _end_tx(self, failed: bool):
        self._tx = None
        self._tx_failed = failed
        if failed:
            self.port.discard_output()

    def send(self, frame: bytes) -> float:
        """Puts a frame on the wire (the caller listened before talking).
        Returns when it left the wire (T_end): its last echo byte arrived,
        or, without echo, the UART drained and len * C passed. Raises
        Collision if the echo differs, EchoTimeout if it never comes."""
        start = now()
        self._tx, self._echo_pos, self._tx_failed = frame, 0, False
        self.last_tx = frame
        self.port.write(frame)
        self.stats.tx_frames += 1
        self.stats.tx_bytes += len(frame)
        end = start + len(frame) * self.char
        if not self.echo:
            self.port.drain()
            self._tx = None
            while now() < end:
                self.pump(end)
            t = now()
            self.last_rx = max(self.last_rx, t)  # our bytes kept the line busy until now
            return t
        # The echo cannot be whole before `end`: sleep until the last few
        # characters are due instead of reading the bytes as a paced line
        # hands them over (21 reads of a 160-byte frame at 2 Mbit/s, each a
        # Python pass; the FILE_WRITE upload ran at 0.73 of its wire bound).
        # A collision is still seen, at the end of our frame.
        wake = end - ECHO_WAKE_CHARS * self.char
        if self.deadline is not None:
            wake = min(wake, self.deadline)
        early = wake - now()
        if early > 0.0:
            time.sleep(early)
        while True:
            self.pump(end + self.echo_timeout)
            if self._tx is None:
                break
            if self.polled >= end + self.echo_timeout:
                self.stats.echo_timeouts += 1
                self.echo_late_at = self.polled
                self._end_tx(failed=True)
                raise EchoTimeout("our bytes did not come back (no echo: wiring, or use --no-echo)")
        if self._tx_failed:
            raise Collision("the echo differed from what we sent (another talker)")
        return self._tx_end


# ---- the master ----


@dataclass
class MasterConfig:
    resp_latency_s: float = 0.050  # reply start window; libdan's default is 10 ms,
    # our Linux tools use 50 ms (USB adapters, ptys)
    gap_s: float = 0.020  # inter-byte gap that ends a frame (Linux tools: 20 ms)
    busy_timeout_s: float = 0.200  # give up waiting for an idle line
    settle_s: float = 0.002  # pause after a baud switch
    retries: int = 2  # extra attempts per transaction
    discovery_attempts: int = 2  # attempts per type per baud when probing
    lbt_chars: int = 3  # idle characters before talking (at least 2)
    scan_all_bauds: bool = True  # probe types missing at 9600 at the other bauds
    max_baud: int = 0  # highest baud the port can do (0: no limit, no fast bauds)
    seed: Optional[int] = None  # backoff jitter seed (default: the process id)


@dataclass
class MasterStats:
    transactions: int = 0
    ok: int = 0
    timeouts: int = 0  # attempts that got no reply
    retries: int = 0
    remote_errors: int = 0  # error frames received for our request
    stray: int = 0  # frames that answered nothing we asked
    lbt_waits: int = 0  # transmissions delayed by a busy line
    busy_failures: int = 0  # the line never went idle
    recoveries: int = 0  # configure failed and was recovered
    bad_replies: int = 0  # replies refused by the reply check (retried)


@dataclass
class Peer:
    type: PeripheralType
    identity: Optional[Identity] = None
    baud: int = 0  # the baud it answers at
    present: bool = False
    refused_fast: bool = False  # refused a fast baud: asked first next time

    def as_dict(self) -> dict:
        d = {"type": self.type.name, "first_code": self.type.first, "baud": self.baud}
        if self.identity is not None:
            d.update(self.identity.as_dict())
        return d


class Master:
    """One master on one port. types: the PeripheralType list to probe."""

    def __init__(
        self,
        port,
        types: list[PeripheralType],
        baud: int = BASE_BAUD,
        config: Optional[MasterConfig] = None,
        echo: bool = True,
        progress: Optional[Callable[[str], None]] = None,
    ):
        self.cfg = config or MasterConfig()
        self.cfg.lbt_chars = max(self.cfg.lbt_chars, 2)  # our rule: never less than 2
        self.cfg.discovery_attempts = max(self.cfg.discovery_attempts, 1)
        self.link = Link(port, baud, echo, self.cfg.gap_s, self.cfg.resp_latency_s)
        self.peers = [Peer(t) for t in types]
        self.stats = MasterStats()
        self.rng = random.Random(os.getpid() if self.cfg.seed is None else self.cfg.seed)
        self.progress = progress or (lambda msg: None)
        self._tried: set[int] = set()  # bauds configure tried (recovery looks there)
        self.wait_until = 0.0  # not before: backoff, or settling after a baud switch
        # An optional check of a reply's payload beyond the frame CRC (the
        # gateway's seal): reply_check(code, payload) -> bool; False makes
        # the attempt fail and the transaction retry (libdan's
        # dan_master_set_reply_check()).
        self.reply_check: Optional[Callable[[int, bytes], bool]] = None

    @property
    def baud(self) -> int:
        return self.link.baud

    def present(self) -> list[Peer]:
        return [p for p in self.peers if p.present]

    def set_time_limit(self, seconds: Optional[float]):
        """Operations started from now raise OperationTimeout after seconds."""
        self.link.deadline = None if seconds is None else now() + seconds

    def stats_dict(self) -> dict:
        """Every counter, named as dan-master's `stats` step names them."""
        d = asdict(self.stats)
        d.update(asdict(self.link.stats))
        dec = self.link.decoder.stats.as_dict()
        d["rx_frames"] = dec.pop("frames")
        d.update(dec)
        return d

    def _port_supports(self, baud: int) -> bool:
        return self.cfg.max_baud == 0 or baud <= self.cfg.max_baud

    def fast_bauds(self) -> list[int]:
        """The fast bauds the port can do, highest first (none without max_baud)."""
        return [b for b in reversed(FAST_BAUDS) if b <= self.cfg.max_baud]

    def scan_bauds(self) -> list[int]:
        """Where to look for peers: 9600, the bauds this master tried to
        configure (a peer that acknowledged and then failed may sit there),
        the fast bauds, then the mask bauds from the highest down."""
        order = [BASE_BAUD] + sorted(self._tried, reverse=True) + self.fast_bauds()
        order += [b for b in DISCOVERY_BAUDS if self._port_supports(b)]
        return list(dict.fromkeys(order))

    def switch_baud(self, baud: int):
        """Talks at baud from now on (the caller knows the bus is there)."""
        self._switch_baud(baud)

    def _switch_baud(self, baud: int):
        if self.link.baud != baud:
            self.link.set_baud(baud)
            self.wait_until = now() + self.cfg.settle_s

    # ---- transactions ----

    def _listen_before_talk(self, busy_since: float):
        counted = False
        while True:
            self.link.pump()
            t = self.link.polled
            if t < self.wait_until:
                self.link.pump(self.wait_until)
                continue
            if self.link.idle(t) >= self.cfg.lbt_chars * self.link.char:
                return
            if t - busy_since >= self.cfg.busy_timeout_s:
                self.stats.busy_failures += 1
                raise Busy(f"the line was never idle for {self.cfg.busy_timeout_s * 1000:.0f} ms")
            if not counted:
                self.stats.lbt_waits += 1
                counted = True
            self.link.pump(
                min(self.link.next_idle(self.cfg.lbt_chars), busy_since + self.cfg.busy_timeout_s)
            )

    def _await_reply(self, code: int, deadline: float) -> bytes:
        """The reply must start by deadline; once bytes arrive we wait while
        they keep coming, at most a maximal frame longer."""
        link = self.link
        while True:
            while link.frames:
                f = link.frames.popleft()
                if link.is_late_echo(f, link.polled):
                    self.stats.stray += 1  # our own request, echoed late: not its reply
                    continue
                if f.code == code:
                    if self.reply_check is not None and not self.reply_check(code, f.payload):
                        self.stats.bad_replies += 1
                        raise BadReply(f"reply to 0x{code:02X} failed its check")
                    return f.payload
                if f.code == CODE_ERROR:
                    try:
                        e = ErrorMessage.decode(f.payload)
                    except PayloadError:
                        e = None
                    if e is not None and e.code == code:
                        self.stats.remote_errors += 1
                        raise RemoteError(e)  # understood and refused: no retry
                self.stats.stray += 1
            t = link.polled  # every byte that came before t was handled
            until = deadline
            if t >= deadline:
                # The tail of a reply that started in time: at least the gap,
                # since at fast bauds a whole frame is shorter than an
                # adapter's burst latency (PROTOCOL.md section 6).
                last = deadline + max(MAX_FRAME * link.char, link.gap)
                if link.idle(t) >= link.gap or t >= last:
                    self.stats.timeouts += 1
                    raise DanTimeout(f"no answer to 0x{code:02X} at {link.baud} baud")
                until = min(link.last_rx + link.gap, last)
            link.pump(until)

    def request(self, code: int, payload: bytes = b"", attempts: Optional[int] = None) -> bytes:
        """One transaction: sends code with payload and returns the payload
        of the reply with the same code. Retries timeouts, collisions and
        replies the reply check refused; an error frame for our code raises RemoteError at once."""
        attempts = attempts or self.cfg.retries + 1
        frame = encode_frame(code, payload)
        self.stats.transactions += 1
        attempt = 0
        busy_since = now()
        while True:
            self._listen_before_talk(busy_since)
            self.stats.stray += len(self.link.frames)
            self.link.frames.clear()
            try:
                t_end = self.link.send(frame)
                reply = self._await_reply(
                    code, t_end + TURNAROUND_CHARS * self.link.char + self.cfg.resp_latency_s
                )
                self.stats.ok += 1
                return reply
            except (DanTimeout, Collision, BadReply) as e:
                failure = e
            attempts -= 1
            if attempts <= 0:
                raise failure
            self.stats.retries += 1
            attempt += 1
            # random backoff: [0, 8 * 2^k) characters, k = min(attempt, 4)
            t = now()
            self.wait_until = t + self.rng.randrange(8 << min(attempt, 4)) * self.link.char
            busy_since = t

    def _identify(self, peer: Peer, attempts: int) -> bytes:
        return self.request(peer.type.identify, b"", attempts)

    def _configure_peer(self, peer: Peer, baud: int) -> None:
        """CONFIGURE(baud); raises Nack for ACK-FAIL, Malformed for a bad ACK."""
        reply = self.request(peer.type.configure, Configure(payloads.CONFIGURE_BPS, baud).encode())
        try:
            ack = payloads.decode_ack(reply)
        except PayloadError as e:
            raise Malformed(f"{peer.type.name}: bad ACK: {e}") from None
        if ack != ACK_OK:
            raise Nack(f"{peer.type.name} refused {baud} baud (ACK-FAIL)")

    # ---- discovery ----

    def _probe(self, peers: list[Peer], baud: int):
        """IDENTIFY each of peers at baud; the ones answering are present there."""
        self._switch_baud(baud)
        self.progress(f"probing {', '.join(p.type.name for p in peers)} at {baud} baud")
        for p in peers:
            try:
                p.identity = Identity.decode(self._identify(p, self.cfg.discovery_attempts))
            except OperationTimeout:
                raise
            except (DanError, PayloadError):
                continue
            p.present, p.baud = True, baud
            self.progress(
                f"found {p.type.name} at {baud} baud: {p.identity.manufacturer} {p.identity.model}"
            )

    def probe(self, baud: int) -> list[Peer]:
        """A quick look at one baud (a bus believed to be there): IDENTIFY
        every type at baud only. Returns the peers that answered (maybe
        none) and leaves the bus at baud."""
        for p in self.peers:
            p.present, p.identity = False, None
        self._probe(self.peers, baud)
        return self.present()

    def discover(self) -> list[Peer]:
        """IDENTIFY every type at 9600, then the missing ones at the other
        discovery bauds. Leaves the bus at the baud of the first peer
        found. Raises NotFound if nobody answered."""
        for p in self.peers:
            p.present, p.identity = False, None
        for i, baud in enumerate(self.scan_bauds()):
            missing = [p for p in self.peers if not p.present]
            if not missing or (i > 0 and not self.cfg.scan_all_bauds):
                break
            self._probe(missing, baud)
        found = self.present()
        if not found:
            raise NotFound("no peripheral answered")
        self._switch_baud(found[0].baud)
        return found

    # ---- configure ----

    def best_baud(self) -> int:
        """The highest baud every present peer and the port support."""
        found = self.present()
        if not found:
            return BASE_BAUD
        mask = MASK_DEFINED
        for p in found:
            mask &= p.identity.baud_mask
        for b in reversed(MASK_BAUDS):
            if mask & payloads.mask_bit_of_baud(b) and self._port_supports(b):
                return b
        return BASE_BAUD

    def configure(self, baud: int = 0) -> int:
        """Moves every present peer to baud (0: the fast bauds of the port
        from the highest down, then best_baud()), switches, and verifies each
        one there. On failure, recovers the bus to 9600 and raises the
        original error. A fast baud some peer refuses (ACK-FAIL) leaves the
        bus where it was: for an explicit baud the refusal is raised.
        Running out of time (--timeout) or a Ctrl-C mid-way also recovers,
        within RECOVER_S more, before it is raised: a configure cut short
        left the bus split over two bauds. Returns the bus baud."""
        try:
            return self._configure(baud)
        except (OperationTimeout, KeyboardInterrupt) as e:
            with self.time_to_recover():
                try:
                    self._recover(e if isinstance(e, DanError) else OperationTimeout("interrupted"))
                except DanError:
                    pass  # recovered as far as it could: the cause is what counts
            raise

    @contextmanager
    def time_to_recover(self):
        """RECOVER_S from now for the clean-up of an operation cut short
        (--timeout, Ctrl-C): the operation's own time limit is back after."""
        deadline = self.link.deadline
        self.link.deadline = now() + RECOVER_S
        try:
            yield
        finally:
            self.link.deadline = deadline

    def _configure(self, baud: int) -> int:
        if baud and baud > BASE_BAUD and baud not in payloads.MASK_BAUDS:
            if not self._try_fast(baud):
                raise Nack(f"a peripheral refused {baud} baud; bus kept at {self.baud}")
            return baud
        if not baud:
            for c in self.fast_bauds():
                try:
                    if self._try_fast(c):
                        return c
                except OperationTimeout:
                    raise
                except DanError as e:
                    # Recovered to 9600: a peer acknowledged and was not
                    # there. It is not trusted with another fast baud.
                    self.progress(f"{c} baud failed ({e}); going on with the draft's bauds")
                    break
        return self._configure_mask(baud or self.best_baud())

    def _try_fast(self, target: int) -> bool:
        """One fast-baud offer. True: every peer verified at target. False:
        some peer refused; the peers already moved were moved back and the
        bus is where it was. Any other failure: recovery, raised."""
        found = self.present()
        if not found:
            raise NotFound("no peripheral discovered")
        if not self._port_supports(target):
            raise Unsupported(f"the port does not do {target} baud")
        self._tried.add(target)
        back = {id(p): p.baud for p in found}
        moved: list[Peer] = []
        try:
            for p in sorted(found, key=lambda q: not q.refused_fast):
                if p.baud == target:
                    continue
                if not self._offer(p, target):
                    self._move_back(moved, target, back)
                    return False
                moved.append(p)
            self._verify(found, target)
        except OperationTimeout:
            raise
        except DanError as e:
            for p in found:
                if p.baud == target or p in moved:
                    p.refused_fast = True  # failed it: asked first from now on
            self._recover(e)
        return True

    def _offer(self, p: Peer, target: int) -> bool:
        """CONFIGURE(target) at the peer's baud: False if it refused."""
        self._switch_baud(p.baud)
        self.progress(f"CONFIGURE {p.type.name} to {target} baud (at {p.baud})")
        try:
            self._configure_peer(p, target)
        except (Nack, RemoteError):
            p.refused_fast = True
            self.progress(f"{p.type.name} refused {target} baud")
            return False
        except OperationTimeout:
            raise
        except DanTimeout:
            pass  # maybe moved with another type of its device: verification decides
        p.baud = target
        return True

    def _move_back(self, moved: list[Peer], target: int, back: dict):
        """The peers that accepted a fast baud another refused go back to
        where they were, and are verified there."""
        if not moved:
            return
        self._switch_baud(target)
        for p in moved:
            self.progress(f"CONFIGURE {p.type.name} back to {back[id(p)]} baud")
            self._configure_peer(p, back[id(p)])
            p.baud = back[id(p)]
        for p in moved:
            self._switch_baud(p.baud)
            self._identify(p, self.cfg.retries + 1)

    def _verify(self, peers: list[Peer], baud: int):
        self._switch_baud(baud)
        self.progress(f"verifying at {baud} baud")
        for p in peers:
            self._identify(p, self.cfg.retries + 1)

    def _configure_mask(self, target: int) -> int:
        """configure() to a baud of the draft's mask."""
        found = self.present()
        for p in found:
            if not payloads.supports(p.identity.baud_mask, target):
                raise Unsupported(
                    f"{p.type.name} does not support {target} baud "
                    f"(it does {', '.join(map(str, p.identity.bauds))})"
                )
        if not found:
            raise NotFound("no peripheral discovered")
        if not self._port_supports(target):
            raise Unsupported(f"the port does not do {target} baud")
        try:
            for p in found:
                if p.baud == target:
                    continue
                self._switch_baud(p.baud)
                self.progress(f"CONFIGURE {p.type.name} to {target} baud (at {p.baud})")
                try:
                    self._configure_peer(p, target)
                except OperationTimeout:
                    raise
                except DanTimeout:
                    # No answer: a device serving several types moved them all
                    # with its first CONFIGURE. Verification decides.
                    pass
                p.baud = target  # it switches once its ACK has left
            self._verify(found, target)
        except OperationTimeout:
            raise
        except DanError as e:
            self._recover(e)
        return target

    def _recover(self, why: DanError):
        """Brings every peer it can find back to 9600, drops the others,
        verifies at 9600, then raises why."""
        self.stats.recoveries += 1
        self.progress(f"configure failed ({why}); recovering the bus to {BASE_BAUD} baud")
        for p in self.present():
            candidates = [p.baud] + [b for b in self.scan_bauds() if b != p.baud]
            for b in candidates:
                self._switch_baud(b)
                try:
                    self._identify(p, self.cfg.discovery_attempts)
                except OperationTimeout:
                    raise
                except DanError:
                    continue
                p.baud = b
                break
            else:
                p.present = False  # lost
                continue
            if p.baud != BASE_BAUD:
                try:
                    self._configure_peer(p, BASE_BAUD)
                    p.baud = BASE_BAUD
                except OperationTimeout:
                    raise
                except DanError:
                    p.present = False  # cannot be brought to a common baud
        self._switch_baud(BASE_BAUD)
        for p in self.present():
            try:
                self._identify(p, self.cfg.retries + 1)
            except OperationTimeout:
                raise
            except DanError:
                p.present = False
        raise why
