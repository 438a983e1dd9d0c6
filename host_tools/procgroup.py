"""Programs run in their own session (so their own process group), stderr
to a log file, and stopped as a group: a program's children go with it and
nothing is left behind. Used by demo.py, the end-to-end tests' procs
fixture and the benchmarks. Standard library only.
"""

import os
import signal
import subprocess
import sys
import time

HOST_TOOLS = os.path.dirname(os.path.realpath(__file__))


def host_tool(name: str, *args) -> list:
    """The command that runs the Python tool host_tools/NAME (slcan_hub.py,
    esc_sim.py, demo.py) with this interpreter, then args."""
    return [sys.executable, os.path.join(HOST_TOOLS, name), *args]


def start(args, log, stdout=subprocess.PIPE, **kw) -> subprocess.Popen:
    """Starts args (str()-ed) with no stdin and stderr to the open file log."""
    return subprocess.Popen(
        [str(a) for a in args],
        stdin=subprocess.DEVNULL,
        stdout=stdout,
        stderr=log,
        start_new_session=True,
        **kw,
    )


def signal_group(p: subprocess.Popen, sig: int):
    """Signals p's process group, if it is still there."""
    try:
        os.killpg(p.pid, sig)
    except ProcessLookupError:
        pass


def group_gone(pgid: int, timeout: float) -> bool:
    """Waits up to timeout seconds until no process of group pgid is left
    (a leader that exited may leave children still stopping)."""
    end = time.monotonic() + timeout
    while True:
        try:
            os.killpg(pgid, 0)
        except ProcessLookupError:
            return True
        except PermissionError:  # only a zombie of another parent is left
            return True
        if time.monotonic() >= end:
            return False
        time.sleep(0.02)


def wait_or_kill(p: subprocess.Popen, timeout: float):
    """Waits for p and the rest of its group; after timeout seconds kills
    the group and waits again."""
    end = time.monotonic() + timeout
    try:
        p.wait(timeout)
    except subprocess.TimeoutExpired:
        signal_group(p, signal.SIGKILL)
        p.wait(5)
    if not group_gone(p.pid, max(0.0, end - time.monotonic())):
        signal_group(p, signal.SIGKILL)
        group_gone(p.pid, 5.0)


def stop(p: subprocess.Popen, sig: int = signal.SIGTERM, timeout: float = 10.0) -> int:
    """Signals p's group (also when p itself has exited: its children may
    not have) and waits for all of it (killing it after timeout seconds);
    returns p's exit code."""
    signal_group(p, sig)
    wait_or_kill(p, timeout)
    return p.returncode


def close_all(procs):
    """Stops procs, the last started first, and closes their stdout pipes
    and their log files (p.log_file)."""
    for p in reversed(procs):
        stop(p)
        if p.stdout:
            p.stdout.close()
        p.log_file.close()
