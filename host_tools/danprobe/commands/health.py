"""danprobe health: the gateway's verdict on the DroneCAN bus."""

from danprobe.commands.common import (
    EXIT_FAIL,
    add_gateway_options,
    gateway_reads,
    gateway_report,
)

NAME = "health"
HELP = "CAN gateway: the bus health verdict (exit 0 OK, 1 FAIL: gate arming on it)"
DESCRIPTION = (
    "Asks the gateway (HEALTH) for its verdict on the bus and the first reason found: "
    "can_down, duplicate (two nodes with one ID), unhealthy (a node's NodeStatus health), "
    "offline (a node went silent), esc_telemetry (an ESC commanded without telemetry), "
    "dna_conflict (another allocation server), dna_full. Exit status 0 when the verdict is "
    "OK, 1 when it is FAIL or the gateway did not answer, so a script can gate arming on it."
)


def add_arguments(p):
    add_gateway_options(p)


def run(ctx) -> int:
    m, failure, ms, got = gateway_reads(ctx, health=lambda gw: gw.health())
    h = got.get("health")
    fields = {"health": h.as_dict() if h else None}
    rc = gateway_report(ctx, m, failure, ms, fields, lambda: print(f"health: {h.text()}"))
    if rc == 0 and not h.ok:
        return EXIT_FAIL
    return rc
