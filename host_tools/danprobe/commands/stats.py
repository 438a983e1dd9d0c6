"""danprobe stats: the gateway's settings and counters."""

from danprobe import gateway_msgs
from danprobe.commands.common import (
    add_gateway_options,
    format_table,
    gateway_reads,
    gateway_report,
)

NAME = "stats"
HELP = "CAN gateway: settings (CONFIG) and counters (STATS), named as in docs/PROTOCOL.md"
DESCRIPTION = (
    "Reads the gateway's settings (DroneCAN node ID, ESC failsafe timeout, arming rate, "
    "flags) and its counters of both sides: DAN frames, CAN frames, DroneCAN transfers, ESC "
    "commands, failsafes, tunnel and raw-frame drops, nodes."
)


def add_arguments(p):
    add_gateway_options(p)


def run(ctx) -> int:
    m, failure, ms, got = gateway_reads(
        ctx, config=lambda gw: gw.read_config(), stats=lambda gw: gw.read_stats()
    )
    cfg, stats = got.get("config"), got.get("stats", {})

    def human():
        print(
            f"stats: gateway node {cfg.node_id}, ESC timeout {cfg.esc_timeout_ms} ms, arming "
            f"{cfg.arming_rate_hz} Hz, telemetry timeout {cfg.telem_timeout_ms} ms, "
            f"DNA {'on' if cfg.dna else 'off'}, "
            f"flags {','.join(gateway_msgs.flags_names(cfg.flags)) or 'none'} ({ms:.1f} ms)"
        )
        print(format_table([("counter", "value")] + [(k, str(v)) for k, v in stats.items()]))

    return gateway_report(
        ctx,
        m,
        failure,
        ms,
        {"config": cfg.as_dict() if cfg else None, "stats": stats, "master": m.stats_dict()},
        human,
    )
