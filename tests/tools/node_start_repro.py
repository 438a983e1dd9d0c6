#!/usr/bin/env python3
"""Reproduction: pydronecan SLCAN nodes made one after another in a process
where another thread holds a lock the I/O child needs if it is forked.

    .venv/bin/python tests/tools/node_start_repro.py --nodes 200 --method spawn
    .venv/bin/python tests/tools/node_start_repro.py --nodes 20 --method fork --py-spy PATH

A thread writes log lines to a root handler whose stream is a buffered pipe
drained slowly (so the stream's buffer lock is held while it waits in
write()); one node is up (its log proxy thread runs); then --nodes more
are made on a second hub port and closed. Prints one JSON line: started,
failed, seconds per node. With --py-spy, the first stuck child's stacks
are printed to stderr. --method default is the helper's (spawn).
"""

import argparse
import json
import logging
import multiprocessing
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host_tools"))
import procgroup  # noqa: E402
import pydronecan_nodes  # noqa: E402


class BusyLogger:
    """A thread that keeps a stream lock held: log lines into a buffered
    pipe that another thread drains slowly. The handler is on the root
    logger too, which is what a forked I/O child inherits and logs to."""

    def __init__(self):
        r, w = os.pipe()
        self.rfd = r
        self.stream = os.fdopen(w, "w", buffering=8192)
        self.handler = logging.StreamHandler(self.stream)
        self.log = logging.getLogger("busy")
        self.log.propagate = False
        self.log.addHandler(self.handler)
        self.log.setLevel(logging.INFO)
        self.root = logging.getLogger()
        self.old_level = self.root.level
        self.root.addHandler(self.handler)
        self.root.setLevel(logging.INFO)
        self.stop = threading.Event()
        self.lines = 0
        self.threads = [
            threading.Thread(target=self._write, daemon=True),
            threading.Thread(target=self._drain, daemon=True),
        ]
        for t in self.threads:
            t.start()
        end = time.monotonic() + 10
        while self.lines < 1000 and time.monotonic() < end:
            time.sleep(0.01)

    def _write(self):
        while not self.stop.is_set():
            self.log.info("x" * 200)
            self.lines += 1

    def _drain(self):
        while True:
            try:
                if not os.read(self.rfd, 4096):
                    return
            except OSError:
                return
            if not self.stop.is_set():
                time.sleep(0.02)

    def close(self):
        self.stop.set()
        self.root.removeHandler(self.handler)
        self.root.setLevel(self.old_level)
        self.threads[0].join(10)
        self.log.removeHandler(self.handler)
        self.stream.close()
        self.threads[1].join(10)
        os.close(self.rfd)


def start_hub(tmp):
    p = subprocess.Popen(
        procgroup.host_tool("slcan_hub.py", "-n", "2", "--link", str(Path(tmp) / "can")),
        stdout=subprocess.PIPE,
        stdin=subprocess.DEVNULL,
    )
    line = p.stdout.readline().decode()
    if not line.startswith("READY"):
        raise RuntimeError(f"slcan_hub did not start: {line!r}")
    return p, [Path(tmp) / "can0", Path(tmp) / "can1"]


def py_spy_children(py_spy):
    kids = subprocess.run(
        ["pgrep", "-P", str(os.getpid())], capture_output=True, text=True
    ).stdout.split()
    for k in kids:
        out = subprocess.run([py_spy, "dump", "--pid", k], capture_output=True, text=True)
        print(f"--- py-spy dump of child {k}\n{out.stdout}{out.stderr}", file=sys.stderr)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--nodes", type=int, default=50)
    ap.add_argument("--method", choices=("default", "spawn", "fork"), default="default")
    ap.add_argument(
        "--init-timeout",
        type=float,
        default=4.0,
        help="pydronecan's wait for a child's start (its default: 10 s)",
    )
    ap.add_argument("--py-spy", metavar="PATH", help="dump the first stuck child with py-spy")
    args = ap.parse_args()
    if args.nodes < 1:
        ap.error("--nodes must be at least 1")
    if args.method == "default":
        pydronecan_nodes.use_spawn()
    else:
        multiprocessing.set_start_method(args.method, force=True)
    import dronecan.driver.slcan as slcan

    slcan.IO_PROCESS_INIT_TIMEOUT = args.init_timeout

    def make(port, node_id):
        return dronecan.make_node("slcan:" + str(port), node_id=node_id, bitrate=1000000)

    import dronecan

    with tempfile.TemporaryDirectory() as tmp:
        hub, links = start_hub(tmp)
        started = failed = 0
        t0 = time.monotonic()
        try:
            first = make(links[0], 20)
            busy = BusyLogger()
            try:
                for _ in range(args.nodes):
                    try:
                        make(links[1], 21).close()
                        started += 1
                    except slcan.DriverError:
                        if failed == 0 and args.py_spy:
                            py_spy_children(args.py_spy)
                        failed += 1
            finally:
                busy.close()
                first.close()
        finally:
            hub.terminate()
            hub.wait(10)
        per = (time.monotonic() - t0) / args.nodes
        print(
            json.dumps(
                {
                    "method": multiprocessing.get_start_method(),
                    "nodes": args.nodes,
                    "started": started,
                    "failed": failed,
                    "s_per_node": round(per, 3),
                }
            )
        )
    return 0 if failed == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
