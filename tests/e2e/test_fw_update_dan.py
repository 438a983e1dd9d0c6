"""A firmware update with only the FC's wire (docs/PROTOCOL.md section 7,
"Files and firmware updates"): dan-fcsim, the FC's client, uploads an
image into dan-gatewayd's file store over DAN (FILE_OPEN, FILE_WRITE,
FILE_COMMIT), a cut upload resumes where the gateway is, the file is
listed, FW_BEGIN starts the update of a pydronecan bootloader
(fw_bootloader.py) that reads the image through the gateway, and
NODE_INFO follows it to the new version.

Deadlines are generous and catch hangs; nothing here asserts a speed.
"""

import json
import queue
import random
import sys
import threading

import pytest

from bus_util import ready
from conftest import ROOT, closing_factory, wait_for
from gw_rig import GW_NODE, Rig, step

IMAGE_SIZE = 6000  # 40 chunks of 150 bytes; not a whole number of 256-byte reads
NODE = 60


@pytest.fixture
def rig(procs, tmp_path):
    def make():
        fwdir = tmp_path / "fw"
        fwdir.mkdir()
        r = Rig(procs, tmp_path, ncan=2, gw_args=("--file-dir", fwdir))
        r.fwdir = fwdir
        return r

    yield from closing_factory(make)


def bootloader(r, image):
    p = r.procs.start(
        [sys.executable, ROOT / "tests" / "e2e" / "fw_bootloader.py"]
        + ["--port", r.tmp / "can1", "--node-id", NODE, "--expect", image, "--pipeline", "4"],
        name="fw_bootloader",
    )
    ready(p, "fw_bootloader")
    p.lines = queue.Queue()
    threading.Thread(
        target=lambda: [p.lines.put(json.loads(line)) for line in p.stdout], daemon=True
    ).start()
    return p


def fc(r, *steps):
    """dan-fcsim's steps after discover and configure; their JSON lines."""
    rc, out = r.fcsim("discover", "configure", *steps, timeout=170)
    assert rc == 0, [line for line in out if not line.get("ok", True)] or out
    return out


def node_info(r):
    return step(fc(r, f"node-info:{NODE}"), "node-info")[0]


def test_upload_begin_follow(rig):
    r = rig()
    image = random.Random(14).randbytes(IMAGE_SIZE)
    src = r.tmp / "new.bin"
    src.write_bytes(image)
    boot = bootloader(r, src)
    # an uploader killed after 1500 bytes, then run again: it goes on where
    # the gateway is; then the file is committed and listed, nothing else
    up = step(fc(r, f"upload:new.bin:{src}:1500"), "upload")[0]
    assert (up["stopped_at"], up["resumed_at"], up["writes"]) == (1500, 0, 10), up
    out = fc(r, f"upload:new.bin:{src}", "files", "stats")
    up = step(out, "upload")[0]
    assert (up["size"], up["resumed_at"], up["writes"]) == (IMAGE_SIZE, 1500, 30), up
    assert step(out, "files")[0]["files"] == [{"name": "new.bin", "size": IMAGE_SIZE}]
    stats = step(out, "stats")[0]
    assert (stats["upload_bytes"], stats["file_commits"]) == (IMAGE_SIZE, 1), stats
    assert (r.fwdir / "new.bin").read_bytes() == image
    # FW_BEGIN of a file that is not there: refused, nothing sent
    rc, out = r.fcsim("discover", "configure", f"fw-begin:{NODE}:nope.bin:7")
    failed = [line for line in out if not line["ok"]]
    assert rc == 1 and "not a committed file" in failed[0]["remote"], out
    wait_for(lambda: node_info(r)["info_state"] == 2, 60, 0.5, what="the node's GetNodeInfo")
    assert node_info(r)["sw"] == [1, 0]
    # the update: FW_BEGIN answered OK, the bootloader reads the image
    # through the gateway, NODE_INFO follows it to the new version
    assert step(fc(r, f"fw-begin:{NODE}:new.bin:8"), "fw-begin")[0]["error"] == 0
    res = boot.lines.get(timeout=120)
    assert res["state"] == "done" and res["equal"] and res["source"] == GW_NODE, res
    assert res["bytes"] == IMAGE_SIZE and res["path"] == "new.bin", res

    def updated():
        i = node_info(r)
        return i["sw"] == [2, 0] and i

    i = wait_for(updated, 60, 0.5, what="the new version in NODE_INFO")
    assert i["file_flags"] == 3 and i["file_size"] == IMAGE_SIZE, i
    assert i["bytes_read"] >= IMAGE_SIZE and i["since_read_ms"] < 120000, i
    assert i["mode"] == 0, i  # OPERATIONAL again
    assert step(fc(r, "stats"), "stats")[0]["fw_begins"] == 1
    assert r.procs.stop(boot) == 0
