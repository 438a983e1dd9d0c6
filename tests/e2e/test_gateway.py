"""CAN-over-DAN gateway end to end: dan-fcsim (libdan master + gateway
client) on a dan-vbus endpoint, dan-gatewayd on the other, an SLCAN hub as
the CAN bus and pydronecan nodes as the independent DroneCAN peers.

Deadlines are generous and catch hangs; nothing here asserts a speed.
"""

import os
import sys
import time

import dronecan
import pytest

from conftest import BIN, ROOT, closing_factory, wait_for
from gw_rig import ESC_LOOP, GW_NODE, Rig, TunnelFarEnd, f16, step

U = dronecan.uavcan


@pytest.fixture
def rig(procs, tmp_path):
    yield from closing_factory(lambda **kw: Rig(procs, tmp_path, **kw))


def test_esc_telemetry_arming_nodes_failsafe(rig):
    r = rig(gw_args=["--esc-timeout-ms", "300"])
    esc = r.node(1, 20, "org.test.esc_a")
    raw, arming = [], []
    # (stamped when read from the port: a late handler does not move them)
    esc.add_handler(
        U.equipment.esc.RawCommand,
        lambda e: raw.append((e.transfer.ts_monotonic, list(e.message.cmd))),
    )
    esc.add_handler(
        U.equipment.safety.ArmingStatus,
        lambda e: arming.append((e.transfer.ts_monotonic, e.message.status)),
    )
    gw_status, gw_info = [], []
    esc.add_handler(
        U.protocol.NodeStatus,
        lambda e: (
            gw_status.append(e.message.health) if e.transfer.source_node_id == GW_NODE else None
        ),
    )
    tele = {
        0: (12.5, 1.25, 300.0, 1000),
        1: (16.8, -3.14159, 310.15, -2000),
        2: (25.2, 123.456, 320.0, 131071),
        3: (11.1, 0.1, 299.0, 0),
    }

    def publish():
        for idx, (v, c, t, rpm) in tele.items():
            esc.broadcast(
                U.equipment.esc.Status(
                    error_count=idx + 7,
                    voltage=v,
                    current=c,
                    temperature=t,
                    rpm=rpm,
                    power_rating_pct=10 + idx,
                    esc_index=idx,
                )
            )

    r.spin(esc, publish, 0.1)

    rc, out = r.fcsim(
        "discover",
        "configure",
        "arm",
        *ESC_LOOP,
        "telemetry",
        "nodes",
        "stats",
    )
    assert rc == 0, [line for line in out if not line.get("ok", True)] or out
    assert step(out, "configure")[0]["baud"] == 115200
    # exact values on the bus, 4 and 8 channels (the node's thread may
    # still be working through them on a loaded host)
    for want in ([0, 100, -8192, 8191], [1, 2, 3, 4, 5, 6, 7, -8]):
        wait_for(lambda want=want: want in [c for _, c in raw], 20, what=f"{want} at the ESC")
    # arming reached the ESC node
    wait_for(lambda: any(s == 255 for _, s in arming), 20, what="FULLY_ARMED at the ESC")
    # telemetry came back exactly (float16-rounded)
    tel = {e["index"]: e for e in step(out, "telemetry")[0]["esc"]}
    assert set(tel) == set(tele)
    for idx, (v, c, t, rpm) in tele.items():
        e = tel[idx]
        assert e["voltage"] == f16(v) and e["current"] == f16(c)
        assert e["temperature"] == f16(t) and e["rpm"] == rpm
        assert e["error_count"] == idx + 7 and e["power_pct"] == 10 + idx and e["node"] == 20
    # one exchange per control cycle also brings telemetry back, round robin
    fast = step(out, "esc")[2]
    assert fast["telemetry_records"] > 0.9 * fast["exchanges"]
    # the rate at 115200 (printed for the report; no bound asserted)
    req = 12  # 'D' code len 8-byte payload crc
    rsp = 4 + 3 + 17  # frame overhead, header, one record
    bound = 115200 / 10 / (req + rsp)
    print(
        f"\nESC exchange rate at 115200: {fast['rate']:.1f}/s "
        f"(wire-time bound {bound:.0f}/s for {req}+{rsp} bytes)"
    )
    # node table lists the pydronecan node with its name
    nodes = {n["id"]: n for n in step(out, "nodes")[0]["nodes"]}
    assert nodes[20]["name"] == "org.test.esc_a"
    assert nodes[20]["sw"] == [2, 7]
    # pydronecan sees the gateway: NodeStatus OK (a master polls) and GetNodeInfo
    wait_for(lambda: 0 in gw_status, 5, what="gateway NodeStatus health OK")
    esc.request(
        U.protocol.GetNodeInfo.Request(),
        GW_NODE,
        lambda e: gw_info.append(e.response if e else None),
    )
    wait_for(lambda: gw_info, 10, what="GetNodeInfo response")
    assert gw_info[0] is not None
    assert gw_info[0].name.decode() == "org.dan.can_gateway"

    # failsafe: the FC stops; zeros and DISARMED arrive within the timeout
    t_stop_len = len(raw)
    rc, out = r.fcsim("discover", "esc:500,500,500,500@500@50", "stop")
    assert rc == 0
    t_stop = time.monotonic()
    wait_for(
        lambda: any(c == [0, 0, 0, 0] for _, c in raw[t_stop_len:]),
        10,
        what="zero throttle after failsafe",
    )
    wait_for(lambda: any(s == 0 and t > t_stop for t, s in arming), 10, what="DISARMED")
    rc, out = r.fcsim("discover", "stats")
    assert step(out, "stats")[0]["failsafes"] >= 1

    # SIGTERM: zero throttle and DISARMED again, exit 0
    n_raw = len(raw)
    assert r.procs.stop(r.gwd) == 0
    wait_for(lambda: any(c == [0, 0, 0, 0] for _, c in raw[n_raw:]), 10, what="zero on SIGTERM")


def test_tunnel_64k_both_ways(rig):
    r = rig()
    far = TunnelFarEnd(r.node(1, 30, "org.test.far_end"), 30, 2)
    r.spin(far.node, far.pump, 0.002)

    data = os.urandom(64 * 1024)
    src = r.tmp / "in.bin"
    dst = r.tmp / "out.bin"
    src.write_bytes(data)
    rc, out = r.fcsim(
        "discover",
        "configure",
        "tunnel:0:targetted:30:2:115200",
        # generous: alone it takes about 10 s, but the Python far end and the
        # SLCAN hub starve when the other test workers load both cores
        f"xfer:0:{src}:{dst}:{len(data)}:300000",
        "stats",
        timeout=330,
    )
    # all of it on failure: where the bytes went (the far end's count, the
    # gateway's and the client's drop counters, "stalled")
    assert rc == 0, f"far end got {len(far.got)} B; " + "; ".join(map(str, out))
    assert bytes(far.got) == data
    assert dst.read_bytes() == bytes(b ^ 0x5A for b in data)
    x = step(out, "xfer")[0]
    print(f"\n64 KiB each way through the tunnel in {x['seconds']:.1f} s")


def test_tunnel_broadcast(rig):
    r = rig()
    far = r.node(1, 31, "org.test.bcast")
    got = bytearray()
    far.add_handler(
        U.tunnel.Broadcast,
        lambda e: (
            got.extend(bytes(e.message.buffer))
            if e.message.channel_id == 7 and e.message.protocol.protocol == 2
            else None
        ),
    )
    sent = []

    def pump():
        if got and len(sent) < 20:  # once the FC's port is open and talking
            b = bytes([len(sent)] * 60)
            sent.append(b)
            far.broadcast(
                U.tunnel.Broadcast(
                    protocol=U.tunnel.Protocol(protocol=2), channel_id=7, buffer=list(b)
                )
            )

    r.spin(far, pump, 0.02)
    data = os.urandom(4000)
    src, dst = r.tmp / "b_in.bin", r.tmp / "b_out.bin"
    src.write_bytes(data)
    rc, out = r.fcsim(
        "discover", "configure", "tunnel:0:broadcast:2:7", f"xfer:0:{src}:{dst}:1200:30000"
    )
    assert rc == 0, [line for line in out if not line.get("ok", True)] or out
    wait_for(lambda: len(got) >= len(data), 20, what="broadcast tunnel data")
    assert bytes(got) == data
    assert dst.read_bytes()[:1200] == b"".join(sent)[:1200]


def test_raw_frames_filtered(rig):
    r = rig()
    can2 = str(r.tmp / "can1")
    # pass 11-bit 0x100..0x1FF only
    rec = r.procs.start(
        [
            BIN / "dan-cantool",
            "--can",
            f"slcan:{can2}",
            "recv",
            "--count",
            "0",
            "--timeout-ms",
            "6000",
        ]
    )
    time.sleep(0.5)
    rc, out = r.fcsim(
        "discover",
        "configure",
        "filter:100/700",
        "cansend:123#DEADBEEF,1ABCDE01#0102030405060708",
        "sleep:200",
    )
    assert rc == 0, [line for line in out if not line.get("ok", True)] or out
    o, _ = rec.communicate(timeout=40)
    lines = o.decode().split()
    assert "123#DEADBEEF" in o.decode()
    assert "1ABCDE01#0102030405060708" in o.decode()
    # the other direction: one frame passes the filter, one does not
    snd = r.procs.start(
        [BIN / "dan-cantool", "--can", f"slcan:{can2}", "send", "1AB#0102", "2AB#0304", "155#"]
    )
    assert snd.wait(20) == 0
    rc, out = r.fcsim("discover", "candump:2:10000")
    assert rc == 0, [line for line in out if not line.get("ok", True)] or out
    assert step(out, "candump")[0]["frames"] == ["1AB#0102", "155#"]
    del lines


def test_uart_lost_failsafe_and_exit(procs, tmp_path):
    """The DAN UART goes away (USB unplug, pty closed): the daemon notices
    the hangup (a tty at VMIN=0 then reads 0 bytes forever), sends the
    failsafe and exits 1 instead of spinning (found by review)."""
    import pty

    m, s = pty.openpty()
    path = os.ttyname(s)
    os.close(s)
    hub = procs.start(
        [
            sys.executable,
            ROOT / "host_tools" / "slcan_hub.py",
            "-n",
            "1",
            "--link",
            tmp_path / "can",
        ],
        name="slcan_hub",
    )
    assert hub.stdout.readline().startswith(b"READY")
    gw = procs.start(
        [BIN / "dan-gatewayd", "--uart", path, "--can", f"slcan:{tmp_path}/can0"],
        name="dan-gatewayd",
    )
    wait_for(lambda: b"DroneCAN node" in gw.log_path.read_bytes(), 20, what="gateway start")
    os.close(m)
    assert gw.wait(20) == 1
    log = gw.log_path.read_text()
    assert "UART lost" in log and "failsafe sent" in log
