#!/usr/bin/env python3
"""Generate tests/vectors/dronecan.txt with pydronecan (pip package dronecan).

Usage: .venv/bin/python tests/vectors/gen_dronecan.py > tests/vectors/dronecan.txt

Each line is one transfer:
    <msg> <key>=<value> ... : <canid>#<data> <canid>#<data> ...
Transport keys: prio, src, dst (services), tid, kind (msg | req | rsp).
Field values: integers (decimal or 0x..), floats (decimal), comma-separated
integer lists (possibly empty), hex byte strings for byte arrays (possibly
empty). CAN IDs and data are hex. Frames are what pydronecan's
Transfer.to_frames() emits for classic CAN.
"""

import os
import sys

import dronecan
from dronecan.transport import Transfer

U = dronecan.uavcan


def frames_of(payload, src, prio, tid, kind="msg", dst=None):
    t = Transfer(
        transfer_id=tid,
        source_node_id=src,
        dest_node_id=dst,
        payload=payload,
        transfer_priority=prio,
        service_not_message=(kind != "msg"),
        request_not_response=(kind == "req"),
    )
    out = []
    for f in t.to_frames():
        out.append("%08X#%s" % (f.message_id, bytes(f.bytes).hex()))
    return out


def fmt(v):
    if isinstance(v, (bytes, bytearray)):
        return v.hex()
    if isinstance(v, (list, tuple)):
        return ",".join(str(x) for x in v)
    return str(v)


def line(name, payload, fields, src=10, prio=20, tid=0, kind="msg", dst=None):
    keys = ["kind=%s" % kind, "prio=%d" % prio, "src=%d" % src, "tid=%d" % tid]
    if dst is not None:
        keys.append("dst=%d" % dst)
    keys += ["%s=%s" % (k, fmt(v)) for k, v in fields]
    print(
        "%s %s : %s"
        % (name, " ".join(keys), " ".join(frames_of(payload, src, prio, tid, kind, dst)))
    )


def fields_line(name, cls, fields, attrs=None, **kw):
    """A message built straight from its vector fields: each (key, value) sets
    the pydronecan field of that name (attrs: where the two names differ)."""
    attrs = attrs or {}
    line(name, cls(**{attrs.get(k, k): v for k, v in fields}), fields, **kw)


def node_status(uptime, health, mode, sub_mode, vendor, **kw):
    fields_line(
        "node_status",
        U.protocol.NodeStatus,
        [
            ("uptime_sec", uptime),
            ("health", health),
            ("mode", mode),
            ("sub_mode", sub_mode),
            ("vendor", vendor),
        ],
        attrs={"vendor": "vendor_specific_status_code"},
        **kw,
    )


def raw_command(cmd, **kw):
    line("raw_command", U.equipment.esc.RawCommand(cmd=cmd), [("cmd", cmd)], **kw)


def esc_status(ec, v, c, t, rpm, pwr, idx, **kw):
    # (fmt() prints a float with str(), which is its repr())
    fields_line(
        "esc_status",
        U.equipment.esc.Status,
        [
            ("error_count", ec),
            ("voltage", v),
            ("current", c),
            ("temperature", t),
            ("rpm", rpm),
            ("power_rating_pct", pwr),
            ("esc_index", idx),
        ],
        **kw,
    )


def esc_status_ext(inp, outp, temp, angle, flags, idx, **kw):
    fields_line(
        "esc_status_extended",
        U.equipment.esc.StatusExtended,
        [
            ("input_pct", inp),
            ("output_pct", outp),
            ("motor_temperature_degC", temp),
            ("motor_angle", angle),
            ("status_flags", flags),
            ("esc_index", idx),
        ],
        **kw,
    )


def arming(status, **kw):
    line(
        "arming_status", U.equipment.safety.ArmingStatus(status=status), [("status", status)], **kw
    )


def targetted(proto, target, serial_id, options, baud, buf, **kw):
    m = U.tunnel.Targetted(target_node=target, serial_id=serial_id, options=options, baudrate=baud)
    m.protocol.protocol = proto
    m.buffer = list(buf)
    line(
        "tunnel_targetted",
        m,
        [
            ("protocol", proto),
            ("target_node", target),
            ("serial_id", serial_id),
            ("options", options),
            ("baudrate", baud),
            ("buffer", bytes(buf)),
        ],
        **kw,
    )


def broadcast(proto, channel, buf, **kw):
    m = U.tunnel.Broadcast(channel_id=channel)
    m.protocol.protocol = proto
    m.buffer = list(buf)
    line(
        "tunnel_broadcast",
        m,
        [("protocol", proto), ("channel_id", channel), ("buffer", bytes(buf))],
        **kw,
    )


def node_info(uptime, sw, hw_major, hw_minor, uid, coa, name, **kw):
    r = U.protocol.GetNodeInfo.Response()
    r.status.uptime_sec = uptime
    r.status.health = 1
    r.status.mode = 0
    r.status.sub_mode = 2
    r.status.vendor_specific_status_code = 0xBEEF
    (
        r.software_version.major,
        r.software_version.minor,
        r.software_version.optional_field_flags,
        r.software_version.vcs_commit,
        r.software_version.image_crc,
    ) = sw
    r.hardware_version.major = hw_major
    r.hardware_version.minor = hw_minor
    r.hardware_version.unique_id = list(uid)
    r.hardware_version.certificate_of_authenticity = list(coa)
    r.name = name
    line(
        "get_node_info_rsp",
        r,
        [
            ("uptime_sec", uptime),
            ("health", 1),
            ("mode", 0),
            ("sub_mode", 2),
            ("vendor", 0xBEEF),
            ("sw_major", sw[0]),
            ("sw_minor", sw[1]),
            ("sw_flags", sw[2]),
            ("vcs_commit", sw[3]),
            ("image_crc", sw[4]),
            ("hw_major", hw_major),
            ("hw_minor", hw_minor),
            ("unique_id", bytes(uid)),
            ("coa", bytes(coa)),
            ("name", name.encode()),
        ],
        kind="rsp",
        **kw,
    )


def node_info_req(**kw):
    line("get_node_info_req", U.protocol.GetNodeInfo.Request(), [], kind="req", **kw)


def allocation(node_id, first, uid, **kw):
    m = U.protocol.dynamic_node_id.Allocation(node_id=node_id, first_part_of_unique_id=first)
    m.unique_id.from_bytes(uid)
    line(
        "allocation",
        m,
        [("node_id", node_id), ("first_part", int(first)), ("unique_id", uid)],
        **kw,
    )


def param_value(v, numeric=False):
    """(pydronecan union, field text): text is tag/value as the C test reads it."""
    t = U.protocol.param.NumericValue() if numeric else U.protocol.param.Value()
    if v is None:
        t.empty = U.protocol.param.Empty()
        return t, "0"
    if isinstance(v, bool):
        t.boolean_value = int(v)
        return t, "3/%d" % int(v)
    if isinstance(v, int):
        t.integer_value = v
        return t, "1/%d" % v
    if isinstance(v, float):
        t.real_value = v
        return t, "2/%r" % v
    t.string_value = v
    return t, "4/" + v.hex()


def getset_req(index, value, name, **kw):
    m = U.protocol.param.GetSet.Request(index=index, name=name)
    m.value, vt = param_value(value)
    line("getset_req", m, [("index", index), ("value", vt), ("name", name)], kind="req", **kw)


def getset_rsp(value, default, mx, mn, name, **kw):
    m = U.protocol.param.GetSet.Response(name=name)
    m.value, vt = param_value(value)
    m.default_value, dt = param_value(default)
    m.max_value, mxt = param_value(mx, True)
    m.min_value, mnt = param_value(mn, True)
    fields = [("value", vt), ("default", dt), ("max", mxt), ("min", mnt), ("name", name)]
    line("getset_rsp", m, fields, kind="rsp", **kw)


def opcode(req, opcode_or_ok, argument, **kw):
    if req:
        m = U.protocol.param.ExecuteOpcode.Request(opcode=opcode_or_ok, argument=argument)
        line("opcode_req", m, [("opcode", opcode_or_ok), ("argument", argument)], kind="req", **kw)
    else:
        m = U.protocol.param.ExecuteOpcode.Response(ok=opcode_or_ok, argument=argument)
        line("opcode_rsp", m, [("ok", int(opcode_or_ok)), ("argument", argument)], kind="rsp", **kw)


def restart(req, v, **kw):
    if req:
        line(
            "restart_req",
            U.protocol.RestartNode.Request(magic_number=v),
            [("magic", v)],
            kind="req",
            **kw,
        )
    else:
        line(
            "restart_rsp", U.protocol.RestartNode.Response(ok=v), [("ok", int(v))], kind="rsp", **kw
        )


def mgmt_vectors():
    """Bus management: the allocator's answers, parameters, opcodes, restart."""
    uid = bytes(range(0xA0, 0xB0))
    allocation(0, False, uid[:6], tid=21)
    allocation(0, False, uid[:12], tid=22)
    allocation(125, False, uid, tid=23)
    kw = dict(src=10, dst=42, prio=24)
    getset_req(0, None, b"", tid=1, **kw)
    getset_req(8191, None, b"", tid=2, **kw)
    getset_req(0, None, b"esc_index", tid=3, **kw)
    getset_req(0, 3, b"esc_index", tid=4, **kw)
    getset_req(0, -(2**63), b"x", tid=5, **kw)
    getset_req(0, 0.25, b"gain", tid=6, **kw)
    getset_req(0, True, b"arming_by_arming_status", tid=7, **kw)
    getset_req(0, b"quad-x", b"frame", tid=8, **kw)
    getset_req(0, bytes(range(128)), b"n" * 92, tid=9, **kw)
    kw = dict(src=42, dst=10, prio=24)
    getset_rsp(3, 0, 31, 0, b"esc_index", tid=3, **kw)
    getset_rsp(1.5, 1.0, 10.0, -10.0, b"gain", tid=6, **kw)
    getset_rsp(True, False, None, None, b"arming_by_arming_status", tid=7, **kw)
    getset_rsp(b"quad-x", b"", None, None, b"frame", tid=8, **kw)
    getset_rsp(None, None, None, None, b"", tid=10, **kw)
    getset_rsp(bytes(range(128)), bytes(range(128, 256)), -5, 2**62, b"n" * 92, tid=11, **kw)
    opcode(True, 0, 0, src=10, dst=42, tid=12)
    opcode(True, 1, -1, src=10, dst=42, tid=13)
    opcode(False, True, 0, src=42, dst=10, tid=12)
    opcode(False, False, -(2**47), src=42, dst=10, tid=13)
    restart(True, 0xACCE551B1E, src=10, dst=42, tid=14)
    restart(True, 0xBEEFCAFE, src=10, dst=42, tid=15)
    restart(False, True, src=42, dst=10, tid=14)
    restart(False, False, src=42, dst=10, tid=15)


def f16_bits(v):
    """The IEEE binary16 bits of v as pydronecan rounds it."""
    import struct

    return struct.unpack("<H", struct.pack("<e", v))[0]


def array_command(cmds, **kw):
    """cmds: (actuator_id, command_type, value); text acts=id/type/f16bits,..."""
    m = U.equipment.actuator.ArrayCommand()
    for a, t, v in cmds:
        m.commands.append(
            U.equipment.actuator.Command(actuator_id=a, command_type=t, command_value=v)
        )
    text = ",".join("%d/%d/%d" % (a, t, f16_bits(v)) for a, t, v in cmds)
    line("array_command", m, [("acts", text or "-")], **kw)


def lights_command(lights, **kw):
    """lights: (light_id, r5, g6, b5); text lights=id/rgb565,..."""
    m = U.equipment.indication.LightsCommand()
    for i, r, g, b in lights:
        c = U.equipment.indication.RGB565(red=r, green=g, blue=b)
        m.commands.append(U.equipment.indication.SingleLightCommand(light_id=i, color=c))
    text = ",".join("%d/%d" % (i, r << 11 | g << 5 | b) for i, r, g, b in lights)
    line("lights_command", m, [("lights", text or "-")], **kw)


def beep_command(freq, dur, **kw):
    m = U.equipment.indication.BeepCommand(frequency=freq, duration=dur)
    line("beep_command", m, [("freq", f16_bits(freq)), ("dur", f16_bits(dur))], **kw)


def safety_state(status, **kw):
    m = dronecan.ardupilot.indication.SafetyState(status=status)
    line("safety_state", m, [("status", status)], **kw)


def temperature(dev, kelvin, flags, **kw):
    m = U.equipment.device.Temperature(device_id=dev, temperature=kelvin, error_flags=flags)
    fields = [("device_id", dev), ("temp", f16_bits(kelvin)), ("flags", flags)]
    line("temperature", m, fields, **kw)


def output_vectors():
    """Outputs and indications the gateway sends, the temperature it hears."""
    array_command([(0, 1, 0.5)], tid=24)
    array_command([(i, i % 5, i * 0.125 - 1.0) for i in range(15)], tid=25)
    array_command([(255, 4, 1500.0), (7, 0, -1.0)], tid=26)
    lights_command([(0, 31, 0, 0)], tid=27)
    lights_command([(i, i % 32, (i * 3) % 64, (31 - i) % 32) for i in range(20)], tid=28)
    lights_command([(255, 31, 63, 31), (246, 0, 0, 0)], tid=29)
    beep_command(440.0, 0.25, tid=30)
    beep_command(65504.0, 0.0, tid=31)
    safety_state(255, tid=0)
    safety_state(0, tid=1)
    temperature(3, 313.15, 0, src=20, tid=2)
    temperature(65535, 0.5, 3, src=21, tid=3)


def main():
    print("# DroneCAN test vectors, generated by tests/vectors/gen_dronecan.py with")
    print(
        "# pydronecan %s. Do not edit; regenerate."
        % getattr(sys.modules["dronecan"], "__version__", "?")
    )
    print("# <msg> <key>=<value>... : <canid>#<data>...  (see the script for the format)")
    # The three reference vectors from the task brief.
    node_status(1, 0, 0, 0, 0x1234)
    raw_command([0, 100, 200, 300])
    esc_status(7, 12.5, -1.25, 300.0, -1234, 50, 3)
    # More node status / IDs.
    node_status(0xFFFFFFFF, 3, 7, 7, 0xFFFF, src=127, prio=0, tid=31)
    node_status(86400, 2, 1, 5, 0, src=1, prio=31, tid=17)
    # RawCommand: empty, one, 8 and 20 channels (multi-frame), extremes.
    raw_command([], tid=1)
    raw_command([-1], tid=2)
    raw_command([-8192, 8191, 0, 1, -1, 1234, -4321, 5000], tid=3)
    raw_command([i * 811 - 8000 for i in range(20)], src=5, prio=8, tid=4)
    raw_command([8191] * 5, tid=5)
    # esc.Status with values that need float16 rounding.
    esc_status(0xFFFFFFFF, 16.8, 3.14159, 310.15, 131071, 127, 31, tid=6)
    esc_status(0, 0.0001, -0.5, 65504.0, -131072, 0, 0, tid=7)
    esc_status(12345, 25.2, 123.456, 1e-7, 0, 100, 19, tid=8)
    # esc.StatusExtended.
    esc_status_ext(50, 48, -40, 359, 0x5A5A5, 7, tid=9)
    esc_status_ext(127, 0, 255, 511, 0x7FFFF, 31, tid=10)
    esc_status_ext(0, 127, -256, 0, 0, 0, tid=11)
    # safety.ArmingStatus.
    arming(255, tid=12)
    arming(0, src=33, tid=13)
    # tunnel.Targetted: 120 bytes (max), a few bytes, none.
    targetted(1, 10, -1, 1, 115200, bytes(range(120)), tid=14)
    targetted(2, 127, 15, 0, 0xFFFFFF, b"\xfe\x00\xff\x55\xaa", src=20, tid=15)
    targetted(0, 1, -16, 15, 57600, b"", tid=16)
    # tunnel.Broadcast: 60 bytes (max), 20, 3 (single frame).
    broadcast(2, 3, bytes((i * 37 + 1) & 0xFF for i in range(60)), tid=17)
    broadcast(1, 0, b"hello, tunnel world!", tid=18)
    broadcast(255, 255, b"abc", tid=19)
    # GetNodeInfo: request (empty) and responses with a name.
    node_info_req(src=42, dst=10, prio=30, tid=20)
    node_info(
        1234,
        (1, 2, 3, 0xDEADBEEF, 0x0123456789ABCDEF),
        4,
        5,
        bytes(range(16, 32)),
        b"",
        "org.dan.can_gateway",
        src=10,
        dst=42,
        prio=30,
        tid=20,
    )
    node_info(
        5,
        (0, 9, 0, 0, 0),
        1,
        0,
        bytes(16),
        bytes(range(200, 220)),
        "n" * 80,
        src=125,
        dst=1,
        prio=24,
        tid=31,
    )
    mgmt_vectors()
    output_vectors()


def fw_vectors():
    """tests/vectors/dronecan_fw.txt: uavcan.protocol.file.BeginFirmwareUpdate
    payloads (the tail arrays: no length bytes) as pydronecan encodes them."""
    T = U.protocol.file.BeginFirmwareUpdate
    lines = [
        "# BeginFirmwareUpdate payloads, generated by tests/vectors/gen_dronecan.py with",
        "# pydronecan. Do not edit; regenerate.",
        "# fw_begin_req source=<node> path=<hex> : <payload hex>",
        "# fw_begin_rsp error=<n> message=<hex> : <payload hex>",
    ]

    def payload(m, req):
        t = Transfer(
            transfer_id=0,
            source_node_id=10,
            dest_node_id=20,
            payload=m,
            service_not_message=True,
            request_not_response=req,
        )
        return bytes(t.payload)

    for src, path in [(10, b"fw.bin"), (0, b"/esc-v2.1_final.apj"), (127, b"p" * 200), (1, b"")]:
        m = T.Request(source_node_id=src)
        m.image_file_remote_path.path = path.decode()
        lines.append(
            "fw_begin_req source=%d path=%s : %s" % (src, path.hex() or "-", payload(m, True).hex())
        )
    for err, msg in [(0, b""), (1, b"armed"), (2, b"busy"), (255, b"m" * 127)]:
        m = T.Response(error=err)
        m.optional_error_message = msg.decode()
        lines.append(
            "fw_begin_rsp error=%d message=%s : %s"
            % (err, msg.hex() or "-", payload(m, False).hex())
        )
    here = os.path.dirname(os.path.abspath(__file__))
    with open(os.path.join(here, "dronecan_fw.txt"), "w") as f:
        f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
    fw_vectors()
