"""Regression test for pydronecan SLCAN nodes that never started
("IO process did not confirm initialization", issue 16).

Cause (host_tools/pydronecan_nodes.py): the driver forked its I/O process
from a process that runs other threads; a lock one of them held at the
fork stayed locked in the child forever. The reproduction
(tests/tools/node_start_repro.py) makes such a lock almost always held: a
thread writes log lines to a root handler whose stream is a buffered pipe
drained slowly. A forked child inherits the handler and blocks on the
stream's lock at its first log line (with `fork`: 0 of 10 nodes started,
py-spy on the child: StreamHandler.flush); a spawned child inherits no
lock. With pydronecan_nodes.make_node every node starts.
"""

import sys

import pydronecan_nodes
from conftest import ROOT

sys.path.insert(0, str(ROOT / "tests" / "tools"))
from node_start_repro import BusyLogger  # noqa: E402

NODES = 10


def test_many_nodes_start_while_other_threads_hold_locks(procs, tmp_path):
    p = procs.start(
        [
            sys.executable,
            ROOT / "host_tools" / "slcan_hub.py",
            "-n",
            "2",
            "--link",
            tmp_path / "can",
        ],
        name="slcan_hub",
    )
    assert p.stdout.readline().decode().startswith("READY")
    first = pydronecan_nodes.make_node(tmp_path / "can0", 20)  # its log proxy thread runs
    busy = BusyLogger()
    started = 0
    try:
        assert busy.lines >= 1000, "the busy logger did not run"
        for _ in range(NODES):
            pydronecan_nodes.make_node(tmp_path / "can1", 21).close()
            started += 1
    finally:
        busy.close()
        first.close()
    assert started == NODES
