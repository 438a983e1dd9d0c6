"""danprobe's file store and firmware update side without a gateway: the
codec of FILE_OPEN..FILE_REMOVE (0x5B-0x5F), FW_BEGIN and NODE_INFO's
appended fields against bytes written by hand from docs/PROTOCOL.md
("Files and firmware updates"), the upload's resume and retry rules
against a model of the gateway's store (written from the same section),
and the follower's verdicts. The real stack: test_fw_update.py."""

import pytest

from conftest import VECTORS, FakeMaster
from danprobe import file_update as U
from danprobe import gateway_file as F
from danprobe import gateway_mgmt as M
from danprobe import gateway_msgs as G
from danprobe import registry
from danprobe.gateway_client import GatewayClient, register_names
from danprobe.master import DanTimeout, RemoteError
from danprobe.payloads import ErrorMessage, PayloadError

# ---- the codec against hand-written bytes ----


def test_file_messages_bytes():
    # name "fw.bin" (array: uv 6 + bytes), u32 size 65536, u8 flags (restart)
    o = F.FileOpen(b"fw.bin", 65536, F.OPEN_RESTART)
    assert o.encode().hex() == "06" + b"fw.bin".hex() + "00000100" + "01"
    assert F.FileOpen.decode(o.encode()) == o and o.restart
    # u8 result, uv have (300 = ac 02)
    assert F.FileState(F.FILE_OK, 300).encode().hex() == "00ac02"
    assert F.FileState.decode(bytes.fromhex("02ac02")) == F.FileState(F.FILE_GAP, 300)
    # uv offset 150 (96 01), array data
    w = F.FileWrite(150, b"\xaa\xbb\xcc")
    assert w.encode().hex() == "960103aabbcc" and F.FileWrite.decode(w.encode()) == w
    # u32 crc32; u8 result, u32 crc32 of the bytes held
    assert F.crc32(b"123456789") == 0xCBF43926
    assert F.FileCommit(crc=0xCBF43926).encode_request().hex() == "2639f4cb"
    assert F.FileCommit.decode(bytes.fromhex("052639f4cb")) == F.FileCommit(F.FILE_CRC, 0xCBF43926)
    # u8 next (0xff end), u8 count, count x (string name, uv size)
    page = F.FileListPage(F.LIST_END, [F.FileEntry(b"a.bin", 1000), F.FileEntry(b"b", 0)])
    assert page.encode().hex() == "ff02" + "05" + b"a.bin".hex() + "e807" + "016200"
    assert F.FileListPage.decode(page.encode()) == page
    # FILE_REMOVE: string name; u8 result
    assert F.encode_name("x").hex() == "0178" and F.decode_name(b"\x01x") == b"x"
    assert F.decode_result(b"\x06") == F.FILE_NOT_FOUND
    assert F.result_name(F.FILE_NO_STORE) == "no file store" and F.result_name(11) == "result 11"


def test_fw_begin_and_node_info_follow_bytes():
    # NODE_CALL: u16 call_id, u8 node_id, u8 op 6, string name
    c = M.NodeCall(0x0102, 30, M.CALL_FW_BEGIN, name=b"fw.bin")
    assert c.encode().hex() == "02011e0606" + b"fw.bin".hex()
    assert M.NodeCall.decode(c.encode()) == c and c.as_dict()["file"] == "fw.bin"
    # result: u8 error, string optional_error_message
    r = F.FwBeginResult(F.FW_IN_PROGRESS, b"busy!")
    assert r.encode().hex() == "0205" + b"busy!".hex()
    assert F.FwBeginResult.decode(r.encode()) == r and r.text() == "in progress (busy!)"
    # NODE_INFO without info (state 0), then the appended fields: status
    # (mode 3 << 2), flags (begun, reading), uv 300, uv 65536, u32 20 ms
    raw = bytes.fromhex("1e00" + "0c" + "03" + "ac02" + "808004" + "14000000")
    i = G.NodeInfo.decode(raw)
    f = i.follow
    assert (f.mode, f.health, f.begun, f.reading) == (F.MODE_SOFTWARE_UPDATE, 0, True, True)
    assert (f.bytes_read, f.file_size, f.since_read_ms) == (300, 65536, 20)
    assert i.encode() == raw and G.NodeInfo.decode(raw + b"\x00\x7f") == i  # trailing ignored
    # with the info: the fields follow the name
    full = G.NodeInfo(30, G.INFO_VALID, 2, 7, 0, 0xDEADBEEF, 1, 0, bytes(range(16)), b"n")
    full.follow = F.FwFollow()
    assert full.encode().endswith(bytes.fromhex("016e" + "ff00" + "00" + "00" + "ffffffff"))
    assert G.NodeInfo.decode(full.encode()) == full
    assert full.as_dict()["follow"]["since_read_ms"] is None
    # an earlier gateway: no appended fields at all
    assert G.NodeInfo.decode(bytes.fromhex("1e00")).follow is None


@pytest.mark.parametrize(
    "name", [b"../x", b"..", b".hidden", b"", b"a" * 33, b"a/b", b"/x", b"a b", b"\xc3\xa9", b"a\0"]
)
def test_bad_names_are_refused_both_ways(name):
    assert F.name_problem(name)
    for make in (
        lambda: F.FileOpen(name, 1).encode(),
        lambda: F.encode_name(name),
        lambda: M.NodeCall(1, 30, M.CALL_FW_BEGIN, name=name).encode(),
    ):
        with pytest.raises(ValueError):
            make()
    arr = bytes([len(name)]) + name
    for decode, payload in (
        (F.FileOpen.decode, arr + bytes(5)),
        (F.decode_name, arr),
        (M.NodeCall.decode, bytes.fromhex("01001e06") + arr),
        (F.FileListPage.decode, b"\xff\x01" + arr + b"\x00"),
    ):
        with pytest.raises(PayloadError):
            decode(payload)


def test_good_names_and_malformed_payloads():
    for ok in (b"a", b"fw-1.2_x.bin", b"A" * 32, b"a..b"):
        assert F.file_name(ok) == ok
    with pytest.raises(ValueError):
        F.FileWrite(0, b"").encode()
    with pytest.raises(ValueError):
        F.FileWrite(0, bytes(151)).encode()
    assert len(F.FileWrite(0xFFFFFFFF, bytes(150)).encode()) == 5 + 2 + 150  # fits the seal
    for decode, hexs in (
        (F.FileOpen.decode, "0178000000"),  # flags missing
        (F.FileWrite.decode, "0000"),  # no data
        (F.FileWrite.decode, "009701" + "00" * 151),  # 151 bytes
        (F.FileWrite.decode, "0005aabb"),  # data cut short
        (F.FileState.decode, "00"),  # have missing
        (F.FileCommit.decode, "00aabbcc"),
        (F.FileCommit.decode_request, "aabbcc"),
        (F.FileListPage.decode, "ff0201620001"),  # second entry cut short
        (F.FwBeginResult.decode, "00"),  # message missing
        (F.FwBeginResult.decode, "008001" + "61" * 128),  # message of 128
        (G.NodeInfo.decode, "1e000c03ac02808004140000"),  # follow cut short
        (G.NodeInfo.decode, "1e00ff"),
    ):
        with pytest.raises(PayloadError):
            decode(bytes.fromhex(hexs))


def test_sniff_names_the_file_codes():
    register_names()
    for code, name in (
        (F.CODE_FILE_OPEN, "FILE_OPEN"),
        (F.CODE_FILE_WRITE, "FILE_WRITE"),
        (F.CODE_FILE_COMMIT, "FILE_COMMIT"),
        (F.CODE_FILE_LIST, "FILE_LIST"),
        (F.CODE_FILE_REMOVE, "FILE_REMOVE"),
    ):
        assert registry.code_name(code) == f"can-gw {name}"
    sealed = G.seal(F.CODE_FILE_COMMIT, G.REQUEST, bytes.fromhex("2639f4cb"))
    assert registry.describe(F.CODE_FILE_COMMIT, sealed, registry.REQUEST)[1] == {
        "crc32": "0xcbf43926"
    }
    sealed = G.seal(F.CODE_FILE_WRITE, G.RESPONSE, bytes.fromhex("00ac02"))
    assert registry.describe(F.CODE_FILE_WRITE, sealed, registry.RESPONSE)[1] == {
        "result": "ok",
        "have": 300,
    }


# ---- the upload against a model of the gateway's store ----


class FakeStore(FakeMaster):
    """A master whose gateway keeps one upload (name, size, bytes held) and
    committed files, as PROTOCOL.md says; .fail holds exceptions for the
    next transactions, .lose makes the next FILE_WRITE forget the upload (a
    gateway restart without the partial file)."""

    def __init__(self, cap=1 << 20):
        super().__init__()
        self.cap = cap
        self.up = None  # [name, size, bytearray]
        self.files = {}
        self.lose = False
        self.stats = None

    def serve(self, code, inner):
        """A malformed request is refused as the gateway does (an ERROR)."""
        try:
            return self.answer(code, inner)
        except PayloadError as e:
            raise RemoteError(ErrorMessage(code, 0, str(e))) from None

    def answer(self, code, inner):
        if code == F.CODE_FILE_OPEN:
            o = F.FileOpen.decode(inner)
            if o.size > self.cap:
                return F.FileState(F.FILE_TOO_LARGE, 0).encode()
            if o.restart or self.up is None or self.up[:2] != [o.name, o.size]:
                self.up = [o.name, o.size, bytearray()]
            return F.FileState(F.FILE_OK, len(self.up[2])).encode()
        if code == F.CODE_FILE_WRITE:
            w = F.FileWrite.decode(inner)
            if self.lose:
                self.up, self.lose = None, False
            if self.up is None:
                return F.FileState(F.FILE_NO_UPLOAD, 0).encode()
            held = self.up[2]
            if w.offset > len(held):
                return F.FileState(F.FILE_GAP, len(held)).encode()
            if w.offset + len(w.data) > self.up[1]:
                return F.FileState(F.FILE_TOO_LARGE, len(held)).encode()
            held += w.data[len(held) - w.offset :]
            return F.FileState(F.FILE_OK, len(held)).encode()
        if code == F.CODE_FILE_COMMIT:
            crc = F.FileCommit.decode_request(inner).crc
            if self.up is None:
                return F.FileCommit(F.FILE_NO_UPLOAD, 0).encode()
            name, size, held = self.up
            if len(held) != size:
                return F.FileCommit(F.FILE_SHORT, F.crc32(held)).encode()
            if F.crc32(held) != crc:
                return F.FileCommit(F.FILE_CRC, F.crc32(held)).encode()
            self.files[name] = bytes(held)
            return F.FileCommit(F.FILE_OK, crc).encode()
        raise AssertionError(f"code {code:#x}")

    def writes(self):
        return [F.FileWrite.decode(p) for c, p in self.sent if c == F.CODE_FILE_WRITE]


IMAGE = bytes((i * 7 + (i >> 8)) & 0xFF for i in range(1000))


def test_upload_resumes_at_the_gateways_offset():
    store = FakeStore()
    gw = GatewayClient(store)
    seen = []

    def stop_after_three():
        return len(store.writes()) >= 3

    with pytest.raises(U.Stopped):
        U.upload(gw, "fw.bin", IMAGE, stop=stop_after_three)
    assert len(store.up[2]) == 450 and not store.files  # kept, not committed
    u = U.upload(gw, "fw.bin", IMAGE, progress=lambda u: seen.append(u.have))
    assert u.resumed_from == 450 and u.committed and store.files[b"fw.bin"] == IMAGE
    assert seen == [600, 750, 900, 1000]
    assert [w.offset for w in store.writes()][3:] == [450, 600, 750, 900]
    # --restart: from 0 again, even with the same name and size
    store.up = [b"fw.bin", len(IMAGE), bytearray(IMAGE[:300])]
    assert U.upload(gw, "fw.bin", IMAGE, restart=True).resumed_from == 0
    # another size: a new upload
    store.up = [b"fw.bin", 999, bytearray(300)]
    assert U.upload(gw, "fw.bin", IMAGE).resumed_from == 0


def test_upload_survives_lost_transactions_and_a_lost_upload():
    store = FakeStore()
    gw = GatewayClient(store)
    store.fail = [DanTimeout("lost")] * 2  # FILE_OPEN twice
    U.upload(gw, "a", IMAGE[:10])
    store.up = None
    store.fail, store.lose = [], False
    calls = [0]

    def progress(u):
        calls[0] += 1
        if calls[0] == 2:
            store.lose = True  # the next write finds no upload: open again, go on
        if calls[0] == 4:
            store.fail = [DanTimeout("lost")]

    u = U.upload(gw, "b", IMAGE, progress=progress)
    assert u.reopens == 1 and store.files[b"b"] == IMAGE
    store.fail = [DanTimeout("lost")] * (U.FAILURES_MAX + 1)
    with pytest.raises(DanTimeout):
        U.upload(gw, "c", IMAGE)


def test_upload_refusals():
    store = FakeStore(cap=500)
    gw = GatewayClient(store)
    with pytest.raises(U.FileError) as e:
        U.upload(gw, "big", IMAGE)
    assert e.value.result == F.FILE_TOO_LARGE and "too large" in str(e.value)
    store = FakeStore()
    gw = GatewayClient(store)
    store.up = [b"x", len(IMAGE), bytearray(b"\xff" * 150)]  # a wrong byte held
    with pytest.raises(U.FileError) as e:
        U.upload(gw, "x", IMAGE)
    assert e.value.result == F.FILE_CRC and f"0x{F.crc32(IMAGE):08x}" in str(e.value)
    with pytest.raises(ValueError):
        U.upload(gw, "../x", IMAGE)


# ---- the follower's verdicts ----


def info(status, bytes_read, size, sw=None, flags=F.FW_BEGUN | F.FW_READING):
    i = G.NodeInfo(30, G.INFO_VALID if sw else G.INFO_PENDING)
    if sw:
        i.sw_major, i.sw_minor = sw
    i.follow = F.FwFollow(status, flags, bytes_read, size, 0)
    return i


UPDATING = F.MODE_SOFTWARE_UPDATE << 2
OPERATIONAL = F.MODE_OPERATIONAL << 2


def test_follow_done_failed_and_stalled():
    before = U.version_of(info(OPERATIONAL, 0, 0, (1, 0)))
    f = U.Follow(30, before, stall=2.0, last_change=0.0)
    f.step(info(UPDATING, 0, 1000, (1, 0)), 0.5)
    f.step(info(UPDATING, 500, 1000, (1, 0)), 1.0)
    f.step(info(OPERATIONAL, 1000, 1000, (1, 0)), 1.5)  # old info still
    assert f.state == U.ONGOING and f.seen_update
    f.step(info(OPERATIONAL, 1000, 1000, (2, 0)), 2.0)
    assert f.state == U.DONE and f.after["sw"] == "2.0" and f.as_dict()["bytes_read"] == 1000
    # stops reading halfway
    f = U.Follow(30, before, stall=2.0, last_change=0.0)
    f.step(info(UPDATING, 500, 1000, (1, 0)), 1.0)
    f.step(info(UPDATING, 500, 1000, (1, 0)), 2.9)
    assert f.state == U.ONGOING
    f.step(info(UPDATING, 500, 1000, (1, 0)), 3.1)
    assert f.state == U.FAILED and "stopped reading at 500 of 1000" in f.why
    # the node's error
    f = U.Follow(30, before, stall=10.0, last_change=0.0)
    f.step(info(UPDATING | 2, 200, 1000, (1, 0)), 1.0)
    assert f.state == U.FAILED and "ERROR" in f.why
    # back with the same version
    f = U.Follow(30, before, stall=1.0, last_change=0.0)
    f.step(info(OPERATIONAL, 1000, 1000, (1, 0)), 0.5)
    f.step(info(OPERATIONAL, 1000, 1000, (1, 0)), 1.6)
    assert f.state == U.FAILED and "not back OPERATIONAL with a new version" in f.why
    with pytest.raises(U.Malformed):
        U.Follow(30, before, 1.0).step(G.NodeInfo(30, 0), 0.0)
    # polls without news (the node out of the table while it reboots): the clock runs
    f = U.Follow(30, before, stall=2.0, last_change=0.0)
    f.step(info(UPDATING, 1000, 1000, (1, 0)), 1.0)
    f.idle(2.9)
    assert f.state == U.ONGOING
    f.step(info(OPERATIONAL, 1000, 1000, (2, 1)), 3.0)
    assert f.state == U.DONE
    f = U.Follow(30, before, stall=2.0, last_change=0.0)
    f.idle(2.1)
    assert f.state == U.FAILED and "no news for 2 s" in f.why


# ---- the codec against the shared vectors (tests/vectors/gateway_file.txt) ----


def unhex(s):
    return b"" if s == "-" else bytes.fromhex(s)


def file_vector_object(msg, d, fields):
    """(encoded payload, decode, what decode must give) of one vector."""
    f = dict(fields)
    i = lambda k: int(f[k])  # noqa: E731
    rep = lambda k: [v for kk, v in fields if kk == k]  # noqa: E731
    if msg in ("file_open", "file_write") and d == "rsp":
        s = F.FileState(i("result"), i("have"))
        return s.encode(), F.FileState.decode, s
    if (msg, d) == ("file_open", "req"):
        o = F.FileOpen(unhex(f["name"]), i("size"), i("flags"))
        return o.encode(), F.FileOpen.decode, o
    if (msg, d) == ("file_write", "req"):
        w = F.FileWrite(i("offset"), unhex(f["data"]))
        return w.encode(), F.FileWrite.decode, w
    if (msg, d) == ("file_commit", "req"):
        c = F.FileCommit(crc=i("crc"))
        return c.encode_request(), F.FileCommit.decode_request, c
    if (msg, d) == ("file_commit", "rsp"):
        c = F.FileCommit(i("result"), i("crc"))
        return c.encode(), F.FileCommit.decode, c
    if (msg, d) == ("file_list", "req"):
        return bytes([i("first")]), G.decode_u8, i("first")
    if (msg, d) == ("file_list", "rsp"):
        entries = [F.FileEntry(unhex(n), int(s)) for n, s in (e.split("/") for e in rep("entry"))]
        p = F.FileListPage(i("next"), entries)
        return p.encode(), F.FileListPage.decode, p
    if (msg, d) == ("file_remove", "req"):
        return F.encode_name(unhex(f["name"])), F.decode_name, unhex(f["name"])
    if (msg, d) == ("file_remove", "rsp"):
        return bytes([i("result")]), F.decode_result, i("result")
    if (msg, d) == ("node_call", "req"):
        c = M.NodeCall(i("id"), i("node"), i("op"), name=unhex(f["name"]))
        return c.encode(), M.NodeCall.decode, c
    if (msg, d) == ("fw_result", "rsp"):
        r = F.FwBeginResult(i("error"), unhex(f["message"]))
        return r.encode(), F.FwBeginResult.decode, r
    if (msg, d) == ("node_info", "rsp"):
        n = G.NodeInfo(i("node"), i("state"))
        if n.info_state == G.INFO_VALID:
            n.sw_major, n.sw_minor, n.sw_flags = map(int, f["sw"].split("/"))
            n.hw_major, n.hw_minor = map(int, f["hw"].split("/"))
            n.vcs_commit, n.unique_id, n.name = i("vcs"), unhex(f["uid"]), unhex(f["name"])
        n.follow = F.FwFollow(i("status"), i("fflags"), i("read"), i("size"), i("since"))
        return n.encode(), G.NodeInfo.decode, n
    if (msg, d) == ("stats", "rsp"):
        values = [int(v) for v in f["values"].split(",")]
        return G.encode_stats(values), G.decode_stats, values
    raise AssertionError(f"no codec for {msg} {d}")


def test_codec_every_file_vector():
    decoders = {
        "file_open": F.FileOpen.decode,
        "file_write": F.FileWrite.decode,
        "file_commit": F.FileCommit.decode_request,
        "file_list": F.FileListPage.decode,
        "file_remove": F.decode_name,
        "node_call": M.NodeCall.decode,
    }
    kinds, n = set(), 0
    for line in (VECTORS / "gateway_file.txt").read_text().splitlines():
        if not line or line.startswith("#"):
            continue
        left, payload = line.split(" : ")
        msg, d, *toks = left.split()
        fields = [t.split("=", 1) for t in toks]
        f = dict(fields)
        payload = unhex(payload)
        kinds.add((msg, d))
        n += 1
        if msg == "crc32":
            assert F.crc32(unhex(f["data"])) == int(f["crc"]), line
            continue
        if d == "bad":
            with pytest.raises(PayloadError):
                decoders[msg](payload)
            continue
        encoded, decode, want = file_vector_object(msg, d, fields)
        assert encoded == payload, f"encode: {line}\n got {encoded.hex()}"
        got = decode(payload)
        assert got == want, f"decode: {line}"
        assert decode(payload + b"\x00\x7f") == got, line  # trailing bytes ignored
    assert n >= 60 and len(kinds) >= 18


# ---- the master's echo check (compared by slices: FILE_WRITE frames are long) ----


class EchoPort:
    def __init__(self):
        self.discarded = 0

    def discard_output(self):
        self.discarded += 1


def test_echo_check_by_slices():
    from danprobe.codec import encode_frame
    from danprobe.master import Link

    frame = encode_frame(0x5C, bytes(range(150)))
    reply = encode_frame(0x5C, b"\x00\x01")
    for chunks in ([frame + reply], [frame[:7], frame[7:100], frame[100:] + reply]):
        link = Link(EchoPort(), 2000000)
        link._tx, link._echo_pos = frame, 0
        for c in chunks:
            link._rx(c, 1.0)
        assert link._tx is None and not link._tx_failed and link.stats.collisions == 0
        assert [f.payload for f in link.frames] == [b"\x00\x01"]  # the reply, not our echo
    bad = bytearray(frame)
    bad[90] ^= 0x40
    link = Link(EchoPort(), 2000000)
    link._tx, link._echo_pos = frame, 0
    link._rx(bytes(bad[:50]), 1.0)
    assert link._tx is not None and link._echo_pos == 50
    link._rx(bytes(bad[50:]), 1.0)
    assert link._tx_failed and link.stats.collisions == 1 and link.port.discarded == 1
