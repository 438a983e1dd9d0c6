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
import os

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


def spin_until(nodes, stop, step=0.002):
    """Spins the nodes in turn until `stop` (a list the signal handlers
    append to) is not empty; a transfer that does not decode is skipped.

    SIGTERM or Ctrl-C sent to the whole process group (procgroup, systemd,
    a terminal) reaches the drivers' I/O processes too; one may die before
    the next check of `stop`, and the node's next call raises DriverError.
    With a signal in (or arriving within a grace time), that is the end;
    without one the error is real."""
    import dronecan
    from dronecan.driver.common import DriverError

    while not stop:
        for n in nodes:
            try:
                n.spin(step)
            except (dronecan.transport.TransferError, ValueError, IndexError):
                # pydronecan's decoders raise ValueError ("Not enough bits")
                # or IndexError for a transfer shorter than its type: a
                # hostile or broken node on the bus must not end the program
                # (tests/e2e/test_hostile_can.py found esc_sim dying so)
                pass
            except DriverError:
                if stop or _signal_follows(stop):
                    return
                raise


def _signal_follows(stop, grace_s=0.5):
    """After a driver error without a signal: waits up to grace_s for one.
    A group signal reaches the I/O process and us at about the same time,
    and the I/O process can die (measured under load in `make test`) before
    our handler ran; a real error costs this grace once, then is raised."""
    import time

    end = time.monotonic() + grace_s
    while not stop and time.monotonic() < end:
        time.sleep(0.01)
    return bool(stop)


def close_nodes(nodes, timeout=1.0):
    """Closes pydronecan SLCAN nodes within about `timeout` seconds in all.

    node.close() asks the driver's I/O process to stop and waits 10 s for
    it, per node. When the adapter has gone (the SLCAN hub stopped first),
    the I/O process sits in its reopen loop and never reads the request, so
    a program with four nodes took 40 s to exit. Here every I/O process is
    asked at once, given `timeout` together, and the ones still running
    are killed; node.close() then finds them gone and returns at once."""
    import signal
    import time

    procs = []
    for n in nodes:
        drv = getattr(n, "can_driver", None)
        proc = getattr(drv, "_proc", None)
        if proc is None:
            continue
        procs.append(proc)
        if proc.is_alive():
            try:
                drv._tx_queue.put_nowait(_slcan_stop())
            except Exception:
                pass
    deadline = time.monotonic() + timeout
    for p in procs:
        p.join(max(0.0, deadline - time.monotonic()))
    for p in procs:
        if p.is_alive():
            try:
                os.kill(p.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            p.join(1.0)
    for n in nodes:
        try:
            n.close()
        except Exception:
            pass


def _slcan_stop():
    from dronecan.driver import slcan

    return slcan.IPC_COMMAND_STOP
