"""pydronecan SLCAN nodes that always start, in a process that has threads.

pydronecan's SLCAN driver runs its I/O in a `multiprocessing.Process`.
With Linux's default start method, `fork`, the child is a copy of a
process that already runs other threads (the log proxy of every node made
before, their queue feeders, our own spin threads). A lock one of those
threads held at the instant of the fork stays locked forever in the child,
and the child blocks on it before it reports that it opened the adapter:
`DriverError: IO process did not confirm initialization`, 10 s later.
Measured with py-spy on a stuck child: it waits in `StreamHandler.emit`
for the buffer lock of the stream a parent thread was writing at the fork
(see the issue note; `tests/e2e/test_pydronecan_nodes.py` reproduces it).

The cure is at the root: children start with `spawn` (a fresh interpreter
that inherits no lock). `forkserver` does not work with this driver: its
I/O process exits at once because its parent (the fork server) is not the
process that made the node. Every program of ours that makes pydronecan
nodes calls `use_spawn()` first, or makes its nodes with `make_node()`.
A spawned child imports dronecan again (about 0.35 s more per node).
"""

import multiprocessing

DEFAULT_BITRATE = 1000000


def use_spawn():
    """Starts every later multiprocessing child with `spawn`. Idempotent;
    call it early in each entry point (the main module must be importable
    without side effects: `if __name__ == "__main__":`)."""
    if multiprocessing.get_start_method(allow_none=True) != "spawn":
        multiprocessing.set_start_method("spawn", force=True)


def make_node(port, node_id, bitrate=DEFAULT_BITRATE, **kw):
    """dronecan.make_node() on an SLCAN tty (`port` without the `slcan:`
    prefix), with children started by `spawn`."""
    use_spawn()
    import dronecan

    return dronecan.make_node("slcan:" + str(port), node_id=node_id, bitrate=bitrate, **kw)
