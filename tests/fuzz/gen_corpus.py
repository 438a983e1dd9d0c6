#!/usr/bin/env python3
"""Writes the fuzz seed corpora (tests/fuzz/corpus/<target>/) from the shared
test vectors in tests/vectors/. Deterministic: file names are the SHA-1 of
the content, so rerunning changes nothing. Input layouts: tests/fuzz/targets.c.

    python3 tests/fuzz/gen_corpus.py [OUTDIR]
"""

import hashlib
import struct
import sys
import zlib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
VEC = ROOT / "tests" / "vectors"

GW_CODES = {
    "esc_cmd": 0x42,
    "esc_telem": 0x43,
    "telem": 0x42,
    "arm": 0x44,
    "config": 0x45,
    "stats": 0x46,
    "nodes": 0x47,
    "node_info": 0x48,
    "tun_open": 0x49,
    "tun_xfer": 0x4A,
    "can_send": 0x4B,
    "can_recv": 0x4C,
    "can_filter": 0x4D,
    "node_call": 0x4E,
    "call_result": 0x4F,
    "health": 0x52,
    "dna": 0x53,
    "safety": 0x54,
    "servo": 0x55,
    "servo_fs": 0x56,
    "lights": 0x57,
    "beep": 0x58,
    "esc_fast": 0x59,  # ESC_FAST_T (0x5A) takes the same requests
    "esc_fast_rsp": 0x59,  # refused response lengths
    "file_open": 0x5B,
    "file_write": 0x5C,
    "file_commit": 0x5D,
    "file_list": 0x5E,
    "file_remove": 0x5F,
}
# call result blobs (read through CALL_RESULT) and CRC checks, not messages
GW_RESULTS = {"opcode", "param", "fw_result", "crc32"}
SEALED_OP = 1  # gw_handlers: op % 4 == 1 seals the request as a client would
SEALED_SEED = 0x80  # gw_client: seed bit 7 seals the response as the gateway would
DSDL_SEL = {
    "node_status": 0,
    "get_node_info_rsp": 1,
    "get_node_info_req": 1,
    "raw_command": 2,
    "esc_status": 3,
    "esc_status_extended": 4,
    "arming_status": 5,
    "tunnel_targetted": 6,
    "tunnel_broadcast": 7,
    "array_command": 8,
    "lights_command": 9,
    "beep_command": 10,
    "safety_state": 11,
    "temperature": 12,
}


def lines(name):
    for line in (VEC / name).read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            yield line


def can_frames(spec):
    """'1401550A#01..' items -> [(id, ext, data)]"""
    out = []
    for item in spec.split():
        i, d = item.split("#")
        out.append((int(i, 16), len(i) == 8, bytes.fromhex(d)))
    return out


def can_record(fid, ext, data, flags_hi=0):
    return struct.pack("<IBB", fid, (1 if ext else 0) | flags_hi, len(data)) + data.ljust(8, b"\0")


def handler_op(code):
    """gw_handlers' op byte for a request code (targets.c fz_code)."""
    k = code - 0x40 if code < 0x50 else 16 + code - 0x50
    return k << 2


def client_sel(code):
    """gw_client's first byte for a response code."""
    return code - 0x42 if code <= 0x4F else 14 + code - 0x52


def upload_script():
    """gw_handlers: a whole upload (sealed requests) with a retried write, a
    gap, a commit, the list, FW_BEGIN of the file, a resumed second upload
    and a removal."""

    def req(code, payload):
        return bytes([handler_op(code) | SEALED_OP, len(payload)]) + payload

    def name(n):
        return bytes([len(n)]) + n

    def uv(v):
        out = b""
        while v >= 0x80:
            out += bytes([(v & 0x7F) | 0x80])
            v >>= 7
        return out + bytes([v])

    img = bytes((i * 7) & 0xFF for i in range(300))
    s = req(0x5B, name(b"fw.bin") + struct.pack("<IB", 300, 0))
    for off in (0, 0, 150, 290):
        s += req(0x5C, uv(off) + uv(150 if off < 290 else 10) + img[off : off + 150][:150])
    s += req(0x5D, struct.pack("<I", zlib.crc32(img)))
    s += req(0x5D, struct.pack("<I", zlib.crc32(img)))
    s += req(0x5E, b"\x00")
    s += req(0x4E, struct.pack("<HBB", 1, 20, 6) + name(b"fw.bin"))
    s += req(0x5B, name(b"b.bin") + struct.pack("<IB", 200, 0))
    s += req(0x5C, uv(0) + uv(100) + img[:100])
    s += req(0x5B, name(b"b.bin") + struct.pack("<IB", 200, 0))
    s += req(0x5C, uv(150) + uv(10) + img[:10])
    s += req(0x5F, name(b"fw.bin"))
    return s


def dna_scripts(calls):
    """Sessions for the allocation server target (targets.c dan_fuzz_dna):
    allocations, a restart that loads the table, static nodes with their
    GetNodeInfo answers, service calls answered, another allocator."""

    def stages(k, pref=0x80, gap=5):
        out = b""
        for st in range(3):
            out += bytes([0, k | st << 4, pref, 3, gap, 0])
        return out

    health, dna = bytes([4 | 2 << 3, 0]), bytes([4 | 3 << 3, 1, 0])
    yield stages(0) + dna + health + bytes([6, 0, 0]) + dna + stages(0) + stages(1, 10)
    yield (
        bytes([1, 125, 5, 3, 5, 0, 2, 125, 2, 3, 5, 0, 1, 50, 9, 3, 250, 0])
        + stages(3)
        + stages(4, 50)
        + bytes([1 | 2 << 3, 50, 10])
        + health
        + bytes([2, 50, 0x80])
    )
    for c in calls:
        yield (
            bytes([1, c[2], 5, 3, 5, 0, 4, len(c)])
            + c
            + bytes([3, 5, 0, 5, 4, 1, 0, 3, 60, 0])
            + bytes([4 | 1 << 3, 4])
            + c[:2]
            + b"\x00\x40"
        )
    yield stages(2) + bytes([7, 0, 0]) + stages(5) + bytes([7, 3, 42]) + health + stages(4)


def main():
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "tests" / "fuzz" / "corpus"
    seeds = {}

    def add(target, data):
        seeds.setdefault(target, set()).add(bytes(data))

    # frame decoder: whole frames and streams, fed at once and byte by byte
    for line in lines("frames.txt"):
        wire = bytes.fromhex(line.split()[-1])
        add("frame", b"\x10\x00" + wire)
        add("frame", b"\x00\x80" + wire)
    for line in lines("streams.txt"):
        stream = bytes.fromhex(line.split()[1])
        add("frame", b"\x10\x00" + stream)
        add("frame", b"\x02\x55" + stream)
    # common payloads
    sel = {
        "identity": 0,
        "bad_identity": 0,
        "configure": 1,
        "bad_configure": 1,
        "unsupported_configure": 1,
        "ack": 2,
        "bad_ack": 2,
        "error": 3,
        "bad_error": 3,
    }
    for line in lines("payloads.txt"):
        f = line.split("\t")
        hx = f[-1].strip()
        add("payloads", bytes([sel[f[0]]]) + (b"" if hx == "-" else bytes.fromhex(hx)))
    # gateway requests (handlers) and responses (client)
    script = bytearray()
    for line in [*lines("gateway.txt"), *lines("gateway_file.txt")]:
        head, hx = line.split(" : ")
        msg, d = head.split()[:2]
        if msg in GW_RESULTS:
            continue
        payload = bytes.fromhex(hx.strip()) if hx.strip() != "-" else b""
        code = GW_CODES[msg]
        if msg == "esc_fast" and d == "rsp":
            code = 0x5A  # the record-bearing response
        if msg == "esc_fast_rsp":
            d = "rsp"
        if d in ("req", "bad"):
            req = bytes([handler_op(code), len(payload)]) + payload
            add("gw_handlers", req)
            add("gw_handlers", bytes([req[0] | SEALED_OP]) + req[1:])
            script += req
        else:
            add("gw_client", bytes([client_sel(code), 0]) + payload)
            add("gw_client", bytes([client_sel(code), SEALED_SEED]) + payload)
    # a session: identify, configure, the requests, CAN traffic, time passing
    dc = [can_frames(line.split(" : ")[1]) for line in lines("dronecan.txt")]
    can = b"".join(b"\x02" + can_record(i, e, d) for fr in dc for (i, e, d) in fr)
    add("gw_handlers", b"\x00\x00" + bytes(script) + can + b"\xff\x03" + bytes(script[:40]))
    add("gw_handlers", b"\x04\x05\x00\x80\x84\x07" + can[:200] + b"\x83")
    add("gw_handlers", upload_script())
    # the allocation server and the node table
    calls = [
        bytes.fromhex(line.split(" : ")[1].strip())
        for line in lines("gateway.txt")
        if line.startswith("node_call req")
    ]
    for script_ in dna_scripts(calls):
        add("dna", script_)
    # DroneCAN reassembly: each vector's frames, and all of them interleaved
    for fr in dc:
        add("dronecan_rx", b"\x0a" + b"".join(can_record(i, e, d) for (i, e, d) in fr))
    add(
        "dronecan_rx",
        b"\x0a" + b"".join(can_record(i, e, d, 0x10) for fr in dc for (i, e, d) in fr),
    )
    # DSDL payloads (transfer CRC and tail bytes removed)
    for line in lines("dronecan.txt"):
        name = line.split()[0]
        if name not in DSDL_SEL:
            continue  # the bus-management types: dronecan_rx and dna reach them
        fr = can_frames(line.split(" : ")[1])
        payload = b"".join(d[:-1] for (_, _, d) in fr)
        if len(fr) > 1:
            payload = payload[2:]
        add("dsdl", bytes([DSDL_SEL[name]]) + payload)
    # SLCAN lines
    for fr in dc[:6]:
        for i, e, d in fr:
            add(
                "slcan",
                (f"T{i:08X}" if e else f"t{i:03X}").encode()
                + f"{len(d)}".encode()
                + d.hex().encode(),
            )
    for s in (
        b"t1230",
        b"t12381122334455667788",
        b"r7FF2",
        b"R1FFFFFFF8",
        b"T0000000100ABCD",
        b"z",
        b"Z",
        b"",
        b"t1AB2010203ff",
        b"x",
    ):
        add("slcan", s)

    for target, items in sorted(seeds.items()):
        d = out / target
        d.mkdir(parents=True, exist_ok=True)
        for data in sorted(items):
            (d / hashlib.sha1(data).hexdigest()).write_bytes(data)
        print(f"{target}: {len(items)} seeds")


if __name__ == "__main__":
    main()
