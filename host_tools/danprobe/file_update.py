"""The gateway's file store and firmware updates from the master's side
(docs/PROTOCOL.md section 7, "Files and firmware updates"): the file
transactions, an upload that resumes where the gateway stopped, and a
follower of one node's update (NODE_INFO's appended fields).

Every transaction is safe to repeat (the master's retries): FILE_OPEN of
the same name and size resumes, FILE_WRITE carries its offset and data
below the gateway's `have` is a retry, FILE_COMMIT with the same CRC
answers OK again, FW_BEGIN is a NODE_CALL (retry-safe by call_id). The
stop() callbacks are checked between transactions only, so a stop (Ctrl-C)
never leaves half a frame on the wire; the gateway keeps a partial upload
for the next FILE_OPEN of the same name and size.
"""

from dataclasses import dataclass, field
from typing import Callable, Optional

from danprobe import gateway_calls
from danprobe import gateway_file as F
from danprobe.gateway_client import GatewayClient
from danprobe.gateway_mgmt import CALL_FW_BEGIN, NodeCall
from danprobe.gateway_msgs import INFO_VALID, NodeInfo
from danprobe.master import (
    BadReply,
    Collision,
    DanError,
    DanTimeout,
    Malformed,
    OperationTimeout,
)
from danprobe.payloads import attrs
from danprobe.port import now

FAILURES_MAX = 5  # failed transactions in a row (after the master's retries)
WRITE_MAX = F.WRITE_MAX


class FileError(DanError):
    """The gateway refused a file operation: .result says why (FILE_*)."""

    code, reason = -6, "refused by the gateway"

    def __init__(self, what: str, result: int):
        super().__init__(f"{what}: {F.result_name(result)}")
        self.result = result


class Stopped(DanError):
    """stop() said so (Ctrl-C), between two transactions."""

    code, reason = -12, "interrupted"


# ---- one transaction each ----


def file_open(gw: GatewayClient, name, size: int, restart: bool = False) -> F.FileState:
    req = F.FileOpen(F.file_name(name), size, F.OPEN_RESTART if restart else 0)
    return gw._call(F.CODE_FILE_OPEN, req.encode(), F.FileState.decode)


def file_write(gw: GatewayClient, offset: int, data: bytes) -> F.FileState:
    req = F.FileWrite(offset, bytes(data))
    return gw._call(F.CODE_FILE_WRITE, req.encode(), F.FileState.decode)


def file_commit(gw: GatewayClient, crc: int) -> F.FileCommit:
    req = F.FileCommit(crc=crc).encode_request()
    return gw._call(F.CODE_FILE_COMMIT, req, F.FileCommit.decode)


def file_list(gw: GatewayClient) -> list[F.FileEntry]:
    """Every committed file, page by page, in name order."""
    out, first = [], 0
    while True:
        p = gw._call(F.CODE_FILE_LIST, bytes([first]), F.FileListPage.decode)
        out += p.entries
        if p.next == F.LIST_END:
            return out
        if p.next <= first:
            raise gw._malformed(F.CODE_FILE_LIST, f"next page {p.next} does not advance")
        first = p.next


def file_remove(gw: GatewayClient, name) -> int:
    return gw._call(F.CODE_FILE_REMOVE, F.encode_name(name), F.decode_result)


def fw_begin(gw: GatewayClient, node_id: int, name) -> F.FwBeginResult:
    """BeginFirmwareUpdate to node_id with the gateway as file server (a
    name that is no committed file: RemoteError, nothing sent)."""
    req = NodeCall(0, node_id, CALL_FW_BEGIN, name=F.file_name(name))
    return F.FwBeginResult.decode(gateway_calls.call(gw, req))


# ---- an upload ----


@dataclass
class Upload:
    name: bytes
    size: int
    crc: int
    resumed_from: int = 0  # the gateway's `have` at FILE_OPEN
    have: int = 0
    sent: int = 0  # data bytes we sent (retries by the master not counted)
    writes: int = 0
    reopens: int = 0  # NO_UPLOAD answered (the gateway restarted): opened again
    seconds: float = 0.0
    committed: bool = False

    def as_dict(self) -> dict:
        return {
            "name": self.name.decode(),
            "size": self.size,
            "crc32": f"0x{self.crc:08x}",
            "resumed_from": self.resumed_from,
            "have": self.have,
            "sent": self.sent,
            "writes": self.writes,
            "committed": self.committed,
            "seconds": round(self.seconds, 3),
            "bytes_per_s": round(self.sent / self.seconds) if self.seconds > 0 else 0,
        }


def guarded(fn: Callable, failures: list):
    """fn(); a failed transaction (no answer, collisions, bad seals after
    the master's retries) is tolerated FAILURES_MAX times in a row (None
    returned: try again); error frames, malformed answers and the time
    limit are not."""
    try:
        out = fn()
    except OperationTimeout:
        raise
    except (DanTimeout, Collision, BadReply):
        if failures[0] >= FAILURES_MAX:
            raise
        failures[0] += 1
        return None
    failures[0] = 0
    return out


def upload(
    gw: GatewayClient,
    name,
    data: bytes,
    restart: bool = False,
    progress: Optional[Callable[[Upload], None]] = None,
    stop: Callable[[], bool] = lambda: False,
    on_open: Optional[Callable[[Upload], None]] = None,
) -> Upload:
    """Puts data into the gateway's store as `name`: FILE_OPEN (resuming a
    partial upload of the same name and size unless restart), FILE_WRITE
    from the gateway's `have` on, FILE_COMMIT with the CRC-32. progress(u)
    after each write; on_open(u) once the resume offset is known. Raises
    FileError (refused), Stopped (stop() was true), DanError."""
    u = Upload(F.file_name(name), len(data), F.crc32(data))
    t0 = now()
    failures = [0]

    def open_(first: bool):
        st = None
        while st is None:
            st = guarded(lambda: file_open(gw, u.name, u.size, restart and first), failures)
        if st.result != F.FILE_OK:
            raise FileError(f"FILE_OPEN {u.name.decode()} ({u.size} bytes)", st.result)
        if st.have > u.size:
            raise gw._malformed(F.CODE_FILE_OPEN, f"have {st.have} beyond the size {u.size}")
        return st.have

    u.have = u.resumed_from = open_(True)
    if on_open:
        on_open(u)
    stuck = 0
    while u.have < u.size:
        if stop():
            raise Stopped(f"stopped at {u.have} of {u.size} bytes")
        chunk = data[u.have : u.have + WRITE_MAX]
        st = guarded(lambda c=chunk: file_write(gw, u.have, c), failures)
        if st is None:
            continue
        u.writes += 1
        u.sent += len(chunk)
        if st.result == F.FILE_NO_UPLOAD:  # the gateway lost it (restarted): resume
            u.reopens += 1
            if u.reopens > FAILURES_MAX:
                raise FileError("FILE_WRITE", st.result)
            u.have = open_(False)
            continue
        if st.result != F.FILE_OK:
            raise FileError(f"FILE_WRITE at {u.have}", st.result)
        if not 0 <= st.have <= u.size:
            raise gw._malformed(F.CODE_FILE_WRITE, f"have {st.have} beyond the size {u.size}")
        stuck = stuck + 1 if st.have <= u.have else 0
        if stuck > FAILURES_MAX:
            raise gw._malformed(F.CODE_FILE_WRITE, f"no progress at {u.have}")
        u.have = st.have
        u.seconds = now() - t0
        if progress:
            progress(u)
    c = None
    while c is None:
        if stop():
            raise Stopped(f"stopped before the commit ({u.have} of {u.size} bytes held)")
        c = guarded(lambda: file_commit(gw, u.crc), failures)
    if c.result == F.FILE_CRC:
        raise FileError(
            f"FILE_COMMIT: the gateway holds CRC-32 0x{c.crc:08x}, the file has 0x{u.crc:08x} "
            "(the upload stays open: --restart sends it again)",
            c.result,
        )
    if c.result == F.FILE_IN_USE:
        raise FileError(
            f"FILE_COMMIT: a node is reading the {u.name.decode()} this would replace (the "
            "upload stays held: run again once its update has ended, or upload under another "
            "name)",
            c.result,
        )
    if c.result != F.FILE_OK:
        raise FileError("FILE_COMMIT", c.result)
    u.committed, u.seconds = True, now() - t0
    return u


# ---- following a node's update ----

ONGOING, DONE, FAILED = "updating", "done", "failed"


def version_of(info: Optional[NodeInfo]) -> Optional[dict]:
    if info is None or info.info_state != INFO_VALID:
        return None
    return {
        "sw": f"{info.sw_major}.{info.sw_minor}",
        "vcs_commit": f"{info.vcs_commit:08x}",
        "name": info.name.decode("utf-8", "backslashreplace"),
    }


def version_text(v: Optional[dict]) -> str:
    return f"{v['sw']} (vcs {v['vcs_commit']})" if v else "unknown"


@dataclass
class Follow:
    """One node's update as NODE_INFO shows it. step(info, t) takes the
    next NODE_INFO and sets .state: ONGOING, DONE (back OPERATIONAL with
    another version after reading), FAILED (.why: the node's error, or no
    read and no NodeStatus change for `stall` seconds)."""

    node_id: int
    before: Optional[dict]
    stall: float
    state: str = ONGOING
    why: str = ""
    after: Optional[dict] = None
    bytes_read: int = 0
    file_size: int = 0
    seen_update: bool = False  # SOFTWARE_UPDATE mode or a read seen
    last_change: float = field(default_factory=now)
    _last: tuple = ()

    def step(self, info: NodeInfo, t: float):
        f = info.follow
        if f is None:
            raise Malformed("NODE_INFO: this gateway does not report updates (no follow fields)")
        key = (f.status, f.bytes_read, f.file_flags, info.info_state, version_of(info))
        if key != self._last:
            self._last, self.last_change = key, t
        self.bytes_read, self.file_size = f.bytes_read, f.file_size
        if f.mode == F.MODE_SOFTWARE_UPDATE or f.reading:
            self.seen_update = True
        done_reading = self.file_size and self.bytes_read >= self.file_size
        v = version_of(info)
        if (
            f.has_status
            and f.mode == F.MODE_OPERATIONAL
            and done_reading
            and v is not None
            and v != self.before
        ):
            self.state, self.after = DONE, v
            return
        if self.seen_update and f.has_status and f.health >= 2:
            self.state = FAILED
            self.why = f"node {self.node_id} reports health {('ERROR', 'CRITICAL')[f.health - 2]}"
            return
        if t - self.last_change > self.stall:
            self.state = FAILED
            if done_reading:
                self.why = (
                    f"node {self.node_id} read the whole image but is not back OPERATIONAL "
                    f"with a new version after {self.stall:g} s (version {version_text(v)})"
                )
            else:
                self.why = (
                    f"node {self.node_id} stopped reading at {self.bytes_read} of "
                    f"{self.file_size or '?'} bytes: no read and no status change for "
                    f"{self.stall:g} s"
                )

    def idle(self, t: float):
        """A poll without news (the node out of the table, a failed
        transaction): only the stall clock runs."""
        if t - self.last_change > self.stall:
            self.state = FAILED
            self.why = (
                f"node {self.node_id}: no news for {self.stall:g} s (at {self.bytes_read} of "
                f"{self.file_size or '?'} bytes)"
            )

    def as_dict(self) -> dict:
        names = ("state", "why", "before", "after", "bytes_read", "file_size")
        return {"node": self.node_id, **attrs(self, *names)}
