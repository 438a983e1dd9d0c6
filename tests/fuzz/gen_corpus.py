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
# gw_msgs: data[0] for (message, direction) of the vectors (targets_msgs.c)
MSGS_SEL = {
    ("esc_cmd", "req"): 0,
    ("esc_fast", "req"): 1,
    ("esc_fast", "bad"): 1,
    ("config", "req"): 2,
    ("config", "rsp"): 3,
    ("stats", "rsp"): 4,
    ("node_info", "rsp"): 5,
    ("tun_open", "req"): 6,
    ("tun_xfer", "req"): 7,
    ("tun_xfer", "rsp"): 8,
    ("can_send", "rsp"): 9,
    ("can_recv", "req"): 10,
    ("esc_fast", "rsp"): 11,
    ("esc_fast_rsp", "bad"): 11,
    ("file_open", "req"): 12,
    ("file_open", "bad"): 12,
    ("file_open", "rsp"): 13,
    ("file_write", "rsp"): 13,
    ("file_write", "req"): 14,
    ("file_write", "bad"): 14,
    ("file_commit", "req"): 15,
    ("file_commit", "bad"): 15,
    ("file_commit", "rsp"): 16,
    ("file_remove", "req"): 17,
    ("file_remove", "bad"): 17,
    ("fw_result", "rsp"): 18,
    ("node_call", "req"): 19,
    ("node_call", "bad"): 19,
    ("node_call", "rsp"): 20,
    ("call_result", "req"): 21,
    ("call_result", "rsp"): 22,
    ("param", "rsp"): 23,
    ("opcode", "rsp"): 24,
    ("health", "rsp"): 25,
    ("servo", "req"): 26,
    ("servo_fs", "req"): 27,
    ("lights", "req"): 28,
    ("beep", "req"): 29,
}
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
    "allocation": 1,  # the Allocation shares GetNodeInfo's data type ID
    "getset_req": 16,
    "getset_rsp": 16,
    "opcode_req": 17,
    "opcode_rsp": 17,
    "restart_req": 18,
    "restart_rsp": 18,
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


def gw_req(code, payload):
    """gw_handlers: a sealed DAN request."""
    return bytes([handler_op(code) | SEALED_OP, len(payload)]) + payload


def file_name(n):
    return bytes([len(n)]) + n


def uvarint(v):
    out = b""
    while v >= 0x80:
        out += bytes([(v & 0x7F) | 0x80])
        v >>= 7
    return out + bytes([v])


def upload_script():
    """gw_handlers: a whole upload (sealed requests) with a retried write, a
    gap, a commit, the list, FW_BEGIN of the file, a resumed second upload
    and a removal."""
    req, name, uv = gw_req, file_name, uvarint
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


FZ_READER = 100  # gw_handlers: the node whose file requests are checked (targets.c)
CAN_TRANSFER = {"read": 1, "getinfo": 2}  # gw_handlers op 2: k = op >> 2


def file_request(kind, path, offset=0, tid=0, src=FZ_READER):
    """gw_handlers: a uavcan.protocol.file.Read / GetInfo request from node
    src into the gateway's file server (uint40 offset, then the path)."""
    body = (offset.to_bytes(5, "little") if kind == "read" else b"") + path
    return bytes([2 | CAN_TRANSFER[kind] << 2, src, tid & 31, len(body)]) + body


def file_server_scripts():
    """gw_handlers: the CAN side of the file server: an upload, then reads
    and GetInfo of it (whole file, at and past the end, paths that are no
    name), a burst of reads that fills the bulk queue (the wait list, its
    drops), reads while the store fails, a read of the file an upload
    replaces."""
    remove = gw_req(0x5F, file_name(b"fw.bin"))
    up = upload_script()[: -len(remove)]  # fw.bin stays committed
    wait = bytes([0x07])  # 25 ms: the bus takes what is queued
    yield (
        up
        + file_request("getinfo", b"fw.bin", tid=1)
        + file_request("read", b"fw.bin", 0, tid=2)
        + wait
        + file_request("read", b"/fw.bin", 256, tid=3)
        + file_request("read", b"fw.bin", 300, tid=4)
        + file_request("read", b"fw.bin", 5000, tid=5)
        + wait
        + file_request("getinfo", b"nope.bin", tid=6)
        + file_request("read", b"../fw.bin", 0, tid=7)
        + file_request("read", b"a/fw.bin", 0, tid=8)
        + file_request("getinfo", b"", tid=9)
        + file_request("read", b"//fw.bin", 0, tid=10)
        + wait
    )
    burst = b"".join(file_request("read", b"fw.bin", 0, tid=t, src=20 + t % 3) for t in range(12))
    yield up + burst + wait * 4 + burst + bytes([0xFF]) * 2 + wait
    yield up + b"\x03" + file_request("read", b"fw.bin", 0, tid=1) + wait + b"\x03"
    # a new upload of fw.bin: the committed one is still what is served
    img = bytes(range(200))
    yield (
        up
        + gw_req(0x5B, file_name(b"fw.bin") + struct.pack("<IB", 200, 0))
        + gw_req(0x5C, uvarint(0) + uvarint(150) + img[:150])
        + file_request("read", b"fw.bin", 0, tid=1)
        + wait
        + gw_req(0x5C, uvarint(150) + uvarint(50) + img[150:])
        + gw_req(0x5D, struct.pack("<I", zlib.crc32(img)))
        + file_request("read", b"fw.bin", 100, tid=2)
        + file_request("getinfo", b"fw.bin", tid=3)
        + wait
        + gw_req(0x5B, file_name(b"big.bin") + struct.pack("<IB", 700, 0))
    )


CAN_OP = {"node_status": 4, "esc_status": 5, "esc_ext": 6, "targetted": 7, "bcast": 8, "temp": 10}
CAN_OP.update({"node_info_rsp": 11, "getset_rsp": 12, "opcode_rsp": 13, "restart_rsp": 14})
CAN_OP.update({"fw_begin_rsp": 15})
WAIT_25MS, WAIT_1S5 = bytes([0x07]), bytes([0xFF])  # gw_handlers op 3: time passes


def can_transfer(kind, src, tid, payload):
    """gw_handlers op 2: a whole transfer of fz_transfers[CAN_OP[kind]] from
    node src (built with its CRC and toggles by the target)."""
    return bytes([2 | CAN_OP[kind] << 2, src, tid & 31, len(payload)]) + payload


def node_status(uptime, health=0, mode=0, sub_mode=0, vendor=0):
    """uavcan.protocol.NodeStatus: uint32 uptime, 2+3+3 bits, uint16."""
    return struct.pack("<IBH", uptime, health << 6 | mode << 3 | sub_mode, vendor)


def sealed_session(requests):
    """gw_handlers: the vectors' requests sealed, around CAN traffic from
    nodes and ESCs and time passing, so the handlers see a populated
    gateway (the node table, ESC telemetry, raw frames)."""
    traffic = b"".join(
        can_transfer("node_status", n, 0, node_status(100 + n)) for n in (20, 21, 33)
    )
    traffic += can_transfer("node_info_rsp", 20, 0, dc_payload("get_node_info_rsp", 20))
    for k, (name, tid) in enumerate((("esc_status", 6), ("esc_status", 8))):
        traffic += can_transfer("esc_status", 10 + k, tid, dc_payload(name, tid))
    traffic += can_transfer("esc_ext", 10, 9, dc_payload("esc_status_extended", 9))
    raw = b"".join(b"\x02" + can_record(i, e, d) for (i, e, d) in dc_vector("esc_status", 6))
    body = b"".join(gw_req(c, p) for (c, p) in requests)
    yield traffic + raw + body + WAIT_25MS + traffic + body
    yield traffic + WAIT_1S5 * 3 + body


def tunnel_scripts():
    """gw_handlers: serial tunnels both ways: a Targetted port to node 20
    (serial_id -1: any of its ports) and two Broadcast ports (channel 0,
    any channel), the nodes' data read back (acknowledged, retried), data
    written and sent as chunks and keepalives, a flood past the receive
    buffer, a transfer on a closed port and one behind the stream."""
    opens = gw_req(0x49, bytes([0, 1, 1, 20, 0xFF, 0, 0]))
    opens += gw_req(0x49, bytes([1, 2, 1, 0, 0, 0, 0]))
    opens += gw_req(0x49, bytes([2, 2, 1, 5, 0, 1, 0]))

    def xfer(port, wr, rd, mx, data):
        return gw_req(
            0x4A,
            bytes([port]) + uvarint(wr) + uvarint(rd) + uvarint(mx) + bytes([len(data)]) + data,
        )

    tgt = can_transfer("targetted", 20, 1, dc_payload("tunnel_targetted", 14))
    bc = can_transfer("bcast", 30, 2, dc_payload("tunnel_broadcast", 18))
    hello = b"hello"
    yield (
        opens
        + tgt
        + bc
        + xfer(0, 0, 0, 128, hello)
        + xfer(0, 0, 0, 128, hello)
        + xfer(1, 0, 0, 16, hello)
        + xfer(2, 0, 10, 255, b"")
        + xfer(0, 5, 60, 200, b"")
        + WAIT_25MS
        + xfer(0, 1000, 0, 8, hello)
        + xfer(3, 0, 0, 8, hello)
        + WAIT_1S5
        + WAIT_25MS
    )
    big = bytes(range(120))
    yield opens + b"".join(xfer(0, 120 * k, 0, 0, big) for k in range(10)) + WAIT_25MS * 8
    tp, bp = dc_payload("tunnel_targetted", 14), dc_payload("tunnel_broadcast", 18)
    flood = b"".join(can_transfer("targetted", 20, k, tp) for k in range(45))
    flood += can_transfer("bcast", 30, 3, b"") + can_transfer("bcast", 30, 4, bp)
    yield (
        opens
        + flood
        + xfer(0, 0, 0, 1000, b"")
        + xfer(0, 0, 4096, 128, b"")
        + xfer(1, 0, 0, 128, b"")
    )


def node_table_scripts():
    """gw_handlers: the node table: more nodes than slots, a node that
    restarts three times (a duplicate), one leaving a software update, the
    GetNodeInfo retries running out, nodes going offline and their slots
    reused, NODES and NODE_INFO of all that."""
    ns = b"".join(can_transfer("node_status", n, 0, node_status(100)) for n in range(1, 41))
    flap = b"".join(
        can_transfer("node_status", 5, t, node_status(100 - 10 * t)) for t in range(1, 4)
    )
    upd = can_transfer("node_status", 6, 1, node_status(200, mode=3))
    upd += can_transfer("node_status", 6, 2, node_status(201, mode=0))
    info = can_transfer("node_info_rsp", 1, 0, dc_payload("get_node_info_rsp", 20))
    info += can_transfer("node_info_rsp", 2, 0, dc_payload("get_node_info_rsp", 31))
    query = b"".join(gw_req(0x47, bytes([k])) for k in (0, 1, 20, 0x80))
    query += b"".join(gw_req(0x48, bytes([n])) for n in (1, 2, 5, 99))
    late = can_transfer("node_status", 50, 0, node_status(1))
    yield ns + flap + upd + info + WAIT_25MS + query + WAIT_1S5 * 3 + late + query + ns


def raw_can_scripts():
    """gw_handlers: raw CAN both ways: filters (all extended frames, a full
    table, one removed), more frames than the receive ring, CAN_RECV that
    acknowledges, with and without times, CAN_SEND past the bulk queue."""

    def filt(fid, mask):
        return struct.pack("<II", fid, mask)

    every = gw_req(0x4D, bytes([0, 1]) + filt(0x80000000, 0))
    full = gw_req(0x4D, bytes([1, 16]) + b"".join(filt(0x80000000 | k, 0x7FF) for k in range(16)))
    full += gw_req(0x4D, bytes([2, 1]) + filt(0x80000000 | 3, 0x7FF))
    full += gw_req(
        0x4D, bytes([1, 2]) + filt(0x80000000 | 20, 0x7FF) + filt(0x80000000 | 21, 0x7FF)
    )
    full += gw_req(0x4D, bytes([3, 0]))
    frames = b"".join(
        b"\x02" + can_record(0x1401550A | k << 16, True, bytes([k] * (k % 9))) for k in range(70)
    )

    def recv(seq, mx, opts):
        return gw_req(0x4C, uvarint(seq) + bytes([mx, opts]))

    reads = recv(0, 11, 0) + recv(5, 11, 1) + recv(5, 11, 1) + recv(70, 4, 0) + recv(1000, 4, 0)
    rtr = b"\x02" + can_record(0x1401550A, True, b"", 2)
    yield gw_req(0x4D, bytes([0, 2]) + filt(0x80000000, 0) + filt(0x40000000, 0))
    yield every + frames + reads + full + frames[:200] + recv(64, 11, 1)
    yield every + rtr + recv(0, 11, 0)
    frame = struct.pack("<IB", 0x9401550A, 8) + bytes(8)
    sends = b"".join(gw_req(0x4B, bytes([k, 11]) + frame * 11) for k in range(14))
    yield every + sends + gw_req(0x4B, bytes([13, 11]) + frame * 11) + WAIT_25MS + sends[:60]


def call_scripts():
    """gw_handlers: node calls answered by the node: a parameter read and
    write (GetSet), a save (ExecuteOpcode), BeginFirmwareUpdate of an
    uploaded file (accepted, refused), a malformed answer, and their
    results read through CALL_RESULT (whole, from an offset, an unknown
    call)."""
    ns = b"".join(can_transfer("node_status", n, 0, node_status(100)) for n in (20, 21, 22, 23))
    up = upload_script()[: -len(gw_req(0x5F, file_name(b"fw.bin")))]

    def call(cid, node, op, rest=b""):
        return gw_req(0x4E, struct.pack("<HBB", cid, node, op) + rest)

    def result(cid, off=0, mx=128):
        return gw_req(0x4F, struct.pack("<H", cid) + uvarint(off) + bytes([mx]))

    name = file_name(b"esc_index")
    yield (
        ns
        + call(2, 20, 1, name)
        + can_transfer("getset_rsp", 20, 0, dc_payload("getset_rsp", 3))
        + call(3, 21, 2, name + b"\x01" + struct.pack("<q", -5))
        + can_transfer("getset_rsp", 21, 0, dc_payload("getset_rsp", 6))
        + call(4, 22, 3)
        + can_transfer("opcode_rsp", 22, 0, dc_payload("opcode_rsp", 12))
        + call(5, 23, 1, name)
        + can_transfer("getset_rsp", 23, 0, b"\xff\xff\xff")
        + can_transfer("getset_rsp", 20, 9, dc_payload("getset_rsp", 3))
        + can_transfer("node_status", 21, 1, b"")
        + WAIT_25MS
        + result(2)
        + result(2, 20, 10)
        + result(3)
        + result(3, 200, 100)
        + result(4)
        + result(5)
        + result(9)
    )
    yield (
        ns
        + up
        + call(1, 20, 6, file_name(b"fw.bin"))
        + can_transfer("fw_begin_rsp", 20, 0, b"\x00")
        + call(6, 21, 6, file_name(b"fw.bin"))
        + can_transfer("fw_begin_rsp", 21, 0, b"\x01armed")
        + result(1)
        + result(6)
        + WAIT_1S5
        + file_request("read", b"fw.bin", 0, tid=1, src=20)
        + WAIT_25MS
        + gw_req(0x48, bytes([20]))
    )


def call_error_scripts():
    """gw_handlers: node calls refused or answered badly: RestartNode with
    another magic (not forced), BeginFirmwareUpdate of a name that is no
    name, more calls than slots, malformed Restart and firmware answers."""
    ns = b"".join(can_transfer("node_status", n, 0, node_status(100)) for n in (20, 21, 22, 23))

    def call(cid, node, op, rest=b""):
        return gw_req(0x4E, struct.pack("<HBB", cid, node, op) + rest)

    magic = (0xACCE551B1E).to_bytes(5, "little")
    yield (
        ns
        + call(1, 23, 5, (0x1234).to_bytes(5, "little") + b"\x00")
        + call(2, 20, 6, file_name(b"../x"))
        + call(3, 21, 5, magic + b"\x00")
        + can_transfer("restart_rsp", 21, 0, b"")
        + call(4, 22, 6, file_name(b"fw.bin"))
        + can_transfer("fw_begin_rsp", 22, 0, b"")
        + b"".join(call(10 + k, 20 + k % 4, 3) for k in range(10))
    )
    # GetSet calls to 20 nodes, one after another: the transfer-ID table
    # (DAN_DC_TX_TIDS) fills, then the calls and broadcasts find no ID
    many = b"".join(call(100 + k, 30 + k, 0, b"\x00\x00") + WAIT_1S5 for k in range(20))
    yield many + gw_req(0x44, b"\xff") + call(200, 60, 0, b"\x00\x00") + WAIT_1S5


def esc_scripts():
    """gw_handlers: ESC telemetry in (esc.Status, StatusExtended and a
    device.Temperature of the same node, and malformed ones), read by
    ESC_CMD, ESC_TELEM, ESC_FAST and ESC_FAST_T, and HEALTH; CAN error
    frames: bus-off (CAN down in HEALTH) and the restart."""
    telem = can_transfer("esc_status", 10, 6, dc_payload("esc_status", 6))
    telem += can_transfer("esc_status", 11, 8, dc_payload("esc_status", 8))
    telem += can_transfer("esc_ext", 10, 9, dc_payload("esc_status_extended", 9))
    telem += can_transfer("temp", 10, 2, dc_payload("temperature", 2))
    bad = b"".join(can_transfer(k, 12, 0, b"") for k in ("esc_status", "esc_ext", "temp"))
    cmd = gw_req(0x42, bytes([4]) + bytes(6)) + gw_req(0x59, bytes.fromhex("000019800cb004"))
    reads = gw_req(0x5A, bytes.fromhex("000019800cb004")) * 3 + gw_req(0x43, b"\x00")
    health = gw_req(0x52, b"")
    busoff = b"\x02" + can_record(0x40, False, bytes(8), 4)
    restarted = b"\x02" + can_record(0x100, False, bytes(8), 4)
    yield cmd + telem + bad + reads + health + busoff + health + restarted + health + cmd
    yield telem * 3 + cmd + WAIT_1S5 * 2 + reads + health


def file_error_scripts():
    """gw_handlers: the upload's error paths: a COMMIT before the last
    byte, a late COMMIT retry after the file was removed, names that are
    not names, a resume of a partial kept while another upload ran (and of
    one longer than the new size), and every step while the store fails
    (op 3 toggles it)."""
    img = bytes(range(100))

    def fopen(name, size, resume=0):
        return gw_req(0x5B, file_name(name) + struct.pack("<IB", size, resume))

    def write(off, data):
        return gw_req(0x5C, uvarint(off) + uvarint(len(data)) + data)

    commit = gw_req(0x5D, struct.pack("<I", zlib.crc32(img)))
    rm, fail = gw_req(0x5F, file_name(b"a.bin")), b"\x03"
    yield (
        fopen(b"a.bin", 100)
        + write(0, img[:50])
        + commit
        + write(50, img[50:])
        + commit
        + rm
        + commit
        + fopen(b"../a", 10)
        + fopen(b"a/b", 10)
        + gw_req(0x5F, file_name(b".x"))
    )
    yield (
        fopen(b"p.bin", 100)
        + write(0, img[:60])
        + fopen(b"q.bin", 100)
        + fopen(b"p.bin", 100, 1)
        + write(60, img[60:])
        + commit
        + fopen(b"q.bin", 100)
        + write(0, img[:70])
        + fopen(b"r.bin", 10)
        + fopen(b"q.bin", 50, 1)
    )
    yield (
        fopen(b"a.bin", 100)
        + fail
        + write(0, img)
        + fail
        + write(0, img)
        + fail
        + commit
        + fail
        + commit
        + fail
        + gw_req(0x5E, b"\x00")
        + rm
        + fopen(b"b.bin", 10)
        + fail
    )


def file_dir_scripts():
    """file_dir: store calls (targets_files.c dan_fuzz_file_dir)."""

    def nm(name, pick=None):
        return bytes([0x80 | pick]) if pick is not None else bytes([len(name)]) + name

    def op(k, hi=0):
        return bytes([k | hi << 3])

    off0 = b"\x00\x00"
    data = bytes(range(30))
    w = op(5, 10) + off0 + data  # 30 bytes at 0
    yield op(4) + nm(b"a") + w + op(6, 31) + off0 + op(7) + nm(b"a") + op(0) + nm(b"a") + off0
    yield (
        (
            op(4)
            + nm(b"fw.bin")
            + w
            + op(5, 10)
            + b"\x1e\x00"
            + data
            + op(5, 10)
            + b"\x3c\x00"
            + data
        )
        + op(7)
        + nm(b"fw.bin")
        + op(1, 31)
        + nm(b"fw.bin")
        + b"\x0a\x00"
        + op(2)
        + op(2, 1)
    )
    yield (
        op(4)
        + nm(b"", 7)
        + op(4)
        + nm(b"b")
        + w
        + op(7)
        + nm(b"", 3)
        + op(1, 5)
        + nm(b"", 3)
        + off0
    )
    yield (
        op(1, 5)
        + nm(b"", 3)
        + off0
        + op(0)
        + nm(b"", 4)
        + off0
        + op(3)
        + nm(b"", 5)
        + op(1)
        + nm(b"", 6)
        + off0
        + op(0)
        + nm(b"../outside/secret")
        + off0
        + op(0)
        + nm(b"/etc/passwd")
        + off0
    )
    yield op(4) + nm(b"c") + w + op(4, 1) + nm(b"c") + op(6, 31) + off0 + op(7) + nm(b"", 6)
    yield op(4) + nm(b"d") + op(5, 31) + off0 + data * 4 + op(5, 2) + b"\x50\x00" + data
    yield op(4) + nm(b"e") + w + op(7) + nm(b"e") + op(3) + nm(b"e") + op(0) + nm(b"e") + off0
    yield op(4) + nm(b"x" * 33) + op(4) + nm(b".hidden") + op(4) + nm(b"a/b") + op(4) + nm(b"~a")
    # the upload calls with no upload open, a write past the end (a gap), a
    # read at the end
    yield (
        w + op(6, 31) + off0 + op(7) + nm(b"a") + op(4) + nm(b"g") + op(5, 10) + b"\x64\x00" + data
    )
    yield op(4) + nm(b"h") + w + op(6, 31) + b"\x1e\x00" + op(6, 31) + b"\x64\x00"


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
    # the stored table with a bit flipped (magic, count, an entry, the CRC)
    for b2 in (0x01, 0x0D, 0x11, 0x21, 0x53, 0xFF):
        yield stages(0) + stages(1, 10) + bytes([6, 0, b2]) + dna + health


def dc_vector(name, tid):
    """The frames [(id, ext, data)] of dronecan.txt's vector name with tid."""
    for line in lines("dronecan.txt"):
        if line.split()[0] == name and f" tid={tid} " in line:
            return can_frames(line.split(" : ")[1])
    raise KeyError((name, tid))


def dc_payload(name, tid):
    """A vector's transfer payload (tail bytes, and a multi-frame CRC, off)."""
    fr = dc_vector(name, tid)
    payload = b"".join(d[:-1] for (_, _, d) in fr)
    return payload[2:] if len(fr) > 1 else payload


def dronecan_rx_scripts():
    """dronecan_rx: the reassembly's error paths, from a four-frame vector
    (tunnel.Broadcast from node 10, tid 18) bent one way at a time: a start
    with the toggle set, a short or anonymous start, a continuation with no
    start, another transfer ID, a skipped frame (toggle), a short middle
    frame, a corrupted byte (CRC), an overlong transfer, a restart and a
    continuation after the 2 s timeout, a duplicate, every session slot
    taken (no free slot, then an expired one taken over), the cleanup."""
    fr = [(i, d) for (i, _, d) in dc_vector("tunnel_broadcast", 18)]
    (i0, d0), (i1, d1), (i2, d2), (i3, d3) = fr

    def rec(fid, data, hi=0):
        return can_record(fid, True, data, hi)

    def tail(data, t):
        return data[:-1] + bytes([t])

    idle = can_record(0x123, False, b"", 0x70)  # 700 ms pass, a frame nobody takes
    late = idle * 3  # past DAN_DC_TRANSFER_TIMEOUT_US (2 s)
    whole = b"".join(rec(i, d) for (i, d) in fr)
    anon = i0 & ~0x7F | 0x55 << 10  # node 0, a discriminator
    yield b"\x0a" + rec(i0, tail(d0, d0[-1] | 0x20)) + rec(i1, d1)
    yield b"\x0a" + rec(i0, d0[:5] + d0[-1:]) + rec(anon, d0) + rec(i1, d1) + rec(i3, d3)
    yield b"\x0a" + rec(i0, d0) + rec(i1, tail(d1, d1[-1] ^ 1)) + rec(i0, d0) + rec(i2, d2)
    yield b"\x0a" + rec(i0, d0) + rec(i1, d1[:4] + d1[-1:]) + rec(i2, d2)
    yield (
        b"\x0a" + rec(i0, d0) + rec(i1, bytes([d1[0] ^ 0xFF]) + d1[1:]) + rec(i2, d2) + rec(i3, d3)
    )
    yield b"\x0a" + whole + whole + rec(i0, d0) + rec(i0, tail(d0, d0[-1] ^ 3)) + rec(i1, d1)
    yield b"\x0a" + rec(i0, d0) + rec(i1, d1) + rec(i0, tail(d0, d0[-1] ^ 3))
    yield b"\x0a" + rec(i0, d0) + late + rec(i1, d1) + rec(i0, d0) + late + rec(i0, d0)
    mids = b"".join(rec(i1, tail(d1, d1[-1] ^ (0x20 if k % 2 else 0))) for k in range(60))
    yield b"\x0a" + rec(i0, d0) + mids
    # every slot held by a transfer in progress (nodes 1..64), one more
    starts = b"".join(rec(i0 & ~0x7F | n, d0) for n in range(1, 66))
    single = rec(i0 & ~0x7F | 66, dc_vector("tunnel_broadcast", 19)[0][2])
    yield b"\x0a" + starts + single + late + rec(i0 & ~0x7F | 67, d0) + rec(i0, d0, 0x80)
    # types nobody knows: a broadcast (even ID: taken), a service request
    unknown = rec(20 << 24 | 0x7FF0 << 8 | 10, b"\x01\xc0") + rec(
        20 << 24 | 0x7FF1 << 8 | 10, b"\xc1"
    )
    unknown += rec(20 << 24 | 0xEE << 16 | 0x8000 | 10 << 8 | 0x80 | 20, b"\xc2")
    yield b"\x0a" + unknown
    # service frames: to another node, from node 0, to node 0
    svc = dc_vector("get_node_info_req", 20)[0]
    yield (
        b"\x2a" + rec(svc[0], svc[2]) + rec(svc[0] & ~0x7F, svc[2]) + rec(svc[0] & ~0x7F00, svc[2])
    )


JUNK = (b"", b"\xff", b"\xff" * 12, b"\x7f" * 60)  # too short, counts and values too large


def bent(payload):
    """A vector's payload one byte short and one byte long: the decoders'
    length checks."""
    out = [payload + b"\x00"]
    if payload:
        out.append(payload[:-1])
    return out


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
    add("frame", b"\x10\x00D\x42" + b"\xff" * 6 + b"\x00")  # a length varint past 5 bytes
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
    requests = []
    for line in [*lines("gateway.txt"), *lines("gateway_file.txt")]:
        head, hx = line.split(" : ")
        msg, d = head.split()[:2]
        payload = bytes.fromhex(hx.strip()) if hx.strip() != "-" else b""
        if (msg, d) in MSGS_SEL:
            add("gw_msgs", bytes([MSGS_SEL[(msg, d)]]) + payload)
        if msg in GW_RESULTS:
            continue
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
            requests.append((code, payload))
        else:
            add("gw_client", bytes([client_sel(code), 0]) + payload)
            add("gw_client", bytes([client_sel(code), SEALED_SEED]) + payload)
    # every code with payloads no decoder takes (sealed: the handlers and
    # the client's decoders see them), the vectors bent by a byte
    for code in sorted(set(GW_CODES.values()) | {0x5A}):
        add("gw_handlers", b"".join(gw_req(code, j) for j in JUNK))
        for j in JUNK:
            add("gw_client", bytes([client_sel(code), SEALED_SEED]) + j)
    big = bytes([0]) + uvarint(0) * 4 + uvarint(200) + bytes(200)  # TUN_XFER data past 128
    add("gw_client", bytes([client_sel(0x4A), SEALED_SEED]) + big)
    for sel_ in range(32):
        for j in JUNK:
            add("gw_msgs", bytes([sel_]) + j)
    for line in [*lines("gateway.txt"), *lines("gateway_file.txt")]:
        head, hx = line.split(" : ")
        msg, d = head.split()[:2]
        if (msg, d) in MSGS_SEL and hx.strip() != "-":
            for b in bent(bytes.fromhex(hx.strip())):
                add("gw_msgs", bytes([MSGS_SEL[(msg, d)]]) + b)
    # a session: identify, configure, the requests, CAN traffic, time passing
    dc = [can_frames(line.split(" : ")[1]) for line in lines("dronecan.txt")]
    can = b"".join(b"\x02" + can_record(i, e, d) for fr in dc for (i, e, d) in fr)
    add("gw_handlers", b"\x00\x00" + bytes(script) + can + b"\xff\x03" + bytes(script[:40]))
    add("gw_handlers", b"\x04\x05\x00\x80\x84\x07" + can[:200] + b"\x83")
    add("gw_handlers", upload_script())
    for script_ in [*sealed_session(requests), *tunnel_scripts(), *node_table_scripts()]:
        add("gw_handlers", script_)
    for script_ in [*raw_can_scripts(), *call_scripts(), *esc_scripts(), *file_error_scripts()]:
        add("gw_handlers", script_)
    for script_ in call_error_scripts():
        add("gw_handlers", script_)
    for script_ in file_server_scripts():
        add("gw_handlers", script_)
    # file names and DroneCAN paths; the directory store
    for n in (
        b"fw.bin",
        b"a",
        b"A-Z_0.9",
        b"x" * 32,
        b"x" * 33,
        b".",
        b"..",
        b".hidden",
        b"/fw.bin",
        b"//fw.bin",
        b"/.x",
        b"a/b",
        b"../etc/passwd",
        b"/etc/passwd",
        b"~partial",
        b"a\\b",
        b"a\x00b",
        b"fw bin",
        b"\xc3\xa9.bin",
        b"",
        b"/",
    ):
        add("file_names", n)
    for script_ in file_dir_scripts():
        add("file_dir", script_)
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
    for script_ in dronecan_rx_scripts():
        add("dronecan_rx", script_)
    # DSDL payloads (transfer CRC and tail bytes removed)
    for line in lines("dronecan.txt"):
        name = line.split()[0]
        if name not in DSDL_SEL:
            continue
        fr = can_frames(line.split(" : ")[1])
        payload = b"".join(d[:-1] for (_, _, d) in fr)
        if len(fr) > 1:
            payload = payload[2:]
        add("dsdl", bytes([DSDL_SEL[name]]) + payload)
        for b in bent(payload):
            add("dsdl", bytes([DSDL_SEL[name]]) + b)
    for sel_ in range(20):
        for j in JUNK:
            add("dsdl", bytes([sel_]) + j)
    # SLCAN lines
    for fr in dc[:6]:
        for i, e, d in fr:
            add(
                "slcan",
                (f"T{i:08X}" if e else f"t{i:03X}").encode()
                + f"{len(d)}".encode()
                + d.hex().encode(),
            )
    lines_ = [b"t1230", b"T1FFFFFFF81122334455667788", b"r7FF2", b"z", b"Z", b"\a", b"t12"]
    add("slcan", b"\r".join(lines_) + b"\r")  # a stream of lines, an error (BEL), a short one
    add("slcan", b"t" + b"1" * 40 + b"\rt1230\r")  # an overlong line, then a good one
    add("slcan", b"t1230\n\rT0000000100ABCD\r\r")
    for arg in (
        b"123#DEADBEEF",
        b"1F334455#R",
        b"123#R8",
        b"123#11.22.33",
        b"7FF#",
        b"12345678#00",
    ):
        add("slcan", arg)  # cansend arguments (dan_can_parse_cansend)
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
    # lines and cansend arguments each parser refuses: bad hex in the ID,
    # the data or the timestamp, an ID too large, a DLC past 8
    for s in (
        b"tX230",
        b"t8000",
        b"T200000000",
        b"t1239",
        b"t1230ZZZZ",
        b"t1231ZZ",
        b"r1239",
        b"12#00",
        b"800#00",
        b"2FFFFFFF#00",
        b"123#R9",
        b"123#001122334455667788",
        b"123#GG",
    ):
        add("slcan", s)
    # 4 reads of garbage (the backend's read limit per call), a frame in the last
    add("slcan", b"x" * 1017 + b"\rt1230\r")

    for target, items in sorted(seeds.items()):
        d = out / target
        d.mkdir(parents=True, exist_ok=True)
        for data in sorted(items):
            (d / hashlib.sha1(data).hexdigest()).write_bytes(data)
        print(f"{target}: {len(items)} seeds")


if __name__ == "__main__":
    main()
