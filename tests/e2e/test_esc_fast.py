"""The compact ESC exchanges end to end (ESC_FAST, ESC_FAST_T;
docs/PROTOCOL.md section 7, "Fast ESC exchanges"): dan-fcsim --fast (libdan
master + gateway client) and `danprobe esc --fast` on a dan-vbus endpoint,
dan-gatewayd on the other, esc_sim's four ESCs behind the SLCAN hub.

Deadlines are generous and catch hangs; nothing here asserts a speed.
"""

import json

import pytest

from bus_util import danprobe, read_capture
from conftest import BIN, closing_factory
from gw_rig import GW_NODE, Stack


@pytest.fixture
def stack(procs, tmp_path):
    yield from closing_factory(lambda **kw: Stack(procs, tmp_path, **kw))


def frames_of_codes(tmp, codes):
    """(source endpoint, code, frame bytes) of every captured frame with one of
    codes (one-byte codes and lengths: 'D', code, length, payload, crc8)."""
    out = []
    for _, src, _, b, _ in read_capture(tmp):
        while len(b) >= 4 and b[0] == 0x44 and b[1] < 0x80 and b[2] < 0x80:
            frame, b = b[: 4 + b[2]], b[4 + b[2] :]
            if frame[1] in codes:
                out.append((src, frame[1], frame))
    return out


def gateway_cmds(s, values):
    """esc_sim's cmd events from the gateway carrying exactly values, per ESC."""
    per = {}
    for e in s.esc_events("cmd"):
        if e["src"] == GW_NODE and e["cmd"] == values:
            per[e["esc"]] = per.get(e["esc"], 0) + 1
    return per


def test_fcsim_fast_exact_values_and_telemetry_of_every_esc(stack):
    s = stack()
    s.wait_gateway_sees(4)
    assert (BIN / "dan-fcsim").exists()
    rc, out = s.fcsim(
        "--fast",
        "--telem-every",
        "4",
        "discover",
        "configure",
        "esc:11,-22,8191,-8192@3000@0",
        "stats",
    )
    assert rc == 0, out
    run = next(line for line in out if line["step"] == "esc")
    assert run["fast"] and run["telem_every"] == 4 and run["errors"] == 0
    assert run["baud"] == 115200
    print(f"\nESC_FAST at {run['baud']} on dan-vbus: {run['rate']:.0f} exchanges/s")
    n = run["exchanges"]
    assert n > 40
    # a record on every 4th exchange exactly (and every ESC has reported)
    assert run["telemetry_records"] == (n + 3) // 4
    assert 0 < run["fresh_records"] <= run["telemetry_records"]
    tel = {e["index"]: e for e in run["esc"]}
    assert set(tel) == {0, 1, 2, 3}
    for e in tel.values():
        assert (
            e["flags"] & 1 and 10 < e["voltage"] < 17 and e["temperature"] > 290
        )  # sags at full throttle
    # the exact values reached every ESC, nearly once per exchange
    per = gateway_cmds(s, [11, -22, 8191, -8192])
    assert set(per) == {0, 1, 2, 3}
    assert min(per.values()) >= 0.9 * n
    stats = next(line for line in out if line["step"] == "stats")
    assert stats["esc_cmds"] >= n and stats["bad_checks"] == 0
    # on the wire: ESC_FAST requests of 13 bytes, responses of 7 or 17
    sizes = frames_of_codes(s.tmp, (0x59, 0x5A))
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
    lines = [json.loads(x) for x in out.splitlines()]
    ex = [line for line in lines if line.get("event") == "exchange"]
    end = lines[-1]
    assert end["event"] == "summary" and end["exchanges"] == len(ex) > 10
    # a record only on the exchanges that asked (every 2nd), once ESCs reported
    assert all(line["telemetry"] is None for line in ex[1::2])
    assert sum(1 for line in ex[0::2] if line["telemetry"]) >= len(ex[0::2]) - 2
    assert [e["index"] for e in end["esc"]] == [0, 1, 2, 3]
    assert end["escs_known"] == 4
    per = gateway_cmds(s, [5, 6, 7, 8])
    assert set(per) == {0, 1, 2, 3} and min(per.values()) >= 0.9 * len(ex)
    cmds = [tuple(e["cmd"]) for e in s.esc_events("cmd") if e["src"] == GW_NODE]
    assert cmds[-1] == (0, 0, 0, 0)  # motors stopped at the end
    # a bad --telem-every is a usage error
    rc, out, err = danprobe(
        "esc", "--port", s.dan, "--values", "0", "--fast", "--telem-every", "-1", "-q"
    )
    assert rc != 0 and "--telem-every" in err
