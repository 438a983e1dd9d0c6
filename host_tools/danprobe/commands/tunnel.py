"""danprobe tunnel: a gateway serial tunnel as a local pseudo-terminal."""

import time

from danprobe import gateway_client, gateway_msgs
from danprobe.commands.common import (
    UsageError,
    add_gateway_options,
    add_pty_options,
    bridge_pty,
    gateway_operation,
    gateway_report,
    int_range,
    long_running,
    non_negative_int,
    time_left,
)
from danprobe.master import DanError, OperationTimeout, RemoteError
from danprobe.port import now

NAME = "tunnel"
HELP = "CAN gateway: bridge a DroneCAN serial tunnel to a local pseudo-terminal"
DESCRIPTION = (
    "Opens a gateway tunnel port (uavcan.tunnel.Targetted to --target NODE, as ArduPilot's "
    "serial-over-DroneCAN, or uavcan.tunnel.Broadcast with --protocol/--channel) and "
    "bridges it to a new pseudo-terminal: bytes written to the pty go out through TUN_XFER, "
    "bytes from the tunnel come back into it, so any serial tool (a GPS configurator, a "
    "terminal, MAVProxy) can talk to the device behind the CAN bus. Prints the pty's path; "
    "runs until Ctrl-C, SIGTERM or --duration, then closes the tunnel port. "
    "Targetted --serial-id -1 asks the node for its default serial port: its replies are "
    "taken whatever serial_id they carry (the node answers with the port it chose). "
    "Broadcast --any-channel takes replies on every channel_id (some nodes, e.g. Vertiq "
    "modules, ignore the channel when they answer)."
)
EXAMPLES = (
    "danprobe tunnel --port /dev/ttyUSB0 --configure --target 30 --serial-id 2 --serial-baud "
    "115200 --lock --link /tmp/gps",
    "danprobe tunnel --port /dev/ttyUSB0 --baud 115200 --target 30 --serial-id -1",
    "danprobe tunnel --port /dev/ttyUSB0 --baud 115200 --protocol 2 --channel 7 --any-channel",
)

IDLE_POLL_S = 0.02  # nothing moved: look again this much later
OUT_LIMIT = 8192  # bytes for the pty client before we stop reading the tunnel
IN_LIMIT = 4096  # bytes from the pty client waiting for the gateway


# --json: events, then the summary (as can.py's and nodes.py's JSON_EVENTS)
JSON_EVENTS = True


def add_arguments(p):
    g = add_gateway_options(p, long_running=True, own="tunnel")
    g.add_argument(
        "--target",
        type=non_negative_int,
        metavar="NODE",
        help="Targetted: the node id of the device's end",
    )
    g.add_argument(
        "--serial-id",
        type=int,
        default=0,
        metavar="N",
        help="Targetted: serial_id of the device's port, 0..15, or -1: the node's default "
        "port (replies on any serial_id taken); default 0",
    )
    g.add_argument(
        "--serial-baud",
        type=non_negative_int,
        default=0,
        metavar="B",
        help="Targetted: baudrate to ask the device's port for (default 0: keep)",
    )
    g.add_argument(
        "--lock",
        action="store_true",
        help="Targetted: set LOCK_PORT (the device's port serves only the tunnel)",
    )
    g.add_argument(
        "--protocol",
        type=non_negative_int,
        metavar="P",
        help="Broadcast: uavcan.tunnel.Protocol value",
    )
    g.add_argument("--channel", type=non_negative_int, metavar="C", help="Broadcast: channel_id")
    g.add_argument(
        "--any-channel",
        action="store_true",
        help="Broadcast: take replies on every channel_id (option ANY_CHANNEL)",
    )
    g.add_argument(
        "--tunnel-port",
        type=int_range(0, 255, "the tunnel port"),
        default=0,
        metavar="N",
        help="the gateway's tunnel port to use (default 0)",
    )
    add_pty_options(g)


def options_problem(a) -> str:
    """What is wrong with the tunnel options ("" if nothing)."""
    if (a.target is None) == (a.protocol is None and a.channel is None):
        return "give --target NODE (Targetted) or --protocol P --channel C (Broadcast)"
    if a.target is None:
        if a.protocol is None or a.channel is None or a.protocol > 255 or a.channel > 255:
            return "Broadcast needs --protocol P and --channel C (0..255)"
    elif a.any_channel:
        return "--any-channel is a Broadcast option (--protocol/--channel)"
    elif not 1 <= a.target <= 127 or not -1 <= a.serial_id <= 15 or a.serial_baud > 0xFFFFFF:
        return "--target 1..127, --serial-id -1..15, --serial-baud up to 16777215"
    return ""


def tunnel_config(a) -> gateway_msgs.TunOpen:
    problem = options_problem(a)
    if problem:
        raise UsageError(problem)
    if a.target is not None:
        return gateway_msgs.TunOpen(
            a.tunnel_port,
            gateway_msgs.TUN_TARGETTED,
            gateway_msgs.PROTOCOL_UNDEFINED,
            a.target,
            a.serial_id,
            gateway_msgs.TUN_LOCK_PORT if a.lock else 0,
            a.serial_baud,
        )
    return gateway_msgs.TunOpen(
        a.tunnel_port,
        gateway_msgs.TUN_BROADCAST,
        a.protocol,
        a.channel,
        options=gateway_msgs.TUN_ANY_CHANNEL if a.any_channel else 0,
    )


def describe(cfg: gateway_msgs.TunOpen) -> str:
    if cfg.mode == gateway_msgs.TUN_TARGETTED:
        serial = "default" if cfg.serial_id == gateway_msgs.TUN_DEFAULT_SERIAL else cfg.serial_id
        return (
            f"Targetted node {cfg.target} serial {serial}"
            + (f" at {cfg.baud} baud" if cfg.baud else "")
            + (" (locked)" if cfg.options & gateway_msgs.TUN_LOCK_PORT else "")
        )
    return f"Broadcast protocol {cfg.protocol} channel {cfg.target}" + (
        " (replies on any channel)" if cfg.options & gateway_msgs.TUN_ANY_CHANNEL else ""
    )


def run(ctx) -> int:
    a = ctx.args
    cfg = tunnel_config(a)
    res = {
        "to_tunnel": 0,
        "from_tunnel": 0,
        "reopens": 0,
        "rd_lost": 0,
        "rd_dropped": 0,
        "pty": None,
        "link": a.link,
    }

    def op(m, gw):
        gw.tunnel_open(cfg)
        what = f" <-> {describe(cfg)}, gateway port {cfg.port}"
        # the tunnel is closed again whatever comes after its opening: a
        # --link that cannot be made, a Ctrl-C before the bridge runs
        try:
            with bridge_pty(ctx, res, what, tunnel=cfg.as_dict()) as pty:
                try:
                    _bridge(ctx, m, gw, cfg, pty, res)
                finally:
                    st = gw.tun.get(cfg.port, gateway_client.TunnelState())
                    res["rd_lost"] += st.rd_lost
                    res["rd_dropped"] = st.rd_dropped
        finally:
            try:
                gw.tunnel_open(gateway_msgs.TunOpen(cfg.port, gateway_msgs.TUN_CLOSED))
            except DanError as e:
                ctx.error(f"could not close tunnel port {cfg.port}: {e}")

    m, failure, ms = gateway_operation(ctx, op)

    def human():
        print(
            f"tunnel: closed; {res['to_tunnel']} byte(s) to the tunnel, {res['from_tunnel']} "
            f"from it" + (f", {res['rd_lost']} lost" if res["rd_lost"] else "")
        )

    return gateway_report(ctx, m, failure, ms, {"event": "summary", **res}, human)


def _bridge(ctx, m, gw, cfg, pty, res):
    stop, dog = long_running(m, ctx)
    t0 = now()
    pending = bytearray()  # from the pty client, for the gateway
    out = bytearray()  # from the tunnel, for the pty client
    with stop:
        while not stop.stop and time_left(ctx, t0):
            if len(pending) < IN_LIMIT:
                pending += pty.read()
            if out:
                del out[: pty.write(out)]
            try:
                data = gw.tunnel_xfer(
                    cfg.port,
                    pending[: gateway_msgs.TUN_CHUNK_MAX],
                    gateway_msgs.TUN_CHUNK_MAX if len(out) < OUT_LIMIT else 0,
                )
            except OperationTimeout:
                raise
            except RemoteError as e:
                # the gateway lost the port (restarted?): open it again, offsets from 0
                dog.failed(e)
                ctx.error(f"tunnel: {e}; opening the port again")
                st = gw.tun.get(cfg.port)
                res["rd_lost"] += st.rd_lost if st else 0
                try:
                    gw.tunnel_open(cfg)
                    res["reopens"] += 1
                except DanError as e2:
                    dog.failed(e2)
                continue
            except DanError as e:
                dog.failed(e)  # the next xfer repeats the same offsets
                continue
            dog.ok()
            taken = gw.tun[cfg.port].accepted
            del pending[:taken]
            res["to_tunnel"] += taken
            res["from_tunnel"] += len(data)
            out += data
            if out:
                del out[: pty.write(out)]
            if not taken and not data:
                if pending:
                    time.sleep(IDLE_POLL_S)  # the gateway's buffer is full
                else:
                    pty.wait_readable(IDLE_POLL_S)
