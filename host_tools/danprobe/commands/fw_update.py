"""danprobe fw-update: a DroneCAN node's firmware through the FC's wire:
the image into the gateway's file store, BeginFirmwareUpdate with the
gateway as file server, the update followed to the node's new version."""

import time

from danprobe import file_update
from danprobe.commands.common import (
    add_gateway_options,
    append_option,
    gateway_operation,
    int_range,
    positive_float,
    stop_signals,
)
from danprobe.commands.files import add_name_option, finish, put, read_image
from danprobe.commands.progress import Progress
from danprobe.gateway_mgmt import NODE_ID_MAX
from danprobe.master import DanError, OperationTimeout, RemoteError
from danprobe.port import now

NAME = "fw-update"
HELP = "CAN gateway: update a DroneCAN node's firmware (upload, begin, follow)"
DESCRIPTION = (
    "Updates the firmware of DroneCAN nodes behind the gateway with nothing but the DAN "
    "wire: reads each node's version (NODE_INFO), uploads IMAGE into the gateway's file "
    "store (resuming an interrupted upload of it; progress on stderr) and commits it with "
    "its CRC-32, sends uavcan.protocol.file.BeginFirmwareUpdate with the gateway as file "
    "server (NODE_CALL FW_BEGIN) and reports the node's answer, then follows the update: the "
    "node in SOFTWARE_UPDATE mode, the bytes it read of the image, until it is back "
    "OPERATIONAL with another software version (exit 0). It fails (exit 1, with the reason) "
    "when the node refuses, reports an error (health ERROR or CRITICAL), reads nothing and "
    "changes no status for --stall seconds, or after --timeout. --node may be given several "
    "times: one upload, then every node is started and followed at once (nodes read the "
    "image independently; the DAN bus has one master, so run one danprobe at a time). "
    "Ctrl-C stops between two transactions (never in the middle of a frame) and exits 130: "
    "during the upload the gateway keeps the partial image (the same command resumes it); "
    "once BeginFirmwareUpdate was sent, the node goes on updating from the gateway's file "
    "and only the following stops ('danprobe nodes' shows it)."
)
EXAMPLES = (
    "danprobe fw-update --port /dev/ttyUSB0 --configure --node 42 esc-2.1.bin",
    "danprobe fw-update --port /dev/ttyUSB0 --baud 115200 --node 42 --node 43 esc-2.1.bin",
)
POLL_S = 0.2  # NODE_INFO polls while following
TIMEOUT_DEFAULT = 600.0


class UpdateFailed(DanError):
    code, reason = -13, "update failed"


def add_arguments(p):
    add_gateway_options(
        p,
        timeout_default=TIMEOUT_DEFAULT,
        timeout_help=f"give up the whole update after S seconds (default {TIMEOUT_DEFAULT:g})",
    )
    g = p.add_argument_group("fw-update options")
    g.add_argument(
        "--node",
        required=True,
        **append_option(int_range(1, NODE_ID_MAX, "--node"), "N"),
        help="the node to update (repeat for several nodes)",
    )
    g.add_argument("image", metavar="IMAGE", help="the firmware image file")
    add_name_option(g)
    g.add_argument(
        "--stall",
        type=positive_float,
        default=10.0,
        metavar="S",
        help="fail when a node reads nothing and changes no status for S seconds (default 10)",
    )
    g.add_argument("--restart", action="store_true", help="upload from byte 0 (default: resume)")


def _before(gw, nodes) -> dict:
    out = {}
    for n in nodes:
        try:
            info = gw.node_info(n)
        except RemoteError:
            raise UpdateFailed(f"node {n} is not in the gateway's node table") from None
        if info.follow is None:
            raise UpdateFailed("this gateway does not report firmware updates (NODE_INFO)")
        out[n] = info
    return out


def _begin(ctx, gw, nodes, name, res):
    for n in nodes:
        r = file_update.fw_begin(gw, n, name)
        res["begin"][str(n)] = r.as_dict()
        if not r.ok:
            raise UpdateFailed(f"node {n} refused BeginFirmwareUpdate: {r.text()}")
        ctx.progress(f"node {n}: BeginFirmwareUpdate accepted, reading {name} from the gateway")


def _poll(gw, node_id: int, failures: list):
    """The node's NODE_INFO; None when this poll tells nothing: the gateway
    dropped the node from its table for a while (a reboot) or a transaction
    failed (tolerated a few times in a row: the stall clock decides)."""
    try:
        return file_update.guarded(lambda: gw.node_info(node_id), failures)
    except RemoteError:
        return None


def _follow(ctx, gw, follows, stop):
    bars = {}
    failures = [0]
    while any(f.state == file_update.ONGOING for f in follows):
        if stop.stop:
            raise file_update.Stopped("stopped following (the nodes go on updating)")
        for f in follows:
            if f.state != file_update.ONGOING:
                continue
            info = _poll(gw, f.node_id, failures)
            if info is None:
                f.idle(now())
            else:
                f.step(info, now())
            if f.file_size and f.node_id not in bars:
                bars[f.node_id] = Progress(
                    f"node {f.node_id} reads", f.file_size, 0, ctx.args.quiet
                )
            if f.node_id in bars:
                bars[f.node_id].update(min(f.bytes_read, f.file_size))
            if f.state != file_update.ONGOING and f.node_id in bars:
                bars[f.node_id].end()
            if f.state == file_update.DONE:
                ctx.progress(f"node {f.node_id}: back OPERATIONAL, version {f.after['sw']}")
            elif f.state == file_update.FAILED and len(follows) > 1:
                ctx.error(f"node {f.node_id} failed: {f.why}")  # the others go on
        time.sleep(POLL_S)
    failed = [f.why for f in follows if f.state == file_update.FAILED]
    if failed:
        raise UpdateFailed("; ".join(failed))


def run(ctx) -> int:
    a = ctx.args
    nodes = list(dict.fromkeys(a.node))
    data, name = read_image(ctx, a.image, a.name)
    res = {"name": name, "size": len(data), "begin": {}, "nodes": []}
    follows = []

    def op(m, gw):
        with stop_signals(ctx) as stop:
            try:
                before = _before(gw, nodes)
                for n, info in before.items():
                    v = file_update.version_of(info)
                    follows.append(file_update.Follow(n, v, a.stall))
                    ctx.progress(f"node {n}: version {file_update.version_text(v)}")
                put(ctx, gw, data, name, a.restart, res)
                if stop.stop:
                    raise file_update.Stopped("stopped after the upload (nothing begun)")
                _begin(ctx, gw, nodes, name, res)
                t = now()
                for f in follows:
                    f.last_change = t
                _follow(ctx, gw, follows, stop)
            except OperationTimeout:
                where = ", ".join(
                    f"node {f.node_id} {f.state} at {f.bytes_read}/{f.file_size}" for f in follows
                )
                raise UpdateFailed(f"timed out after {a.timeout:g} s ({where})") from None

    m, failure, ms = gateway_operation(ctx, op)
    res["nodes"] = [f.as_dict() for f in follows]

    def human():
        for f in follows:
            print(
                f"fw-update: node {f.node_id}: {file_update.version_text(f.before)} -> "
                f"{file_update.version_text(f.after)}, read {f.bytes_read} of {f.file_size} "
                f"bytes ({ms / 1000:.1f} s)"
            )

    return finish(ctx, m, failure, ms, res, human)
