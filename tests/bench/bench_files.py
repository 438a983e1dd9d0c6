"""The `files` rows of run_bench.py: a firmware image uploaded into
dan-gatewayd's file store through DAN on dan-vbus at 115200 and 2000000, by
the FC's C client (libdan's master and dan_gw_file_*, run by dan-fcsim) and
by danprobe's Python client, against the wire bound of its own bytes, and
the time a bootloader node behind the SLCAN hub takes to read it through
the gateway.

The bound of an upload is the time its frames (FILE_OPEN, FILE_WRITE,
FILE_COMMIT requests and responses, as the vbus capture holds them) take
on the wire at 10 bits a byte, plus the mandatory gaps of docs/PROTOCOL.md
section 6 for each exchange: turnaround 2 C and listen-before-talk 3 C.
Goal: >= 0.8 of the bound.

Each row also runs the same bytes per exchange between two bare processes
on dan-vbus (bench_pty_rtt, no DAN engine, no gaps): on ptys every hop
costs tens of microseconds of wake-ups that a UART does not, a quarter of
a 2 Mbit/s FILE_WRITE exchange, and that comparison shows what is ours."""

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host_tools"))
from danprobe import file_update, registry  # noqa: E402
from danprobe import gateway_file as F  # noqa: E402
from danprobe.gateway_client import GatewayClient  # noqa: E402
from danprobe.master import Master, MasterConfig, RemoteError  # noqa: E402
from danprobe.port import SerialPort  # noqa: E402

SIZE = 256 * 1024
BAUDS = (115200, 2000000)
GOAL = 0.8
GAP_CHARS = 2 + 3  # turnaround + listen-before-talk, per exchange
UPLOAD_CODES = (F.CODE_FILE_OPEN, F.CODE_FILE_WRITE, F.CODE_FILE_COMMIT)
BOOT_NODE = 30
BOOTLOADER = ROOT / "tests" / "e2e" / "fw_bootloader.py"
PY = sys.executable


def image(size: int) -> bytes:
    return bytes((i * 131 + (i >> 9)) & 0xFF for i in range(size))


def gateway_at(port, baud: int) -> GatewayClient:
    cfg = MasterConfig(max_baud=max(baud, 115200), resp_latency_s=0.05)
    m = Master(port, [registry.lookup("can-gw")], 9600, cfg)
    m.discover()
    m.configure(baud)
    if m.baud != baud:
        raise RuntimeError(f"the bus is at {m.baud}, not {baud}")
    return GatewayClient(m)


def wire_bound(capture, frame_code, baud: int) -> dict:
    """Bytes and exchanges of the upload's frames at baud; the bound in s."""
    c_us = (10_000_000 + baud - 1) // baud
    ours = [b for b in capture if b[2] == baud and frame_code(b[3]) in UPLOAD_CODES]
    req = sum(len(b[3]) for b in ours if b[1] == 0)
    rsp = sum(len(b[3]) for b in ours if b[1] == 1)
    exchanges = sum(1 for b in ours if b[1] == 1)
    return {
        "req_bytes": req,
        "rsp_bytes": rsp,
        "exchanges": exchanges,
        "bound_s": (req + rsp + GAP_CHARS * exchanges) * c_us / 1e6,
    }


def upload_fcsim(build, tmp: Path, data: bytes, baud: int) -> dict:
    """The upload by dan-fcsim (libdan's master and the FC client's
    dan_gw_file_* calls, as an FC runs them); its own timing of the upload."""
    (tmp / "image.bin").write_bytes(data)
    p = subprocess.run(
        [build / "bin" / "dan-fcsim", "--port", tmp / "dan0", "--max-baud", str(baud)]
        + ["discover", f"configure:{baud}", f"upload:bench.bin:{tmp / 'image.bin'}", "stats"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    lines = [json.loads(x) for x in p.stdout.splitlines() if x.strip()]
    up = [x for x in lines if x.get("step") == "upload"]
    if p.returncode != 0 or not up or not up[0]["ok"]:
        raise RuntimeError(f"dan-fcsim upload failed: {lines} {p.stderr[-300:]}")
    stats = [x for x in lines if x.get("step") == "stats"]
    return {
        "client": "fcsim",
        "baud": baud,
        "size": len(data),
        "seconds": up[0]["seconds"],
        "retries": stats[0].get("master_retries") if stats else None,
    }


BARE_SECONDS = 4


def bench_upload(rig, baud: int, read: bool, client):
    """One upload of SIZE bytes at baud by client ('fcsim' or 'danprobe');
    with read (danprobe), the bootloader node then reads the image through
    the gateway (FW_BEGIN, NODE_INFO until done). rig: bench_files()'s
    arguments."""
    build, stack_cls, gw_rig, read_capture, frame_code, bare = rig
    data = image(SIZE)
    with tempfile.TemporaryDirectory(prefix="danbench-") as tmp:
        tmp = Path(tmp)
        (tmp / "store").mkdir()
        st = stack_cls(tmp)
        try:
            gw_rig(
                st,
                build,
                tmp,
                n_esc=0,
                extra_can=1,
                gw_args=("--file-dir", tmp / "store", "--file-max", str(2 * SIZE)),
            )
            if client == "fcsim":
                out = upload_fcsim(build, tmp, data, baud)
            else:
                out = upload_danprobe(st, tmp, data, baud, read)
        finally:
            st.close()
        out.update(wire_bound(read_capture(tmp / "bus.cap"), frame_code, baud))
    out["ratio"] = out["bound_s"] / out["seconds"]
    out["goal"] = GOAL
    n = out["exchanges"]
    out["bare_rate"] = bare(build, baud, out["req_bytes"] / n, out["rsp_bytes"] / n, BARE_SECONDS)
    out["vs_bare"] = n / out["seconds"] / out["bare_rate"]
    return out


def upload_danprobe(st, tmp: Path, data: bytes, baud: int, read: bool) -> dict:
    """The upload by danprobe's client (Python), then the bootloader's read."""
    with SerialPort(str(tmp / "dan0"), 9600) as port:
        gw = gateway_at(port, baud)
        u = file_update.upload(gw, "bench.bin", data, restart=True)
        retries = gw.m.stats.retries
        out = {
            "client": "danprobe",
            "baud": baud,
            "size": SIZE,
            "seconds": u.seconds,
            "retries": retries,
        }
        if read:  # the node starts after the upload: its CPU is not the upload's
            (tmp / "image.bin").write_bytes(data)
            boot = st.start(
                [PY, BOOTLOADER, "--port", tmp / "can1", "--node-id", BOOT_NODE]
                + ["--expect", tmp / "image.bin", "--pipeline", "4"],  # as AP_Bootloader
                "fw_bootloader",
            )
            st.ready(boot)
            out.update(read_through_gateway(gw, SIZE))
    return out


def read_through_gateway(gw: GatewayClient, size: int) -> dict:
    """FW_BEGIN to the bootloader node, then NODE_INFO until it read size bytes."""
    deadline = time.monotonic() + 600
    while True:  # the node is in the gateway's table once its NodeStatus was heard
        try:
            gw.node_info(BOOT_NODE)
            break
        except RemoteError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.1)
    r = file_update.fw_begin(gw, BOOT_NODE, "bench.bin")
    if not r.ok:
        raise RuntimeError(f"the bootloader refused: {r.text()}")
    t0 = time.monotonic()
    failures = [0]  # a loaded host can stall a transaction: a few in a row are tolerated
    while True:
        info = file_update.guarded(lambda: gw.node_info(BOOT_NODE), failures)
        if info is not None and info.follow.bytes_read >= size:
            break
        if time.monotonic() > deadline:
            raise RuntimeError(f"the bootloader did not read {size} bytes in time")
        time.sleep(0.02)
    secs = time.monotonic() - t0
    return {"read_seconds": secs, "read_bytes_per_s": size / secs}


def bench_files(build, stack_cls, gw_rig, read_capture, frame_code, bare) -> dict:
    """bare: run_bench's bare_round_trip(build, baud, req, rsp, seconds)."""
    rig = (build, stack_cls, gw_rig, read_capture, frame_code, bare)
    rows = [
        bench_upload(rig, baud, read, client)
        for client in ("fcsim", "danprobe")
        for baud in BAUDS
        for read in [client == "danprobe" and baud == BAUDS[-1]]
    ]
    fc = [r["ratio"] for r in rows if r["client"] == "fcsim"]
    return {
        "rows": rows,
        "ratio_min": min(fc),
        "ratio_min_danprobe": min(r["ratio"] for r in rows if r["client"] == "danprobe"),
    }


def files_rows(r: dict) -> list:
    """The table rows of bench_files()'s result."""
    out = []
    for e in r.get("rows", []):
        kib = e["size"] // 1024
        out.append(
            (
                f"upload {kib} KiB {e['baud']} ({e.get('client', 'danprobe')})",
                f"{e['seconds']:.2f} s, {e['size'] / e['seconds'] / 1024:.1f} KiB/s",
                f"wire+gaps {e['bound_s']:.2f} s ({e['exchanges']} exch, "
                f"{e['req_bytes'] + e['rsp_bytes']} B); goal {e['goal']}",
                f"{e['ratio']:.2f}",
            )
        )
        if "bare_rate" in e:
            out.append(
                (
                    "  vs a bare pty round trip (same bytes)",
                    f"{e['exchanges'] / e['seconds']:.0f} exch/s",
                    f"bare {e['bare_rate']:.0f}/s",
                    f"{e['vs_bare']:.2f}",
                )
            )
        if "read_seconds" in e:
            out.append(
                (
                    f"  bootloader reads {kib} KiB (SLCAN hub)",
                    f"{e['read_seconds']:.2f} s, {e['read_bytes_per_s'] / 1024:.1f} KiB/s",
                    f"the upload at {e['baud']}: {e['seconds']:.2f} s",
                    f"{e['read_seconds'] / e['seconds']:.2f}",
                )
            )
    return out
