#!/usr/bin/env python3
"""A DroneCAN node with a firmware-update bootloader, for the file server's
end-to-end tests: the reader of the gateway's uavcan.protocol.file.Read.

    .venv/bin/python tests/e2e/fw_bootloader.py --port /tmp/can1 --node-id 60
        --expect IMAGE [--chunk 256] [--pipeline 1] [--stall-after N]
        [--new-version 2.0]

It publishes NodeStatus (mode OPERATIONAL) and answers GetNodeInfo with
software version 1.0. On uavcan.protocol.file.BeginFirmwareUpdate it
answers ERROR_OK (IN_PROGRESS while one runs), goes to mode
SOFTWARE_UPDATE and reads the image path from source_node_id (0: the
caller) with file.Read: offsets 0, chunk, 2 x chunk, ... (--pipeline reads
in flight; a read unanswered within 2 s is sent again, 10 times at most),
keeping chunk bytes of each answer, until an answer shorter than chunk (the
end: ArduPilot's AP_Bootloader reads 256 at a time, 4 in flight, and stops
at the first short read; it asks no GetInfo). Then it compares what it read
with --expect and, when equal, "restarts" into the new firmware: uptime
back to 0, mode OPERATIONAL, GetNodeInfo answers --new-version. An answer
with an error, a mismatch or no answer ends the update as failed (mode
OPERATIONAL, old version, no restart). --stall-after N stops reading once
N bytes are in (stays in SOFTWARE_UPDATE: a bootloader that hangs).

Prints READY when up, a JSON line {"event": "end", ...the result} when an
update ends, and on SIGTERM or SIGINT one JSON line, the result:
{"event": "exit", "node_id", "state": idle|reading|stalled|done|failed, "bytes",
"reads", "retries", "error" (the file error code, 0 none), "equal",
"source", "path", "version", "seconds" (BeginFirmwareUpdate to the end
of the reads)} and exits 0. Standard pydronecan (its I/O
child starts with spawn, host_tools/pydronecan_nodes.py).
"""

import argparse
import json
import signal
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host_tools"))
import pydronecan_nodes  # noqa: E402

READ_TIMEOUT_S = 2.0  # generous: a loaded host delays the answers
READ_TRIES = 10
OLD_VERSION = (1, 0)


class Bootloader:
    def __init__(self, node, expect, chunk, pipeline, stall_after, new_version):
        import dronecan

        self.U = dronecan.uavcan
        self.node = node
        self.expect, self.chunk, self.pipeline = expect, chunk, pipeline
        self.stall_after, self.new_version = stall_after, new_version
        self.state = "idle"
        self.source, self.path = 0, ""
        self.data = {}  # offset -> bytes kept
        self.inflight = {}  # offset -> tries
        self.next_offset = 0
        self.end = None  # where the image ends, once a short answer came
        self.reads = self.retries = self.error = 0
        self.equal = False
        self.began = self.seconds = None
        self.set_version(OLD_VERSION)
        node.mode = self.U.protocol.NodeStatus().MODE_OPERATIONAL
        node.add_handler(self.U.protocol.file.BeginFirmwareUpdate, self.on_begin)

    def set_version(self, v):
        self.version = v
        self.node.node_info.software_version.major = v[0]
        self.node.node_info.software_version.minor = v[1]

    def on_begin(self, e):
        R = self.U.protocol.file.BeginFirmwareUpdate.Response
        if self.state == "reading":
            return R(error=R().ERROR_IN_PROGRESS)
        q = e.request
        self.source = q.source_node_id or e.transfer.source_node_id
        self.path = bytes(q.image_file_remote_path.path).decode("latin-1")
        self.state = "reading"
        self.data, self.inflight, self.next_offset, self.end = {}, {}, 0, None
        self.error = 0
        self.began = time.monotonic()
        self.node.mode = self.U.protocol.NodeStatus().MODE_SOFTWARE_UPDATE
        return R(error=R().ERROR_OK)

    def have(self):
        return sum(len(b) for b in self.data.values())

    def pump(self):
        """Keeps --pipeline reads in flight; called from the spin loop."""
        if self.state != "reading":
            return
        if self.stall_after >= 0 and self.have() >= self.stall_after:
            self.state = "stalled"
            return
        while len(self.inflight) < self.pipeline and (
            self.end is None or self.next_offset < self.end
        ):
            self.send_read(self.next_offset)
            self.next_offset += self.chunk

    def send_read(self, offset):
        tries = self.inflight.get(offset, 0)
        if tries >= READ_TRIES:
            self.finish(False)
            return
        self.retries += tries > 0
        self.inflight[offset] = tries + 1
        req = self.U.protocol.file.Read.Request(
            offset=offset, path=self.U.protocol.file.Path(path=self.path)
        )
        self.node.request(
            req,
            self.source,
            lambda e, o=offset: self.on_read(o, e),
            priority=8,  # high, as AP_Bootloader's reads
            timeout=READ_TIMEOUT_S,
        )

    def on_read(self, offset, e):
        if self.state != "reading" or offset not in self.inflight:
            return
        if e is None:  # no answer: the same offset again
            self.send_read(offset)
            return
        del self.inflight[offset]
        self.reads += 1
        r = e.response
        if r.error.value != 0:
            self.error = r.error.value
            self.finish(False)
            return
        got = bytes(r.data)[: self.chunk]
        self.data[offset] = got
        if len(got) < self.chunk and (self.end is None or offset + len(got) < self.end):
            self.end = offset + len(got)
        if self.end is not None and all(o in self.data for o in range(0, self.end, self.chunk)):
            self.finish(True)

    def finish(self, complete):
        image = b"".join(
            self.data[o] for o in sorted(self.data) if self.end is None or o < self.end
        )
        self.equal = complete and image == self.expect
        self.inflight = {}
        self.seconds = round(time.monotonic() - self.began, 3)
        self.node.mode = self.U.protocol.NodeStatus().MODE_OPERATIONAL
        if self.equal:
            self.state = "done"
            self.set_version(self.new_version)
            self.node.start_time_monotonic = time.monotonic()  # the restart: uptime from 0
        else:
            self.state = "failed"
        print(json.dumps({"event": "end", **self.result()}), flush=True)

    def result(self):
        return {
            "node_id": self.node.node_id,
            "state": self.state,
            "bytes": self.have(),
            "reads": self.reads,
            "retries": self.retries,
            "error": self.error,
            "equal": self.equal,
            "source": self.source,
            "path": self.path,
            "version": "%d.%d" % self.version,
            "seconds": self.seconds,
        }


def version(s):
    major, _, minor = s.partition(".")
    return int(major), int(minor or 0)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    where = ap.add_mutually_exclusive_group(required=True)
    where.add_argument("--port", help="SLCAN tty")
    where.add_argument("--iface", help="pydronecan interface, e.g. socketcan:vcan0")
    ap.add_argument("--node-id", type=int, default=60)
    ap.add_argument("--expect", required=True, help="the image the node must read")
    ap.add_argument("--chunk", type=int, default=256, help="bytes per Read (1..256)")
    ap.add_argument("--pipeline", type=int, default=1, help="reads in flight (1..8)")
    ap.add_argument("--stall-after", type=int, default=-1, help="stop reading after N bytes")
    ap.add_argument("--new-version", type=version, default=(2, 0), help="MAJOR.MINOR")
    a = ap.parse_args()
    if not 1 <= a.node_id <= 125 or not 1 <= a.chunk <= 256 or not 1 <= a.pipeline <= 8:
        ap.error("--node-id 1..125, --chunk 1..256, --pipeline 1..8")
    expect = Path(a.expect).read_bytes()
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    signal.signal(signal.SIGINT, lambda *_: stop.append(1))
    import dronecan
    from dronecan.driver.common import DriverError

    info = dronecan.uavcan.protocol.GetNodeInfo.Response()
    info.name = "org.dan.fw_bootloader"
    info.hardware_version.unique_id = bytes([0xB0, a.node_id] + [0x42] * 14)
    if a.port:
        node = pydronecan_nodes.make_node(a.port, a.node_id, node_info=info)
    else:
        node = dronecan.make_node(a.iface, node_id=a.node_id, node_info=info)
    bl = Bootloader(node, expect, a.chunk, a.pipeline, a.stall_after, a.new_version)
    print("READY", flush=True)
    try:
        while not stop:
            try:
                node.spin(0.002)
            except (dronecan.transport.TransferError, ValueError, IndexError):
                pass  # a transfer that does not decode is skipped
            bl.pump()
    except DriverError:
        if not stop:
            raise
    finally:
        pydronecan_nodes.close_nodes([node])
    print(json.dumps({"event": "exit", **bl.result()}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
