"""Firmware updates of CAN nodes through the FC's wire, end to end: danprobe
(files, fw-update) on dan-vbus, dan-gatewayd with its file store in a tmp
dir (--file-dir), bootloader nodes (fw_bootloader.py, pydronecan) behind
the SLCAN hub reading the image from the gateway.

The protocol's answer to "two nodes at once": the gateway holds one upload
but serves committed files to any number of readers (Read is stateless),
and FW_BEGIN and NODE_INFO are per node; the DAN bus has one master, so
one danprobe starts and follows both (fw-update --node A --node B).

Deadlines are generous and catch hangs; nothing here asserts a speed."""

import json
import signal
import sys
import time

import pytest

from bus_util import danprobe, ready
from conftest import BIN, MASTER_WAIT_MS, ROOT, wait_for
from danprobe import file_update as U
from danprobe import gateway_file as F
from danprobe import gateway_msgs as G
from danprobe import registry
from danprobe.gateway_client import GatewayClient
from danprobe.gateway_mgmt import CALL_FW_BEGIN
from danprobe.master import Master, MasterConfig, RemoteError
from danprobe.payloads import Writer
from danprobe.port import SerialPort
from gw_rig import gatewayd_cmd

BOOTLOADER = ROOT / "tests" / "e2e" / "fw_bootloader.py"
FAST = ("--max-baud", "2000000", "--configure")  # danprobe: the bus at 2 Mbit/s
# a generous reply window: a loaded test host stalls replies (conftest)
WINDOW = ("--latency-ms", MASTER_WAIT_MS)
NODE_A, NODE_B = 30, 31


def image(size, seed=1):
    return bytes((i * 131 + seed * 17 + (i >> 9)) & 0xFF for i in range(size))


class FwRig:
    """dan-vbus (dan0: danprobe, dan1: the gateway), slcan_hub (can0: the
    gateway, can1..: bootloaders), dan-gatewayd --file-dir tmp/store."""

    def __init__(self, procs, tmp, ncan=3):
        self.procs, self.tmp = procs, tmp
        self.store = tmp / "store"
        self.store.mkdir()
        self.dan = str(tmp / "dan0")
        self.vbus = procs.start([BIN / "dan-vbus", "-n", "2", "--link", tmp / "dan"])
        ready(self.vbus, "dan-vbus")
        self.hub = procs.start(
            ["python3", ROOT / "host_tools" / "slcan_hub.py", "-n", str(ncan)]
            + ["--link", tmp / "can"],
            name="slcan_hub",
        )
        ready(self.hub, "slcan_hub")
        self.gwd = procs.start(
            gatewayd_cmd(tmp, "--file-dir", self.store),
            stdout=None,
        )

    def bootloader(self, k, node_id, img, *extra, wait=True):
        """A bootloader node on hub port k expecting img, 4 reads in flight
        (as ArduPilot's AP_Bootloader); returns its process (wait=False: not
        yet READY; ready() it)."""
        path = self.tmp / f"expect{node_id}.bin"
        path.write_bytes(img)
        p = self.procs.start(
            [sys.executable, BOOTLOADER, "--port", self.tmp / f"can{k}", "--node-id", node_id]
            + ["--expect", path, "--pipeline", "4", *extra],
            name=f"fw_bootloader{node_id}",
        )
        if wait:
            ready(p, "fw_bootloader")
        return p

    def probe(self, *args, timeout=120):
        return danprobe(*args, "--port", self.dan, *FAST, *WINDOW, timeout=timeout)

    def probe_json(self, *args, rc=0, timeout=120):
        code, out, err = self.probe(*args, "--json", timeout=timeout)
        assert code == rc, (code, out, err)
        return json.loads(out.splitlines()[-1]), err

    def boot_result(self, p):
        """Stops a bootloader (SIGTERM) and returns its result line."""
        assert self.procs.stop(p) == 0, p.log_path.read_text()
        lines = [json.loads(x) for x in p.stdout.read().decode().splitlines() if x.strip()]
        assert lines and lines[-1]["event"] == "exit", lines
        return lines[-1]

    def wait_nodes(self, *ids):
        def seen():
            return set(ids) <= {n["node_id"] for n in self.probe_json("nodes", "-q")[0]["nodes"]}

        wait_for(seen, 60, 0.5, what=f"nodes {ids} in the gateway's table")


@pytest.fixture
def rig(procs, tmp_path):
    return FwRig(procs, tmp_path)


def test_full_update(rig, tmp_path):
    img = image(64 * 1024)
    (tmp_path / "fw-2.0.bin").write_bytes(img)
    boot = rig.bootloader(1, NODE_A, img)
    rig.wait_nodes(NODE_A)
    doc, err = rig.probe_json("fw-update", "--node", NODE_A, tmp_path / "fw-2.0.bin", timeout=180)
    node = doc["nodes"][0]
    assert doc["result"] == 0 and node["state"] == "done", doc
    assert node["before"]["sw"] != node["after"]["sw"], doc
    assert node["bytes_read"] == node["file_size"] == len(img)
    assert doc["upload"]["committed"] and doc["upload"]["size"] == len(img)
    assert doc["begin"][str(NODE_A)]["error"] == 0
    assert (rig.store / "fw-2.0.bin").read_bytes() == img
    assert "BeginFirmwareUpdate accepted" in err and "back OPERATIONAL, version 2.0" in err
    # the node checked every byte it read against the image (--expect)
    end = rig.boot_result(boot)
    assert (end["state"], end["equal"], end["bytes"]) == ("done", True, len(img)), end


def progress_bytes(log):
    """The byte counts of the plain progress lines in a danprobe log."""
    out = []
    for line in log.read_text().splitlines():
        if line.startswith("upload ") and " bytes " in line:
            out.append(int(line.split(": ")[1].split("/")[0]))
    return out


def start_put(procs, rig, path, name, beyond=0):
    """danprobe files put at 115200 (slow enough to stop halfway: about 4 s
    for 32 KiB), its progress in its log; waits for progress past beyond."""
    p = procs.start(
        [sys.executable, "-m", "danprobe", "files", "put", path, "--port", rig.dan, "--configure"]
        + list(WINDOW),
        name=name,
    )

    def progressed():
        assert p.poll() is None, p.log_path.read_text()  # ended before any progress
        return max(progress_bytes(p.log_path) or [0]) > beyond

    wait_for(progressed, 60, 0.01, what="progress")
    return p


def test_upload_interrupted_killed_then_resumed(rig, procs, tmp_path):
    img = image(32 * 1024, seed=2)
    path = tmp_path / "esc.bin"
    path.write_bytes(img)
    # Ctrl-C: exit 130 between two transactions, the gateway keeps what it got
    p = start_put(procs, rig, path, "danprobe-int")
    assert procs.stop(p, signal.SIGINT, timeout=30) == 130
    log = p.log_path.read_text()
    kept = int(log.split("the gateway keeps ")[1].split(" of ")[0])
    assert max(progress_bytes(p.log_path)) <= kept < len(img) and kept % F.WRITE_MAX == 0, log
    assert "Traceback" not in log
    # SIGKILL: no chance to clean up at all
    p = start_put(procs, rig, path, "danprobe-kill", beyond=kept)
    assert procs.stop(p, signal.SIGKILL) == -signal.SIGKILL
    acked = max(progress_bytes(p.log_path))
    assert kept < acked < len(img)
    assert not (rig.store / "esc.bin").exists()  # only the partial ~esc.bin
    doc, err = rig.probe_json("files", "put", path)
    up = doc["upload"]
    assert up["resumed_from"] >= acked and up["resumed_from"] % F.WRITE_MAX == 0, (acked, up)
    assert up["resumed_from"] < len(img) and up["committed"]
    assert f"resuming esc.bin at byte {up['resumed_from']} of {len(img)}" in err
    assert up["sent"] <= len(img) - up["resumed_from"] + F.WRITE_MAX  # no resend from 0
    assert (rig.store / "esc.bin").read_bytes() == img
    doc, _ = rig.probe_json("files", "list")
    assert doc["files"] == [{"name": "esc.bin", "size": len(img)}]


def gateway(rig):
    port = SerialPort(rig.dan, 9600)
    m = Master(port, [registry.lookup("can-gw")], 9600, MasterConfig(resp_latency_s=0.1))
    m.discover()
    m.configure()
    return port, GatewayClient(m)


def raw_name(name: bytes) -> bytes:
    """A name's array bytes without danprobe's check (the gateway must refuse it)."""
    return Writer().array(name).bytes()


def test_crc_mismatch_and_names_outside_the_store(rig, tmp_path):
    data = image(700, seed=3)
    port, gw = gateway(rig)
    with port:
        st = U.file_open(gw, "x.bin", len(data), restart=True)
        assert (st.result, st.have) == (F.FILE_OK, 0)
        for off in range(0, len(data), F.WRITE_MAX):
            assert U.file_write(gw, off, data[off : off + F.WRITE_MAX]).result == F.FILE_OK
        bad = U.file_commit(gw, F.crc32(data) ^ 1)
        assert (bad.result, bad.crc) == (F.FILE_CRC, F.crc32(data))
        assert "x.bin" not in [e.name_text for e in U.file_list(gw)]
        assert not (rig.store / "x.bin").exists()
        # the upload stays open: the right CRC commits it
        assert U.file_commit(gw, F.crc32(data)).result == F.FILE_OK
        assert (rig.store / "x.bin").read_bytes() == data
        # a gap is refused and writes nothing
        U.file_open(gw, "y.bin", 300, restart=True)
        assert U.file_write(gw, 150, data[:150]) == F.FileState(F.FILE_GAP, 0)
        # names outside the store: error frames, before the store is asked
        for name in (b"../x", b"/etc/passwd", b"a/b", b".x", b"~x.bin"):
            with pytest.raises(RemoteError):
                gw._call(F.CODE_FILE_OPEN, raw_name(name) + bytes(5), F.FileState.decode)
            with pytest.raises(RemoteError):
                gw._call(F.CODE_FILE_REMOVE, raw_name(name), F.decode_result)
            call = bytes([1, 0, NODE_A, CALL_FW_BEGIN]) + raw_name(name)
            with pytest.raises(RemoteError):
                gw._call(G.CODE_NODE_CALL, call, lambda p: p)
        # FW_BEGIN of a file that is not committed: refused, nothing sent
        with pytest.raises(RemoteError):
            U.fw_begin(gw, NODE_A, "y.bin")
        assert U.file_remove(gw, "nothing.bin") == F.FILE_NOT_FOUND
    assert not (tmp_path / "x").exists()
    assert sorted(p.name for p in rig.store.iterdir() if not p.name.startswith("~")) == ["x.bin"]
    doc, _ = rig.probe_json("files", "rm", "x.bin")
    assert doc["removed"] == "x.bin" and not (rig.store / "x.bin").exists()
    code, _, err = danprobe("files", "put", tmp_path / "none.bin", "--port", rig.dan)
    assert code == 2 and "No such file" in err and "Traceback" not in err
    (tmp_path / "a.bin").write_bytes(b"1")
    code, _, err = danprobe("files", "put", tmp_path / "a.bin", "--name", "../x", "--port", rig.dan)
    assert code == 2 and "starts with '.'" in err and "Traceback" not in err


def test_node_stops_reading(rig, tmp_path):
    img = image(8 * 1024, seed=4)
    (tmp_path / "fw.bin").write_bytes(img)
    rig.bootloader(1, NODE_A, img, "--stall-after", "2048")
    rig.wait_nodes(NODE_A)
    t0 = time.monotonic()
    doc, err = rig.probe_json(
        "fw-update", "--node", NODE_A, tmp_path / "fw.bin", "--stall", "2", rc=1
    )
    node = doc["nodes"][0]
    assert node["state"] == "failed" and "stopped reading at" in node["why"], doc
    assert 0 < node["bytes_read"] < len(img)
    assert "stopped reading" in err and time.monotonic() - t0 < 60


def test_two_nodes_at_once(rig, tmp_path):
    img = image(8 * 1024, seed=5)
    (tmp_path / "fw.bin").write_bytes(img)
    boots = [rig.bootloader(k, n, img, wait=False) for k, n in ((1, NODE_A), (2, NODE_B))]
    for b in boots:
        ready(b, "fw_bootloader")
    rig.wait_nodes(NODE_A, NODE_B)
    doc, _ = rig.probe_json("fw-update", "--node", NODE_A, "--node", NODE_B, tmp_path / "fw.bin")
    assert [n["state"] for n in doc["nodes"]] == ["done", "done"], doc
    assert all(n["bytes_read"] == len(img) for n in doc["nodes"])
    for b in boots:
        end = rig.boot_result(b)
        assert (end["state"], end["equal"], end["bytes"]) == ("done", True, len(img)), end


def test_ctrl_c_while_following(rig, procs, tmp_path):
    """Ctrl-C once BeginFirmwareUpdate was sent: danprobe exits 130 between
    two transactions and says so; the node goes on reading the image from
    the gateway's store and finishes (the defined state of the help text)."""
    img = image(48 * 1024, seed=6)
    (tmp_path / "fw.bin").write_bytes(img)
    boot = rig.bootloader(1, NODE_A, img, "--pipeline", "1", "--chunk", "64")  # slow: ~750 reads
    rig.wait_nodes(NODE_A)
    p = procs.start(
        [sys.executable, "-m", "danprobe", "fw-update", "--node", NODE_A, tmp_path / "fw.bin"]
        + ["--port", rig.dan, *FAST, *WINDOW],
        name="danprobe-follow",
    )

    def following():
        assert p.poll() is None, p.log_path.read_text()
        return "BeginFirmwareUpdate accepted" in p.log_path.read_text()

    wait_for(following, 120, 0.01, what="the update begun")
    assert procs.stop(p, signal.SIGINT, timeout=30) == 130
    log = p.log_path.read_text()
    assert "stopped following (the nodes go on updating)" in log and "Traceback" not in log, log

    # the node finishes by itself and comes back with its new version
    def updated():
        nodes = {n["node_id"]: n for n in rig.probe_json("nodes", "-q")[0]["nodes"]}
        n = nodes.get(NODE_A)
        return n is not None and n["mode"] == 0 and list(n["sw"]) == [2, 0]

    wait_for(updated, 120, 0.5, what="the node back OPERATIONAL at 2.0")
    end = rig.boot_result(boot)
    assert (end["state"], end["equal"], end["bytes"]) == ("done", True, len(img)), end
