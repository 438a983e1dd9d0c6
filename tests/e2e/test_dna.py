"""Bus management end to end: the gateway as the dynamic node ID allocation
server, its table in a file (dan-gatewayd --dna-db), --no-dna, the HEALTH
verdict for duplicate and unhealthy nodes, the gateway's unique ID (--uid,
/etc/machine-id), its own frames in the raw capture, and --can-bitrate.

dan-fcsim is the FC on a dan-vbus endpoint, dan-gatewayd on the other, an
SLCAN hub the CAN bus. The independent DroneCAN peers are pydronecan nodes,
and an allocatee written from the DroneCAN specification (gw_rig.Allocatee:
pydronecan cannot send anonymous transfers, so its requests are raw frames).
Allocatees run one at a time: two at once may interleave their stages, which
the protocol resolves by retrying, but a test that counts IDs must not
depend on that. Deadlines are generous: they catch hangs, not speed.
"""

import json
import os
import socket
import subprocess
import sys
import time

import dronecan
import pytest

import pydronecan_nodes
from bus_util import control, ready
from conftest import BIN, ROOT, closing_factory, wait_for
from gw_rig import GW_NODE, AllocateeHost, Rig

U = dronecan.uavcan

UID_A = bytes(range(0xA0, 0xB0))
UID_B = bytes(range(0xB0, 0xC0))
UID_C = bytes(range(0xC0, 0xD0))
UID_D = bytes(range(0xD0, 0xE0))
UID_E = bytes(range(0xE0, 0xF0))
NODE_STATUS_DTID = 341
HEALTH_ERROR = 2


@pytest.fixture
def rig(procs, tmp_path):
    yield from closing_factory(lambda **kw: Rig(procs, tmp_path, **kw))


def fc(r, *steps):
    """dan-fcsim's lines for steps (after discover), by step name (the
    last line of each); fails on a step that failed."""
    rc, out = r.fcsim("discover", *steps)
    assert rc == 0, [line for line in out if not line.get("ok", True)] or out
    return {line["step"]: line for line in out}


def static_node(r, k, node_id, uid, name="org.test.static"):
    """A pydronecan node with a fixed node ID and unique ID on hub port k,
    spinning (NodeStatus once a second, GetNodeInfo answered)."""
    info = U.protocol.GetNodeInfo.Response()
    info.name = name
    info.hardware_version.unique_id = list(uid)
    n = pydronecan_nodes.make_node(r.tmp / f"can{k}", node_id, node_info=info)
    r.nodes.append(n)
    r.spin(n)
    return n


def crc16_ccitt_false(data):
    crc = 0xFFFF
    for b in data:
        crc ^= b << 8
        for _ in range(8):
            crc = (crc << 1 ^ 0x1021 if crc & 0x8000 else crc << 1) & 0xFFFF
    return crc


def read_table_file(path):
    """docs/PROTOCOL.md's blob: "DNA1", u8 count, count x (u8 node_id, 16
    bytes unique ID), u16 CRC-16/CCITT-FALSE LE; {node_id: unique ID}."""
    b = path.read_bytes()
    assert b[:4] == b"DNA1"
    n = b[4]
    assert len(b) == 5 + 17 * n + 2
    assert int.from_bytes(b[-2:], "little") == crc16_ccitt_false(b[:-2])
    return {b[5 + 17 * i]: b[6 + 17 * i : 22 + 17 * i] for i in range(n)}


def table_of(dna_line):
    return {e["id"]: bytes.fromhex(e["uid"]) for e in dna_line["table"]}


def restart_gatewayd(r):
    """SIGTERM (exit 0), then the same command line again."""
    assert r.procs.stop(r.gwd) == 0
    r.gwd = r.procs.start(r.gwd.args, stdout=None)


def test_allocation_and_table_across_restart(rig, tmp_path):
    db = tmp_path / "dna.db"
    r = rig(gw_args=["--dna-db", db])
    assert fc(r, "dna")["dna"]["server_on"]  # the daemon is up before the requests
    host = AllocateeHost(r, 1)
    assert host.add(UID_A, seed=1).wait() == 125  # no preference: the highest free
    assert host.add(UID_B, preferred=42, seed=2).wait() == 42  # the preferred one, free
    # the gateway's own ID is never handed out, even when preferred
    assert host.add(UID_C, preferred=GW_NODE, seed=3).wait() == GW_NODE + 1
    want = {125: UID_A, 42: UID_B, GW_NODE + 1: UID_C}
    d = fc(r, "dna")["dna"]
    assert table_of(d) == want
    assert d["entries"] == 3 and d["capacity"] == 64 and not d["loaded"]
    wait_for(lambda: db.exists() and read_table_file(db) == want, 10, what="table saved")
    assert not (tmp_path / "dna.db.tmp").exists()

    restart_gatewayd(r)
    d = fc(r, "dna")["dna"]
    assert d["loaded"] and not d["storage_error"] and table_of(d) == want
    log = r.gwd.log_path.read_text()
    assert f"DNA table {db}: 3 entries" in log
    # the same unique ID gets the same ID, whatever it prefers now
    assert host.add(UID_A, preferred=77, seed=4).wait() == 125
    assert host.add(UID_D, seed=5).wait() == 124  # a second allocatee: another ID
    wait_for(lambda: read_table_file(db) == {**want, 124: UID_D}, 10, what="table saved")
    assert fc(r, "stats")["stats"]["dna_allocations"] == 2


def test_allocation_skips_ids_in_use(rig):
    r = rig(ncan=4)
    static_node(r, 2, 125, UID_C)
    static_node(r, 3, 42, UID_D)

    def both_known():
        nodes = fc(r, "nodes")["nodes"]["nodes"]
        return {n["id"] for n in nodes if n["info"] == 2} >= {42, 125}

    wait_for(both_known, 60, interval=0.5, what="the static nodes in the node table")
    host = AllocateeHost(r, 1)
    assert host.add(UID_A, seed=1).wait() == 124  # 125 is taken by a static node
    assert host.add(UID_B, preferred=42, seed=2).wait() == 43
    assert host.add(UID_E, preferred=GW_NODE, seed=3).wait() == GW_NODE + 1
    assert set(table_of(fc(r, "dna")["dna"])) == {124, 43, GW_NODE + 1}


def test_corrupt_table_refused(rig, tmp_path):
    db = tmp_path / "dna.db"
    blob = b"DNA1\x01" + bytes([50]) + UID_A + b"\x00\x00"  # the right length, a wrong CRC
    db.write_bytes(blob)
    r = rig(gw_args=["--dna-db", db])
    d = fc(r, "dna")["dna"]
    assert d["storage_error"] and not d["loaded"] and d["entries"] == 0 and d["server_on"]
    log = r.gwd.log_path.read_text()
    assert (
        f"DNA table {db}: CRC mismatch; renamed to {db}.bad; starting with an empty table" in log
    ), log
    assert (tmp_path / "dna.db.bad").read_bytes() == blob
    assert not db.exists()
    host = AllocateeHost(r, 1)
    assert host.add(UID_A, seed=1).wait() == 125  # not the 50 of the refused file
    wait_for(lambda: db.exists() and read_table_file(db) == {125: UID_A}, 10, what="new table")


def test_no_dna_answers_nothing(rig):
    r = rig(gw_args=["--no-dna"])
    d = fc(r, "dna")["dna"]
    assert not d["server_on"]
    host = AllocateeHost(r, 1)
    a = host.add(UID_A, seed=1)
    # four first stages unanswered (an answer would follow each within ms)
    wait_for(lambda: a.stages >= 4, 30, what="four requests")
    assert a.answers == [] and a.node_id is None
    assert fc(r, "stats")["stats"]["dna_allocations"] == 0
    # CONFIG turns the server on: the same allocatee is served
    assert fc(r, "config-dna:1")["config-dna"]["dna"] == 1
    assert a.wait() == 125
    assert fc(r, "config-dna:0")["config-dna"]["dna"] == 0


def health_when(r, pred, what):
    """Asks HEALTH until pred(line) holds; that line."""

    def ask():
        h = fc(r, "health")["health"]
        return h if pred(h) else None

    return wait_for(ask, 60, interval=0.5, what=what)


def test_duplicate_node_id_fails_health(rig):
    r = rig()
    static_node(r, 1, 50, UID_A, "org.test.first")
    time.sleep(2.5)  # the second starts later: its uptime is 2-3 s behind
    static_node(r, 2, 50, UID_B, "org.test.second")
    h = health_when(r, lambda h: h["reason_name"] == "duplicate", "HEALTH DUPLICATE")
    assert h["verdict"] == 1 and h["verdict_name"] == "fail"
    assert h["reason"] == 2 and h["subject"] == 50 and h["problems"] >= 1
    assert fc(r, "stats")["stats"]["duplicates"] >= 1


def test_unhealthy_node_fails_health(rig):
    r = rig()
    n = static_node(r, 1, 60, UID_A, "org.test.sick")
    h = health_when(r, lambda h: h["verdict"] == 0, "HEALTH OK")
    assert h["reason_name"] == "none" and h["problems"] == 0
    n.health = HEALTH_ERROR
    h = health_when(r, lambda h: h["reason_name"] == "unhealthy", "HEALTH UNHEALTHY")
    assert h["verdict"] == 1 and h["reason"] == 3
    assert h["subject"] == 60 and h["detail"] == HEALTH_ERROR
    out = fc(r, "telem-timeout:250", "config", "telem-timeout:0")
    assert (
        out["config"]["telem_timeout_ms"] == 250 and out["telem-timeout"]["telem_timeout_ms"] == 0
    )


def gateway_unique_id(r):
    """The unique ID in the gateway's GetNodeInfo, asked by a pydronecan node."""
    asker = r.node(1, 20, "org.test.asker")
    got = []
    r.spin(asker)
    asker.request(U.protocol.GetNodeInfo.Request(), GW_NODE, lambda e: got.append(e))
    wait_for(lambda: got, 20, what="GetNodeInfo response")
    assert got[0] is not None
    return bytes(got[0].response.hardware_version.unique_id)


def fnv1a32(data, h=2166136261):
    for b in data:
        h = ((h ^ b) * 16777619) & 0xFFFFFFFF
    return h


def derived_uid():
    """README: bytes 4k..4k+3 = FNV-1a-32 (LE) of "dan-gatewayd:k:" and the
    machine ID's 32 hex digits; without one, "host:" and the host name."""
    try:
        mid = open("/etc/machine-id").readline().strip()
    except OSError:
        mid = ""
    if len(mid) != 32 or any(c not in "0123456789abcdefABCDEF" for c in mid):
        mid = "host:" + socket.gethostname()
    return b"".join(
        fnv1a32(f"dan-gatewayd:{k}:{mid}".encode()).to_bytes(4, "little") for k in range(4)
    )


def test_unique_id_given(rig):
    uid = bytes.fromhex("0123456789abcdef0011223344556677")
    r = rig(gw_args=["--uid", uid.hex().upper()])
    assert gateway_unique_id(r) == uid


def test_unique_id_derived_and_own_frames_captured(rig):
    r = rig()
    uid = gateway_unique_id(r)
    assert uid == derived_uid() and uid != bytes(16)
    assert f"DroneCAN unique ID {uid.hex()}" in r.gwd.log_path.read_text()
    # a filter entry with bit29 passes the gateway's own frames (those it
    # handed to the CAN interface): its NodeStatus, source node 10
    out = fc(r, "filter:20000000/00000000", "candump:30:20000")
    ids = [int(f.split("#")[0], 16) for f in out["candump"]["frames"]]
    assert any(i & 0x7F == GW_NODE and (i >> 8) & 0xFFFF == NODE_STATUS_DTID for i in ids), ids


def test_can_bitrate_sets_the_slcan_adapter(procs, tmp_path):
    import pty

    hub = procs.start(
        [sys.executable, ROOT / "host_tools" / "slcan_hub.py", "-n", "1"]
        + ["--link", tmp_path / "can", "--control", tmp_path / "hub.ctl"],
        name="slcan_hub",
    )
    ready(hub, "slcan_hub")
    m, s = pty.openpty()
    try:
        gw = procs.start(
            [BIN / "dan-gatewayd", "--uart", os.ttyname(s), "--can", f"slcan:{tmp_path}/can0"]
            + ["--can-bitrate", "500000", "--no-dna"],
            stdout=None,
        )
        wait_for(lambda: b"DroneCAN node" in gw.log_path.read_bytes(), 20, what="gateway start")
        port = json.loads(control(tmp_path / "hub.ctl", "stats"))["ports"][0]
        assert port["open"] and port["bitrate"] == 500000
        assert "allocation off (--no-dna)" in gw.log_path.read_text()
        assert procs.stop(gw) == 0
    finally:
        os.close(m)
        os.close(s)


@pytest.mark.parametrize(
    "args, message",
    [
        (["--can-bitrate", "300000"], "--can-bitrate must be one of the SLCAN rates"),
        (["--can-bitrate", "1M"], "--can-bitrate must be one of the SLCAN rates"),
        (["--uid", "00" * 16], "--uid must be 32 hex digits (16 bytes), not all zeros"),
        (["--uid", "0123"], "--uid must be 32 hex digits"),
        (["--dna-db", "/nonexistent/dna.db"], "directory /nonexistent does not exist"),
        (["--stats-file", "/tmp/" + "s" * 600], "--stats-file path longer than 507 bytes"),
        (
            ["--can", "socketcan:can0", "--can-bitrate", "500000"],
            "set a SocketCAN interface's bitrate with ip link",
        ),
    ],
)
def test_bad_options_exit_2(args, message, tmp_path):
    p = subprocess.run(
        [BIN / "dan-gatewayd", "--uart", "/dev/null", "--can", f"slcan:{tmp_path}/x", *args],
        stdin=subprocess.DEVNULL,
        capture_output=True,
        timeout=20,
    )
    assert p.returncode == 2
    assert message in p.stderr.decode()
