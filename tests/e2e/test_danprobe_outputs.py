"""danprobe's output commands (docs/PROTOCOL.md section 7, "Outputs"):
safety, arm --safety-off, servo (and its failsafe table), lights, beep;
the device temperature in telemetry; negative value lists on the command
line; the tunnel's default serial port and any-channel option.

First the codec, the client and the argument parsing without a bus; then
the real stack (dan-vbus, slcan_hub.py, dan-gatewayd), with a pydronecan
listener on the hub recording exactly what the gateway broadcast.

Deadlines are generous and catch hangs; nothing here asserts a speed.
"""

import json
import os
import struct
import threading

import pytest

from bus_util import danprobe
from conftest import closing_factory, wait_for
from danprobe import gateway_msgs as G
from danprobe import gateway_out as O
from danprobe.cli import build_parser
from danprobe.gateway_client import GatewayClient
from danprobe.payloads import PayloadError
from gw_rig import GW_NODE, Stack, TunnelFarEnd, danprobe_json, pty_open, pump_pty


def f16(x):
    """x rounded to binary16, as a float."""
    return struct.unpack("<e", struct.pack("<e", x))[0]


# ---- without a bus ----


def test_output_codec_details():
    # RGB565 keeps each channel's high bits
    for rgb, want in [
        (0xFF0000, 0xF800),
        (0x00FF00, 0x07E0),
        (0x0000FF, 0x001F),
        (0xFFFFFF, 0xFFFF),
        (0x808080, 0x8410),
        (0x07030F, 0x0001),
        (0x000000, 0x0000),
    ]:
        assert O.rgb565_from_rgb(rgb) == want, hex(rgb)
    assert O.rgb565_fields(0x8410) == (16, 32, 16)
    # float16: rounded to nearest; beyond 65504 refused
    assert [O.f16_bits(x) for x in (65519, 0.1, 1500, -1)] == [0x7BFF, 0x2E66, 0x65DC, 0xBC00]
    assert O.ServoCommand.make(7, O.TYPE_PWM, 1500).value == 1500.0
    assert O.ServoFailsafe.value_of(7, O.TYPE_PWM, 1100).text() == "7=1100 pwm"
    assert O.ServoFailsafe.hold(3).as_dict() == {"actuator_id": 3, "mode": "hold"}
    for bad in (
        lambda: O.f16_bits(65520),
        lambda: O.f16_bits(float("inf")),
        lambda: O.f16_bits(float("nan")),
        lambda: O.encode_safety(1),
        lambda: O.ServoRequest([]).encode(),
        lambda: O.ServoRequest([O.ServoCommand(0, 5, 0)]).encode(),
        lambda: O.ServoRequest([O.ServoCommand(i) for i in range(33)]).encode(),
        lambda: O.ServoFailsafeTable([O.ServoFailsafe(0, 2)]).encode(),
        lambda: O.LightsRequest([O.Light(i) for i in range(21)]).encode(),
        lambda: O.Beep(0, 1).encode(),
        lambda: O.Beep(65505, 1).encode(),
        lambda: O.Beep(1, 65504001).encode(),
        lambda: O.rgb565_from_rgb(1 << 24),
    ):
        with pytest.raises(ValueError):
            bad()
    for decode, hexs in [
        (O.decode_safety, "01"),
        (O.decode_safety, ""),
        (O.ServoRequest.decode, "00"),  # n 0
        (O.ServoRequest.decode, "21" + "00000000" * 33),  # n 33
        (O.ServoRequest.decode, "0100050000"),  # command_type 5
        (O.ServoRequest.decode, "02000100"),  # cut short
        (O.ServoFailsafeTable.decode, "0100100000"),  # kind bit 4
        (O.ServoFailsafeTable.decode, "0100850000"),  # VALUE with command_type 5
        (O.ServoFailsafeTable.decode, "21"),  # n 33
        (O.LightsRequest.decode, "00"),
        (O.LightsRequest.decode, "15" + "000000" * 21),
        (O.Beep.decode, "0000"),  # 0 Hz
        (O.Beep.decode, "e1ff0300"),  # 65505 Hz
        (O.Beep.decode, "01818786ca1f"),  # 65504001 ms
        (G.Telemetry.decode, "010001000104"),  # device record cut short
    ]:
        with pytest.raises(PayloadError):
            decode(bytes.fromhex(hexs))
    # the new flag and telemetry bit
    assert G.flags_names(0x0C) == ["can-up", "safety-off"] and G.flags_dict(8)["safety_off"]
    rec = G.TelemRecord(2, 30, G.TELEM_DEVICE, dev_age_ms=12, dev_temp_f16=0x5CF8, dev_flags=1)
    d = G.Telemetry.decode(G.Telemetry(1, 2, [rec]).encode()).records[0].as_dict()
    assert d["dev_temperature"] == 318.0 and d["overheating"] and not d["status"]


class FlagsMaster:
    """Answers every request with `reply` (sealed); .sent: (code, inner)."""

    def __init__(self, reply):
        self.reply, self.sent, self.reply_check = reply, [], None

    def request(self, code, payload=b"", attempts=None):
        self.sent.append((code, G.unseal(code, G.REQUEST, payload)))
        return G.seal(code, G.RESPONSE, self.reply)


def test_client_output_calls():
    m = FlagsMaster(bytes([0x0C]))
    gw = GatewayClient(m)
    assert gw.safety(True) == 0x0C and gw.flags == 0x0C
    gw.safety(False)
    gw.servo([(0, O.TYPE_POSITION, 0.5), O.ServoCommand.make(7, O.TYPE_PWM, 1500)])
    assert gw.servo_failsafe([O.ServoFailsafe.hold(1), O.ServoFailsafe(2)]) == 0x0C
    assert gw.servo_fs_kept == 0x0C
    gw.lights([O.Light(0, 0xF800)])
    gw.beep(2000, 100)
    assert m.sent == [
        (O.CODE_SAFETY, b"\xff"),
        (O.CODE_SAFETY, b"\x00"),
        (O.CODE_SERVO, bytes.fromhex("02000100380704dc65")),
        (O.CODE_SERVO_FAILSAFE, bytes.fromhex("020100000002000000")),
        (O.CODE_LIGHTS, bytes.fromhex("010000f8")),
        (O.CODE_BEEP, bytes.fromhex("d00f64")),
    ]


def parse(*argv):
    return build_parser().parse_args([str(a) for a in argv])


def test_negative_values_parse_in_every_list_option():
    """argparse took '-8192,-1,0' for an option ('expected one argument')."""
    assert parse("esc", "--port", "x", "--values", "-8192,-1,0,8191").values == [-8192, -1, 0, 8191]
    assert parse("esc", "--port", "x", "--values", "-50%,-1").values == [-4096, -1]
    assert parse("esc", "--port", "x", "--ramp", "-10%:10%").ramp == (-819, 819)
    assert parse("esc", "--port", "x", "--ramp", "-8192:-100").ramp == (-8192, -100)
    assert parse("esc", "--port", "x", "--throttle", "-5").throttle == -410
    a = parse("servo", "--port", "x", "--set", "0=-1,1=-0.25:position", "--failsafe", "2=-0.5")
    assert [c.text() for c in a.set[0]] == ["0=-1 unitless", "1=-0.25 position"]
    assert a.failsafe[0][0].text() == "2=-0.5 unitless"
    assert parse("param", "set", "--port", "x", "--node", "5", "n", "-1e3").value == "-1e3"
    assert parse("param", "set", "--port", "x", "--node", "5", "n", "-.5").value == "-.5"
    assert parse("tunnel", "--port", "x", "--target", "5", "--serial-id", "-1").serial_id == -1
    # the real command line: the port error, not an argument error
    rc, out, err = danprobe("esc", "--port", "/nonexistent/tty", "--values", "-8192,-1,0")
    assert rc == 2 and "No such file or directory" in err, err
    rc, out, err = danprobe("esc", "--help")
    assert rc == 0 and "--values -8192,-1,0,8191" in out and "--ramp -10%:10%" in out


def test_output_commands_arguments_and_help():
    a = parse("lights", "--port", "x", "--light", "0=ff0000", "--light", "1=#00FF00,19=565:ffe0")
    assert [x.rgb565 for g in a.light for x in g] == [0xF800, 0x07E0, 0xFFE0]
    a = parse("servo", "--port", "x", "--set", "7=1500:pwm", "--failsafe", "3=hold,7=1100:4")
    assert a.set[0][0] == O.ServoCommand(7, O.TYPE_PWM, 0x65DC)
    assert [e.text() for e in a.failsafe[0]] == ["3=hold", "7=1100 pwm"]
    for args, message in [
        (["safety", "--port", "x", "maybe"], "invalid choice"),
        (["servo", "--port", "x"], "--set ID=VALUE[:TYPE], --failsafe or --failsafe-clear"),
        (["servo", "--port", "x", "--set", "3=1500"], "(PWM? write 1500:pwm)"),
        (["servo", "--port", "x", "--set", "3=0.5:angle"], "command type 'angle'"),
        (["servo", "--port", "x", "--set", "256=0"], "ID 256 is outside 0..255"),
        (["servo", "--port", "x", "--set", "3"], "expected ID=VALUE[:TYPE]"),
        (["servo", "--port", "x", "--set", "1=70000:pwm"], "does not fit a float16"),
        (["servo", "--port", "x", "--failsafe", "1=hold", "--failsafe-clear"], "not allowed"),
        (["lights", "--port", "x", "--light", "0=fff"], "RRGGBB (6 hex digits)"),
        (["lights", "--port", "x"], "--light"),
        (["beep", "--port", "x", "--hz", "0"], "--hz must be 1..65504"),
        (["beep", "--port", "x", "--ms", "65504001"], "--ms must be 0..65504000"),
        (["tunnel", "--port", "x", "--target", "5", "--any-channel"], "Broadcast option"),
        (["arm", "--port", "x", "--safety-on"], "unrecognized arguments"),
    ]:
        rc, out, err = danprobe(*args)
        assert rc == 2 and message in err, (args, rc, err)
    for cmd, example in [
        ("safety", "danprobe safety off"),
        ("arm", "--safety-off"),
        ("disarm", "--safety-on"),
        ("servo", "--set 3=0.5 --set 7=1500:pwm"),
        ("lights", "--light 0=ff0000"),
        ("beep", "--hz 2000 --ms 100"),
        ("tunnel", "--serial-id -1"),
        ("tunnel", "--any-channel"),
    ]:
        rc, out, err = danprobe(cmd, "--help")
        assert rc == 0 and "examples:" in out and example in out, (cmd, out)
        assert "--bus-baud" in out and "--json" in out


# ---- the real stack ----


class Listener:
    """A pydronecan node on the hub recording, in arrival order, every
    output message the gateway (node 10) broadcast: (kind, value)."""

    def __init__(self, stack, node_id=60):
        import dronecan

        self.dc = dronecan
        self.node = stack.node(stack.free, node_id, "org.test.listener")
        self.got, self.lock = [], threading.Lock()
        E = dronecan.uavcan.equipment
        for dtype, kind, value in [
            (dronecan.ardupilot.indication.SafetyState, "safety", lambda m: m.status),
            (E.safety.ArmingStatus, "arming", lambda m: m.status),
            (E.esc.RawCommand, "esc", lambda m: tuple(m.cmd)),
            (E.actuator.ArrayCommand, "servo", self.servos),
            (E.indication.LightsCommand, "lights", self.lights),
            (E.indication.BeepCommand, "beep", lambda m: (m.frequency, m.duration)),
        ]:
            self.node.add_handler(dtype, self.recorder(kind, value))
        stack.spin(self.node)

    @staticmethod
    def servos(m):
        return {(c.actuator_id, c.command_type, c.command_value) for c in m.commands}

    @staticmethod
    def lights(m):
        return [(c.light_id, c.color.red, c.color.green, c.color.blue) for c in m.commands]

    def recorder(self, kind, value):
        def record(e):
            if e.transfer.source_node_id == GW_NODE:
                with self.lock:
                    self.got.append((kind, value(e.message)))

        return record

    def mark(self):
        with self.lock:
            return len(self.got)

    def since(self, mark, kind):
        with self.lock:
            return [v for k, v in self.got[mark:] if k == kind]

    def wait(self, mark, kind, want, timeout=20):
        """Waits for `want` among the kind's values since mark; returns them."""
        wait_for(lambda: want in self.since(mark, kind), timeout, what=f"{kind} {want!r}")
        return self.since(mark, kind)


@pytest.fixture
def stack(procs, tmp_path):
    yield from closing_factory(lambda **kw: Stack(procs, tmp_path, **kw))


def dp(s, *args):
    """danprobe COMMAND ... --json at 115200 (the bus configured once): its document."""
    return danprobe_json(*args, "--port", s.dan, "--baud", "115200", "-q")


def test_safety_arm_and_disarm(stack):
    s = stack(escs=0)
    ear = Listener(s)
    danprobe_json("stats", "--port", s.dan, "--configure", "-q")
    ear.wait(0, "safety", 0)  # from power-up: safety ON, at the arming rate
    assert set(ear.since(0, "safety")) == {0}
    mark = ear.mark()
    doc = dp(s, "safety", "off")
    assert doc["safety_off"] and doc["safety"] == 255 and "status" not in doc
    ear.wait(mark, "safety", 255)
    wait_for(lambda: ear.since(mark, "safety").count(255) >= 3, 20, what="safety off repeated")
    assert ear.since(mark, "safety")[-1] == 255  # kept, not a one-shot
    rc, out, err = danprobe("safety", "on", "--port", s.dan, "--baud", "115200", "-q")
    assert rc == 0 and "safety ON (0)" in out and "safety-off" not in out, (out, err)
    mark = ear.mark()
    ear.wait(mark, "safety", 0)
    # arm --safety-off: SafetyState 255 and ArmingStatus 255
    mark = ear.mark()
    doc = dp(s, "arm", "--safety-off")
    assert doc["armed"] and doc["safety_off"] and (doc["status"], doc["safety"]) == (255, 255)
    ear.wait(mark, "safety", 255)
    ear.wait(mark, "arming", 255)
    mark = ear.mark()
    rc, out, err = danprobe("disarm", "--safety-on", "--port", s.dan, "--baud", "115200", "-q")
    assert rc == 0 and "gateway disarmed" in out and "safety ON (0)" in out, (out, err)
    ear.wait(mark, "arming", 0)
    ear.wait(mark, "safety", 0)
    mark = ear.mark()
    wait_for(lambda: len(ear.since(mark, "safety")) >= 3, 20, what="more SafetyState")
    assert set(ear.since(mark, "safety")) == {0}
    assert dp(s, "stats")["config"]["safety_off"] is False


def test_servo_lights_beep_and_negative_esc_values(stack):
    s = stack(escs=0)
    ear = Listener(s)
    danprobe_json("stats", "--port", s.dan, "--configure", "-q")
    # servos: exactly the commands given, every kept actuator in each ArrayCommand
    mark = ear.mark()
    doc = dp(s, "servo", "--set", "3=0.5", "--set", "7=1500:pwm,0=-0.25:position")
    assert [(c["actuator_id"], c["type"], c["value"]) for c in doc["servos"]] == [
        (3, "unitless", 0.5),
        (7, "pwm", 1500.0),
        (0, "position", -0.25),
    ]
    first = {(3, 0, 0.5), (7, 4, 1500.0), (0, 1, -0.25)}
    ear.wait(mark, "servo", first)
    mark = ear.mark()
    dp(s, "servo", "--set", "3=-1")  # only what changed: the gateway sends all three
    second = {(3, 0, -1.0), (7, 4, 1500.0), (0, 1, -0.25)}
    got = ear.wait(mark, "servo", second)
    assert set(map(frozenset, got)) <= {frozenset(first), frozenset(second)}  # a hold resend
    wait_for(lambda: ear.since(mark, "servo").count(second) >= 2, 20, what="second held")
    got = ear.since(mark, "servo")
    assert all(v == second for v in got[got.index(second) :]), got
    # the failsafe table: commands stopped, so the failsafe goes out (7 its value, the rest hold)
    mark = ear.mark()
    doc = dp(s, "servo", "--failsafe", "7=1100:pwm", "--failsafe", "3=hold")
    assert doc["kept"] == 2 and doc["failsafe"][0] == {
        "actuator_id": 7,
        "mode": "value",
        "command_type": 4,
        "type": "pwm",
        "value": 1100.0,
        "value_f16": O.f16_bits(1100),
    }
    ear.wait(mark, "servo", {(3, 0, -1.0), (7, 4, 1100.0), (0, 1, -0.25)})
    assert dp(s, "servo", "--failsafe-clear")["kept"] == 0
    # lights: RGB hex to RGB565 exactly
    lights_mark = ear.mark()
    args = ("--light", "0=ff0000", "--light", "1=00ff00,2=0000ff", "--light", "3=808080")
    doc = dp(s, "lights", *args, "--light", "19=565:ffe0")
    assert [x["rgb565"] for x in doc["lights"]] == [0xF800, 0x07E0, 0x001F, 0x8410, 0xFFE0]
    want = [(0, 31, 0, 0), (1, 0, 63, 0), (2, 0, 0, 31), (3, 16, 32, 16), (19, 31, 63, 0)]
    ear.wait(lights_mark, "lights", want)
    # beep: float16 Hz and seconds
    mark = ear.mark()
    dp(s, "beep", "--hz", "2000", "--ms", "100")
    rc, out, err = danprobe(
        "beep", "--port", s.dan, "--baud", "115200", "--hz", "440", "--ms", "1500"
    )
    assert rc == 0 and "440 Hz for 1500 ms" in out, err
    wait_for(lambda: len(ear.since(mark, "beep")) == 2, 20, what="two BeepCommands")
    assert ear.since(mark, "beep") == [(2000.0, f16(0.1)), (440.0, 1.5)]
    assert ear.since(lights_mark, "lights") == [want]  # once: a command, not a state
    # ESC values below zero, from the command line as written
    mark = ear.mark()
    rc, out, err = danprobe(
        "esc", "--port", s.dan, "--baud", "115200", "--values", "-8192,-1,0,8191", "--duration", "1"
    )
    assert rc == 0 and "esc:" in out, (out, err)
    wait_for(lambda: (0, 0, 0, 0) in ear.since(mark, "esc"), 20, what="zero throttle at the end")
    cmds = ear.since(mark, "esc")
    assert (-8192, -1, 0, 8191) in cmds and set(cmds) <= {(-8192, -1, 0, 8191), (0, 0, 0, 0)}
    assert cmds[-1] == (0, 0, 0, 0)


def test_device_temperature_in_telemetry(stack):
    import dronecan

    E = dronecan.uavcan.equipment
    s = stack(escs=0)
    esc = s.node(s.free, 31, "org.test.esc_with_temperature")

    def publish():
        esc.broadcast(E.esc.Status(esc_index=2, voltage=12.5, current=1.0, temperature=300.0))
        esc.broadcast(E.device.Temperature(device_id=7, temperature=318.0, error_flags=1))

    s.spin(esc, publish, 0.1)

    def with_device():
        doc = danprobe_json("telemetry", "--port", s.dan, "-q")
        return doc if doc["esc"] and doc["esc"][0]["device"] else None

    e = wait_for(with_device, 30, 0.5, what="the ESC's telemetry with its temperature")["esc"][0]
    assert (e["index"], e["node"], e["status"], e["voltage"]) == (2, 31, True, 12.5)
    assert e["dev_temperature"] == 318.0 and e["dev_flags"] == 1 and e["overheating"]
    assert not e["overcooling"] and 0 <= e["dev_age_ms"] < 5000
    rc, out, err = danprobe("telemetry", "--port", s.dan)
    head, row = out.splitlines()[1:3]
    assert rc == 0 and head.split()[-2:] == ["dev", "temp"], out
    assert row.endswith("44.9 C overheating"), out


def test_tunnel_default_serial_and_any_channel(stack):
    import dronecan

    U = dronecan.uavcan
    s = stack(escs=0)
    # serial_id -1: the node answers with the port it chose (2)
    far_end = TunnelFarEnd(s.node(s.free, 30, "org.test.far_end"), 30, -1, reply_serial_id=2)
    s.spin(far_end.node, far_end.pump, 0.005)
    p, ev = s.start_danprobe(
        "tunnel", "--port", s.dan, "--configure", "--target", "30", "--serial-id", "-1", "-q"
    )
    assert ev["tunnel"]["serial_id"] == G.TUN_DEFAULT_SERIAL
    data = os.urandom(600)
    fd = pty_open(ev["pty"])
    try:
        back, written = pump_pty(fd, data, len(data), timeout=60)
    finally:
        os.close(fd)
    assert bytes(far_end.got) == data and back == bytes(b ^ 0x5A for b in data)
    summary = s.finish(p)
    assert summary["to_tunnel"] == summary["from_tunnel"] == len(data)
    # Broadcast on channel 7, any channel: a reply on channel 9 is taken
    p, ev = s.start_danprobe(
        "tunnel",
        *("--port", s.dan, "--baud", "115200", "--protocol", "2", "--channel", "7"),
        *("--any-channel", "--tunnel-port", "1", "-q"),
    )
    assert ev["tunnel"]["options"] == G.TUN_ANY_CHANNEL and ev["tunnel"]["target"] == 7
    reply = b"answered on channel 9 " * 2
    far_end.node.broadcast(
        U.tunnel.Broadcast(protocol=U.tunnel.Protocol(protocol=2), channel_id=9, buffer=list(reply))
    )
    fd = pty_open(ev["pty"])
    try:
        back, _ = pump_pty(fd, b"", len(reply), timeout=30)
    finally:
        os.close(fd)
    assert back == reply
    assert s.finish(p)["from_tunnel"] == len(reply)


def test_sniff_names_the_output_messages(stack):
    s = stack(escs=0)
    danprobe_json("safety", "off", "--port", s.dan, "-q")
    danprobe_json("servo", "--port", s.dan, "--set", "7=1500:pwm", "-q")
    danprobe_json("beep", "--port", s.dan, "-q")
    rc, out, err = danprobe("sniff", "--capture", s.tmp / "bus.cap", "--json")
    frames = [json.loads(x) for x in out.splitlines() if '"frame"' in x]
    by = {(f["name"], f["role"]): f["fields"] for f in frames}
    assert by[("can-gw SAFETY", "request")] == {"status": 255, "safety_off": True}
    assert by[("can-gw SAFETY", "response")]["safety_off"]
    assert by[("can-gw SERVO", "request")]["servos"][0]["value"] == 1500.0
    assert by[("can-gw BEEP", "request")] == {"frequency_hz": 2000, "duration_ms": 100}
