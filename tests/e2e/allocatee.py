"""A DroneCAN dynamic node ID allocatee made of raw CAN frames, for the
end-to-end tests: pydronecan cannot send anonymous transfers, so this one
writes its anonymous Allocation requests as SLCAN lines on a port of the
hub and reads the allocators' answers from the same port.

uavcan.protocol.dynamic_node_id.Allocation (message 1; the DSDL in
pydronecan's dsdl_specs): payload byte 0 is node_id << 1 |
first_part_of_unique_id, then the unique ID bytes (the last field: no
length). An anonymous request is one frame: CAN ID priority << 24 |
discriminator << 10 | (1 & 3) << 8, source 0; the unique ID goes out in
three stages of 6, 6 and 4 bytes, each after the allocator's answer with
everything received so far; the answer with all 16 bytes and a node ID is
the allocation.
"""

import os
import select
import time
import tty

from danprobe.gateway_msgs import crc16_ccitt_false
from danprobe.slcan_codec import Frame, format_frame, parse_frame

ALLOCATION_DTID = 1
NODE_STATUS_DTID = 341
PRIORITY = 30
STAGES = (6, 6, 4)


def allocation_payload(node_id: int, first: bool, uid_part: bytes) -> bytes:
    return bytes([(node_id << 1) | int(first)]) + uid_part


class Reassembler:
    """DroneCAN transfers from raw frames: (source, dtid, payload) of each
    complete message transfer (the CRC of a multi-frame one is dropped)."""

    def __init__(self):
        self.parts = {}

    def feed(self, f: Frame):
        if not f.ext or f.rtr or not f.data or f.id & 0x80:  # services are not ours
            return None
        src, tail = f.id & 0x7F, f.data[-1]
        dtid = (f.id >> 8) & 0xFFFF if src else (f.id >> 8) & 0x3
        key = (src, dtid)
        if tail & 0x80:  # start of transfer
            self.parts[key] = bytearray()
        if key not in self.parts:
            return None
        self.parts[key] += f.data[:-1]
        if not tail & 0x40:  # not the end yet
            return None
        data = bytes(self.parts.pop(key))
        multi = not (tail & 0x80)
        return src, dtid, data[2:] if multi else data


class Allocatee:
    """An anonymous node on an SLCAN port (a hub port's link)."""

    def __init__(self, port, unique_id: bytes):
        assert len(unique_id) == 16
        self.uid = unique_id
        self.fd = os.open(str(port), os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        tty.setraw(self.fd)
        self.buf = bytearray()
        self.rx = Reassembler()
        self.tid = 0
        self.answers = []  # (source, node_id, unique_id bytes) of every Allocation heard
        os.write(self.fd, b"S8\rO\r")

    def close(self):
        os.close(self.fd)

    def send(self, frame_id: int, payload: bytes):
        data = payload + bytes([0xC0 | (self.tid & 0x1F)])  # a single-frame transfer
        self.tid += 1
        os.write(self.fd, format_frame(Frame(frame_id, True, False, len(data), data)))

    def send_request(self, node_id: int, first: bool, part: bytes):
        payload = allocation_payload(node_id, first, part)
        disc = crc16_ccitt_false(payload) & 0x3FFF
        self.send(PRIORITY << 24 | disc << 10 | (ALLOCATION_DTID & 3) << 8, payload)

    def send_node_status(self, node_id: int, uptime: int):
        payload = uptime.to_bytes(4, "little") + bytes([0, 0, 0])  # OK, OPERATIONAL
        self.send(16 << 24 | NODE_STATUS_DTID << 8 | node_id, payload)

    def poll(self, timeout: float):
        """Reads the port for up to timeout seconds; Allocation answers land
        in .answers (and are returned)."""
        got = []
        end = time.monotonic() + timeout
        while True:
            left = end - time.monotonic()
            if left <= 0 or not select.select([self.fd], [], [], left)[0]:
                return got
            try:
                self.buf += os.read(self.fd, 4096)
            except BlockingIOError:
                continue
            while b"\r" in self.buf:
                line, _, rest = bytes(self.buf).partition(b"\r")
                self.buf = bytearray(rest)
                got += self._line(line.lstrip(b"\x07"))
            if got:
                return got

    def _line(self, line: bytes):
        if line[:1] == b"T" and len(line) > 10:
            line = line[: 10 + 2 * int(line[9:10], 16)]  # without a timestamp
        f = parse_frame(line)
        t = self.rx.feed(f) if f else None
        if t is None or t[1] != ALLOCATION_DTID or not t[0] or not t[2]:
            return []
        a = (t[0], t[2][0] >> 1, t[2][1:])
        self.answers.append(a)
        return [a]

    def allocate(self, preferred: int = 0, deadline_s: float = 60.0):
        """Runs the three stages, starting over when an answer does not come
        within a second; returns (allocator node, node ID) once an answer
        carries the whole unique ID and a node ID."""
        end = time.monotonic() + deadline_s
        while time.monotonic() < end:
            sent = 0
            self.send_request(preferred, True, self.uid[:6])
            sent = 6
            while time.monotonic() < end:
                got = [a for a in self.poll(1.0) if self.uid.startswith(a[2]) and a[2]]
                if not got:
                    break  # start over
                src, node_id, uid = got[-1]
                if len(uid) == 16 and node_id:
                    return src, node_id
                if len(uid) != sent:
                    continue
                n = STAGES[1] if sent == 6 else STAGES[2]
                self.send_request(preferred, False, self.uid[sent : sent + n])
                sent += n
            time.sleep(0.6)  # the request period's lower bound
        raise AssertionError(f"no allocation within {deadline_s} s; answers {self.answers}")
