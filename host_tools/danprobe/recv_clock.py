"""Receive times of raw CAN frames (CAN_RECV with RECV_TIMES): the
gateway's microsecond clock, low 32 bits, unwrapped here into one
continuous count, and mapped onto the host's clock.

The mapping is one fixed offset (host seconds minus gateway seconds),
estimated from the responses: a frame cannot have arrived at the gateway
after the host received the response that carries it, so
host_time - last_frame_time bounds the offset from above; the smallest such
bound seen is the estimate (the transfer time of a response is its
error). A frame's host time is its gateway time plus the offset, never
earlier than the previous one printed (the estimate only shrinks).
"""

from typing import Optional

WRAP = 1 << 32
HALF = 1 << 31


class RecvClock:
    def __init__(self):
        self.reset()
        self.restarts = 0  # the gateway's clock went backwards (it restarted)

    def reset(self):
        self.last_us: Optional[int] = None  # unwrapped time of the newest frame
        self.offset: Optional[float] = None  # seconds, host - gateway
        self.last_host: Optional[float] = None

    def unwrap(self, times_us: list[int]) -> list[int]:
        """One response's frame times (t0_us, a u32, plus the deltas) on
        the continuous count."""
        if not times_us:
            return []
        t0 = times_us[0]
        if self.last_us is None:
            base = t0
        else:
            step = (t0 - self.last_us) % WRAP
            if step >= HALF:  # backwards: a new clock
                self.restarts += 1
                self.reset()
                base = t0
            else:
                base = self.last_us + step
        out = [base + t - t0 for t in times_us]
        self.last_us = out[-1]
        return out

    def host_times(self, us: list[int], host_now: float) -> list[float]:
        """Host-clock seconds of unwrapped gateway times received with the
        response that arrived at host_now."""
        if not us:
            return []
        bound = host_now - us[-1] / 1e6
        self.offset = bound if self.offset is None else min(self.offset, bound)
        out = []
        for t in us:
            h = t / 1e6 + self.offset
            if self.last_host is not None and h < self.last_host:
                h = self.last_host
            self.last_host = h
            out.append(h)
        return out


def slcan_stamp_ms(us: int) -> int:
    """Lawicel's timestamp of a frame: milliseconds modulo 60000."""
    return (us // 1000) % 60000
