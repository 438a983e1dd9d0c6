"""A byte progress display on stderr for the file and firmware commands:
on a terminal one line redrawn in place (bar, bytes, %, rate); otherwise
(a log, a pipe) a plain line at every 10 % step, so a log stays short and
a script can follow it. Nothing with -q."""

import sys
from typing import Optional

from danprobe.port import now

WIDTH = 24
STEP_PCT = 10
RATE_AFTER_S = 0.5
REDRAW_S = 0.1  # a terminal line at most this often (and at the end)


def rate_text(bytes_per_s: float) -> str:
    if bytes_per_s >= 1e6:
        return f"{bytes_per_s / 1e6:.2f} MB/s"
    if bytes_per_s >= 1e3:
        return f"{bytes_per_s / 1e3:.1f} kB/s"
    return f"{bytes_per_s:.0f} B/s"


class Progress:
    """label: what moves ("upload fw.bin", "node 30 reads"); total bytes;
    start: bytes already there (a resumed upload: the rate counts only the
    bytes moved now)."""

    def __init__(self, label: str, total: int, start: int = 0, quiet: bool = False, stream=None):
        self.label, self.total, self.start = label, total, start
        self.stream = stream or sys.stderr
        self.quiet = quiet
        self.tty = self.stream.isatty()
        self.t0 = now()
        self.last_step: Optional[int] = None
        self.drawn = False
        self.drawn_at = 0.0

    def line(self, done: int) -> tuple[str, float]:
        pct = 100.0 * done / self.total if self.total else 100.0
        dt = now() - self.t0
        # the rate once it means something (not over the first poll's instant)
        rate = f" {rate_text((done - self.start) / dt)}" if dt >= RATE_AFTER_S else ""
        return f"{self.label}: {done}/{self.total} bytes {pct:5.1f} %{rate}", pct

    def update(self, done: int):
        if self.quiet:
            return
        text, pct = self.line(done)
        if self.tty:
            t = now()
            if done < self.total and t - self.drawn_at < REDRAW_S:
                return
            self.drawn_at = t
            filled = int(WIDTH * min(pct, 100.0) / 100)
            bar = "#" * filled + "." * (WIDTH - filled)
            self.stream.write(f"\r[{bar}] {text}\033[K")
            self.stream.flush()
            self.drawn = True
            return
        step = int(pct // STEP_PCT)
        if step != self.last_step:
            self.last_step = step
            print(text, file=self.stream, flush=True)

    def end(self):
        """Leaves the terminal line (the next message starts on its own)."""
        if self.drawn:
            self.stream.write("\n")
            self.stream.flush()
            self.drawn = False
