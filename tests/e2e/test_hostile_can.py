"""A hostile node on the CAN bus while the FC drives ESCs (docs/SECURITY.md).

The whole stack of test_faults (dan-fcsim on dan-vbus, dan-gatewayd, the
SLCAN hub, esc_sim's four ESCs) with a fifth hub port writing raw SLCAN
frames from a seeded schedule: forged responses to the gateway's service
calls, replays of old transfers, a flood of allocation requests, NodeStatus
claiming the gateway's node ID, malformed multi-frame transfers, oversized
and overflowing tunnel data. One dan-fcsim run makes a clean ESC loop, then
the same loop under attack; the test prints both rates and what the
gateway's STATS counted. Values at the ESCs must be exact and no exchange
may fail. That the loop under attack keeps at least 90 % of the clean rate
(both runs ask for the same 150 Hz, below the bus's ~184/s, so only a
slower gateway lowers it) is measured by make bench (row 'hostile', which
runs this test with DAN_HOSTILE_OUT), not asserted on a loaded test host."""

import json
import os
import random
import threading
import time
import tty

import dronecan
from dronecan.transport import Transfer

import test_faults

U = dronecan.uavcan
GW = 10  # the gateway's node ID
TUN_NODE = 60  # the tunnel's far end the FC opens (the attacker speaks for it)
CLEAN = (101, 202, 303, 404)
CLEAN_AFTER = (111, 222, 333, 444)
UNDER_ATTACK = (505, 606, 707, 808)
ESC_MS, ESC_HZ = 4000, 150


def slcan(can_id, data):
    return b"T%08X%d%s\r" % (can_id, len(data), bytes(data).hex().upper().encode())


def frames(payload, raw=None, **kw):
    """SLCAN lines of a DroneCAN transfer of the DSDL object payload
    (pydronecan's encoder: IDs, tail bytes, transfer CRC); raw replaces the
    encoded bytes (same type, same CRC seed) to send what the type forbids."""
    t = Transfer(payload=payload, **kw)
    if raw is not None:
        t.payload = bytes(raw)
    return [slcan(f.message_id, f.bytes) for f in t.to_frames()]


def service_id(dtid, src, dst, request, prio=30):
    return prio << 24 | dtid << 16 | (request << 15) | dst << 8 | 1 << 7 | src


def node_status(src, uptime, tid):
    return frames(
        U.protocol.NodeStatus(uptime_sec=uptime, health=0, mode=0),
        source_node_id=src,
        transfer_id=tid,
    )


class Hostile:
    """Writes the attack to an SLCAN port in rounds; .sent counts frames by
    kind. Everything random comes from one seed."""

    KINDS = ("forge", "replay", "alloc", "claim", "malformed", "tunnel")

    def __init__(self, path, seed=15):
        self.fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(self.fd)
        os.write(self.fd, b"C\rS8\rO\r")
        time.sleep(0.2)
        os.set_blocking(self.fd, False)
        self.rng = random.Random(seed)
        self.sent = dict.fromkeys(self.KINDS, 0)
        self.tid = 0
        self.uptime = 1
        self.stop = threading.Event()
        # recorded once, replayed identically ever after
        self.recorded = (
            node_status(50, 7, 3)
            + [slcan(service_id(1, 51, GW, 1), [0xC0 | 5])]  # GetNodeInfo request
            + frames(self._chunk(b"old bytes"), source_node_id=TUN_NODE, transfer_id=9)
        )

    def _next_tid(self):
        self.tid = (self.tid + 1) & 31
        return self.tid

    def _chunk(self, data, target=GW):
        return U.tunnel.Targetted(
            protocol=U.tunnel.Protocol(protocol=255),
            target_node=target,
            serial_id=0,
            options=0,
            baudrate=0,
            buffer=list(data),
        )

    def forge(self):
        """Responses to calls nobody made, or made to another node: random
        services the gateway calls, random sources, transfer IDs, content."""
        out = []
        for dtid in (1, 5, 10, 11):
            src = self.rng.choice([n for n in range(1, 128) if n != GW])
            tid = self.rng.randrange(32)
            data = bytes(self.rng.randrange(256) for _ in range(self.rng.randint(0, 6)))
            out.append(slcan(service_id(dtid, src, GW, 0), data + bytes([0xC0 | tid])))
        resp = U.protocol.GetNodeInfo.Response(name="org.hostile.forger")
        out += frames(
            resp,
            source_node_id=self.rng.randint(20, 23),  # the ESCs' IDs
            dest_node_id=GW,
            service_not_message=True,
            transfer_id=self.rng.randrange(32),
        )
        return out

    def replay(self):
        return list(self.recorded)

    def alloc(self):
        """A complete three-stage allocation for a new random unique ID,
        sent back to back (the gateway answers between the stages)."""
        uid = bytes(self.rng.randrange(256) for _ in range(16))
        disc = self.rng.getrandbits(14)
        can_id = 30 << 24 | disc << 10 | 1 << 8
        out = []
        for off, first in ((0, True), (6, False), (12, False)):
            head = 1 if first else 0
            out.append(slcan(can_id, bytes([head]) + uid[off : off + 6] + bytes([0xC0 | off])))
        return out

    def claim(self):
        self.uptime += 1
        return node_status(GW, self.uptime, self._next_tid())

    def malformed(self):
        out = []
        gs = service_id(11, 40, GW, 0)
        tid = self._next_tid()
        out.append(slcan(gs, bytes(7) + bytes([0x80 | 0x20 | tid])))  # start with toggle set
        out.append(slcan(gs, bytes(3) + bytes([0x80 | tid])))  # short non-final start
        out.append(slcan(gs, bytes(7) + bytes([0x20 | tid])))  # middle without a start
        # a whole transfer with a wrong CRC
        out.append(slcan(gs, bytes([0x12, 0x34]) + bytes(5) + bytes([0x80 | tid])))
        out.append(slcan(gs, bytes(3) + bytes([0x40 | 0x20 | tid])))
        # 420 bytes of GetNodeInfo response: more than any transfer may be
        big = U.protocol.GetNodeInfo.Response()
        out += frames(
            big,
            raw=bytes(self.rng.randrange(256) for _ in range(420)),
            source_node_id=41,
            dest_node_id=GW,
            service_not_message=True,
            transfer_id=tid,
        )
        # start frames from many sources, never finished: they hold sessions
        for src in self.rng.sample(range(64, 128), 8):
            out.append(slcan(service_id(1, src, GW, 0), bytes(7) + bytes([0x80 | tid])))
        return out

    def tunnel(self):
        """Tunnel bytes as the far end: three full 120-byte chunks (the FC never
        reads them, so its 4096-byte buffer overflows: counted), and a chunk
        of 200 bytes, longer than the type allows (malformed, ignored)."""
        ok = []
        for _ in range(3):
            ok += frames(
                self._chunk(bytes(self.rng.randrange(256) for _ in range(120))),
                source_node_id=TUN_NODE,
                transfer_id=self._next_tid(),
            )
        bad = frames(
            self._chunk(b""),
            raw=bytes([255, GW, 0, 0, 0, 0, 0, 0]) + bytes(200),
            source_node_id=TUN_NODE,
            transfer_id=self._next_tid(),
        )
        return ok + bad

    def run(self):
        try:
            # first 36 chunks (4320 bytes) for the tunnel the FC never
            # reads: more than its 4096-byte buffer, whatever the timing
            fill = [self.tunnel() for _ in range(12)]
            self._write(b"".join(sum(fill, [])))
            self.sent["tunnel"] += sum(map(len, fill))
            while not self.stop.is_set():
                kind = self.rng.choice(self.KINDS)
                lines = getattr(self, kind)()
                self._write(b"".join(lines))
                self.sent[kind] += len(lines)
                try:
                    while os.read(self.fd, 65536):  # the hub's acknowledgements
                        pass
                except (BlockingIOError, OSError):
                    pass
                time.sleep(0.04)  # ~600 frames/s: the Python hub and ESCs share 2 cores
        finally:
            os.close(self.fd)

    def _write(self, data):
        while data and not self.stop.is_set():
            try:
                data = data[os.write(self.fd, data) :]
            except BlockingIOError:
                time.sleep(0.002)


def delta(after, before):
    return {k: after[k] - before[k] for k in after if isinstance(after[k], int)}


def test_hostile_can_node(procs, tmp_path):
    r = test_faults.Rig(procs, tmp_path)
    hostile = Hostile(tmp_path / "can5")
    t = threading.Thread(target=hostile.run, daemon=True)
    snap = {}

    def on_line(line):
        if line.get("step") != "esc":
            return
        if "clean" not in snap:
            snap["clean"] = line
            snap["before"] = r.gw_stats()
            t.start()
        elif "attacked" not in snap:
            snap["attacked"] = line
            hostile.stop.set()
        else:
            snap["clean_after"] = line

    try:
        rc, out = r.fcsim(
            "discover",
            "configure",
            f"tunnel:0:targetted:{TUN_NODE}:0",
            "arm",
            f"esc:{','.join(map(str, CLEAN))}@{ESC_MS}@{ESC_HZ}",
            "sleep:1500",  # the attack is under way
            f"esc:{','.join(map(str, UNDER_ATTACK))}@{ESC_MS}@{ESC_HZ}",
            f"esc:{','.join(map(str, CLEAN_AFTER))}@{ESC_MS}@{ESC_HZ}",
            on_line=on_line,
            timeout=180,
        )
    finally:
        hostile.stop.set()
        if t.is_alive():
            t.join(10)
    assert rc == 0, [x for x in out if not x.get("ok")]
    assert "clean_after" in snap, out
    # counted during the attack (the stats file lags by up to a second:
    # the clean run after it is quiet on CAN, so its end is taken)
    d = delta(r.gw_stats(), snap["before"])
    clean, attacked, after = snap["clean"], snap["attacked"], snap["clean_after"]
    base = min(clean["exchanges"], after["exchanges"])
    wrong = r.wrong_values()

    def heard_under_attack():
        return [e for e in r.esc_events() if tuple(e["cmd"]) == UNDER_ATTACK]

    # The ESC simulators (pydronecan) also received the flood: on a loaded
    # host they log what they heard seconds late (seen in make test: none yet).
    # All of them within 5 s, or at least one within 30 s.
    t0 = time.monotonic()
    while time.monotonic() < t0 + 30:
        n = len(heard_under_attack())
        if n >= attacked["exchanges"] or (n and time.monotonic() > t0 + 5):
            break
        time.sleep(0.2)
    heard = heard_under_attack()
    print(
        f"\nclean before: {clean['exchanges']} exchanges, {clean['rate']}/s, errors "
        f"{clean['errors']}; clean after: {after['exchanges']} exchanges, {after['rate']}/s"
        f"\nunder attack: {attacked['exchanges']} exchanges, {attacked['rate']}/s, "
        f"errors {attacked['errors']}; hostile frames sent {hostile.sent} "
        f"(total {sum(hostile.sent.values())})"
        f"\ngateway counters during the attack: "
        + ", ".join(
            f"{k} {d[k]}"
            for k in (
                "can_rx",
                "dc_transfers",
                "dc_crc_errors",
                "dc_errors",
                "dna_allocations",
                "dna_bad",
                "tun_dropped",
                "nodes",
                "duplicates",
                "can_tx_dropped",
                "bad_checks",
                "failsafes",
            )
        )
        + f"\nwrong values at the ESCs {len(wrong)}, commands heard under attack {len(heard)}"
    )
    figures = {
        "clean": clean["exchanges"],
        "clean_after": after["exchanges"],
        "attacked": attacked["exchanges"],
        "clean_rate": clean["rate"],
        "attacked_rate": attacked["rate"],
        "ratio": attacked["exchanges"] / base if base else 0.0,
        "hostile_frames": sum(hostile.sent.values()),
        "heard": len(heard),
        "counters": {k: d[k] for k in d},
    }
    if os.environ.get("DAN_HOSTILE_OUT"):  # make bench's 'hostile' row: the rate goal is there
        with open(os.environ["DAN_HOSTILE_OUT"], "w") as f:
            json.dump(figures, f)
    assert not wrong, wrong[:5]
    assert attacked["errors"] == 0 and clean["errors"] == 0, (clean, attacked)
    # The rate under attack against the clean one (goal 0.9) is a speed
    # figure: make bench measures it. Here the loop must go on under attack,
    # and the ESCs (Python, behind the Python hub, which drops frames for a
    # reader that lags like a real adapter) hear commands sent under attack.
    assert attacked["exchanges"] > 0 and heard, (clean, attacked, len(heard))
    assert all(hostile.sent[k] > 0 for k in Hostile.KINDS), hostile.sent
    # what the gateway dropped is counted
    assert d["dc_crc_errors"] > 0 and d["dc_errors"] > 0, d
    # The hostile allocations are granted, or refused while the gateway
    # still asks nodes for GetNodeInfo (an allocator waits for "all nodes
    # discovered"; the forged traffic keeps adding some): then stages 2 and
    # 3, sent back to back, come out of sequence and count as dna_bad.
    assert d["tun_dropped"] > 0 and d["dna_allocations"] + d["dna_bad"] > 0, d
    assert d["duplicates"] >= 1, d  # the node claiming our ID is flagged
    assert d["can_tx_dropped"] == 0, d
