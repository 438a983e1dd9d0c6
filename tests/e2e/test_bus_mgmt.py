"""Bus management through danprobe (docs/PROTOCOL.md section 7, "Bus
management"): parameters, RestartNode, health, node flags, the allocation
table, the gateway's own frames and receive times.

First the client's call pipeline, the receive clock and the SLCAN bridge
against scripted gateways; then the real stack: dan-vbus, the SLCAN hub,
dan-gatewayd and pydronecan as the independent peer on the CAN side
(tests/tools/param_node.py serving parameters; a node, a node monitor and
pydronecan's CentralizedServer allocation server through `danprobe slcan`;
a raw anonymous allocatee, allocatee.py).

Deadlines are generous and catch hangs; nothing here asserts a speed.
"""

import json
import os
import select
import subprocess
import sys
import threading
import time
from types import SimpleNamespace

import pytest

from allocatee import Allocatee
from bus_util import danprobe, ready
from conftest import BIN, ROOT, FakeMaster, closing_factory, wait_for
from danprobe import gateway_calls as C
from danprobe import gateway_can as GC
from danprobe import gateway_mgmt as M
from danprobe import gateway_msgs as G
from danprobe import registry
from danprobe.commands.slcan import Bridge
from danprobe.gateway_client import GatewayClient
from danprobe.master import DanTimeout, Master, MasterConfig, RemoteError
from danprobe.payloads import ErrorMessage
from danprobe.port import SerialPort
from danprobe.recv_clock import RecvClock, slcan_stamp_ms
from gw_rig import GW_NODE, Rig, finish_danprobe, pty_open, start_danprobe

sys.path.insert(0, str(ROOT / "tests" / "tools"))
import param_node  # noqa: E402

PARAM_NODE = 50
LAPTOP_NODE = 100


# ---- the call pipeline against a scripted gateway ----


class FakeGateway(FakeMaster):
    """A master whose gateway holds calls as libdan's does: a NODE_CALL with
    a held call's id and content is a retry (its state), a new one is
    PENDING (or BUSY while .busy > 0) and DONE after .delay polls with the
    node's answer (params: name -> ParamResult), or TIMEOUT for a node in
    .silent. .fail holds exceptions for the next transactions."""

    def __init__(self, params=(), delay=2):
        self.params = list(params)
        self.delay = delay
        super().__init__()
        self.calls = {}  # call_id -> dict(req, state, polls, result)
        self.busy, self.silent = 0, set()
        self.max_pending = 0
        self.stats = SimpleNamespace(retries=0)

    def serve(self, code, inner):
        if code == G.CODE_NODE_CALL:
            out = self._node_call(inner)
        else:
            out = self._result(M.CallResultRequest.decode(inner))
        pending = sum(1 for k in self.calls.values() if k["state"] == M.CALL_PENDING)
        self.max_pending = max(self.max_pending, pending)
        return out.encode()

    def _node_call(self, inner):
        c = M.NodeCall.decode(inner)
        k = self.calls.get(c.call_id)
        if k is not None and k["req"] == inner:
            return M.CallState(c.call_id, k["state"], len(k["result"]))
        if self.busy:
            self.busy -= 1
            return M.CallState(c.call_id, M.CALL_BUSY)
        self.calls[c.call_id] = dict(req=inner, state=M.CALL_PENDING, polls=self.delay, result=b"")
        return M.CallState(c.call_id, M.CALL_PENDING)

    def answer(self, c: M.NodeCall) -> bytes:
        if c.op == M.CALL_PARAM_GET_INDEX:
            p = self.params[c.index] if c.index < len(self.params) else M.ParamResult()
        else:
            p = next((p for p in self.params if p.name == c.name), M.ParamResult())
        return p.encode()

    def _result(self, q):
        k = self.calls.get(q.call_id)
        if k is None:
            raise RemoteError(ErrorMessage(G.CODE_CALL_RESULT, 0, "unknown call"))
        c = M.NodeCall.decode(k["req"])
        if k["state"] == M.CALL_PENDING:
            k["polls"] -= 1
            if k["polls"] <= 0:
                silent = c.node_id in self.silent
                k["state"] = M.CALL_TIMEOUT if silent else M.CALL_DONE
                k["result"] = b"" if silent else self.answer(c)
        n = len(k["result"]) if k["state"] == M.CALL_DONE else 0
        data = k["result"][q.offset : q.offset + min(q.max, 128)] if q.offset < n else b""
        return M.CallResultResponse(q.call_id, k["state"], n, q.offset, data)


def fake_params(n):
    out = []
    for i in range(n):
        v = M.Value.integer(i) if i % 2 else M.Value.string(f"s{i}")
        out.append(M.ParamResult(v, v, name=f"p{i:02d}".encode()))
    return out


def test_pipeline_lists_with_calls_in_flight():
    gw_fake = FakeGateway(fake_params(30))
    gw = GatewayClient(gw_fake, seed=1)
    got = C.param_list(gw, 20, window=5)
    assert [(i, p.name) for i, p in got] == [(i, f"p{i:02d}".encode()) for i in range(30)]
    assert all(p == gw_fake.params[i] for i, p in got)
    assert gw_fake.max_pending == 5  # pipelined, never more than the window
    calls = [M.NodeCall.decode(p) for code, p in gw_fake.sent if code == G.CODE_NODE_CALL]
    assert len({c.call_id for c in calls}) == len(calls)  # a new id per call
    assert max(c.index for c in calls) <= 30 + 5  # stopped soon after the end
    one = C.param_result(gw, M.NodeCall(0, 20, M.CALL_PARAM_GET_NAME, name=b"p07"))
    assert one.value == M.Value.integer(7)


def test_pipeline_busy_failures_forgotten_timeout():
    f = FakeGateway(fake_params(3))
    gw = GatewayClient(f, seed=2)
    f.busy = 1  # every slot busy once: nothing was sent, started again
    f.fail = [DanTimeout("lost")]  # the NODE_CALL's transaction failed: repeated as it was
    req = M.NodeCall(0, 20, M.CALL_PARAM_GET_INDEX, index=1)
    assert M.ParamResult.decode(C.call(gw, req)).value == M.Value.integer(1)
    nc = [p for code, p in f.sent if code == G.CODE_NODE_CALL]
    assert nc[0] == nc[1]  # the same call_id and content: the gateway's retry rule applies
    # a CALL_RESULT that failed is only polled again
    f.fail = [DanTimeout("lost")] * 2
    assert M.ParamResult.decode(C.call(gw, M.NodeCall(0, 20, 0, index=2))).exists
    # the gateway forgot a call: a parameter call starts again under a new id
    p = C.Pipeline(gw, 1)
    p.start("k", M.NodeCall(0, 20, M.CALL_PARAM_GET_INDEX, index=0))
    first_id = p.flight[0].req.call_id
    del f.calls[first_id]
    done = next(p.drain())
    assert done.req.call_id != first_id and M.ParamResult.decode(bytes(done.result)).exists
    # ... a RestartNode does not (it may have run)
    p = C.Pipeline(gw, 1)
    p.start("r", M.NodeCall(0, 20, M.CALL_RESTART))
    f.calls.clear()
    with pytest.raises(C.CallLost, match="no longer holds restart"):
        next(p.drain())
    # a node that never answers: the gateway's TIMEOUT, named
    f.silent.add(99)
    with pytest.raises(C.NoAnswer, match="node 99 did not answer param get 'x'"):
        C.call(gw, M.NodeCall(0, 99, M.CALL_PARAM_GET_NAME, name=b"x"))


def test_client_stale_call_ids_and_long_results():
    big = M.ParamResult(M.Value.string(b"v" * 128), M.Value.string(b"d" * 128), name=b"n" * 92)
    f = FakeGateway([big])
    gw = GatewayClient(f, seed=3)
    # a call someone else left in the gateway with our next id and content
    stale = M.NodeCall((gw.call_id + 1) & 0xFFFF, 20, M.CALL_PARAM_GET_INDEX, index=0)
    f.calls[stale.call_id] = dict(
        req=stale.encode(), state=M.CALL_DONE, polls=0, result=M.ParamResult().encode()
    )
    r = M.ParamResult.decode(C.call(gw, M.NodeCall(0, 20, M.CALL_PARAM_GET_INDEX, index=0)))
    assert gw.stale_calls == 1 and r == big  # not the stale (empty) answer
    reads = [M.CallResultRequest.decode(p) for c, p in f.sent if c == G.CODE_CALL_RESULT]
    assert [q.offset for q in reads if q.offset] == [128, 256]  # 364 bytes in three reads
    with pytest.raises(RemoteError):
        gw.call_result(0x1234)  # a call the gateway does not hold
    # a NODE_CALL repeated after a failed transaction finds its own call done: not stale
    req = M.NodeCall(gw.new_call_id(), 20, M.CALL_PARAM_GET_INDEX, index=0)
    f.calls[req.call_id] = dict(req=req.encode(), state=M.CALL_DONE, polls=0, result=f.answer(req))
    st = gw.node_call(req, fresh=False)
    assert (st.call_id, st.state, gw.stale_calls) == (req.call_id, M.CALL_DONE, 1)


# ---- receive times ----


def test_recv_clock_unwraps_and_maps():
    c = RecvClock()
    assert c.unwrap([0xFFFFFF00, 0xFFFFFF80]) == [0xFFFFFF00, 0xFFFFFF80]
    assert c.unwrap([0x40, 0x50]) == [(1 << 32) + 0x40, (1 << 32) + 0x50]  # wrapped
    assert c.host_times([2_000_000, 3_000_000], 100.5) == [99.5, 100.5]
    # a tighter bound moves the offset down, never a printed time back
    assert c.host_times([4_000_000], 101.0) == [101.0]
    assert c.offset == 97.0 and c.host_times([4_100_000], 200.0) == [101.1]
    c.last_us = 5_000_000
    assert c.unwrap([1_000]) == [1_000] and c.restarts == 1  # backwards: a restarted gateway
    assert slcan_stamp_ms(61_234_567) == 1234


class FakeRecv:
    """The client side of CAN_RECV for the SLCAN bridge."""

    def __init__(self, frames, times):
        self.frames, self.recv_times = frames, times
        self.can_rx_resyncs = 0
        self.opts = []

    def can_recv(self, opts=0):
        self.opts.append(opts)
        out, self.frames = self.frames, []
        return out


def test_slcan_bridge_times_and_echoes():
    peer = GC.CanFrame(0x1401557B, b"\x01\xc0", True)
    ours = GC.CanFrame(0x15552A, b"\x02\xc0", True)
    echo = GC.CanFrame(0x15552A, b"\x02\xc0", True, own=True)
    gws = GC.CanFrame(0x1001550A, b"\x03\xc0", True, own=True)  # the gateway's own
    t0 = 0xFFFFFC18  # 4294966.296 ms: the stamps are the gateway's, modulo 60000
    gw = FakeRecv([peer, echo, gws], [t0, t0 + 1500, t0 + 70_000])
    ctx = SimpleNamespace(args=SimpleNamespace(no_own=False))
    b = Bridge(ctx, None, gw, None, {"from_can": 0, "echoes": 0})
    assert b.filters == GC.PASS_ALL_OWN
    assert b.ad.feed(b"S8\rZ1\rO\r") == b"\r\r\r" and b.ad.timestamps
    b.sent.append(ours)  # the client sent it: its copy is not handed back
    b._recv()
    stamp = lambda us: b"%04X" % (us // 1000 % 60000)  # noqa: E731
    assert bytes(b.out).split(b"\r") == [
        b"T1401557B201C0" + stamp(t0),
        b"T1001550A203C0" + stamp(t0 + 70_000),
        b"",
    ]
    assert gw.opts == [GC.RECV_TIMES] and b.res == {"from_can": 2, "echoes": 1}
    assert not b.sent


# ---- the real stack ----


class MgmtRig(Rig):
    """Rig (dan-vbus: tmp/dan0 ours, dan1 the gateway; the hub: can0 the
    gateway, can1 the parameter node (node 50, 100 parameters, its requests
    logged), can2.. for the test) with the bus moved to 115200 once."""

    def __init__(self, procs, tmp, ncan=4, gw_args=(), params=True):
        super().__init__(procs, tmp, ncan, gw_args)
        self.dan = str(tmp / "dan0")
        self.param_log = tmp / "param.log"
        if params:
            p = procs.start(
                [sys.executable, ROOT / "tests" / "tools" / "param_node.py"]
                + ["--port", tmp / "can1", "--node-id", PARAM_NODE, "--log", self.param_log],
                name="param_node",
            )
            ready(p, "param_node")
        self.dp_json("stats", "--configure")

    def dp(self, *args):
        """danprobe COMMAND ... on our endpoint at 115200: (rc, out, err)."""
        return danprobe(*args, "--port", self.dan, "--baud", "115200", "-q")

    def dp_json(self, *args, rc=0):
        code, out, err = self.dp(*args, "--json")
        assert code == rc, (args, code, out, err)
        return json.loads(out.splitlines()[-1])

    def events(self, kind):
        if not self.param_log.exists():
            return []
        lines = self.param_log.read_text().splitlines()
        return [e for e in map(json.loads, lines) if e["event"] == kind]

    def stat(self, name):
        return self.dp_json("stats")["stats"][name]


@pytest.fixture
def mrig(procs, tmp_path):
    """mrig(**kw): a MgmtRig, its pydronecan nodes closed at teardown."""
    yield from closing_factory(lambda **kw: MgmtRig(procs, tmp_path, **kw))


def expected_row(p):
    row = {k: p[k] for k in ("index", "name", "type", "value", "default")}
    row.update({k: p[k] for k in ("min", "max") if k in p})
    return row


def test_param_list_get_set_save_erase(mrig):
    r = mrig()
    doc = r.dp_json("param", "list", "--node", PARAM_NODE)
    assert doc["node"] == PARAM_NODE and doc["action"] == "list"
    assert doc["params"] == [expected_row(p) for p in param_node.params(100)]  # exact
    rc, out, err = r.dp("param", "list", "--node", PARAM_NODE)
    lines = out.splitlines()
    assert rc == 0 and lines[0] == f"param list: node {PARAM_NODE}: 100 parameter(s)"
    assert lines[1].split() == ["index", "name", "type", "value", "default", "min", "max"]
    assert lines[3].split() == ["1", "real_001", "real", "-3.25", "-3.25", "-100", "101"]
    rc, out, err = r.dp("param", "get", "int_004", "--node", PARAM_NODE)
    assert rc == 0, err
    assert out == "param get: node 50: int_004 = -10 (integer; default -10, min -1000, max 1004)\n"

    # set: the value changes at the node, and the node's answer says so
    for name, value, typ, want in [
        ("int_004", "77", None, 77),
        ("real_005", "2.5", "real", 2.5),
        ("bool_002", "false", None, False),
        ("str_003", "hello DAN", "string", "hello DAN"),
    ]:
        args = ("param", "set", name, value, "--node", PARAM_NODE) + (
            ("--type", typ) if typ else ()
        )
        doc = r.dp_json(*args)
        assert doc["param"]["value"] == want and doc["param"]["name"] == name
        last = [e for e in r.events("getset") if e["set"]][-1]
        assert (last["found"], last["changed"], last["value"]) == (name, True, want)
    assert r.dp_json("param", "get", "int_004", "--node", PARAM_NODE)["param"]["value"] == 77
    # what the node does not take, and what it does not have
    rc, out, err = r.dp("param", "set", "int_008", "99999", "--node", PARAM_NODE)
    assert rc == 1 and "node 50 kept int_008 = 1008" in err and "(asked 99999)" in err
    rc, out, err = r.dp("param", "set", "int_008", "x1", "--node", PARAM_NODE, "--type", "int")
    assert rc == 2 and "'x1' is not an integer" in err
    rc, out, err = r.dp("param", "get", "no_such", "--node", PARAM_NODE)
    assert rc == 1 and "node 50 has no parameter 'no_such'" in err

    # save and erase (the node restores its defaults)
    rc, out, err = r.dp("param", "save", "--node", PARAM_NODE)
    assert rc == 0 and out == "param save: node 50: ok\n", err
    assert r.dp_json("param", "erase", "--node", PARAM_NODE)["ok"]
    assert [e["name"] for e in r.events("opcode")] == ["save", "erase"]
    assert r.dp_json("param", "get", "int_004", "--node", PARAM_NODE)["param"]["value"] == -10


def test_param_set_repeated_by_the_master_is_applied_once(mrig):
    """A NODE_CALL the master sends again with the same call_id and content
    (a retry: the same bytes on the wire), while the call is pending and
    after it is done, is one GetSet at the node."""
    r = mrig()  # the bus at 115200 now
    with SerialPort(r.dan, 115200) as port:
        m = Master(port, [registry.lookup("can-gw")], 115200, MasterConfig(resp_latency_s=0.25))
        gw = GatewayClient(m, seed=11)
        calls_before = gw.read_stats()["calls"]
        call = M.NodeCall(gw.new_call_id(), PARAM_NODE, M.CALL_PARAM_SET, name=b"int_012")
        call.value = M.Value.integer(123)
        request = G.seal(G.CODE_NODE_CALL, G.REQUEST, call.encode())

        def send():
            return M.CallState.decode(
                G.unseal(G.CODE_NODE_CALL, G.RESPONSE, m.request(G.CODE_NODE_CALL, request))
            )

        states = [send(), send()]  # the second at once: the call is still pending
        assert states[0].state == M.CALL_PENDING and states[1].call_id == call.call_id
        done = wait_for(lambda: (q := gw.call_result(call.call_id)).state == M.CALL_DONE and q, 20)
        again = send()  # after it is done: its state, not a new call
        assert (again.state, again.result_len) == (M.CALL_DONE, done.result_len)
        result = M.ParamResult.decode(bytes(done.data))
        assert (result.name, result.value) == (b"int_012", M.Value.integer(123))
        time.sleep(1.5)  # longer than an attempt: a second GetSet would have been made by now
        assert gw.read_stats()["calls"] == calls_before + 1
    sets = [e for e in r.events("getset") if e["set"]]
    assert [(e["found"], e["value"]) for e in sets] == [("int_012", 123)]


def test_no_answer_and_restart(mrig):
    r = mrig()
    rc, out, err = r.dp("param", "get", "x", "--node", 99)  # nobody has ID 99
    assert rc == 1 and "node 99 did not answer param get 'x'" in err, err
    doc = r.dp_json("param", "list", "--node", 99, rc=1)
    assert doc["result"] == -4 and "node 99 did not answer" in doc["detail"]

    # another magic: refused by the gateway before anything is sent
    calls = r.stat("calls")
    rc, out, err = r.dp("restart", "--node", PARAM_NODE, "--magic", "0xBEEFCAFE")
    assert rc == 1 and "the gateway refused magic 0xBEEFCAFE for node 50" in err, err
    assert "--force sends it anyway" in err
    assert r.stat("calls") == calls and r.events("restart") == []
    # RestartNode's magic reaches the node
    rc, out, err = r.dp("restart", "--node", PARAM_NODE)
    assert rc == 0 and out == "restart: node 50 accepted RestartNode (magic 0xACCE551B1E)\n"
    assert [e["magic"] for e in r.events("restart")] == [M.RESTART_MAGIC]
    # forced: the node sees it (and, being no bootloader, says no)
    doc = r.dp_json("restart", "--node", PARAM_NODE, "--magic", "0xBEEFCAFE", "--force", rc=1)
    assert doc["force"] and doc["ok"] is False and "not ok" in doc["detail"]
    assert [e["magic"] for e in r.events("restart")] == [M.RESTART_MAGIC, 0xBEEFCAFE]


def test_health_nodes_flags_and_dna_table(mrig, tmp_path):
    r = mrig()
    rc, out, err = r.dp("health")
    assert rc == 0 and out == "health: OK\n", err
    # the gateway allocates an ID to an anonymous node (its own server, on by default)
    uid = bytes(range(0xC0, 0xD0))
    a = Allocatee(tmp_path / "can2", uid)
    try:
        src, node_id = a.allocate(preferred=0)
        assert (src, node_id) == (GW_NODE, 125)  # no preference: the highest free
        doc = r.dp_json("dna")
        assert doc["server_on"] and doc["entries"] == 1 and doc["capacity"] == 64
        assert doc["table"] == [{"node_id": 125, "unique_id": uid.hex()}]
        rc, out, err = r.dp("dna")
        assert out.splitlines()[0] == "dna: server on; 1 of 64 entries"
        assert out.splitlines()[2].split() == ["125", uid.hex()]
        # it starts, then falls silent: allocated, then offline
        for k in range(3):
            a.send_node_status(125, k)
            time.sleep(0.3)

        def node125():
            nodes = r.dp_json("nodes")["nodes"]
            return next((n for n in nodes if n["node_id"] == 125), None)

        n = wait_for(node125, 30, 0.2, "node 125 in the node table")
        assert n["allocated"] and not n["duplicate"]
        wait_for(lambda: node125()["offline"], 30, 0.5, "node 125 offline")
    finally:
        a.close()
    rc, out, err = r.dp("health")
    assert rc == 1 and out.startswith("health: FAIL: offline node 125"), out
    rc, out, err = r.dp("nodes")
    assert rc == 0 and out.startswith("nodes: 2 DroneCAN node(s) seen by the gateway; health FAIL")
    row = next(line for line in out.splitlines() if line.startswith("125 "))
    assert row.split()[-1] == "offline,allocated"
    # an unhealthy node comes first in the verdict (the reasons' order)
    sick = r.node(3, 60, "org.test.sick")
    sick.health = 2  # ERROR
    r.spin(sick)
    doc = wait_for(
        lambda: (lambda d: d if d["health"]["reason"] == "unhealthy" else None)(
            r.dp_json("health", rc=1)
        ),
        30,
        0.5,
        "the unhealthy node in the verdict",
    )
    assert doc["health"]["subject"] == 60 and doc["health"]["detail"] == 2
    assert doc["health"]["problems"] >= 2 and doc["health"]["verdict"] == "FAIL"


def circular_ms(a, b):
    d = (a - b) % 60000
    return min(d, 60000 - d)


def test_slcan_own_frames_and_receive_times(mrig, tmp_path):
    """A DroneCAN node on this host, through `danprobe slcan`, sees the
    gateway's node 10 (its NodeStatus; it answers GetNodeInfo) besides the
    other nodes, never its own frames back; with timestamps on, a frame's
    stamp is the gateway's receive time."""
    import dronecan

    U = dronecan.uavcan
    r = mrig()
    p, ev = start_danprobe(
        r.procs,
        "slcan",
        "--port",
        r.dan,
        "--baud",
        115200,
        "-q",
        "--link",
        tmp_path / "can_danprobe",
        name="danprobe-slcan",
    )
    node = r.node("_danprobe", LAPTOP_NODE, "org.test.laptop")
    seen = set()
    node.add_handler(U.protocol.NodeStatus, lambda e: seen.add(e.transfer.source_node_id))
    r.spin(node)
    wait_for(lambda: {GW_NODE, PARAM_NODE} <= seen, 30, what="NodeStatus of nodes 10 and 50")
    info = []
    node.request(
        U.protocol.GetNodeInfo.Request(),
        GW_NODE,
        lambda e: info.append(e.response.name.decode() if e else None),
    )
    wait_for(lambda: info, 20, what="GetNodeInfo answer from node 10")
    assert info == ["org.dan.can_gateway"]
    assert LAPTOP_NODE not in seen  # its own NodeStatus left, but did not come back
    r.close()  # the node says C, closing the channel
    summary = finish_danprobe(r.procs, p)
    assert summary["own"] and summary["echoes"] >= 1 and summary["lost"] == 0

    # Z1: the stamps are the gateway's receive times. dan-gatewayd's clock is
    # CLOCK_MONOTONIC, as time.monotonic() is: on one host they agree.
    p, ev = start_danprobe(
        r.procs, "slcan", "--port", r.dan, "--baud", 115200, "-q", name="danprobe-slcan-z1"
    )
    fd = pty_open(ev["pty"])
    try:
        os.write(fd, b"S8\rZ1\rO\r")
        got = pump_lines(fd, 6, 30)
    finally:
        os.close(fd)
    now_ms = time.monotonic() * 1000 % 60000
    frames = [line for line in got if line[:1] == b"T"]
    assert len(frames) >= 4, got
    for line in frames:
        n = int(line[9:10], 16)
        stamp = line[10 + 2 * n :]
        assert len(stamp) == 4 and int(stamp, 16) < 60000, line
        assert circular_ms(int(stamp, 16), now_ms) < 35000, (line, now_ms)
    finish_danprobe(r.procs, p)

    # can dump --own: the gateway's NodeStatus (node 10), marked own, host-clock times
    t_before = time.time()
    rc, out, err = r.dp(
        "can", "dump", "--own", "--filter", "1550A:FFFFFF:ext", "--count", "2", "--json"
    )
    docs = [json.loads(x) for x in out.splitlines()]
    frames = [d for d in docs if d.get("event") == "frame"]
    assert rc == 0 and len(frames) == 2, (out, err)
    assert all(f["own"] and f["id"] & 0xFFFFFF == 0x01550A for f in frames)
    assert t_before - 5 < frames[0]["time"] <= frames[1]["time"] < time.time() + 1


def pump_lines(fd, want, timeout):
    """CR-ended lines read from fd until `want` frame lines came (or timeout)."""
    buf, end = b"", time.monotonic() + timeout
    while time.monotonic() < end:
        if select.select([fd], [], [], 0.1)[0]:
            try:
                buf += os.read(fd, 4096)
            except BlockingIOError:
                pass
        lines = buf.split(b"\r")
        if sum(1 for x in lines[:-1] if x[:1] == b"T") >= want:
            break
    return buf.split(b"\r")[:-1]


def allocator_on_laptop(r, node_id, name):
    """A pydronecan node through the SLCAN pty (tmp/can_danprobe) with a
    node monitor and a CentralizedServer, spun by a thread of its own (the
    server's table is SQLite: made, used and closed in that thread); returns
    the monitor once it runs. Rig.close() stops the thread."""
    from dronecan.app.dynamic_node_id import CentralizedServer
    from dronecan.app.node_monitor import NodeMonitor

    node = r.node("_danprobe", node_id, name)
    made = []

    def loop():
        monitor = NodeMonitor(node)
        server = CentralizedServer(node, monitor)
        made.append(monitor)
        try:
            while not r.stop.is_set():
                try:
                    node.spin(0.01)
                except Exception:  # a malformed frame must not end the thread
                    pass
        finally:
            server.close()

    t = threading.Thread(target=loop, daemon=True)
    t.start()
    r.threads.append(t)
    return wait_for(lambda: made and made[0], 30, what="the allocation server")


def gateway_dna_off(r):
    """The gateway's own allocation server off: dan-gatewayd --no-dna when
    this build has it, else CONFIG (danprobe dna --server off)."""
    doc = r.dp_json("dna") if r.no_dna_flag else r.dp_json("dna", "--server", "off")
    assert not doc["server_on"] and doc["entries"] == 0


def gatewayd_has(flag):
    h = subprocess.run([BIN / "dan-gatewayd", "--help"], capture_output=True, timeout=30)
    return flag in (h.stdout + h.stderr).decode()


def allocate_through_slcan(r, own: bool, uid: bytes):
    """danprobe slcan (with or without the gateway's own frames), the
    laptop's allocation server behind it, an allocatee asking for node ID
    10 on the bus: (allocator, node ID) it got."""
    p, ev = start_danprobe(
        r.procs,
        *("slcan", "--port", r.dan, "--baud", 115200, "-q", "--link", r.tmp / "can_danprobe"),
        *(() if own else ("--no-own",)),
        name=f"danprobe-slcan-{'own' if own else 'no-own'}",
    )
    monitor = allocator_on_laptop(r, LAPTOP_NODE, "org.test.allocator")
    a = Allocatee(r.tmp / "can2", uid)
    try:
        if own:
            wait_for(
                lambda: monitor.exists(GW_NODE) and monitor.are_all_nodes_discovered(),
                30,
                what="node 10 discovered by the laptop's node monitor",
            )
        return a.allocate(preferred=GW_NODE)
    finally:
        a.close()
        r.close()
        r.nodes, r.threads = [], []
        r.stop.clear()
        finish_danprobe(r.procs, p)


def test_allocator_through_slcan_skips_the_gateway_node(procs, tmp_path):
    """pydronecan's allocation server on this host, through `danprobe slcan`,
    sees node 10 (the gateway's own frames) and so never hands 10 out, even
    to an allocatee that asks for it. Without the own frames (--no-own) it
    does: the failure the own frames prevent."""
    no_dna = gatewayd_has("--no-dna")
    r = MgmtRig(procs, tmp_path, gw_args=("--no-dna",) if no_dna else (), params=False)
    r.no_dna_flag = no_dna
    try:
        gateway_dna_off(r)
        src, node_id = allocate_through_slcan(r, True, bytes([0xA1] * 16))
        assert src == LAPTOP_NODE and node_id not in (0, GW_NODE, LAPTOP_NODE)
        assert node_id == GW_NODE + 1  # pydronecan: the first free ID from the preferred one up
        blind = allocate_through_slcan(r, False, bytes([0xB2] * 16))
        assert blind == (LAPTOP_NODE, GW_NODE)  # blind to node 10: handed out
        assert r.dp_json("dna")["entries"] == 0  # the gateway allocated nothing
    finally:
        r.close()


def test_sniff_names_and_arguments(monkeypatch):
    """sniff names and decodes the new codes; bad arguments are exit 2."""
    from danprobe import gateway_client, registry

    # names registered here only: other tests see the registry as it was
    monkeypatch.setattr(registry, "_MESSAGES", dict(registry._MESSAGES))
    gateway_client.register_names()
    assert registry.code_name(G.CODE_HEALTH) == "can-gw HEALTH"
    assert registry.code_name(G.CODE_NODE_CALL) == "can-gw NODE_CALL"
    sealed = G.seal(G.CODE_HEALTH, G.RESPONSE, M.Health(1, M.REASON_OFFLINE, 125, 0, 1).encode())
    role, fields, _ = registry.describe(G.CODE_HEALTH, sealed, registry.RESPONSE)
    assert role == registry.RESPONSE and fields["reason"] == "offline" and fields["subject"] == 125
    call = M.NodeCall(9, 50, M.CALL_PARAM_SET, name=b"int_004", value=M.Value.integer(7))
    sealed = G.seal(G.CODE_NODE_CALL, G.REQUEST, call.encode())
    _, fields, _ = registry.describe(G.CODE_NODE_CALL, sealed, registry.REQUEST)
    assert fields == {
        "call_id": 9,
        "node_id": 50,
        "op": 2,
        "op_name": "param set",
        "name": "int_004",
        "type": "integer",
        "value": 7,
    }
    for args, message in [
        (["param", "get", "--port", "x", "--node", "0", "n"], "--node must be 1..127"),
        (["param", "set", "--port", "x", "--node", "5", "n"], "VALUE"),
        (
            ["param", "set", "--port", "x", "--node", "5", "n", "1.5", "--type", "int"],
            "not an integer",
        ),
        (
            ["param", "set", "--port", "x", "--node", "5", "n", "maybe", "--type", "bool"],
            "not a boolean",
        ),
        (["param", "--port", "x"], "list|get|set|save|erase"),
        (["restart", "--port", "x"], "--node"),
        (["restart", "--port", "x", "--node", "5", "--magic", "0x10000000000"], "40 bits"),
        (["dna", "--port", "x", "--server", "maybe"], "invalid choice"),
        (["slcan", "--port", "x", "--no-own", "--own"], "unrecognized arguments"),
    ]:
        rc, out, err = danprobe(*args)
        assert rc == 2 and message in err, (args, rc, err)
    for cmd in (["health"], ["dna"], ["restart"], ["param", "list"], ["param", "set"]):
        rc, out, err = danprobe(*cmd, "--help")
        assert rc == 0 and "--bus-baud" in out and "--configure" in out and "--json" in out
    rc, out, err = danprobe("slcan", "--help")
    assert rc == 0 and "--no-own" in out
    rc, out, err = danprobe("can", "dump", "--help")
    assert rc == 0 and "--own" in out
