"""The DAN v1 wire basics the vector generators share (gen_vectors.py,
gen_gateway.py): crc8_dvb_s2, uvarint, the frame and little-endian
integers, written plainly from docs/PROTOCOL.md. Like the generators it
uses neither danprobe nor libdan: the vectors are an independent
reference for both.
"""

import struct

SYNC = b"D"


def crc8(data):
    """crc8_dvb_s2: polynomial 0xD5, init 0, no reflection, no final XOR."""
    crc = 0
    for b in data:
        crc ^= b
        for _ in range(8):
            crc = ((crc << 1) ^ 0xD5) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc


def uvarint(v):
    """7-bit groups, low group first, 0x80 on every byte but the last.
    Written from the groups a value's bit length gives (not as danprobe's
    and libdan's shift loop), so the two are checked against another
    derivation: 127 is one byte, 128 is two (80 01), 16384 three."""
    groups = [(v >> shift) & 0x7F for shift in range(0, max(v.bit_length(), 1), 7)]
    return bytes([g | 0x80 for g in groups[:-1]] + groups[-1:])


def frame(code, payload=b""):
    """The whole frame: sync, uvarint code, uvarint length, payload, crc8
    of everything after the sync."""
    body = uvarint(code) + uvarint(len(payload)) + payload
    return SYNC + body + bytes([crc8(body)])


def u8(v):
    return bytes([v & 0xFF])


def u16(v):
    return struct.pack("<H", v & 0xFFFF)


def u24(v):
    return struct.pack("<I", v & 0xFFFFFF)[:3]


def u32(v):
    return struct.pack("<I", v & 0xFFFFFFFF)


def array(b):
    """A uvarint length, then the bytes."""
    return uvarint(len(b)) + bytes(b)
