"""danprobe, the Python host tool: its codec against the shared vectors
(the same semantics as tests/unit/test_codec.c), then the CLI against
dan-vbus, dan-testperiph and dan-master."""

import json
import os
import signal
import subprocess
import sys
import termios
from pathlib import Path

import pytest
import serial

from bus_util import danprobe, start_mixed_periphs, start_vbus
from conftest import BIN, MASTER_WAIT_MS, VECTORS, wait_for
from danprobe import registry
from danprobe.codec import (
    MAX_FRAME,
    MAX_PAYLOAD,
    Decoder,
    MalformedError,
    crc8,
    encode_frame,
    uvarint_decode,
    uvarint_encode,
    uvarint_size,
)
from danprobe.payloads import (
    Configure,
    ErrorMessage,
    Identity,
    PayloadError,
    UnsupportedRequest,
    decode_ack,
    encode_ack,
)
from danprobe.sniff import Sniffer, read_capture, sniff_capture

TYPES = "test-a,test-b,can-gw,vtx"


def vectors(name, sep=" "):
    for line in (VECTORS / name).read_text().splitlines():
        if line and not line.startswith("#"):
            yield line.split(sep)


def unhex(s):
    return b"" if s == "-" else bytes.fromhex(s)


# ---- codec: the shared vectors ----


def test_crc8_vectors():
    assert crc8(b"123456789") == 0xBC
    rows = list(vectors("crc8.txt"))
    assert len(rows) >= 5
    for data, want in rows:
        assert crc8(bytes.fromhex(data)) == int(want, 16), data


def test_uvarint_vectors():
    n = 0
    for row in vectors("uvarint.txt"):
        kind = row[0]
        if kind == "ok":
            value, b = int(row[1]), bytes.fromhex(row[2])
            assert uvarint_decode(b) == (value, len(b))
            if uvarint_size(value) == len(b):
                assert uvarint_encode(value) == b
        elif kind == "truncated":
            assert uvarint_decode(bytes.fromhex(row[1]))[1] == 0
        elif kind == "malformed":
            with pytest.raises(MalformedError):
                uvarint_decode(bytes.fromhex(row[1]))
        else:
            pytest.fail(f"unknown kind {kind}")
        n += 1
    assert n >= 20
    assert uvarint_encode(128) == b"\x80\x01" and uvarint_encode(16384) == b"\x80\x80\x01"
    with pytest.raises(ValueError):
        uvarint_encode(1 << 32)


def decode_all(wire, chunk=0):
    """Feeds wire whole (chunk 0) or chunk bytes a call, then lets the line
    go idle; returns the frames re-encoded, like decode_all() in the C test."""
    d = Decoder()
    frames = []
    step = chunk or max(len(wire), 1)
    for i in range(0, len(wire), step):
        frames += d.feed(wire[i : i + step])
    frames += d.drain()
    assert not d.busy()
    return [encode_frame(f.code, f.payload) for f in frames], d


def test_frame_vectors():
    rows = list(vectors("frames.txt"))
    assert len(rows) >= 10
    for _, code, payload, wire in rows:
        code, payload, wire = int(code), unhex(payload), bytes.fromhex(wire)
        assert encode_frame(code, payload) == wire
        for chunk in (0, 1):
            d = Decoder()
            frames = []
            step = chunk or len(wire)
            for i in range(0, len(wire), step):
                frames += d.feed(wire[i : i + step])
            assert [(f.code, f.payload, f.start, f.size) for f in frames] == [
                (code, payload, 0, len(wire))
            ]
            assert not d.busy()
    assert MAX_FRAME == 169
    with pytest.raises(ValueError):
        encode_frame(1, bytes(MAX_PAYLOAD + 1))
    assert len(encode_frame(0xFFFFFFFF, bytes(MAX_PAYLOAD))) == MAX_FRAME


def test_stream_vectors():
    rows = list(vectors("streams.txt"))
    assert len(rows) >= 8
    for row in rows:
        assert row[0] == "stream"
        wire, want = bytes.fromhex(row[1]), [bytes.fromhex(x) for x in row[2:]]
        for chunk in (0, 1, 2, 3):
            got, _ = decode_all(wire, chunk)
            assert got == want, (row[1], chunk)


def test_every_bit_flip_of_the_frame_vectors_rejected():
    for row in vectors("frames.txt"):
        wire = bytearray(bytes.fromhex(row[3]))
        for i in range(len(wire)):
            for bit in range(8):
                wire[i] ^= 1 << bit
                assert decode_all(bytes(wire))[0] == []
                assert decode_all(bytes(wire), 1)[0] == []
                wire[i] ^= 1 << bit


def test_decoder_counters():
    d = Decoder()
    for data in (
        b"xyz",
        bytes.fromhex("442000B6"),
        bytes.fromhex("4420FF7F"),
        bytes.fromhex("44FFFFFFFF7F"),
        bytes.fromhex("442000"),
    ):
        assert d.feed(data) == []
        assert d.drain() == []
    assert d.feed(bytes.fromhex("442000B5"))[0].code == 0x20
    s = d.stats
    assert (s.garbage, s.crc_errors, s.oversize, s.bad_varint, s.aborted, s.frames) == (
        3,
        1,
        1,
        1,
        1,
        1,
    )


def test_payload_vectors():
    n = 0
    for f in vectors("payloads.txt", "\t"):
        kind = f[0]
        if kind == "identity":
            want = bytes.fromhex(f[8])
            ident = Identity(int(f[1]), f[2], f[3], f[4], f[5], int(f[6], 16), int(f[7], 16))
            assert ident.encode() == want
            assert Identity.decode(want) == ident
        elif kind == "configure":
            want = bytes.fromhex(f[3])
            c = Configure(int(f[1]), int(f[2]))
            assert c.encode() == want and Configure.decode(want) == c
        elif kind == "ack":
            assert encode_ack(int(f[1])) == bytes.fromhex(f[2])
            assert decode_ack(bytes.fromhex(f[2])) == int(f[1])
        elif kind == "error":
            want = bytes.fromhex(f[4])
            e = ErrorMessage(int(f[1]), int(f[2]), f[3])
            assert e.encode() == want and ErrorMessage.decode(want) == e
        elif kind.startswith("bad_"):
            decode = {
                "identity": Identity.decode,
                "configure": Configure.decode,
                "ack": decode_ack,
                "error": ErrorMessage.decode,
            }[kind[4:]]
            with pytest.raises(PayloadError):
                decode(unhex(f[1]))
        elif kind == "unsupported_configure":
            with pytest.raises(UnsupportedRequest):
                Configure.decode(unhex(f[1]))
        else:
            pytest.fail(f"unknown kind {kind}")
        n += 1
    assert n >= 20


def test_code_names():
    assert registry.code_name(0) == "ERROR"
    assert registry.code_name(0x60) == "test-a IDENTIFY"
    assert registry.code_name(0x41) == "can-gw CONFIGURE"
    assert registry.code_name(0x42) == "can-gw 0x42"
    assert registry.code_name(0x50) == "can-gw 0x50"  # the gateway's second block
    assert registry.code_name(0x30) == "0x30"  # no type's
    assert registry.lookup("0x40").name == "can-gw" and registry.lookup("nope") is None


def test_json_has_no_nan(capsys):
    """--json documents are JSON: a float16 NaN or infinity (an ESC's
    "unknown" voltage) is null, not the NaN json.dumps writes by default."""
    from danprobe.commands.common import Context, json_safe

    doc = {"voltage": float("nan"), "esc": [{"current": float("inf")}, 1.5], "n": 3}
    assert json_safe(doc) == {"voltage": None, "esc": [{"current": None}, 1.5], "n": 3}
    Context.emit_json(None, doc)
    assert json.loads(capsys.readouterr().out) == json_safe(doc)


def test_sleep_until_reads_the_clock_once_per_pass():
    """A loop that runs late must not ask for a negative sleep (danprobe esc
    crashed with ValueError under load): the clock jumps past `due` between
    passes, and sleep_until returns instead."""
    from types import SimpleNamespace

    from danprobe.commands.common import sleep_until

    readings = iter([0.0, 0.99, 1.2])
    sleeps = []
    sleep_until(1.0, SimpleNamespace(stop=False), clock=lambda: next(readings), sleep=sleeps.append)
    assert sleeps == [0.05, pytest.approx(0.01)]
    sleeps.clear()
    sleep_until(1.0, SimpleNamespace(stop=True), clock=lambda: 0.0, sleep=sleeps.append)
    assert sleeps == []


def test_sniff_capture_counts_errors(tmp_path):
    """A hand-made capture: a good exchange, a corrupted frame, a collision
    (decoded as it was on the wire), a partial frame cut by an idle gap."""
    good = encode_frame(0x61, Configure(0, 57600).encode())
    ack = encode_frame(0x61, encode_ack(0))
    jammed = bytearray(good)
    jammed[4] ^= 0x10
    bad = bytearray(encode_frame(0x62, b"abc"))
    bad[-1] ^= 0xFF
    cap = tmp_path / "bus.cap"
    cap.write_text(
        "\n".join(
            [
                "# dan-vbus capture: <time> <source> <baud> <hex> [collision] [noise] [rx=<hex>]",
                "# 0=/dev/pts/1 1=/dev/pts/2",
                f"1.000000 0 9600 {good.hex()}",
                f"1.020000 1 9600 {ack.hex()}",
                f"1.500000 0 9600 {bad.hex()}",
                f"1.700000 0 9600 {good.hex()} collision rx={jammed.hex()}",
                f"2.000000 1 9600 {good[:4].hex()}",
                f"3.000000 1 115200 {encode_frame(0, ErrorMessage(0x62, 0, 'no').encode()).hex()}",
            ]
        )
        + "\n"
    )
    sn = Sniffer()
    events = list(sniff_capture(read_capture(cap), sn))
    frames = [e for e in events if e.kind == "frame"]
    assert [(e.name, e.role, e.source) for e in frames] == [
        ("test-a CONFIGURE", "request", 0),
        ("test-a CONFIGURE", "response", 1),
        ("ERROR", "response", 1),
    ]
    assert frames[0].fields == {"request_type": 0, "baud": 57600}
    assert frames[1].fields == {"ack": "OK"}
    assert frames[2].fields["request"] == "test-a 0x62" and frames[2].fields["description"] == "no"
    assert frames[0].time == 1.0 and frames[2].baud == 115200
    s = sn.summary()
    assert s["crc_errors"] == 2 and s["aborted"] == 1 and s["collision_bursts"] == 1
    assert [e.kind for e in events if e.kind != "frame"] == ["crc_errors", "crc_errors", "aborted"]


@pytest.mark.parametrize("line", ["1.0 0 0 4420", "1.0 0 -9600 4420", "nan 0 9600 4420"])
def test_sniff_capture_bad_baud_or_time(tmp_path, line):
    """A capture line with baud 0 (a hand-edited or foreign file) is a clear
    error with exit 1, not a ZeroDivisionError traceback."""
    cap = tmp_path / "bus.cap"
    cap.write_text(line + "\n")
    rc, out, err = danprobe("sniff", "--capture", str(cap))
    assert rc == 1 and "not a dan-vbus capture line" in err and "Traceback" not in err, (out, err)


# ---- the CLI on a virtual bus ----


def danprobe_json(*args):
    rc, out, err = danprobe(*args, "--json")
    assert rc == 0, (rc, out, err)
    return json.loads(out)


def dan_master(port, *steps, types=TYPES):
    r = subprocess.run(
        [str(BIN / "dan-master"), "--port", port, "--types", types, "--json"]
        + ["--latency-ms", MASTER_WAIT_MS, *steps],
        stdin=subprocess.DEVNULL,
        capture_output=True,
        timeout=120,
    )
    assert r.returncode == 0, (r.stdout, r.stderr)
    return [json.loads(x) for x in r.stdout.decode().splitlines()]


@pytest.fixture
def bus3(procs, tmp_path):
    """Master endpoint 0, test-a, test-b, can-gw (no 57600) on 1..3, endpoint 4 spare."""
    vbus, eps, ctl = start_vbus(procs, tmp_path, 5)
    start_mixed_periphs(procs, eps)
    return eps


def test_discover_identities(bus3):
    doc = danprobe_json("discover", "--port", bus3[0], "--types", TYPES, "-q")
    assert doc["command"] == "discover" and doc["result"] == 0 and doc["baud"] == 9600
    peers = {p["type"]: p for p in doc["peers"]}
    assert set(peers) == {"test-a", "test-b", "can-gw"}  # no VTX on this bus
    assert peers["test-a"]["manufacturer"] == "DAN Project" and peers["test-b"]["model"] == "test-b"
    assert peers["can-gw"]["baud_mask"] == 0x0B and peers["can-gw"]["bauds"] == [
        9600,
        19200,
        38400,
        115200,
    ]
    assert all(p["baud"] == 9600 and p["dan_version"] == 1 for p in peers.values())
    rc, out, err = danprobe("discover", "--port", bus3[0], "--types", "test-a,can-gw")
    assert rc == 0
    assert "test-a" in out and "can-gw" in out and "DAN Project" in out and "test-b" not in out
    assert "probing" in err  # progress on stderr


def test_discover_after_configure_finds_higher_baud(bus3):
    """Peripherals keep their baud when the master restarts: discovery finds
    them at 38400 (set by dan-master) and danprobe's configure is seen by
    dan-master the same way."""
    dan_master(bus3[0], "discover", "configure:38400")
    doc = danprobe_json("discover", "--port", bus3[0], "--types", TYPES, "-q")
    assert {p["baud"] for p in doc["peers"]} == {38400} and len(doc["peers"]) == 3
    assert doc["baud"] == 38400
    doc = danprobe_json("configure", "--port", bus3[0], "--types", TYPES, "-q")
    assert doc["result"] == 0 and doc["target"] == 115200 and doc["baud"] == 115200
    disc = dan_master(bus3[0], "discover")[0]
    assert {p["baud"] for p in disc["peers"]} == {115200} and len(disc["peers"]) == 3


def test_configure_cut_short_leaves_one_baud(bus3, monkeypatch):
    """--timeout (or Ctrl-C) ending a configure after the first peer moved
    left the bus split over two bauds (review finding: --timeout 0.17-0.35 s
    of a 0.4 s configure did it): the configure now recovers before it
    raises. The limit is made to hit at the second CONFIGURE, every time."""
    from danprobe import master as MM
    from danprobe.port import SerialPort

    real = MM.Master._configure_peer
    calls = []

    def cut_at_second(self, p, target):
        calls.append(p.type.name)
        if len(calls) == 2 and target != MM.BASE_BAUD:
            raise MM.OperationTimeout("operation timed out")
        return real(self, p, target)

    monkeypatch.setattr(MM.Master, "_configure_peer", cut_at_second)
    types = [registry.lookup(t) for t in TYPES.split(",")]
    with SerialPort(bus3[0], 9600) as port:
        m = MM.Master(port, types, 9600, MM.MasterConfig(resp_latency_s=0.4))
        m.discover()
        with pytest.raises(MM.OperationTimeout):
            m.configure(115200)
        assert m.stats.recoveries == 1 and m.baud == 9600
    doc = danprobe_json("discover", "--port", bus3[0], "--types", TYPES, "-q")
    assert {p["type"]: p["baud"] for p in doc["peers"]} == dict.fromkeys(
        ("test-a", "test-b", "can-gw"), 9600
    )


def test_configure_then_sniff_capture(bus3, tmp_path):
    rc, out, err = danprobe("configure", "--port", bus3[0], "--types", TYPES, "--baud", "115200")
    assert rc == 0, err
    assert "bus at 115200 baud" in out
    doc = danprobe_json("discover", "--port", bus3[0], "--types", "test-a", "-q")
    assert doc["peers"][0]["baud"] == 115200
    # an unsupported target is refused up front: can-gw has no 57600
    rc, out, err = danprobe(
        "configure", "--port", bus3[0], "--types", TYPES, "--baud", "57600", "-q"
    )
    assert rc == 1 and "can-gw does not support 57600" in err

    rc, out, err = danprobe("sniff", "--capture", tmp_path / "bus.cap", "--json")
    assert rc == 0, err
    events = [json.loads(x) for x in out.splitlines()]
    summary = events.pop()
    assert summary["event"] == "summary" and summary["crc_errors"] == 0
    frames = [e for e in events if e["event"] == "frame"]
    conf_req = [e for e in frames if e["name"].endswith("CONFIGURE") and e["role"] == "request"]
    conf_rsp = [e for e in frames if e["name"].endswith("CONFIGURE") and e["role"] == "response"]
    assert {e["name"] for e in conf_req} == {
        "test-a CONFIGURE",
        "test-b CONFIGURE",
        "can-gw CONFIGURE",
    }
    assert all(
        e["fields"] == {"request_type": 0, "baud": 115200}
        and e["source"] == 0
        and e["baud"] == 9600
        for e in conf_req
    )
    assert len(conf_rsp) == 3 and all(e["fields"] == {"ack": "OK"} for e in conf_rsp)
    assert {e["source"] for e in conf_rsp} == {1, 2, 3}
    ids = [e for e in frames if e["name"] == "test-b IDENTIFY" and e["role"] == "response"]
    assert ids and ids[0]["fields"]["model"] == "test-b" and ids[0]["source"] == 2
    assert any(e["baud"] == 115200 and e["name"] == "test-a IDENTIFY" for e in frames)
    assert all(e["gap_ms"] is None or e["gap_ms"] >= 0 for e in frames)
    assert summary["frames_by_name"]["vtx IDENTIFY"] >= 2  # probed, never answered
    # the human form, and --count
    rc, out, err = danprobe("sniff", "--capture", tmp_path / "bus.cap", "--count", "2")
    lines = out.splitlines()
    assert rc == 0 and len(lines) == 3 and lines[-1].startswith("summary:")
    assert "test-a IDENTIFY (0x60) request" in lines[0] and "manufacturer='DAN Project'" in lines[1]


def test_live_sniff_while_dan_master_runs(bus3, procs):
    """The sniffer only listens on a spare endpoint while dan-master talks."""
    sn = procs.start(
        [
            sys.executable,
            "-m",
            "danprobe",
            "sniff",
            "--port",
            bus3[4],
            "--json",
            "--count",
            "8",
            "--timeout",
            "60",
        ],
        name="danprobe-sniff",
    )
    wait_for(lambda: "listening" in sn.log_path.read_text(), timeout=30, what="sniffer ready")
    dan_master(bus3[0], "discover", "request:0x62:616263", types="test-a,test-b,can-gw")
    out, _ = sn.communicate(timeout=60)
    assert sn.returncode == 0, sn.log_path.read_text()
    events = [json.loads(x) for x in out.decode().splitlines()]
    frames = [e for e in events if e["event"] == "frame"]
    assert [(e["name"], e["role"]) for e in frames] == [
        ("test-a IDENTIFY", "request"),
        ("test-a IDENTIFY", "response"),
        ("test-b IDENTIFY", "request"),
        ("test-b IDENTIFY", "response"),
        ("can-gw IDENTIFY", "request"),
        ("can-gw IDENTIFY", "response"),
        ("test-a 0x62", "request"),
        ("test-a 0x62", "response"),
    ]
    assert frames[3]["fields"]["model"] == "test-b" and frames[5]["fields"]["baud_mask"] == 0x0B
    assert frames[6]["payload"] == "616263" and frames[7]["payload"] == "636261"
    assert all(e["source"] is None and e["baud"] == 9600 for e in frames)
    assert events[-1]["event"] == "summary" and events[-1]["frames"] == 8
    assert events[-1]["crc_errors"] == 0


def test_silent_busy_and_missing_ports(procs, tmp_path):
    vbus, eps, ctl = start_vbus(procs, tmp_path, 2)
    rc, out, err = danprobe("discover", "--port", eps[0], "--types", "test-a")
    assert rc == 1 and "no peripheral answered" in err
    rc, out, err = danprobe("discover", "--port", eps[0], "--types", "test-a", "--json", "-q")
    doc = json.loads(out)
    assert rc == 1 and doc["result"] == -9 and doc["peers"] == []
    rc, out, err = danprobe("sniff", "--port", eps[0], "--timeout", "0.5", "-q")
    assert rc == 1 and "no DAN frame heard" in err
    with serial.Serial(eps[1], 9600, exclusive=True):
        rc, out, err = danprobe("discover", "--port", eps[1])
        assert rc == 2 and "busy" in err
    rc, out, err = danprobe("discover", "--port", tmp_path / "nope")
    assert rc == 2 and "No such file or directory" in err
    rc, out, err = danprobe("sniff", "--port", "/dev/null")
    assert rc == 2 and "not a serial port" in err
    rc, out, err = danprobe("sniff", "--capture", tmp_path / "nope.cap")
    assert rc == 2 and "nope.cap" in err


@pytest.mark.parametrize(
    "args, message",
    [
        ([], "required"),
        (["frobnicate"], "invalid choice"),
        (["discover"], "--port"),
        (["discover", "--port", "/dev/null", "--types", "bogus"], "unknown type"),
        (["configure", "--port", "/dev/null", "--baud", "fast"], "not a number"),
        (["discover", "--port", "/dev/null", "--timeout", "0"], "must be positive"),
        (["sniff"], "--port or --capture"),
        (["sniff", "--port", "/dev/null", "--capture", "x"], "not both"),
        (["sniff", "--capture", "x", "--count", "0"], "at least 1"),
        # were tracebacks (review finding)
        (["tunnel", "--port", "/dev/null", "--tunnel-port", "256"], "must be 0..255"),
        (["param", "get", "x" * 93, "--port", "/dev/null", "--node", "5"], "1..92 bytes"),
        (
            ["lights", "--port", "/dev/null"] + ["--light=%d=ff0000" % i for i in range(21)],
            "at most 20 lights",
        ),
    ],
)
def test_bad_arguments(args, message):
    rc, out, err = danprobe(*args)
    assert rc == 2 and message in err and "Traceback" not in err, (rc, err)


def test_baud_beyond_the_driver_is_a_clear_error():
    """--baud 3000000000 raised OverflowError from pyserial (a traceback)."""
    import pty

    m, s = pty.openpty()
    try:
        rc, out, err = danprobe("discover", "--port", os.ttyname(s), "--baud", "3000000000")
    finally:
        os.close(m)
        os.close(s)
    assert rc == 2 and "Traceback" not in err and "danprobe:" in err, err


def pty_at_19200_cooked():
    """A pty pair of the test's own whose slave side is at 19200 baud in
    cooked mode (echo, line editing): a port as another program left it.
    (master fd, slave fd, slave path, its termios settings)."""
    master, slave = os.openpty()
    attrs = termios.tcgetattr(slave)
    attrs[2] = (attrs[2] & ~termios.CBAUD) | termios.B19200
    attrs[3] |= termios.ICANON | termios.ECHO
    attrs[4] = attrs[5] = termios.B19200
    termios.tcsetattr(slave, termios.TCSANOW, attrs)
    return master, slave, os.ttyname(slave), termios.tcgetattr(slave)


def test_port_settings_restored_at_close():
    """pyserial makes the port raw at our baud and left it so: danprobe
    puts the termios settings it found back when it closes the port, as
    can-utils' tools do (review finding), also after a baud change."""
    from danprobe.port import SerialPort

    master, slave, path, found = pty_at_19200_cooked()
    try:
        rc, out, err = danprobe("sniff", "--port", path, "--baud", "115200", "--timeout", "0.3")
        assert rc == 1 and "no DAN frame heard" in err, err
        assert termios.tcgetattr(slave) == found
        with SerialPort(path, 9600) as port:
            raw = termios.tcgetattr(slave)
            assert raw != found and raw[4] == termios.B9600 and not raw[3] & termios.ICANON
            port.set_baud(115200)
            assert termios.tcgetattr(slave)[4] == termios.B115200
        assert termios.tcgetattr(slave) == found
    finally:
        os.close(master)
        os.close(slave)


def test_vanished_port_is_device_disconnected():
    """The pty's other side closed (as a USB adapter unplugged): drain,
    discard and set_baud raised termios.error (a traceback) or named no
    disconnection; now PortError 'device disconnected', and close() says
    nothing (the settings cannot go back to a device that is gone)."""
    from danprobe.port import PortError, SerialPort

    master, slave, path, found = pty_at_19200_cooked()
    try:
        port = SerialPort(path, 9600)
        os.close(master)  # the pty hangs up
        master = None
        for what, call in (
            ("drain", port.drain),
            ("discard", port.discard_output),
            ("set baud", lambda: port.set_baud(115200)),
            ("write", lambda: port.write(b"x")),
        ):
            with pytest.raises(PortError, match=rf": device disconnected \({what}: "):
                call()
        port.close()
        assert not port.ser.is_open
    finally:
        if master is not None:
            os.close(master)
        os.close(slave)


def test_json_document_when_cut_short(procs, tmp_path):
    """--json printed nothing when --timeout or Ctrl-C ended a command
    (review finding): a script reading stdout now gets one document with
    result/error/detail as any failure's, and the same exit codes (1, 130)
    and stderr message as before. Every probe waits 400 ms for an answer
    that never comes, so the discovery outlasts --timeout 0.5."""
    _, eps, _ = start_vbus(procs, tmp_path, 2)
    rc, out, err = danprobe("stats", "--port", eps[0], "--timeout", "0.5", "--json")
    assert rc == 1 and err.endswith("danprobe: stats: timed out after 0.5 s\n"), err
    doc = json.loads(out)
    assert (doc["command"], doc["result"], doc["error"]) == ("stats", -4, "timeout"), doc
    assert doc["detail"] == "timed out after 0.5 s" and doc["port"] == eps[0], doc
    assert doc["peers"] == [] and isinstance(doc["baud"], int) and "event" not in doc, doc
    # a command whose --json is events: the document is its summary
    rc, out, err = danprobe("esc", "--port", eps[0], "--values", "0", "--timeout", "0.5", "--json")
    doc = json.loads(out)
    assert rc == 1 and doc["event"] == "summary" and doc["result"] == -4, (out, err)
    # Ctrl-C mid-discovery (2 s a probe): exit 130, "interrupted"
    p = procs.start(
        [sys.executable, "-m", "danprobe", "discover", "--port", eps[0], "--json"]
        + ["--latency-ms", "2000"],
        name="danprobe-discover",
    )
    wait_for(lambda: "probing" in p.log_path.read_text(), 60, what="discovery started")
    assert procs.stop(p, signal.SIGINT, timeout=30) == 130, p.log_path.read_text()
    doc = json.loads(p.stdout.read().decode())
    assert (doc["command"], doc["result"], doc["error"]) == ("discover", -12, "interrupted")
    assert doc["peers"] == [] and p.log_path.read_text().endswith("danprobe: interrupted\n")


def test_help():
    script = Path(sys.executable).parent / "danprobe"
    if script.exists():  # the console script (make venv)
        r = subprocess.run([str(script), "--help"], capture_output=True, timeout=60)
        assert r.returncode == 0 and b"discover" in r.stdout
    for cmd in ("discover", "configure", "sniff"):
        rc, out, err = danprobe(cmd, "--help")
        assert rc == 0 and "--port" in out and "--json" in out and "--timeout" in out


def test_latency_default_from_the_environment(procs, tmp_path):
    """$DANPROBE_LATENCY_MS is --latency-ms's default (a slow adapter or
    host, set once); a bad value is a usage error. A discovery that finds
    nobody waits the whole window for each attempt: 5 bauds x 2 attempts,
    so it cannot end sooner than 10 windows (a lower bound, not a speed)."""
    _, eps, _ = start_vbus(procs, tmp_path, 2)
    args = ("discover", "--port", eps[0], "--types", "test-a", "--json", "-q")
    env = dict(os.environ, DANPROBE_LATENCY_MS="300")
    r = subprocess.run([sys.executable, "-m", "danprobe", *args], env=env, capture_output=True)
    doc = json.loads(r.stdout)
    assert r.returncode == 1 and doc["ms"] >= 10 * 300, doc
    env["DANPROBE_LATENCY_MS"] = "0"
    r = subprocess.run([sys.executable, "-m", "danprobe", *args], env=env, capture_output=True)
    assert r.returncode == 2 and b"DANPROBE_LATENCY_MS" in r.stderr, r.stderr
