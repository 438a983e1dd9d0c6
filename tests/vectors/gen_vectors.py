#!/usr/bin/env python3
"""Generates tests/vectors/*.txt with an independent, deliberately plain
Python implementation of the DAN v1 frame and payloads.

The generated files are committed; the C and Python tests read them. Run it
again only when adding vectors, and check the diff: existing lines must not
change. Two anchors come from the project's brief, not from this script:
  44 20 00 B5                  code 0x20, empty payload
  44 21 04 00 80 84 07 DC      code 0x21, CONFIGURE bps 115200
"""

import random
from pathlib import Path

from _wire import array, crc8, frame, u16, uvarint

HERE = Path(__file__).resolve().parent


def string(s):
    return array(s.encode())


def identity(ver, manu, model, hw, sw, mask, caps):
    return (
        bytes([ver])
        + string(manu)
        + string(model)
        + string(hw)
        + string(sw)
        + u16(mask)
        + u16(caps)
    )


def configure(t, baud):
    return bytes([t]) + uvarint(baud)


def error(code, err, text):
    return uvarint(code) + uvarint(err) + string(text)


def h(b):
    return b.hex().upper() if b else "-"


def write(name, header, lines):
    (HERE / name).write_text(
        "".join(f"# {line}\n" for line in header) + "".join(line + "\n" for line in lines)
    )


def crc8_vectors():
    """crc8.txt, after the brief's two anchor frames check out."""
    assert crc8(b"123456789") == 0xBC
    assert frame(0x20) == bytes.fromhex("442000B5")
    assert frame(0x21, configure(0, 115200)) == bytes.fromhex("44210400808407DC")

    write(
        "crc8.txt",
        ["crc8_dvb_s2 vectors: <input hex> <crc hex>"],
        [
            f"{h(b'123456789')} BC",
            f"{h(bytes([0]))} {crc8(bytes([0])):02X}",
            f"{h(bytes([0xFF]))} {crc8(bytes([0xFF])):02X}",
            f"{h(bytes(range(256)))} {crc8(bytes(range(256))):02X}",
            f"2000 {crc8(bytes([0x20, 0])):02X}",
        ],
    )


def uvarint_vectors():
    """uvarint.txt."""
    ok = [
        0,
        1,
        127,
        128,
        255,
        300,
        16383,
        16384,
        65535,
        2097151,
        2097152,
        268435455,
        268435456,
        0x7FFFFFFF,
        0xFFFFFFFF,
    ]
    lines = [f"ok {v} {h(uvarint(v))}" for v in ok]
    lines += [
        "ok 0 8000",  # non-minimal encodings are accepted
        "ok 1 818000",
        "truncated 80",
        "truncated FFFF",
        "truncated FFFFFFFF",
        "malformed FFFFFFFF10",  # 5th byte carries more than 4 bits
        "malformed 8080808010",
        "malformed FFFFFFFF8F",  # continuation in the 5th byte: overlong
        "malformed 808080808000",
    ]
    write(
        "uvarint.txt",
        [
            "uvarint vectors:",
            "  ok <decimal value> <hex>         decodes to value; minimal ones also encode to hex",
            "  truncated <hex>                  needs more bytes",
            "  malformed <hex>                  rejected (overlong or over 32 bits)",
        ],
        lines,
    )


def frame_vectors():
    """frames.txt."""
    rnd = random.Random(1)
    frames = [
        (0x20, b""),
        (0x21, configure(0, 115200)),
        (0, error(0x42, 0, "bad payload")),
        (0x40, b""),
        (127, b"\x01"),
        (128, b"\x02\x03"),
        (16384, b""),
        (0xFFFFFFFF, b"\xaa"),
        (0x44, bytes(rnd.randrange(256) for _ in range(127))),
        (0x46, bytes(rnd.randrange(256) for _ in range(128))),
        (0x48, bytes(rnd.randrange(256) for _ in range(160))),
    ]
    write(
        "frames.txt",
        [
            "frame vectors: frame <code decimal> <payload hex or -> <wire hex>",
            "the first two are the brief's anchors; the last carries DAN_MAX_PAYLOAD (160) bytes",
        ],
        [f"frame {c} {h(p)} {h(frame(c, p))}" for c, p in frames],
    )


def payload_vectors():
    """payloads.txt."""
    ident = ("identity", 1, "DAN Project", "vbus test A", "rev B", "1.2.3", 0x000F, 0)
    p_ident = identity(*ident[1:])
    lines = [
        "\t".join(
            [
                "identity",
                "1",
                "DAN Project",
                "vbus test A",
                "rev B",
                "1.2.3",
                "000F",
                "0000",
                h(p_ident),
            ]
        ),
        "\t".join(
            ["identity", "1", "", "", "", "", "0000", "0000", h(identity(1, "", "", "", "", 0, 0))]
        ),
        "\t".join(
            [
                "identity",
                "1",
                "ACME",
                "GW",
                "1",
                "0.1",
                "0009",
                "0000",
                h(identity(1, "ACME", "GW", "1", "0.1", 9, 0)),
            ]
        ),
        # reserved bits travel as they are; the decoder keeps the raw value
        "\t".join(
            [
                "identity",
                "1",
                "X",
                "Y",
                "Z",
                "W",
                "FFF5",
                "8001",
                h(identity(1, "X", "Y", "Z", "W", 0xFFF5, 0x8001)),
            ]
        ),
        "\t".join(["configure", "0", "115200", h(configure(0, 115200))]),
        "\t".join(["configure", "0", "9600", h(configure(0, 9600))]),
        "\t".join(["configure", "0", "19200", h(configure(0, 19200))]),
        # fast bauds (PROTOCOL.md section 6): the same payload, a longer uvarint
        "\t".join(["configure", "0", "230400", h(configure(0, 230400))]),
        "\t".join(["configure", "0", "1000000", h(configure(0, 1000000))]),
        "\t".join(["configure", "0", "2000000", h(configure(0, 2000000))]),
        "\t".join(["ack", "0", "00"]),
        "\t".join(["ack", "1", "01"]),
        "\t".join(["error", str(0x42), "0", "bad payload", h(error(0x42, 0, "bad payload"))]),
        "\t".join(["error", "200", "0", "", h(error(200, 0, ""))]),
        # malformed payloads: each must be rejected by its decoder
        "\t".join(["bad_identity", h(p_ident[:-1])]),
        "\t".join(["bad_identity", h(bytes([1, 40]) + b"short")]),
        "\t".join(["bad_identity", h(bytes([1]))]),
        "\t".join(["bad_identity", "-"]),
        "\t".join(["bad_configure", "-"]),
        "\t".join(["bad_configure", "00"]),
        "\t".join(["bad_configure", "0080"]),
        "\t".join(["bad_configure", "00FFFFFFFF7F"]),
        "\t".join(["bad_ack", "-"]),
        "\t".join(["bad_ack", "02"]),
        "\t".join(["bad_error", "-"]),
        "\t".join(["bad_error", "42"]),
        "\t".join(["bad_error", "420005AB"]),
        # unknown configure request type: well formed but unsupported
        "\t".join(["unsupported_configure", "07"]),
    ]
    write(
        "payloads.txt",
        [
            "common payload vectors, TAB-separated:",
            "  identity <ver> <manufacturer> <model> <hw> <sw> <baud mask hex> <caps hex> <payload hex>",
            "  configure <type> <baud> <payload hex>",
            "  ack <value> <payload hex>",
            "  error <code> <error> <text> <payload hex>",
            "  bad_<kind> <payload hex or ->        must be rejected as malformed",
            "  unsupported_configure <payload hex>  well formed, unknown request type",
        ],
        lines,
    )


def stream_vectors():
    """streams.txt: wire bytes and the frames a resynchronising decoder returns."""
    a, b, c = frame(0x20), frame(0x21, configure(0, 115200)), frame(0x60, b"hi")
    bad_crc = bytearray(b)
    bad_crc[-1] ^= 0xFF
    big = bytearray(frame(0x44, b"\x00" * 40))
    inner = frame(0x61, b"\x07")
    big[10 : 10 + len(inner)] = inner  # a valid frame inside a frame with a bad CRC,
    big[-1] ^= 0x01  # followed by bytes that start no frame
    straddle = bytearray(frame(0x44, b"\x00" * 20))
    straddle = straddle[:-6] + a  # a frame cut short by a sender reset, then a whole one
    swallow = b"D\x50\x7f" + a + c  # a stray sync and length swallow real frames
    while len(swallow) < 1 + 1 + 1 + 127 + 1 + len(c):
        swallow += c
    streams = [
        (a + b + c, [a, b, c]),
        (b"\x00\xff\x13" + a + b"xyz" + c, [a, c]),
        (bytes(bad_crc) + a, [a]),
        (b"D" + a, [a]),  # stray sync right before a frame (found at idle)
        (b"DD" + b, [b]),
        (swallow, [a] + [c] * ((len(swallow) - 3 - len(a)) // len(c))),
        (bytes(big) + c, [c]),  # our rule: the inner frame is not trusted
        (bytes(straddle) + c, [a, c]),
        (b"D\xff\xff\xff\xff\xff" + a, [a]),  # overlong code
        (b"D\x20\xff\x7f" + a, [a]),  # oversize length
        (a[:-1] + a, [a]),  # truncated frame followed by a whole one
    ]
    lines = [f"stream {h(wire)} {' '.join(h(f) for f in expect)}" for wire, expect in streams]
    write(
        "streams.txt",
        [
            "decoder streams: stream <wire hex> <expected frames, in order, each as wire hex>",
            "the decoder must return exactly these frames (fed whole, and fed byte by byte),",
            "after which the line goes idle: a partial frame is dropped, keeping only a whole frame ending at the last byte.",
            "A frame found inside a rejected one and ending inside it is kept only if a sync byte follows it.",
        ],
        lines,
    )


def main():
    crc8_vectors()
    uvarint_vectors()
    frame_vectors()
    payload_vectors()
    stream_vectors()


if __name__ == "__main__":
    main()
