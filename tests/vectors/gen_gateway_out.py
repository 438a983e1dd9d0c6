"""Output vectors of tests/vectors/gateway.txt (docs/PROTOCOL.md section 7,
"Outputs"), written from the document like gen_gateway.py, which prints
them after its own.

Field texts:
  safety req       status=          safety rsp   flags=
  servo req        then cmd=<actuator>/<command_type>/<value f16, 4 hex>
  servo rsp        flags=
  servo_fs req     then fs=<actuator>/<mode>/<command_type>/<value f16, 4 hex>
  servo_fs rsp     kept=
  lights req       then light=<light_id>/<rgb565, 4 hex>
  lights rsp       flags=
  beep req         hz= ms=          beep rsp     flags=
"""

import struct

from _wire import u8, u16, uvarint


def f16(x):
    """IEEE binary16 bits of x (struct's 'e' rounds to nearest even; the
    values used here are exact)."""
    return struct.unpack("<H", struct.pack("<e", x))[0]


def rgb565(r, g, b):
    return (r << 11) | (g << 5) | b


def safety_vectors(emit):
    for status in (0, 255):
        emit("safety", "req", ["status=%d" % status], u8(status))
    emit("safety", "rsp", ["flags=12"], u8(12))


def servo_vectors(emit):
    cmds = [(0, 1, f16(0.5)), (1, 1, f16(-1.0)), (7, 4, f16(1500.0)), (255, 0, f16(0.0))]
    p = u8(len(cmds)) + b"".join(u8(a) + u8(t) + u16(v) for (a, t, v) in cmds)
    emit("servo", "req", ["cmd=%d/%d/%04x" % c for c in cmds], p)
    many = [(i, 2, f16(i / 4.0)) for i in range(32)]
    p = u8(32) + b"".join(u8(a) + u8(t) + u16(v) for (a, t, v) in many)
    emit("servo", "req", ["cmd=%d/%d/%04x" % c for c in many], p)
    emit("servo", "rsp", ["flags=4"], u8(4))
    fs = [(0, 0, 1, 0), (1, 1, 1, f16(-0.25)), (7, 1, 4, f16(1100.0))]
    p = u8(len(fs)) + b"".join(u8(a) + u8(t | (m << 7)) + u16(v) for (a, m, t, v) in fs)
    emit("servo_fs", "req", ["fs=%d/%d/%d/%04x" % f for f in fs], p)
    emit("servo_fs", "req", [], u8(0))
    many = [(i, i & 1, 3, f16(float(i))) for i in range(32)]
    p = u8(32) + b"".join(u8(a) + u8(t | (m << 7)) + u16(v) for (a, m, t, v) in many)
    emit("servo_fs", "req", ["fs=%d/%d/%d/%04x" % f for f in many], p)
    emit("servo_fs", "rsp", ["kept=3"], u8(3))


def lights_vectors(emit):
    lights = [(0, rgb565(31, 0, 0)), (1, rgb565(0, 63, 0)), (19, rgb565(0, 0, 31)), (255, 0xFFFF)]
    p = u8(len(lights)) + b"".join(u8(i) + u16(c) for (i, c) in lights)
    emit("lights", "req", ["light=%d/%04x" % x for x in lights], p)
    emit("lights", "rsp", ["flags=0"], u8(0))


def beep_vectors(emit):
    for hz, ms in [(2000, 100), (1, 0), (65504, 65504000), (440, 1500)]:
        emit("beep", "req", ["hz=%d" % hz, "ms=%d" % ms], uvarint(hz) + uvarint(ms))
    emit("beep", "rsp", ["flags=8"], u8(8))


def out_vectors(emit):
    safety_vectors(emit)
    servo_vectors(emit)
    lights_vectors(emit)
    beep_vectors(emit)
