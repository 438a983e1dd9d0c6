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
    out = bytearray()
    while v >= 0x80:
        out.append((v & 0x7F) | 0x80)
        v >>= 7
    out.append(v)
    return bytes(out)


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
