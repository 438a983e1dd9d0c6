"""Bus-management vectors of tests/vectors/gateway.txt (docs/PROTOCOL.md
section 7, "Bus management"), written from the document like
gen_gateway.py, which prints them after its own.

Field texts:
  node_call req    id= node= op= then per op: index= | name=<hex> |
                   name=<hex> value=<tag>/<v> | magic= force=
  node_call rsp    id= state= len=
  call_result req  id= offset= max=
  call_result rsp  id= state= len= offset= data=<hex>
  param rsp        present= value= [default=] [max=] [min=] name=<hex>
                   (a call's result; value=<tag>/<v>: 0 empty, 1 integer
                   (decimal), 2 real (f32 bits, 8 hex), 3 boolean, 4
                   string (hex))
  opcode rsp       ok= arg=
  health req       (empty)
  health rsp       verdict= reason= subject= detail= problems=
  dna req          first=
  dna rsp          flags= entries= capacity= next= then entry=<node>/<uid hex>
"""

import struct

from _wire import array, u8, u16, u32, uvarint


def hx(b):
    return bytes(b).hex() if b else "-"


def le(v, n):
    return (v & ((1 << (8 * n)) - 1)).to_bytes(n, "little")


def value(tag, v=None):
    """(bytes, text) of a param value."""
    if tag == 0:
        return u8(0), "0"
    if tag == 1:
        return u8(1) + le(v, 8), "1/%d" % v
    if tag == 2:
        bits = struct.unpack("<I", struct.pack("<f", v))[0]
        return u8(2) + u32(bits), "2/%08x" % bits
    if tag == 3:
        return u8(3) + u8(v), "3/%d" % v
    return u8(4) + array(v), "4/" + hx(v)


def node_call_vectors(emit):
    emit(
        "node_call",
        "req",
        ["id=1", "node=20", "op=0", "index=0"],
        u16(1) + u8(20) + u8(0) + uvarint(0),
    )
    emit(
        "node_call",
        "req",
        ["id=65535", "node=127", "op=0", "index=8191"],
        u16(65535) + u8(127) + u8(0) + uvarint(8191),
    )
    name = b"esc_index"
    emit(
        "node_call",
        "req",
        ["id=2", "node=20", "op=1", "name=" + hx(name)],
        u16(2) + u8(20) + u8(1) + array(name),
    )
    for tag, v in [(1, -5), (2, 0.25), (3, 1), (4, b"hello"), (0, None), (1, -(1 << 63))]:
        vb, vt = value(tag, v)
        emit(
            "node_call",
            "req",
            ["id=3", "node=21", "op=2", "name=" + hx(name), "value=" + vt],
            u16(3) + u8(21) + u8(2) + array(name) + vb,
        )
    emit("node_call", "req", ["id=4", "node=22", "op=3"], u16(4) + u8(22) + u8(3))
    emit("node_call", "req", ["id=5", "node=22", "op=4"], u16(5) + u8(22) + u8(4))
    for magic, force in [(0xACCE551B1E, 0), (0xBEEFCAFE, 1)]:
        emit(
            "node_call",
            "req",
            ["id=6", "node=23", "op=5", "magic=%d" % magic, "force=%d" % force],
            u16(6) + u8(23) + u8(5) + le(magic, 5) + u8(force),
        )
    emit("node_call", "rsp", ["id=1", "state=0", "len=0"], u16(1) + u8(0))
    emit("node_call", "rsp", ["id=2", "state=1", "len=300"], u16(2) + u8(1) + uvarint(300))
    emit("node_call", "rsp", ["id=3", "state=2", "len=0"], u16(3) + u8(2))
    emit("node_call", "rsp", ["id=4", "state=3", "len=0"], u16(4) + u8(3))


def result_vectors(emit):
    emit("call_result", "req", ["id=2", "offset=0", "max=128"], u16(2) + uvarint(0) + u8(128))
    emit("call_result", "req", ["id=2", "offset=200", "max=100"], u16(2) + uvarint(200) + u8(100))
    data = bytes((i * 7) & 0xFF for i in range(40))
    emit(
        "call_result",
        "rsp",
        ["id=2", "state=1", "len=300", "offset=200", "data=" + hx(data)],
        u16(2) + u8(1) + uvarint(300) + uvarint(200) + array(data),
    )
    emit(
        "call_result",
        "rsp",
        ["id=9", "state=0", "len=0", "offset=0", "data=-"],
        u16(9) + u8(0) + uvarint(0) + uvarint(0) + array(b""),
    )
    name = b"esc_index"
    v, vt = value(1, 3)
    d, dt = value(1, 0)
    mx, mxt = value(1, 31)
    mn, mnt = value(1, 0)
    emit(
        "param",
        "rsp",
        [
            "present=7",
            "value=" + vt,
            "default=" + dt,
            "max=" + mxt,
            "min=" + mnt,
            "name=" + hx(name),
        ],
        u8(7) + v + d + mx + mn + array(name),
    )
    v, vt = value(2, 1.5)
    mx, mxt = value(2, 10.0)
    emit(
        "param",
        "rsp",
        ["present=2", "value=" + vt, "max=" + mxt, "name=" + hx(b"gain")],
        u8(2) + v + mx + array(b"gain"),
    )
    v, vt = value(4, b"quad-x")
    emit(
        "param",
        "rsp",
        ["present=0", "value=" + vt, "name=" + hx(b"frame")],
        u8(0) + v + array(b"frame"),
    )
    v, vt = value(0)
    emit("param", "rsp", ["present=0", "value=" + vt, "name=-"], u8(0) + v + array(b""))
    emit("opcode", "rsp", ["ok=1", "arg=0"], u8(1) + le(0, 6))
    emit("opcode", "rsp", ["ok=0", "arg=-2"], u8(0) + le(-2, 6))


def health_vectors(emit):
    emit("health", "req", [], b"")
    for v in [(0, 0, 0, 0, 0), (1, 2, 30, 0, 1), (1, 3, 31, 2, 3), (1, 5, 1, 0, 255)]:
        emit(
            "health",
            "rsp",
            [
                "verdict=%d" % v[0],
                "reason=%d" % v[1],
                "subject=%d" % v[2],
                "detail=%d" % v[3],
                "problems=%d" % v[4],
            ],
            bytes(v),
        )


def dna_vectors(emit):
    emit("dna", "req", ["first=0"], u8(0))
    uid_a = bytes(range(0xA0, 0xB0))
    uid_b = bytes(range(0xB0, 0xC0))
    p = u8(3) + u8(2) + u8(64) + u8(0xFF) + u8(2) + u8(125) + uid_a + u8(60) + uid_b
    emit(
        "dna",
        "rsp",
        [
            "flags=3",
            "entries=2",
            "capacity=64",
            "next=255",
            "entry=125/" + hx(uid_a),
            "entry=60/" + hx(uid_b),
        ],
        p,
    )
    emit(
        "dna",
        "rsp",
        ["flags=4", "entries=0", "capacity=64", "next=255"],
        u8(4) + u8(0) + u8(64) + u8(0xFF) + u8(0),
    )


def mgmt_vectors(emit):
    node_call_vectors(emit)
    result_vectors(emit)
    health_vectors(emit)
    dna_vectors(emit)
