"""Passive decoding of a DAN line: byte chunks with their time (and source
when known) in, events out. Used on a live port and on dan-vbus capture
files (docs/VBUS.md, "Capture format")."""

import bisect
import math
from dataclasses import dataclass, field
from typing import NamedTuple, Optional

from danprobe.codec import Decoder, Frame
from danprobe.master import GAP_CHARS, GAP_MIN_S, TURNAROUND_CHARS, char_s
from danprobe.registry import CODE_ERROR, REQUEST, RESPONSE, code_name, describe

DECODER_ERRORS = ("crc_errors", "oversize", "bad_varint", "aborted")


class _Chunk(NamedTuple):
    offset: int  # stream offset of its first byte
    time: float  # when its first byte started on the wire
    source: Optional[int]
    baud: int


@dataclass
class Event:
    kind: str  # "frame" or a decoder counter name ("crc_errors", ...)
    time: float
    source: Optional[int] = None
    baud: int = 0
    code: int = 0
    name: str = ""
    role: Optional[str] = None  # "request" / "response" (a guess from the sequence)
    payload: bytes = b""
    fields: Optional[dict] = None  # decoded payload, when the code has a describer
    problem: str = ""  # why the payload did not decode
    gap: Optional[float] = None  # seconds since the previous frame ended
    size: int = 0

    def as_dict(self) -> dict:
        d = {
            "event": "frame" if self.kind == "frame" else "error",
            "time": round(self.time, 6),
            "source": self.source,
            "baud": self.baud,
        }
        if self.kind != "frame":
            d["kind"] = self.kind
            return d
        d.update(
            code=self.code,
            name=self.name,
            role=self.role,
            payload=self.payload.hex(),
            fields=self.fields,
            gap_ms=None if self.gap is None else round(self.gap * 1000, 3),
        )
        if self.problem:
            d["problem"] = self.problem
        return d


@dataclass
class Counters:
    frames: int = 0
    by_name: dict[str, int] = field(default_factory=dict)
    bursts: int = 0
    collision_bursts: int = 0  # capture flags
    noise_bursts: int = 0


class Sniffer:
    """reply_window_s: a frame with the request's code is taken for its
    response only if it starts within TURNAROUND + this after the request
    (the master's own response deadline; later ones are retries)."""

    def __init__(self, reply_window_s: float = 0.050):
        self.reply_window_s = reply_window_s
        self.decoder = Decoder()
        self.counters = Counters()
        self._chunks: list[_Chunk] = []
        self._prev: Optional[Event] = None
        self._prev_end: Optional[float] = None

    def _chunk_of(self, offset: int) -> _Chunk:
        i = bisect.bisect_right([c.offset for c in self._chunks], offset) - 1
        return self._chunks[max(i, 0)]

    def _frame_event(self, f: Frame) -> Event:
        c = self._chunk_of(f.start)
        t = c.time + (f.start - c.offset) * char_s(c.baud)
        prev = self._prev
        gap = None if self._prev_end is None else max(t - self._prev_end, 0.0)
        if f.code == CODE_ERROR:
            role = RESPONSE
        elif (
            prev is not None
            and prev.code == f.code
            and prev.role == REQUEST
            and (prev.source is None or c.source is None or prev.source != c.source)
            and gap <= TURNAROUND_CHARS * char_s(prev.baud) + self.reply_window_s
        ):
            role = RESPONSE
        else:
            role = REQUEST
        role, fields, problem = describe(f.code, f.payload, role)
        ev = Event(
            "frame",
            t,
            c.source,
            c.baud,
            f.code,
            code_name(f.code),
            role,
            f.payload,
            fields,
            problem,
            gap,
            f.size,
        )
        self._prev = ev
        self._prev_end = t + f.size * char_s(c.baud)
        self.counters.frames += 1
        self.counters.by_name[ev.name] = self.counters.by_name.get(ev.name, 0) + 1
        return ev

    def _run(self, fn, time: float, source: Optional[int], baud: int) -> list[Event]:
        before = self.decoder.stats.as_dict()
        frames = fn()
        after = self.decoder.stats.as_dict()
        events = [
            Event(k, time, source, baud)
            for k in DECODER_ERRORS
            for _ in range(after[k] - before[k])
        ]
        events += [self._frame_event(f) for f in frames]
        events.sort(key=lambda e: e.time)
        first = self.decoder.consumed - len(self.decoder.buf)
        self._chunks = [
            c
            for i, c in enumerate(self._chunks)
            if i + 1 == len(self._chunks) or self._chunks[i + 1].offset > first
        ]
        return events

    def feed(
        self, data: bytes, time: float, source: Optional[int] = None, baud: int = 9600
    ) -> list[Event]:
        """Bytes heard on the line; time is when the first one started."""
        self._chunks.append(_Chunk(self.decoder.consumed, time, source, baud))
        return self._run(lambda: self.decoder.feed(data), time, source, baud)

    def busy(self) -> bool:
        return self.decoder.busy()

    def idle(self, time: float, baud: int = 9600) -> list[Event]:
        """The line went idle: a partial frame is dropped (an "aborted" event)."""
        return self._run(self.decoder.drain, time, None, baud)

    def summary(self) -> dict:
        d = self.decoder.stats.as_dict()
        d["frames_by_name"] = dict(sorted(self.counters.by_name.items()))
        if self.counters.bursts:
            d.update(
                bursts=self.counters.bursts,
                collision_bursts=self.counters.collision_bursts,
                noise_bursts=self.counters.noise_bursts,
            )
        return d


def libdan_gap_s(baud: int) -> float:
    """libdan's default inter-byte gap at baud: max(10 C, 2 ms)."""
    return max(GAP_CHARS * char_s(baud), GAP_MIN_S)


class CaptureError(ValueError):
    pass


class Burst(NamedTuple):
    time: float
    source: int
    baud: int
    data: bytes  # the bytes on the wire (after corruption, if flagged)
    flags: list[str]


def read_capture(path) -> list[Burst]:
    """The bursts of a dan-vbus capture file, in start-time order."""
    bursts = []
    with open(path, encoding="ascii", errors="replace") as f:
        for lineno, line in enumerate(f, 1):
            line = line.strip()
            if not line or line.startswith("#"):
                continue
            fields = line.split()
            try:
                t, src, baud, data = (
                    float(fields[0]),
                    int(fields[1]),
                    int(fields[2]),
                    bytes.fromhex(fields[3]),
                )
                flags = [x for x in fields[4:] if not x.startswith("rx=")]
                rx = [x[3:] for x in fields[4:] if x.startswith("rx=")]
                if rx:
                    data = bytes.fromhex(rx[0])
                if baud <= 0 or not math.isfinite(t):
                    raise ValueError("baud 0 (char_s divides by it) or no time")
            except (IndexError, ValueError):
                raise CaptureError(
                    f"{path}:{lineno}: not a dan-vbus capture line: {line[:60]!r}"
                ) from None
            bursts.append(Burst(t, src, baud, data, flags))
    bursts.sort(key=lambda b: b.time)
    return bursts


def sniff_capture(bursts: list[Burst], sniffer: Sniffer):
    """Yields the events of a capture: the line is idle between bursts
    further apart than libdan's gap, and at a baud change."""
    end, baud = None, None
    for b in bursts:
        if end is not None and (b.baud != baud or b.time - end >= libdan_gap_s(baud)):
            yield from sniffer.idle(end, baud)
        sniffer.counters.bursts += 1
        sniffer.counters.collision_bursts += "collision" in b.flags
        sniffer.counters.noise_bursts += "noise" in b.flags
        yield from sniffer.feed(b.data, b.time, b.source, b.baud)
        end, baud = b.time + len(b.data) * char_s(b.baud), b.baud
    if end is not None:
        yield from sniffer.idle(end, baud)
