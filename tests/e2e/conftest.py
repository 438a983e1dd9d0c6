"""Shared fixtures for the end-to-end tests.

Every process a test starts goes through the `spawn` fixture, which puts it
in its own process group and kills the group at teardown, so no test leaves
a process behind whatever happens.
"""

import os
import select
import signal
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "host_tools"))
# Programs the tests start (python -m danprobe, the tools) import this
# checkout's host_tools too: worktrees may share one venv, whose editable
# install points at another checkout.
os.environ["PYTHONPATH"] = os.pathsep.join(
    filter(None, (str(ROOT / "host_tools"), os.environ.get("PYTHONPATH")))
)
# A loaded 2-core test host stalls a process for up to about 0.3 s (measured:
# a C loop of 1 ms sleeps beside `make pytest`, worst 0.31 s, 2 stalls over
# 0.2 s in 4 minutes). Every master of these tests waits MASTER_WAIT_MS for
# a reply (danprobe's --latency-ms default included) and every peripheral
# drops a reply it has not started within PERIPH_WINDOW_MS: less, so a reply
# the master gave up on never runs into its next request. One lost reply
# costs MASTER_WAIT_MS, under the gateway's 500 ms failsafe, so a retry in
# time keeps the motors running (600 ms once gave a failsafe mid-run). The
# tests check behaviour, not speed; those about the windows set their own.
MASTER_WAIT_MS = "400"
PERIPH_WINDOW_MS = "350"
os.environ.setdefault("DANPROBE_LATENCY_MS", MASTER_WAIT_MS)
import procgroup  # noqa: E402
import pydronecan_nodes  # noqa: E402
from danprobe import gateway_msgs  # noqa: E402

# Before any pydronecan node exists: their I/O children start with spawn,
# never forked from this multi-threaded test process (issue 16).
pydronecan_nodes.use_spawn()
BIN = ROOT / "build" / "bin"
VECTORS = ROOT / "tests" / "vectors"


def read_line(fd, timeout, what="the pipe", on_eof=lambda: "closed"):
    """One line from fd (a pipe) within timeout seconds. AssertionError at
    the deadline or at end of file (its text from on_eof())."""
    end = time.monotonic() + timeout
    buf = b""
    while not buf.endswith(b"\n"):
        left = end - time.monotonic()
        if left <= 0:
            raise AssertionError(f"no line from {what} within {timeout}s (got {buf!r})")
        if select.select([fd], [], [], left)[0]:
            c = os.read(fd, 1)
            if not c:
                raise AssertionError(f"{what}: {on_eof()}, got {buf!r}")
            buf += c
    return buf.decode()


class FakeMaster:
    """A master whose gateway a test models, for GatewayClient: request()
    records (code, unsealed payload) in .sent, raises .fail's next exception
    if any, else answers with serve(code, payload) (the response payload),
    sealed as a gateway seals it."""

    def __init__(self):
        self.sent, self.fail = [], []
        self.reply_check = None

    def request(self, code, payload=b"", attempts=None):
        inner = gateway_msgs.unseal(code, gateway_msgs.REQUEST, payload)
        self.sent.append((code, inner))
        if self.fail:
            raise self.fail.pop(0)
        return gateway_msgs.seal(code, gateway_msgs.RESPONSE, self.serve(code, inner))

    def serve(self, code, inner) -> bytes:
        raise NotImplementedError


def wait_for(pred, timeout=10.0, interval=0.02, what="condition", explain=None):
    """Polls pred() until it returns a truthy value; fails after timeout
    (with explain()'s text, if given: what the test saw instead).
    Deadlines are generous: they catch hangs, they do not measure speed."""
    end = time.monotonic() + timeout
    while True:
        v = pred()
        if v:
            return v
        if time.monotonic() > end:
            seen = f"; {explain()}" if explain else ""
            raise AssertionError(f"timed out after {timeout}s waiting for {what}{seen}")
        time.sleep(interval)


class Procs:
    def __init__(self, tmp_path):
        self.tmp = tmp_path
        self.procs = []

    def start(self, args, name=None, **kw):
        """Starts a program in its own session; stderr goes to a log file
        in the test's tmp dir (shown on failure)."""
        name = name or Path(str(args[0])).name
        log = open(self.tmp / f"{name}.{len(self.procs)}.log", "wb")
        p = procgroup.start(args, log, **kw)
        p.log_path = Path(log.name)
        p.log_file = log
        self.procs.append(p)
        return p

    def stop(self, p, sig=signal.SIGTERM, timeout=10.0):
        """Signals a process (group) and waits; returns its exit code."""
        return procgroup.stop(p, sig, timeout)

    def close(self):
        procgroup.close_all(self.procs)

    def report(self, lines=12):
        """For a failed test: each process, whether it still ran (or its
        exit code: one that died early is often the cause) and the tail of
        its stderr log. CI keeps only the output, not the tmp dir."""
        out = []
        for p in self.procs:
            rc = p.poll()
            state = "running" if rc is None else f"exited {rc}"
            p.log_file.flush()
            tail = p.log_path.read_bytes().decode(errors="replace").splitlines()[-lines:]
            out.append(f"--- {p.log_path.name} ({state})")
            out.extend("    " + line for line in tail)
        for f in sorted(self.tmp.glob("**/*.stats")):  # counters the programs wrote
            out.append(f"--- {f.relative_to(self.tmp)}: {f.read_text().strip()}")
        return "\n".join(out)


def closing_factory(make):
    """For a fixture that hands out a factory (rig(**kw), bus(n=...)): yields
    one that remembers what make() returned, then closes those, in order,
    at teardown. Use as: yield from closing_factory(make)."""
    made = []

    def factory(*args, **kw):
        made.append(make(*args, **kw))
        return made[-1]

    yield factory
    for x in made:
        x.close()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    rep = outcome.get_result()
    if rep.when == "call":
        item.call_failed = rep.failed


@pytest.fixture
def procs(tmp_path, request):
    ps = Procs(tmp_path)
    yield ps
    if getattr(request.node, "call_failed", False):
        print("\nprocesses of the failed test:\n" + ps.report())
    ps.close()
