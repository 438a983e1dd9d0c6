"""Fast bauds (docs/PROTOCOL.md section 6, "Fast bauds") end to end on
dan-vbus: dan-master negotiates 1000000 and 2000000 with dan-testperiph
peripherals; a v1-only peripheral on the same bus refuses and the bus
settles on the best common baud; a peripheral that acknowledges and does
not switch is recovered; a restarted master finds a bus left at a fast
baud; dan-gatewayd and dan-fcsim run an ESC loop at 1M and 2M with exact
values and the failsafe on time. Generous reply windows: these tests check
behaviour, not speed (the rates are printed for the report). The QEMU
firmware runs at its fastest baud."""

import json

import dronecan
import pytest

from bus_util import (
    danprobe,
    periph_stats,
    read_capture,
    start_periph,
    start_vbus,
    vbus_stats,
)
from conftest import closing_factory, wait_for
from gw_rig import ESC_LOOP, Rig, f16, step
from test_bus import master
from test_firmware import firmware_bus, need_qemu, run_firmware

U = dronecan.uavcan

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
    _, conf, req, mst = out
    assert conf["result"] == 0 and conf["baud"] == 115200, conf
    assert conf["fast_refusals"] == len(FAST) and conf["recoveries"] == 0
    assert bytes.fromhex(req["payload"]) == b"ih"
    st = periph_stats(procs, old)
    # one refusal per fast baud, and one more for each CONFIGURE the master
    # repeated (an echo or a reply a loaded host delivered late)
    assert len(FAST) <= st["nacks"] <= len(FAST) + mst["retries"], (st, mst)
    assert st["baud"] == 115200
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
    # one refusal per fast baud (and one per CONFIGURE repeated on a loaded host)
    assert len(FAST) <= periph_stats(procs, old)["nacks"] <= len(FAST) + conf["retries"], conf
    # Without the v1 peripheral (stopped above): 115200 -> 2M.
    conf = danprobe_doc(
        "configure", "--port", eps[0], "--types", "test-a,can-gw", "--max-baud", 2000000
    )
    assert conf["result"] == 0 and conf["baud"] == 2000000, conf
    print("danprobe configure 115200 -> 2000000: %.1f ms" % conf["ms"])
    disc = danprobe_doc("discover", "--port", eps[0], "--types", "test-a,can-gw", "--baud", 2000000)
    assert [p["baud"] for p in disc["peers"]] == [2000000, 2000000]
    assert talkers_at(tmp_path, 2000000) == {0, 1, 2}


# ---- the gateway: dan-gatewayd with dan-fcsim at 1M and 2M ----


@pytest.fixture
def gw_rig(procs, tmp_path):
    yield from closing_factory(lambda **kw: Rig(procs, tmp_path, **kw))


def esc_rig(gw_rig):
    """The gateway (ESC timeout 300 ms) and ESC node 20; raw gets each
    RawCommand the node receives as (when, values)."""
    r = gw_rig(gw_args=["--esc-timeout-ms", "300"])
    esc = r.node(1, 20, "org.test.esc_a")
    raw = []
    # (when the frame was read from the port: a handler late on a loaded
    # host does not move it)
    esc.add_handler(
        U.equipment.esc.RawCommand,
        lambda e: raw.append((e.transfer.ts_monotonic, list(e.message.cmd))),
    )
    return r, esc, raw


def failsafe_after(raw, n, values):
    """In what the ESC got since raw[n]: (the last command of values, the
    first zeros after it, all of it), or None before the zeros. In the order
    received: an earlier FC's failsafe zeros come before its commands."""
    got = raw[n:]
    ours = [i for i, (_, c) in enumerate(got) if c == values]
    zeros = [t for t, c in got[ours[-1] + 1 :] if c == [0, 0, 0, 0]] if ours else []
    return (got[ours[-1]][0], zeros[0], got) if zeros else None


@pytest.mark.parametrize("baud", [1000000, 2000000])
def test_gateway_esc_loop_and_failsafe(gw_rig, baud):
    """dan-gatewayd accepts the fast bauds by default; dan-fcsim moves the
    bus to 1M / 2M; ESC values reach the ESC node exactly, telemetry comes
    back exactly, and the failsafe (300 ms) still fires on time."""
    r, esc, raw = esc_rig(gw_rig)
    tele = {0: (12.5, 1.25, 300.0, 1000), 1: (16.8, -3.14159, 310.15, -2000)}

    def publish():
        for idx, (v, c, t, rpm) in tele.items():
            esc.broadcast(
                U.equipment.esc.Status(
                    voltage=v, current=c, temperature=t, rpm=rpm, esc_index=idx, error_count=idx
                )
            )

    r.spin(esc, publish, 0.1)
    fast = ("--max-baud", str(baud))
    rc, out = r.fcsim(
        "discover",
        "configure",
        "arm",
        *ESC_LOOP,
        "telemetry",
        opts=fast,
    )
    assert rc == 0, [line for line in out if not line.get("ok", True)] or out
    conf = step(out, "configure")[0]
    assert conf["baud"] == baud and conf["fast_refusals"] == 0 and conf["recoveries"] == 0
    for want in ([0, 100, -8192, 8191], [1, 2, 3, 4, 5, 6, 7, -8], [0, 100, 200, 300]):
        wait_for(lambda want=want: want in [c for _, c in raw], 20, what=f"{want} at the ESC")
    tel = {e["index"]: e for e in step(out, "telemetry")[0]["esc"]}
    for idx, (v, c, t, rpm) in tele.items():
        e = tel[idx]
        assert e["voltage"] == f16(v) and e["current"] == f16(c)
        assert e["temperature"] == f16(t) and e["rpm"] == rpm and e["node"] == 20
    loop = step(out, "esc")[2]
    assert loop["errors"] == 0
    print(f"\nESC exchanges at {baud} (4 ESCs, back to back, dan-vbus): {loop['rate']:.1f}/s")

    # failsafe: a new FC process finds the bus at the fast baud, commands,
    # stops; zeros arrive no sooner than the timeout after the last command
    n = len(raw)
    rc, out = r.fcsim("discover", "esc:500,500,500,500@500@50", "stop", opts=fast)
    assert rc == 0 and step(out, "discover")[0]["baud"] == baud, out

    last, zero, _ = wait_for(
        lambda: failsafe_after(raw, n, [500, 500, 500, 500]),
        20,
        what="zero throttle after the last command",
    )
    print(f"failsafe at {baud}: zeros {1000 * (zero - last):.0f} ms after the last command")
    assert 0.25 <= zero - last <= 2.0


def test_every_fast_baud_exact_values_and_failsafe(gw_rig):
    """At each of the other fast bauds (1M and 2M above): dan-fcsim moves the
    bus there, exactly its values reach the ESC node, and after the FC
    stops the failsafe's zeros come no sooner than the timeout (300 ms)."""
    r, esc, raw = esc_rig(gw_rig)
    r.spin(esc)
    for k, baud in enumerate(b for b in FAST if b not in (1000000, 2000000)):
        values = [10 + k, -20 - k, 30 + k, 8191 - k]
        n = len(raw)
        rc, out = r.fcsim(
            "discover",
            f"configure:{baud}",
            f"esc:{','.join(map(str, values))}@400@50",
            "stop",
            opts=("--max-baud", "2000000"),
        )
        assert rc == 0 and step(out, "configure")[0]["baud"] == baud, out

        last, zero, got = wait_for(
            lambda n=n, values=values: failsafe_after(raw, n, values),
            20,
            what=f"the failsafe at {baud}",
        )
        # nothing but this run's values (and the zeros of the failsafes)
        assert {tuple(c) for _, c in got} <= {tuple(values), (0, 0, 0, 0)}, (baud, got)
        print(f"\n{baud}: exact values, zeros {1000 * (zero - last):.0f} ms after the last")
        assert 0.25 <= zero - last <= 2.0, baud


# ---- the QEMU firmware (examples/fc_firmware) at its fastest baud ----


def test_firmware_at_its_fastest_baud(procs, tmp_path):
    """fc_firmware with fast=on offers the fast bauds its UART can do
    (board_fast_bauds(): QEMU's tty backend turns 1000000 into 921600 at
    the pty, so the board leaves it out) and the bus ends at 1500000: the
    divisor 17 gives 1470588, which QEMU sets on the pty as 1500000."""
    need_qemu()
    eps, ctl, ps = firmware_bus(procs, tmp_path)
    rc, steps, text = run_firmware(procs, tmp_path, eps[0], append="fast=on gw=off")
    assert rc == 0, text
    assert steps["boot"]["fast_max"] > 0
    conf = steps["configure"]
    assert conf["result"] == 0 and conf["baud"] == 1500000, conf
    assert conf["uart_baud"] == 1470588 and conf["recoveries"] == 0
    txn = steps["transactions"]
    assert txn["ok"] == txn["count"] == 40 and txn["bad"] == 0 and txn["baud"] == 1500000
    print(f"\nfirmware: configure 9600 -> 1500000 in {conf['ms']} ms (QEMU time)")
    assert vbus_stats(ctl)["endpoints"][0]["baud"] == 1500000
    assert talkers_at(tmp_path, 1500000) == {0, 1, 2, 3}
    for p in ps:
        assert periph_stats(procs, p)["baud"] == 1500000
