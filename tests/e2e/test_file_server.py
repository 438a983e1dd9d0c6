"""The gateway as the bus's file server (docs/PROTOCOL.md section 7,
"Files and firmware updates"): dan-gatewayd --file-dir on dan-vbus and the
SLCAN hub, pydronecan as the independent peer. A pydronecan node starts an
update with uavcan.protocol.file.BeginFirmwareUpdate (source: the gateway,
path: an image the test put in the directory); the bootloader node
(fw_bootloader.py) reads it through the gateway with file.Read, checks it
byte for byte and restarts with a new version, which the gateway's node
table then shows (it asks GetNodeInfo again). Two bootloaders read at
once; bad paths are answered INVALID_VALUE, a missing file NOT_FOUND.

Deadlines are generous and catch hangs; nothing here asserts a speed.
"""

import json
import queue
import random
import subprocess
import sys
import threading

import dronecan
import pytest

from bus_util import danprobe, ready
from conftest import BIN, ROOT, closing_factory, wait_for
from gw_rig import GW_NODE, Rig

U = dronecan.uavcan
F = U.protocol.file
IMAGE_SIZE = 64 * 1024
SMALL_SIZE = 16 * 1024 + 100  # not a whole number of reads
COMMANDER = 90


class FileRig(Rig):
    """Rig with --file-dir tmp/fw (fw.bin: IMAGE_SIZE random bytes,
    small.bin: SMALL_SIZE) and the DAN bus at 115200 (danprobe on
    tmp/dan0); can1 is the commander's, can2.. the bootloaders'."""

    def __init__(self, procs, tmp, ncan=6):
        self.fwdir = tmp / "fw"
        self.fwdir.mkdir()
        rng = random.Random(14)
        self.image = rng.randbytes(IMAGE_SIZE)
        (self.fwdir / "fw.bin").write_bytes(self.image)
        (self.fwdir / "small.bin").write_bytes(rng.randbytes(SMALL_SIZE))
        super().__init__(procs, tmp, ncan, gw_args=("--file-dir", self.fwdir))
        self.dan = str(tmp / "dan0")
        self.dp_json("stats", "--configure")
        self.calls = queue.Queue()
        self.cmd = self.node(1, COMMANDER, "org.dan.commander")
        self.spin(self.cmd, self._send_calls, 0.005)

    def dp_json(self, *args):
        rc, out, err = danprobe(*args, "--port", self.dan, "--baud", "115200", "-q", "--json")
        assert rc == 0, (args, rc, out, err)
        return json.loads(out.splitlines()[-1])

    def _send_calls(self):  # in the commander's spin thread: pydronecan is not thread-safe
        while not self.calls.empty():
            req, dest, box = self.calls.get()
            self.cmd.request(req, dest, box.append, timeout=5)  # a loaded host is slow

    def call_start(self, req, dest):
        """Sends a service call from the commander; call_end(its result)
        waits for the response."""
        box = []
        self.calls.put((req, dest, box))
        return box

    def call_end(self, box):
        wait_for(lambda: len(box), 20, what="an answer")
        return box[0].response if box[0] is not None else None

    def call(self, req, dest):
        """A service call from the commander; the response (None: no answer)."""
        return self.call_end(self.call_start(req, dest))

    def bootloaders(self, *specs):
        """Starts fw_bootloader.py for each (hub port, node id, image name,
        options...), all at once (each takes seconds to import pydronecan);
        returns them once all are READY."""
        ps = [
            self.procs.start(
                [sys.executable, ROOT / "tests" / "e2e" / "fw_bootloader.py"]
                + ["--port", self.tmp / f"can{k}", "--node-id", node_id]
                + ["--expect", self.fwdir / image, *opts],
                name=f"fw_bootloader{node_id}",
            )
            for k, node_id, image, *opts in specs
        ]
        for p in ps:
            ready(p, "fw_bootloader")
            p.lines = queue.Queue()  # its JSON lines, read by a thread
            threading.Thread(target=self._read_lines, args=(p,), daemon=True).start()
        return ps

    @staticmethod
    def _read_lines(p):
        for line in p.stdout:
            p.lines.put(json.loads(line))

    def update_end(self, p, timeout=120):
        """The result a bootloader prints when its update ends."""
        try:
            return p.lines.get(timeout=timeout)
        except queue.Empty:
            assert self.procs.stop(p) == 0, p.log_path.read_text()
            pytest.fail(f"the update did not end: {p.lines.get(timeout=10)}")

    def result(self, p):
        """Stops a bootloader; the result it prints on exit."""
        assert self.procs.stop(p) == 0, p.log_path.read_text()
        while True:
            res = p.lines.get(timeout=10)
            if res["event"] == "exit":
                return res

    def sw_versions(self):
        """node id -> [major, minor] of the nodes whose GetNodeInfo the gateway has."""
        return {n["node_id"]: n.get("sw") for n in self.dp_json("nodes")["nodes"]}

    def modes(self):
        """node id -> mode name from its last NodeStatus, as the gateway has it."""
        return {n["node_id"]: n["mode_name"] for n in self.dp_json("nodes")["nodes"]}

    def begin(self, node_id, path):
        """BeginFirmwareUpdate sent to node_id (source: the gateway); call_end()
        of it is the node's answer."""
        req = F.BeginFirmwareUpdate.Request(
            source_node_id=GW_NODE, image_file_remote_path=F.Path(path=path)
        )
        return self.call_start(req, node_id)


@pytest.fixture
def frig(procs, tmp_path):
    yield from closing_factory(lambda **kw: FileRig(procs, tmp_path, **kw))


def wait_versions(r, want, what):
    wait_for(lambda: all(r.sw_versions().get(n) == v for n, v in want.items()), 60, 0.5, what=what)


def done(r, p, size):
    res = r.update_end(p)
    assert res["state"] == "done" and res["equal"], res
    assert res["bytes"] == size and res["error"] == 0 and res["source"] == GW_NODE, res
    return res


def check_bad_paths(r):
    """Paths that are no name: INVALID_VALUE; a missing file: NOT_FOUND."""
    for path in ("../etc/passwd", "/etc/passwd", "a/b/c", ".hidden", "//fw.bin"):
        rsp = r.call(F.Read.Request(offset=0, path=F.Path(path=path)), GW_NODE)
        assert rsp.error.value == 22 and len(rsp.data) == 0, path  # INVALID_VALUE
    rsp = r.call(F.Read.Request(offset=0, path=F.Path(path="/nope.bin")), GW_NODE)
    assert rsp.error.value == 2 and len(rsp.data) == 0  # NOT_FOUND
    rsp = r.call(F.Read.Request(offset=IMAGE_SIZE - 100, path=F.Path(path="fw.bin")), GW_NODE)
    assert rsp.error.value == 0 and bytes(rsp.data) == r.image[-100:]  # the short end
    info = r.call(F.GetInfo.Request(path=F.Path(path="../fw.bin")), GW_NODE)
    assert info.error.value == 22
    info = r.call(F.GetInfo.Request(path=F.Path(path="/fw.bin")), GW_NODE)
    assert (info.error.value, info.size, info.entry_type.flags) == (0, IMAGE_SIZE, 9)


def test_updates_through_the_gateway(frig):
    """One rig (the bootloaders take seconds each to start): a bootloader
    sent to a bad path fails with the gateway's error, then sent to the
    image it hangs after 1 KiB (a failure for the FC to see); one reads the
    64 KiB image alone, as AP_Bootloader does (256 bytes, 4 in flight), and
    the gateway's table shows its new version; then two read another image
    at once, one of them 128 bytes a step."""
    r = frig()
    bad, one, two, three = r.bootloaders(
        (2, 63, "fw.bin", "--stall-after", "1024"),
        (3, 60, "fw.bin", "--pipeline", "4"),
        (4, 61, "small.bin", "--pipeline", "4"),
        (5, 62, "small.bin", "--chunk", "128", "--pipeline", "2"),
    )
    check_bad_paths(r)
    # the bootloader accepts (it cannot know the path is bad), then fails
    assert r.call_end(r.begin(63, "../etc/passwd")).error == 0
    wait_versions(r, {60: [1, 0]}, "the bootloader's old version in the gateway's table")
    res = r.update_end(bad)
    assert res["state"] == "failed" and res["error"] == 22 and res["bytes"] == 0, res
    # sent to the right file it hangs after 1 KiB: SOFTWARE_UPDATE in the table
    assert r.call_end(r.begin(63, "fw.bin")).error == 0
    wait_for(lambda: r.modes().get(63) == "SOFTWARE_UPDATE", 60, 0.5, what="node 63 updating")
    res = r.result(bad)  # stopped: one node fewer to load the host
    assert (res["state"], res["bytes"], res["version"]) == ("stalled", 1024, "1.0"), res

    assert r.call_end(r.begin(60, "/fw.bin")).error == 0
    assert done(r, one, IMAGE_SIZE)["reads"] >= IMAGE_SIZE // 256 + 1
    wait_versions(r, {60: [2, 0]}, "the new version in the gateway's table")
    assert r.result(one)["version"] == "2.0"

    calls = [r.begin(61, "small.bin"), r.begin(62, "/small.bin")]  # at once
    assert [r.call_end(c).error for c in calls] == [0, 0]
    done(r, two, SMALL_SIZE)
    done(r, three, SMALL_SIZE)
    wait_versions(r, {61: [2, 0], 62: [2, 0]}, "both updated")


@pytest.mark.parametrize(
    "args, message",
    [
        (["--file-dir", "/nonexistent/fw"], "--file-dir /nonexistent/fw: No such file"),
        (["--file-dir", "{tmp}/plain"], "plain: not a directory"),
        (["--file-dir", "{tmp}", "--file-max", "0"], "--file-max must be 1..2147483647"),
        (["--file-dir", "{tmp}", "--file-max", "3000000000"], "--file-max must be 1..2147483647"),
        (["--file-dir", "{tmp}", "--file-max", "4M"], "--file-max must be 1..2147483647"),
        (["--file-max", "1000"], "--file-max needs --file-dir"),
        (["--file-total", "1000"], "--file-total needs --file-dir"),
        (["--file-dir", "{tmp}", "--file-total", "-1"], "--file-total must be 1..4294967295"),
        (["--file-dir", "{tmp}", "--file-count", "255"], "--file-count must be 1..254"),
        (["--file-dir", "{tmp}", "--file-count", " 5"], "--file-count must be 1..254"),
    ],
)
def test_bad_file_options_exit_2(args, message, tmp_path):
    (tmp_path / "plain").write_bytes(b"x")
    p = subprocess.run(
        [BIN / "dan-gatewayd", "--uart", "/dev/null", "--can", f"slcan:{tmp_path}/x"]
        + [a.format(tmp=tmp_path) for a in args],
        stdin=subprocess.DEVNULL,
        capture_output=True,
        timeout=20,
    )
    assert p.returncode == 2
    assert message in p.stderr.decode()
