"""Fast bauds (docs/PROTOCOL.md section 6, "Fast bauds") end to end on
dan-vbus: dan-master negotiates 1000000 and 2000000 with dan-testperiph
peripherals; a v1-only peripheral on the same bus refuses and the bus
settles on the best common baud; a peripheral that acknowledges and does
not switch is recovered; a restarted master finds a bus left at a fast
baud. Generous reply windows: these tests check behaviour, not speed."""

import json

from bus_util import danprobe, periph_stats, read_capture, start_periph, start_vbus
from test_bus import master

TYPES = "test-a,test-b,can-gw"
FAST = [230400, 460800, 921600, 1000000, 1500000, 2000000]


def fast_master(port, max_baud, *steps, check=True):
    return master(port, *steps, types=TYPES, check=check, opts=("--max-baud", str(max_baud)))


def start_two(procs, eps, *extra_b):
    """test-a on endpoint 1 (fast), can-gw on 2 (fast, or with extra_b)."""
    return [
        start_periph(procs, eps[1], "test-a"),
        start_periph(procs, eps[2], "can-gw", "0x0F", *extra_b),
    ]


def talkers_at(tmp_path, baud):
    return {b[1] for b in read_capture(tmp_path) if b[2] == baud}


def test_negotiates_2m(procs, tmp_path):
    _, eps, _ = start_vbus(procs, tmp_path, 3)
    ps = start_two(procs, eps)
    _, out = fast_master(
        eps[0], 2000000, "discover", "configure", "repeat:200:0x62:00112233", "stats"
    )
    disc, conf, rep, stats = out
    assert all(p["baud"] == 9600 for p in disc["peers"])
    assert conf["result"] == 0 and conf["baud"] == 2000000, conf
    assert conf["fast_refusals"] == 0 and conf["recoveries"] == 0
    assert rep["result"] == 0 and rep["done"] == 200
    print(
        "configure 9600 -> 2000000: %.1f ms; 200 requests at 2M: %.1f/s"
        % (conf["ms"], 200 / rep["seconds"])
    )
    assert stats["collisions"] == 0
    # Every talker was on the wire at 2M (the master, both peripherals).
    assert talkers_at(tmp_path, 2000000) == {0, 1, 2}
    for p in ps:
        st = periph_stats(procs, p)
        assert st["baud"] == 2000000 and st["baud_changes"] == 1 and st["nacks"] == 0


def test_negotiates_1m_and_names_2m(procs, tmp_path):
    """--max-baud 1000000 stops at 1M; then configure:2000000 names a
    baud outright (no --max-baud needed for it)."""
    _, eps, _ = start_vbus(procs, tmp_path, 3)
    start_two(procs, eps)
    _, out = fast_master(
        eps[0],
        1000000,
        "discover",
        "configure",
        "request:0x62:414243",
        "configure:2000000",
        "request:0x62:58595a",
    )
    _, conf1, req1, conf2, req2 = out
    assert conf1["result"] == 0 and conf1["baud"] == 1000000
    assert bytes.fromhex(req1["payload"]) == b"CBA"
    assert conf2["result"] == 0 and conf2["baud"] == 2000000
    assert bytes.fromhex(req2["payload"]) == b"ZYX"
    assert talkers_at(tmp_path, 1000000) == {0, 1, 2}
    assert talkers_at(tmp_path, 2000000) == {0, 1, 2}


def test_v1_only_peripheral_mixed_in(procs, tmp_path):
    """A peripheral that knows only DAN v1 (mask bauds) beside two fast
    ones: it refuses each fast baud, nobody is left behind, the bus runs at
    the best common baud (115200)."""
    _, eps, _ = start_vbus(procs, tmp_path, 4)
    fast = start_two(procs, eps)
    old = start_periph(procs, eps[3], "test-b", "0x0F", "--v1-only")
    _, out = fast_master(eps[0], 2000000, "discover", "configure", "request:0x62:6869", "stats")
    _, conf, req, _ = out
    assert conf["result"] == 0 and conf["baud"] == 115200, conf
    assert conf["fast_refusals"] == len(FAST) and conf["recoveries"] == 0
    assert bytes.fromhex(req["payload"]) == b"ih"
    st = periph_stats(procs, old)
    assert st["nacks"] == len(FAST) and st["baud"] == 115200
    for p in fast:
        assert periph_stats(procs, p)["baud"] == 115200
    # the v1 peripheral never heard a byte at a fast baud from itself
    assert 3 not in set().union(*(talkers_at(tmp_path, b) for b in FAST))


def test_ack_without_switch_is_recovered(procs, tmp_path):
    """can-gw acknowledges 2M and stays at 9600: verification fails,
    recovery finds everyone (test-a at 2M, the baud tried), and configure
    goes on with the best mask baud."""
    _, eps, _ = start_vbus(procs, tmp_path, 3)
    ps = start_two(procs, eps, "--ack-no-switch")
    _, out = fast_master(eps[0], 2000000, "discover", "configure", "request:0x62:7172")
    _, conf, req = out
    assert conf["result"] == 0 and conf["baud"] == 115200, conf
    assert conf["recoveries"] == 1
    assert bytes.fromhex(req["payload"]) == b"rq"
    assert [periph_stats(procs, p)["baud"] for p in ps] == [115200, 115200]


def test_restarted_master_finds_fast_bus(procs, tmp_path):
    """Peripherals keep their baud: a master started again finds them at
    1M (discovery scans its fast bauds after 9600); a v1 master does not."""
    _, eps, _ = start_vbus(procs, tmp_path, 3)
    start_two(procs, eps)
    fast_master(eps[0], 1000000, "discover", "configure")
    _, out = fast_master(eps[0], 1000000, "discover", "configure", "request:0x62:01")
    disc, conf, req = out
    assert [p["baud"] for p in disc["peers"]] == [1000000, 1000000]
    assert conf["result"] == 0 and conf["baud"] == 1000000
    assert req["payload"] == "01"
    rc, out = master(eps[0], "discover", types=TYPES, check=False)
    assert rc != 0 and out[0]["peers"] == []


def danprobe_doc(*args):
    rc, out, err = danprobe(*args, "--json", "-q")
    assert rc == 0, (rc, out, err)
    return json.loads(out)


def test_danprobe_negotiates_and_finds_fast_bauds(procs, tmp_path):
    """danprobe follows the same rules: --max-baud 2000000 with a v1-only
    peripheral mixed in settles on 115200; alone with fast peripherals it
    reaches 2M, and a later discover --max-baud finds the bus there."""
    _, eps, _ = start_vbus(procs, tmp_path, 4)
    start_two(procs, eps)
    old = start_periph(procs, eps[3], "test-b", "0x0F", "--v1-only")
    conf = danprobe_doc("configure", "--port", eps[0], "--types", TYPES, "--max-baud", 2000000)
    assert conf["result"] == 0 and conf["baud"] == 115200 and conf["target"] == 115200, conf
    assert periph_stats(procs, old)["nacks"] == len(FAST)
    # Without the v1 peripheral (stopped above): 115200 -> 2M.
    conf = danprobe_doc(
        "configure", "--port", eps[0], "--types", "test-a,can-gw", "--max-baud", 2000000
    )
    assert conf["result"] == 0 and conf["baud"] == 2000000, conf
    print("danprobe configure 115200 -> 2000000: %.1f ms" % conf["ms"])
    disc = danprobe_doc("discover", "--port", eps[0], "--types", "test-a,can-gw", "--baud", 2000000)
    assert [p["baud"] for p in disc["peers"]] == [2000000, 2000000]
    assert talkers_at(tmp_path, 2000000) == {0, 1, 2}
