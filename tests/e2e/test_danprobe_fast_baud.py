"""danprobe's master negotiating bauds above the draft's mask
(docs/PROTOCOL.md section 6, "Fast bauds"), on an in-process model of the
wire: each modelled peripheral hears a frame only when the master talks at
its baud, answers IDENTIFY and CONFIGURE as libdan's peripheral engine does,
and switches after its ACK. No pty, no timing: every outcome is exact."""

import pytest

from danprobe import codec, payloads, registry
from danprobe.master import FAST_BAUDS, DanTimeout, Master, MasterConfig, Nack

TEST_A, TEST_B = registry.lookup("test-a"), registry.lookup("test-b")
MASK_ALL = 0x0F  # 19200..115200


class Periph:
    """One modelled peripheral. extra: the bauds above the mask it accepts;
    liar: acknowledges every fast baud and stays where it is."""

    def __init__(self, ptype, baud=9600, extra=(), liar=False):
        self.type, self.baud, self.extra, self.liar = ptype, baud, set(extra), liar
        self.configures = []  # (baud heard at, requested baud)

    def accepts(self, baud: int) -> bool:
        return payloads.supports(MASK_ALL, baud) or baud in self.extra

    def answer(self, frame):
        if frame.code == self.type.identify:
            ident = payloads.Identity(1, "DAN", self.type.name, "1", "1", MASK_ALL, 0)
            return codec.encode_frame(frame.code, ident.encode()), None
        if frame.code == self.type.configure:
            want = payloads.Configure.decode(frame.payload).baud
            self.configures.append((self.baud, want))
            lie = self.liar and want in FAST_BAUDS
            ok = lie or self.accepts(want)
            ack = payloads.encode_ack(payloads.ACK_OK if ok else payloads.ACK_FAIL)
            switch_to = want if ok and not lie else None
            return codec.encode_frame(frame.code, ack), switch_to
        return None, None


class ModelPort:
    """The master's port on the modelled wire (no echo)."""

    def __init__(self, periphs):
        self.periphs, self.baud, self.rx = periphs, 9600, b""
        self.decoder = codec.Decoder()

    def set_baud(self, baud):
        self.baud = baud
        self.decoder.reset()

    def write(self, data):
        for frame in self.decoder.feed(data):
            for p in self.periphs:
                if p.baud != self.baud:
                    continue  # at another baud the bytes are noise to it
                reply, switch_to = p.answer(frame)
                if reply:
                    self.rx += reply
                if switch_to:
                    p.baud = switch_to

    def read(self, timeout):
        data, self.rx = self.rx, b""
        return data

    def drain(self):
        pass

    def discard_output(self):
        pass

    def close(self):
        pass


def run(periphs, max_baud=2_000_000, target=0):
    port = ModelPort(periphs)
    cfg = MasterConfig(resp_latency_s=0.01, gap_s=0.005, max_baud=max_baud, seed=1)
    m = Master(port, [p.type for p in periphs], 9600, cfg, echo=False)
    m.discover()
    return m, m.configure(target)


def test_fast_peers_go_to_the_fastest_baud_the_port_allows():
    a, b = Periph(TEST_A, extra=FAST_BAUDS), Periph(TEST_B, extra=FAST_BAUDS)
    m, baud = run([a, b])
    assert baud == m.baud == a.baud == b.baud == 2_000_000
    m, baud = run([Periph(TEST_A, extra=FAST_BAUDS)], max_baud=1_000_000)
    assert baud == 1_000_000


def test_a_v1_peer_refuses_and_nobody_is_left_behind():
    fast, v1 = Periph(TEST_A, extra=FAST_BAUDS), Periph(TEST_B)
    m, baud = run([fast, v1])
    assert baud == m.baud == fast.baud == v1.baud == 115200
    # The refusing peer is asked first once it refused: the fast one is
    # moved (and moved back) at most once, at the first candidate.
    moved_back = [c for c in fast.configures if c[0] == 2_000_000]
    assert len([c for c in fast.configures if c[1] == 2_000_000]) <= 1
    assert moved_back == [(2_000_000, 9600)] or moved_back == []
    assert all(want not in FAST_BAUDS or at == 9600 for at, want in v1.configures)


def test_common_fast_baud_below_the_best_of_one_peer():
    a = Periph(TEST_A, extra=FAST_BAUDS)
    b = Periph(TEST_B, extra=(230400, 460800, 921600, 1_000_000))
    m, baud = run([a, b])
    assert baud == a.baud == b.baud == 1_000_000


def test_explicit_fast_baud_refused_keeps_the_bus():
    fast, v1 = Periph(TEST_A, extra=FAST_BAUDS), Periph(TEST_B)
    port = ModelPort([fast, v1])
    m = Master(port, [TEST_A, TEST_B], 9600, MasterConfig(max_baud=1_000_000, seed=1), echo=False)
    m.discover()
    with pytest.raises(Nack):
        m.configure(1_000_000)
    assert fast.baud == v1.baud == 9600


def test_a_peer_that_acknowledges_and_stays_is_recovered():
    # A named fast baud: recovery to 9600 and the failure.
    liar, good = Periph(TEST_A, liar=True), Periph(TEST_B, extra=FAST_BAUDS)
    port = ModelPort([liar, good])
    m = Master(port, [TEST_A, TEST_B], 9600, MasterConfig(max_baud=2_000_000, seed=1), echo=False)
    m.discover()
    with pytest.raises(DanTimeout):
        m.configure(2_000_000)
    # Recovery found the good peer at the baud it was moved to and brought
    # it back; the liar never left 9600. Both answer at 9600.
    assert m.stats.recoveries == 1
    assert good.baud == liar.baud == m.baud == 9600
    assert {p.type.name for p in m.present()} == {"test-a", "test-b"}


def test_after_a_lie_configure_goes_on_with_the_mask_bauds():
    liar, good = Periph(TEST_A, liar=True), Periph(TEST_B, extra=FAST_BAUDS)
    m, baud = run([liar, good])
    assert m.stats.recoveries == 1
    # No second fast candidate was offered to anyone after the failure.
    assert [w for _, w in good.configures if w in FAST_BAUDS] == [2_000_000]
    assert baud == m.baud == good.baud == liar.baud == 115200


def test_discovery_finds_a_peer_left_at_a_fast_baud():
    left = Periph(TEST_A, baud=1_500_000, extra=FAST_BAUDS)
    port = ModelPort([left])
    m = Master(port, [TEST_A], 9600, MasterConfig(max_baud=2_000_000, seed=1), echo=False)
    assert [p.baud for p in m.discover()] == [1_500_000]
    # Without a fast port nobody looks there.
    m = Master(ModelPort([left]), [TEST_A], 9600, MasterConfig(seed=1), echo=False)
    assert 1_500_000 not in m.scan_bauds()
