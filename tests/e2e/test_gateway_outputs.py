"""Outputs at parity with ArduPilot (issue 12) end to end through the C
client: dan-fcsim (libdan master + gateway client, built to keep 20 ESCs'
telemetry) on a dan-vbus endpoint, dan-gatewayd on the other, an SLCAN hub
as the CAN bus and pydronecan nodes as the independent DroneCAN peers that
record exactly what arrives (docs/PROTOCOL.md section 7, "Outputs",
"Tunnels", "Raw frames", "Node table").

Deadlines are generous and catch hangs; nothing here asserts a speed.
"""

import itertools
import os
import struct
import threading

import dronecan
import pytest

import pydronecan_nodes
from conftest import BIN, closing_factory, wait_for
from gw_rig import GW_NODE, Rig, TunnelFarEnd

U = dronecan.uavcan
SafetyState = dronecan.ardupilot.indication.SafetyState

FLAG_ARMED, FLAG_FAILSAFE, FLAG_SAFETY_OFF = 1, 2, 8
REFUSED = "peer answered with an error frame"


def state_flags(hex_response):
    """A flags response's armed, failsafe and safety bits (not CAN up)."""
    return int(hex_response, 16) & (FLAG_ARMED | FLAG_FAILSAFE | FLAG_SAFETY_OFF)


def f16(x):
    """x rounded to float16, as it travels in the DSDL messages."""
    return struct.unpack("<e", struct.pack("<e", x))[0]


# What each recorded message becomes: plain values, compared exactly.
PLAIN = {
    SafetyState: lambda m: m.status,
    U.equipment.safety.ArmingStatus: lambda m: m.status,
    U.equipment.esc.RawCommand: lambda m: list(m.cmd),
    U.equipment.actuator.ArrayCommand: lambda m: [
        (c.actuator_id, c.command_type, c.command_value) for c in m.commands
    ],
    U.equipment.indication.LightsCommand: lambda m: [
        (c.light_id, c.color.red, c.color.green, c.color.blue) for c in m.commands
    ],
    U.equipment.indication.BeepCommand: lambda m: (m.frequency, m.duration),
}


class Heard:
    """Every message of the given types a pydronecan node hears from the
    gateway, in order of arrival, as the plain values of PLAIN."""

    def __init__(self, node, *types):
        self.lock = threading.Lock()
        self.msgs = {t: [] for t in types}
        for t in types:
            node.add_handler(t, lambda e, t=t: self._add(t, e))

    def _add(self, t, e):
        if e.transfer.source_node_id == GW_NODE:
            with self.lock:
                self.msgs[t].append(PLAIN[t](e.message))

    def of(self, t):
        with self.lock:
            return list(self.msgs[t])

    def changes(self, t):
        """The values with repeats in a row folded: the states in turn."""
        return [k for k, _ in itertools.groupby(self.of(t))]


@pytest.fixture
def rig(procs, tmp_path):
    yield from closing_factory(lambda **kw: Rig(procs, tmp_path, **kw))


def step(lines, name):
    return [line for line in lines if line["step"] == name]


def failed(out):
    return [line for line in out if not line.get("ok", True)] or out


def listener(r, k, node_id, *types):
    """A pydronecan node on hub port k recording types (a Heard)."""
    node = r.node(k, node_id, "org.test.listener")
    heard = Heard(node, *types)
    r.spin(node)
    return heard


def test_safety_servos_lights_beep_and_failsafe(rig):
    # a long timeout: a stalled host must not start the failsafe mid-script
    r = rig(ncan=2, gw_args=["--esc-timeout-ms", "2000"])
    h = listener(r, 1, 60, *PLAIN)
    wait_for(lambda: h.of(SafetyState), 20, what="SafetyState from power-up")
    assert set(h.of(SafetyState)) == {0}  # safety ON until the FC says otherwise

    rc, out = r.fcsim(
        "discover",
        "configure",
        # actuator 1 holds, 2 gets -0.5 unitless, 3 is not listed (holds)
        "servo-fs:1=hold,2=-0.5:0",
        "safety:off",
        "arm",
        "lights:1=F800,2=07E0,7=001F,9=FFFF,200=1234",
        "beep:2000:250",
        "beep:440:1234",
        "esc:100,200,300,400@300@50",
        "servo:1=0.1,2=1500:4,3=0.75:1",
        "stop",  # the FC goes silent: ESC and servo commands stop
    )
    assert rc == 0, failed(out)
    assert step(out, "servo-fs")[0]["kept"] == 2
    assert step(out, "safety")[0]["flags"] & FLAG_SAFETY_OFF
    normal = [(1, 0, f16(0.1)), (2, 4, 1500.0), (3, 1, 0.75)]
    failsafe = [(1, 0, f16(0.1)), (2, 0, -0.5), (3, 1, 0.75)]
    AC = U.equipment.actuator.ArrayCommand
    wait_for(lambda: h.of(AC).count(failsafe) >= 2, 20, what="failsafe servos, repeated")
    wait_for(lambda: h.changes(SafetyState)[-1:] == [0], 20, what="safety ON after the failsafe")
    wait_for(lambda: h.changes(U.equipment.safety.ArmingStatus)[-1:] == [0], 20, what="DISARMED")
    # the states in turn, exactly: nothing else was ever sent
    assert h.changes(SafetyState) == [0, 255, 0]
    assert h.changes(U.equipment.safety.ArmingStatus) == [0, 255, 0]
    assert h.changes(AC) == [normal, failsafe]
    assert h.changes(U.equipment.esc.RawCommand) == [[100, 200, 300, 400], [0, 0, 0, 0]]
    lights = [(1, 31, 0, 0), (2, 0, 63, 0), (7, 0, 0, 31), (9, 31, 63, 31), (200, 2, 17, 20)]
    LC = U.equipment.indication.LightsCommand
    assert h.of(LC) and all(x == lights for x in h.of(LC))  # a retry sends it again
    BC = U.equipment.indication.BeepCommand
    assert h.changes(BC) == [(2000.0, 0.25), (440.0, f16(1.234))]

    # the flags show it; the FC resumes with safety off again
    rc, out = r.fcsim("discover", "config", "safety:off")
    assert rc == 0, failed(out)
    flags = step(out, "config")[0]["flags"]
    assert flags & FLAG_FAILSAFE and not flags & (FLAG_SAFETY_OFF | FLAG_ARMED)
    assert step(out, "safety")[0]["flags"] & FLAG_SAFETY_OFF
    wait_for(lambda: h.changes(SafetyState) == [0, 255, 0, 255], 20, what="safety off again")


def test_device_temperature_and_status_extended_reach_the_fc(rig):
    r = rig(ncan=3)
    esc = r.node(1, 20, "org.test.esc")
    other = r.node(2, 21, "org.test.thermometer")  # no ESC telemetry: not kept

    def publish():
        for idx, v in ((0, 15.5), (1, 16.25)):
            esc.broadcast(
                U.equipment.esc.Status(
                    error_count=7 + idx,
                    voltage=v,
                    current=2.25,
                    temperature=310.5,
                    rpm=4321 - idx,
                    power_rating_pct=33,
                    esc_index=idx,
                )
            )
        esc.broadcast(
            U.equipment.esc.StatusExtended(
                input_pct=55,
                output_pct=44,
                motor_temperature_degC=-12,
                motor_angle=300,
                status_flags=0x5A5A5,
                esc_index=0,
            )
        )
        esc.broadcast(U.equipment.device.Temperature(device_id=7, temperature=333.3, error_flags=1))

    def publish_other():
        other.broadcast(
            U.equipment.device.Temperature(device_id=7, temperature=250.0, error_flags=2)
        )

    r.spin(esc, publish, 0.1)
    r.spin(other, publish_other, 0.1)

    def telemetry():
        rc, out = r.fcsim("discover", "telemetry")
        assert rc == 0, failed(out)
        tel = {e["index"]: e for e in step(out, "telemetry")[0]["esc"]}
        return tel if {i: e["flags"] for i, e in tel.items()} == {0: 7, 1: 5} else None

    tel = wait_for(telemetry, 60, interval=0.5, what="telemetry with StatusExtended, Temperature")
    for idx, v in ((0, 15.5), (1, 16.25)):
        e = tel[idx]
        assert e["node"] == 20 and e["voltage"] == v and e["current"] == 2.25
        assert e["temperature"] == 310.5 and e["rpm"] == 4321 - idx
        assert e["error_count"] == 7 + idx and e["power_pct"] == 33
        # the thermometer node's 250 K never joins: only the ESC's own node
        assert e["dev_temp"] == f16(333.3) and e["dev_flags"] == 1
        assert 0 <= e["dev_age_ms"] < 10000
    e = tel[0]
    assert (e["input_pct"], e["output_pct"], e["motor_temp_c"]) == (55, 44, -12)
    assert (e["motor_angle"], e["status_flags"]) == (300, 0x5A5A5)
    assert 0 <= e["ext_age_ms"] < 10000
    assert "input_pct" not in tel[1]


def test_twenty_escs_commands_and_telemetry(rig):
    r = rig(ncan=3)
    h = listener(r, 1, 60, U.equipment.esc.RawCommand)
    escs = r.node(2, 20, "org.test.esc20")

    def publish():
        for idx in range(20):
            escs.broadcast(
                U.equipment.esc.Status(
                    error_count=idx * 3,
                    voltage=10.0 + idx * 0.5,
                    current=idx * 0.25,
                    temperature=300.0 + idx,
                    rpm=idx * 100 - 1000,
                    power_rating_pct=idx * 5,
                    esc_index=idx,
                )
            )

    r.spin(escs, publish, 0.25)
    values = [-8192, 8191] + [i * 397 - 3000 for i in range(18)]
    cmd = "esc:" + ",".join(map(str, values)) + "@1500@50"

    def telemetry():
        rc, out = r.fcsim("discover", "configure", cmd, "telemetry")
        assert rc == 0, failed(out)
        tel = {e["index"]: e for e in step(out, "telemetry")[0]["esc"]}
        return tel if len(tel) == 20 and step(out, "esc")[0]["esc_seen"] == 20 else None

    tel = wait_for(telemetry, 90, interval=0.5, what="telemetry of 20 ESCs")
    assert values in h.of(U.equipment.esc.RawCommand)  # all 20 values, exactly
    assert set(tel) == set(range(20))
    for idx, e in tel.items():
        assert e["node"] == 20 and e["flags"] == 1 and e["error_count"] == idx * 3
        assert e["voltage"] == f16(10.0 + idx * 0.5) and e["current"] == idx * 0.25
        assert e["temperature"] == 300.0 + idx and e["rpm"] == idx * 100 - 1000
        assert e["power_pct"] == idx * 5


def test_out_of_range_arm_and_safety_refused(rig):
    r = rig(ncan=2)
    h = listener(r, 1, 60, U.equipment.safety.ArmingStatus, SafetyState)
    wait_for(lambda: h.of(U.equipment.safety.ArmingStatus), 20, what="ArmingStatus at power-up")
    wait_for(lambda: h.of(SafetyState), 20, what="SafetyState at power-up")
    rc, out = r.fcsim(
        "discover",
        "configure",
        "raw:0x44:ff",  # a hand-made ARM 255: accepted, armed
        "raw:0x44:07",
        "raw:0x54:07",
        "raw:0x54:ff",
        "raw:0x44:00",
    )
    raws = [x for x in out if x["step"].startswith("raw")]  # a failure names the whole step
    assert rc == 1  # the two refused steps
    assert [x["ok"] for x in raws] == [True, False, False, True, True]
    assert state_flags(raws[0]["response"]) == FLAG_ARMED
    assert raws[1]["error"] == REFUSED and "ARM takes 0 or 255" in raws[1]["remote"], raws[1]
    assert raws[2]["error"] == REFUSED and "SAFETY takes 0 or 255" in raws[2]["remote"], raws[2]
    assert state_flags(raws[3]["response"]) == FLAG_ARMED | FLAG_SAFETY_OFF
    assert state_flags(raws[4]["response"]) == FLAG_SAFETY_OFF
    wait_for(lambda: h.changes(U.equipment.safety.ArmingStatus)[-1:] == [0], 20, what="disarmed")
    wait_for(lambda: h.changes(SafetyState)[-1:] == [255], 20, what="safety off")
    # 7 was never sent: the state went 0 -> 255 -> 0 only
    assert h.changes(U.equipment.safety.ArmingStatus) == [0, 255, 0]
    assert h.changes(SafetyState) == [0, 255]


def xfer(r, port, data, want, timeout_ms, *before):
    """fcsim: discover, configure, the steps before, then an xfer of data
    reading want bytes; (exit code, the lines, the bytes read)."""
    src, dst = r.tmp / f"x{port}_in.bin", r.tmp / f"x{port}_out.bin"
    src.write_bytes(data)
    rc, out = r.fcsim(
        "discover", "configure", *before, f"xfer:{port}:{src}:{dst}:{want}:{timeout_ms}"
    )
    return rc, out, dst.read_bytes() if dst.exists() else b""


def test_targetted_tunnel_default_serial_and_open_fields(rig):
    r = rig(ncan=3)
    # asked for -1, answers as its port 2 (AP_Periph resolves -1 so)
    far = TunnelFarEnd(r.node(1, 30, "org.test.far_default"), 30, -1, reply_serial_id=2)
    r.spin(far.node, far.pump, 0.005)
    # a port opened for serial 1 must not take the answers on serial 2
    strict = TunnelFarEnd(r.node(2, 31, "org.test.far_strict"), 31, 1, reply_serial_id=2)
    r.spin(strict.node, strict.pump, 0.005)

    data = os.urandom(1000)
    rc, out, back = xfer(r, 0, data, len(data), 60000, "tunnel:0:targetted:30:-1:57600:1")
    assert rc == 0, failed(out)
    assert bytes(far.got) == data
    assert back == bytes(b ^ 0x5A for b in data)
    # every message, keepalives too: protocol UNDEFINED and TUN_OPEN's fields
    assert far.heard and set(far.heard) == {(255, -1, 1, 57600)}

    rc, out, back = xfer(r, 1, b"abc" * 10, 30, 4000, "tunnel:1:targetted:31:1:921600:0")
    assert rc == 1 and step(out, "xfer")[0]["read"] == 0 and back == b""
    assert bytes(strict.got) == b"abc" * 10  # it was sent and answered
    assert set(strict.heard) == {(255, 1, 0, 921600)}


class BroadcastFarEnd:
    """A node on a Broadcast tunnel (protocol, channel) that answers every
    chunk from the gateway XORed with 0x5A on another channel_id, as some
    nodes do (Vertiq modules, seed 003)."""

    def __init__(self, node, protocol, channel, reply_channel):
        self.node, self.protocol = node, protocol
        self.channel, self.reply_channel = channel, reply_channel
        self.got, self.outq = bytearray(), bytearray()
        self.lock = threading.Lock()
        node.add_handler(U.tunnel.Broadcast, self._on_broadcast)

    def _on_broadcast(self, e):
        m = e.message
        if (
            e.transfer.source_node_id == GW_NODE
            and m.protocol.protocol == self.protocol
            and m.channel_id == self.channel
        ):
            data = bytes(m.buffer)
            with self.lock:
                self.got.extend(data)
                self.outq.extend(bytes(b ^ 0x5A for b in data))

    def pump(self):
        with self.lock:
            chunk = bytes(self.outq[:60])
            del self.outq[:60]
        if chunk:
            self.node.broadcast(
                U.tunnel.Broadcast(
                    protocol=U.tunnel.Protocol(protocol=self.protocol),
                    channel_id=self.reply_channel,
                    buffer=list(chunk),
                )
            )


def test_broadcast_tunnel_any_channel(rig):
    r = rig(ncan=2)
    far = BroadcastFarEnd(r.node(1, 32, "org.test.bcast_other_channel"), 2, 7, 9)
    r.spin(far.node, far.pump, 0.005)

    # without the option the answers on channel 9 are not ours
    rc, out, back = xfer(r, 0, b"xyz" * 20, 60, 4000, "tunnel:0:broadcast:2:7")
    assert rc == 1 and step(out, "xfer")[0]["read"] == 0 and back == b""
    assert bytes(far.got) == b"xyz" * 20
    assert step(out, "tunnel")[0]["options"] == 0

    data = os.urandom(600)
    with far.lock:
        far.got.clear()
    rc, out, back = xfer(r, 1, data, len(data), 60000, "tunnel:1:broadcast:2:7:1")
    assert rc == 0, failed(out)
    assert step(out, "tunnel")[0]["options"] == 1
    assert bytes(far.got) == data
    assert back == bytes(b ^ 0x5A for b in data)


def test_filter_add_remove_and_table_full(rig):
    r = rig(ncan=2)
    table = [f"{0x400 + i:03X}/7FF" for i in range(16)]  # DAN_GW_FILTERS_MAX entries
    rc, out = r.fcsim(
        "discover",
        "configure",
        "filter:" + ",".join(table),
        "filter-add:123/7FF",  # one more than the table holds
        "filter-remove:" + table[3],
        "filter-remove:" + table[3],  # absent now: nothing changes
        "filter-add:123/7FF",
        "filter-add:123/7FF",  # present: nothing changes
        "filter:200/7FF,12345678/1FFFFFFF",
        "filter-remove:200/7FF",
        "filter-add:300/7FF",
        "filter-read",
    )
    assert rc == 1  # the add to the full table
    f = [x for x in out if x["step"].startswith("filter")]
    assert [x["ok"] for x in f] == [True, False] + [True] * 8
    assert f[0]["table"] == table and f[0]["result"] == 0
    assert f[1]["result"] == 1 and f[1]["table"] == table  # full: unchanged
    fewer = [t for t in table if t != table[3]]
    assert sorted(f[2]["table"]) == sorted(fewer) and f[2]["entries"] == 15
    assert sorted(f[3]["table"]) == sorted(fewer)
    assert sorted(f[4]["table"]) == sorted(fewer + ["123/7FF"]) and f[4]["entries"] == 16
    assert sorted(f[5]["table"]) == sorted(f[4]["table"])
    assert sorted(f[6]["table"]) == ["12345678/1FFFFFFF", "200/7FF"]
    assert f[7]["table"] == ["12345678/1FFFFFFF"]
    assert sorted(f[9]["table"]) == ["12345678/1FFFFFFF", "300/7FF"]

    # end to end: 200 removed, 300 added, the 29-bit entry kept
    snd = r.procs.start(
        [
            BIN / "dan-cantool",
            "--can",
            f"slcan:{r.tmp / 'can1'}",
            "send",
            "200#01",
            "300#02",
            "12345678#03",
            "12345679#04",
        ]
    )
    assert snd.wait(20) == 0
    rc, out = r.fcsim("discover", "candump:2:20000", "candump:1:2000")
    dumps = step(out, "candump")
    assert dumps[0]["ok"] and dumps[0]["frames"] == ["300#02", "12345678#03"], dumps
    assert dumps[1]["frames"] == [] and rc == 1  # nothing else passed


def restart_node(r, k, node_id, name, sw):
    """A new pydronecan node on hub port k with node_id, name and software
    version sw (its uptime starts at 0 again)."""
    info = U.protocol.GetNodeInfo.Response()
    info.name = name
    info.software_version.major, info.software_version.minor = sw
    node = pydronecan_nodes.make_node(r.tmp / f"can{k}", node_id, node_info=info)
    r.nodes.append(node)
    r.spin(node)
    return node


def test_node_info_asked_again_after_a_restart(rig):
    r = rig(ncan=2)
    first = restart_node(r, 1, 40, "org.test.before", (1, 2))

    def node40(name, min_uptime=0):
        rc, out = r.fcsim("discover", "nodes")
        assert rc == 0, failed(out)
        n = {x["id"]: x for x in step(out, "nodes")[0]["nodes"]}.get(40)
        return n if n and n["name"] == name and n["uptime"] >= min_uptime else None

    n = wait_for(lambda: node40("org.test.before", 3), 60, interval=0.5, what="first node info")
    assert n["info"] == 2 and n["sw"] == [1, 2]
    r.stop.set()  # its spin thread ends; then it goes away
    for t in r.threads:
        t.join(5)
    r.threads.clear()
    r.stop.clear()
    pydronecan_nodes.close_nodes([first])
    r.nodes.remove(first)
    restart_node(r, 1, 40, "org.test.after", (3, 4))
    n = wait_for(lambda: node40("org.test.after"), 60, interval=0.5, what="new node info")
    assert n["info"] == 2 and n["sw"] == [3, 4]
