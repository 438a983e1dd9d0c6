"""The compact ESC exchanges end to end (ESC_FAST, ESC_FAST_T;
docs/PROTOCOL.md section 7, "Fast ESC exchanges"): dan-fcsim --fast (libdan
master + gateway client) and `danprobe esc --fast` on a dan-vbus endpoint,
dan-gatewayd on the other, esc_sim's four ESCs behind the SLCAN hub.

Deadlines are generous and catch hangs; nothing here asserts a speed.
"""

import pytest

from bus_util import danprobe, read_capture
from conftest import BIN, closing_factory, wait_for
from danprobe import gateway_fast as F
from gw_rig import GW_NODE, Stack, esc_run


@pytest.fixture
def stack(procs, tmp_path):
    yield from closing_factory(lambda **kw: Stack(procs, tmp_path, **kw))


def frames_of_codes(tmp, codes, baud):
    """(source endpoint, code, frame bytes) of every frame captured at baud with
    one of codes (one-byte codes and lengths: 'D', code, length, payload, crc8)."""
    out = []
    for _, src, b_baud, b, _ in read_capture(tmp):
        if b_baud != baud:
            continue
        while len(b) >= 4 and b[0] == 0x44 and b[1] < 0x80 and b[2] < 0x80:
            frame, b = b[: 4 + b[2]], b[4 + b[2] :]
            if frame[1] in codes:
                out.append((src, frame[1], frame))
    return out


def gateway_cmds(s, values, least):
    """esc_sim's cmd events from the gateway carrying exactly values, per ESC,
    once every ESC has logged at least `least` of them (the Python ESCs
    behind the SLCAN hub lag on a loaded host)."""

    def per_esc():
        per = {}
        for e in s.esc_events("cmd"):
            if e["src"] == GW_NODE and e["cmd"] == values:
                per[e["esc"]] = per.get(e["esc"], 0) + 1
        return per if set(per) == {0, 1, 2, 3} and min(per.values()) >= least else None

    return wait_for(per_esc, 60, 0.2, what=f"{least} commands {values} at every ESC")


def only_values_then_zeros(s, values):
    """Every command the ESCs got from the gateway is values, except the
    failsafe's zeros after the FC stopped (a lagging ESC log may already
    hold them): none before an ESC's last command with values."""
    cmds = [e for e in s.esc_events("cmd") if e["src"] == GW_NODE]
    assert {tuple(e["cmd"]) for e in cmds} <= {tuple(values), (0,) * len(values)}, cmds[-5:]
    for esc in {e["esc"] for e in cmds}:
        mine = [tuple(e["cmd"]) for e in cmds if e["esc"] == esc]
        last = max(i for i, c in enumerate(mine) if c == tuple(values))
        assert (0,) * len(values) not in mine[:last], (esc, mine[:last][-5:])


def fcsim_fast_run(s, baud, ms):
    """dan-fcsim: discover, configure to baud, ESC_FAST with 11,-22,8191,-8192
    for ms (a record every 4th exchange), stats; (output lines, the esc step)."""
    rc, out = s.fcsim(
        "--fast",
        "--telem-every",
        "4",
        "discover",
        f"configure:{baud}",
        f"esc:11,-22,8191,-8192@{ms}@0",
        "stats",
    )
    assert rc == 0, out
    return out, next(line for line in out if line["step"] == "esc")


@pytest.mark.parametrize("baud", [115200, 1000000])
def test_fcsim_fast_exact_values_and_telemetry_of_every_esc(stack, baud):
    s = stack()
    s.wait_gateway_sees(4)
    assert (BIN / "dan-fcsim").exists()
    out, run = fcsim_fast_run(s, baud, 3000)
    assert run["fast"] and run["telem_every"] == 4 and run["errors"] == 0
    assert run["baud"] == baud
    print(f"\nESC_FAST at {run['baud']} on dan-vbus: {run['rate']:.0f} exchanges/s")
    n = run["exchanges"]
    assert n > 40
    # a record on every 4th exchange exactly (and every ESC has reported)
    assert run["telemetry_records"] == (n + 3) // 4
    assert 0 < run["fresh_records"] <= run["telemetry_records"]
    tel = {e["index"]: e for e in run["esc"]}
    assert set(tel) == {0, 1, 2, 3}
    for e in tel.values():
        # the voltage sags at full throttle
        assert e["flags"] & 1 and 10 < e["voltage"] < 17 and e["temperature"] > 290
    # the exact values reached every ESC, and no others; at 115200 nearly once
    # per exchange (at 1M the exchanges outrun the SLCAN hub and the Python
    # ESCs: throttle is latest-wins on the way, so fewer arrive, none wrong)
    gateway_cmds(s, [11, -22, 8191, -8192], 0.9 * n if baud == 115200 else 100)
    only_values_then_zeros(s, [11, -22, 8191, -8192])
    stats = next(line for line in out if line["step"] == "stats")
    assert stats["esc_cmds"] >= n and stats["bad_checks"] == 0
    # on the wire: ESC_FAST requests of 13 bytes, responses of 7 or 17, at the baud
    sizes = frames_of_codes(s.tmp, (0x59, 0x5A), baud)
    assert len(sizes) >= 2 * n
    assert {len(f) for d, c, f in sizes if d == 0} == {13}
    assert {len(f) for d, c, f in sizes if d == 1 and c == 0x59} == {7}
    assert {len(f) for d, c, f in sizes if d == 1 and c == 0x5A} == {17}


def test_danprobe_esc_fast(stack):
    s = stack()
    s.wait_gateway_sees(4)
    rc, out, err = danprobe(
        "esc",
        "--json",
        "-q",
        "--port",
        s.dan,
        "--configure",
        "--values",
        "5,6,7,8",
        "--fast",
        "--telem-every",
        "2",
        "--duration",
        "2",
    )
    assert rc == 0, err
    ex, end = esc_run(out)
    assert end["exchanges"] == len(ex) > 10
    # a record only on the exchanges that asked (every 2nd), once ESCs reported
    assert all(line["telemetry"] is None for line in ex[1::2])
    assert sum(1 for line in ex[0::2] if line["telemetry"]) >= len(ex[0::2]) - 2
    assert [e["index"] for e in end["esc"]] == [0, 1, 2, 3]
    assert end["escs_known"] == 4
    gateway_cmds(s, [5, 6, 7, 8], 0.9 * len(ex))
    wait_for(  # motors stopped at the end
        lambda: [e["cmd"] for e in s.esc_events("cmd") if e["src"] == GW_NODE][-1] == [0] * 4,
        60,
        0.2,
        what="zero throttle last",
    )
    # a bad --telem-every is a usage error
    rc, out, err = danprobe(
        "esc", "--port", s.dan, "--values", "0", "--fast", "--telem-every", "-1", "-q"
    )
    assert rc != 0 and "--telem-every" in err


def test_sniff_names_and_decodes_the_fast_codes(monkeypatch):
    """danprobe sniff names ESC_FAST / ESC_FAST_T and decodes both directions
    (the wire bytes of tests/vectors/gateway_sealed.txt)."""
    from danprobe import gateway_client, registry

    monkeypatch.setattr(registry, "_MESSAGES", dict(registry._MESSAGES))
    gateway_client.register_names()
    assert registry.code_name(F.CODE_ESC_FAST) == "can-gw ESC_FAST"
    assert registry.code_name(F.CODE_ESC_FAST_T) == "can-gw ESC_FAST_T"
    req = bytes.fromhex("000019800cb0043ba1")  # 0,100,200,300 sealed for 0x5A
    role, fields, _ = registry.describe(F.CODE_ESC_FAST_T, req, registry.REQUEST)
    assert role == registry.REQUEST and fields == {"values": [0, 100, 200, 300]}
    rsp = bytes.fromhex("05334c0043d85c8a13880361a6")
    _, fields, _ = registry.describe(F.CODE_ESC_FAST_T, rsp, registry.RESPONSE)
    rec = fields["record"]
    assert fields["armed"] and fields["can_up"] and not fields["failsafe"]
    assert (rec["index"], rec["fresh"], rec["age_ms"], rec["rpm"]) == (2, True, 12, 5002)
    assert rec["voltage"] == 16.796875 and rec["current"] == 3.5 and rec["temperature"] == 310.0
    _, fields, _ = registry.describe(F.CODE_ESC_FAST, bytes.fromhex("05576f"), registry.RESPONSE)
    assert fields["record"] is None and fields["flags"] == 5
