"""Programs run in their own session (so their own process group), stderr
to a log file, and stopped as a group: a program's children go with it and
nothing is left behind. Used by demo.py, the end-to-end tests' procs
fixture and the benchmarks. Standard library only.
"""

import os
import signal
import subprocess


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


def wait_or_kill(p: subprocess.Popen, timeout: float):
    """Waits for p; after timeout seconds kills its group and waits again."""
    try:
        p.wait(timeout)
    except subprocess.TimeoutExpired:
        signal_group(p, signal.SIGKILL)
        p.wait(5)


def stop(p: subprocess.Popen, sig: int = signal.SIGTERM, timeout: float = 10.0) -> int:
    """Signals a running p's group and waits (killing it after timeout
    seconds); returns its exit code."""
    if p.poll() is None:
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
