#!/usr/bin/env python3
"""The one-command demo (`make demo`): a whole DAN bus with a CAN-over-DAN
gateway and four DroneCAN ESCs, on virtual wires, no hardware.

    dan-vbus (2 ptys)  <- DAN wire ->  dan-gatewayd  <- SLCAN ->  slcan_hub.py (5 ptys)
        ^ endpoint 0                                                 |-> esc_sim.py: 4 ESC nodes
        danprobe: discover, configure 115200, safety off, arm, throttle ramp, nodes,
                  disarm, safety on

Every process runs in its own process group and is stopped at the end, on
error, or on Ctrl-C/SIGTERM; nothing is left behind. Exit 0 on success.
"""

import argparse
import json
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import procgroup  # this directory is sys.path[0]

ROOT = Path(__file__).resolve().parents[1]
BIN = ROOT / "build" / "bin"
PY = sys.executable
DANPROBE = [PY, "-m", "danprobe"]


class Stack:
    def __init__(self, tmp, verbose):
        self.tmp = tmp
        self.verbose = verbose
        self.procs = []

    def start(self, name, args, ready=True):
        log = open(self.tmp / f"{name}.log", "wb")
        p = procgroup.start(args, log)
        p.name, p.log = name, log
        self.procs.append(p)
        if ready:
            deadline = time.monotonic() + 30
            line = b""
            while not line.startswith(b"READY"):
                line = p.stdout.readline()
                if not line or time.monotonic() > deadline:
                    raise RuntimeError(f"{name} did not start; see {log.name}:\n{self.tail(name)}")
        return p

    def tail(self, name, n=15):
        try:
            return "\n".join(
                (self.tmp / f"{name}.log").read_text(errors="replace").splitlines()[-n:]
            )
        except OSError:
            return ""

    def check_alive(self):
        for p in self.procs:
            if p.poll() is not None:
                raise RuntimeError(f"{p.name} exited with {p.returncode}:\n{self.tail(p.name)}")

    def stop(self):
        """SIGTERM to all first, so they wind down together."""
        for p in reversed(self.procs):  # also a group whose leader exited
            procgroup.signal_group(p, signal.SIGTERM)
        for p in reversed(self.procs):
            procgroup.wait_or_kill(p, 10)
            p.stdout.close()
            p.log.close()


def step(title):
    print(f"\n=== {title}", flush=True)


def danprobe(*args, check=True):
    """Runs a danprobe command with its output shown live."""
    cmd = [*DANPROBE, *map(str, args)]
    print("$ danprobe " + " ".join(map(str, args)), flush=True)
    r = subprocess.run(cmd, stdin=subprocess.DEVNULL)
    if check and r.returncode != 0:
        raise RuntimeError(f"danprobe {args[0]} failed with exit code {r.returncode}")
    return r.returncode


def on_sigterm(signum, frame):
    raise KeyboardInterrupt  # unwinds to the cleanup in main()


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--keep", action="store_true", help="keep the temporary directory with logs")
    ap.add_argument("--ramp-seconds", type=float, default=6.0)
    ap.add_argument(
        "--plot",
        default=str(ROOT / "build" / "demo" / "esc.png"),
        help="where the ESC telemetry plot goes (default: build/demo/esc.png)",
    )
    ap.add_argument("--verbose", action="store_true")
    return ap.parse_args()


def start_wires(stack, tmp):
    step("Virtual wires: a DAN bus (dan-vbus) and a CAN bus of SLCAN adapters (slcan_hub.py)")
    stack.start(
        "dan-vbus",
        [BIN / "dan-vbus", "-n", "2", "--link", tmp / "dan", "--capture", tmp / "dan-bus.log"],
    )
    stack.start(
        "slcan_hub",
        procgroup.host_tool(
            "slcan_hub.py", "-n", "5", "--link", tmp / "can", "--log", tmp / "can-bus.log"
        ),
    )
    print(f"DAN wire endpoints {tmp}/dan0 (the FC side: danprobe) and {tmp}/dan1 (the gateway)")
    print(f"CAN adapters {tmp}/can0 (gateway) and {tmp}/can1..4 (ESCs)")


def start_escs_and_gateway(stack, tmp):
    step("Four DroneCAN ESCs (pydronecan nodes 20..23) and the CAN-over-DAN gateway (node 10)")
    stack.start(
        "esc_sim",
        procgroup.host_tool(
            "esc_sim.py",
            "--log",
            tmp / "escs.jsonl",
            *sum((["--port", tmp / f"can{i}"] for i in range(1, 5)), []),
        ),
    )
    stack.start(
        "dan-gatewayd",
        [
            BIN / "dan-gatewayd",
            "--uart",
            tmp / "dan1",
            "--can",
            f"slcan:{tmp}/can0",
            "--node-id",
            "10",
            "--verbose",
        ],
        ready=False,
    )
    time.sleep(0.5)
    stack.check_alive()


def drive(port, ramp_seconds, plot):
    """What a technician does with danprobe, step by step: (what the step
    says, the danprobe command, its options after the port)."""
    bus = ("--bus-baud", "115200")
    ramp = ("--count", "4", "--ramp", "0:3000", "--rate", "50", "--duration", ramp_seconds)
    steps = (
        ("Discover the DAN bus at 9600 baud", ("discover",), ()),
        ("Configure the bus to 115200 baud", ("configure",), ("--baud", "115200")),
        (
            "Safety off: SafetyState 255, the outputs may move (AP_Periph ESCs wait for it)",
            ("safety", "off"),
            bus,
        ),
        ("Arm", ("arm",), bus),
        (
            f"Throttle ramp on four ESCs with live telemetry ({ramp_seconds:g} s)",
            ("esc",),
            (*bus, *ramp, "--plot", plot),
        ),
        ("The gateway's DroneCAN node table", ("nodes",), bus),
        ("Disarm", ("disarm",), bus),
        ("Safety on: SafetyState 0, the outputs locked", ("safety", "on"), bus),
        ("Gateway counters", ("stats",), bus),
    )
    for text, command, options in steps:
        step(text)
        danprobe(*command, *port, *options)


def esc_events(tmp, event):
    return [e for e in map(json.loads, open(tmp / "escs.jsonl")) if e["event"] == event]


def changes(values):
    """The values without repeats in a row: 0, 0, 255, 255, 0 -> [0, 255, 0]."""
    return [v for i, v in enumerate(values) if i == 0 or values[i - 1] != v]


def what_the_escs_saw(tmp, plot):
    """The ESCs' own log: the proof the commands arrived."""
    # the last SafetyState went out just before; give ESC 0 a moment to log it
    deadline = time.monotonic() + 5
    while True:
        safety = changes([e["status"] for e in esc_events(tmp, "safety") if e["esc"] == 0])
        if safety[-1:] == [0] and 255 in safety or time.monotonic() > deadline:
            break
        time.sleep(0.1)
    cmds, arming = esc_events(tmp, "cmd"), esc_events(tmp, "arming")
    top = max((max(c["cmd"][:4]) for c in cmds), default=0)
    step("What the ESCs received")
    print(
        f"{len(cmds)} RawCommand transfers, highest raw value {top}; "
        f"{len(arming)} ArmingStatus messages, last status {arming[-1]['status'] if arming else '-'}"
    )
    print(
        f"{len(esc_events(tmp, 'safety'))} SafetyState messages; ESC 0 heard safety "
        + " -> ".join({0: "ON (0)", 255: "OFF (255)"}.get(v, str(v)) for v in safety)
    )
    print(f"plot of RPM, current, voltage and temperature: {plot}")
    if not cmds or top <= 0:
        raise RuntimeError("the ESCs received no throttle")
    if 255 not in safety or safety[-1] != 0:
        raise RuntimeError(f"the ESCs did not hear safety off, then on: {safety}")


def main():
    args = parse_args()
    for b in ("dan-vbus", "dan-gatewayd"):
        if not (BIN / b).exists():
            print(
                f"demo: {BIN / b} is missing: run 'make demo' (it builds everything)",
                file=sys.stderr,
            )
            return 2
    tmp = Path(tempfile.mkdtemp(prefix="dan-demo-"))
    stack = Stack(tmp, args.verbose)
    signal.signal(signal.SIGTERM, on_sigterm)
    ok = False
    try:
        start_wires(stack, tmp)
        start_escs_and_gateway(stack, tmp)
        plot = Path(args.plot)
        plot.parent.mkdir(parents=True, exist_ok=True)
        drive(["--port", tmp / "dan0"], args.ramp_seconds, plot)
        stack.check_alive()
        what_the_escs_saw(tmp, plot)
        ok = True
    except KeyboardInterrupt:
        print("\ndemo: interrupted", file=sys.stderr)
    except (RuntimeError, OSError) as e:
        print(f"\ndemo: {e}", file=sys.stderr)
    finally:
        step("Stopping everything")
        stack.stop()
        if ok and not args.keep:
            shutil.rmtree(tmp, ignore_errors=True)
        else:
            print(f"logs kept in {tmp}")
    print("\ndemo: " + ("done" if ok else "FAILED"))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
