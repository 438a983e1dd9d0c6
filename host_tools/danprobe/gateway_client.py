"""A blocking client of the CAN-over-DAN gateway over master.Master, and
the gateway's names in the registry (for sniff and error messages). The
messages are gateway_msgs.py and gateway_can.py.

The client mirrors libdan's (peripherals/can_gateway/gw_client.c), so
retried transactions never duplicate or lose anything: the master's
retries repeat the same request bytes; tunnel writes carry their stream
offset and reads acknowledge by offset; CAN_SEND carries a sequence number that changes per call, not per
attempt; CAN_RECV acknowledges by sequence number. Two additions for a
tool that joins a running gateway (libdan's FC client starts with it):
the first CAN_SEND of a session is preceded by an empty one that sets the
gateway's "last accepted" sequence number (so our first real sequence
number is never mistaken for a retry of someone else's), and frames the
first CAN_RECV skips are not counted as lost (they were before our time).
A CAN_SEND whose transaction failed is sent again with the same sequence
number by can_send_again(), so a lost response never duplicates frames.

Bus management (gw_client_mgmt.c): node service calls carry a call_id the
client picks, a new one per call (from a random start, so a new run never
reuses the ids a previous one left in the gateway): the master's retries
repeat it and the gateway never sends a retried call twice. A first
attempt answered with a finished state is a call of someone else's with
our id and content (a fresh call is always PENDING or BUSY): node_call()
then starts it again with the next id. gateway_calls.py pipelines calls.

Outputs (gw_client_out.c): the safety state, servo commands and their
failsafe table are states the gateway keeps; lights and beeps are one-shot
commands. A retried transaction sets the same state or sends the same
command again, so they need no sequence numbers.
"""

import random
from collections.abc import Sequence
from contextlib import nullcontext
from dataclasses import dataclass, replace
from typing import Callable, Optional

from danprobe import registry
from danprobe.codec import MalformedError
from danprobe.gateway_can import (
    RECV_TIMES,
    CanFrame,
    CanRecvRequest,
    CanRecvResponse,
    CanSendRequest,
    CanSendResponse,
    Filter,
    FilterTable,
)
from danprobe.gateway_fast import (
    CODE_ESC_FAST,
    CODE_ESC_FAST_T,
    FastRecord,
    FastResponse,
    decode_esc_fast,
    encode_esc_fast,
)
from danprobe.gateway_file import (
    CODE_FILE_COMMIT,
    CODE_FILE_LIST,
    CODE_FILE_OPEN,
    CODE_FILE_REMOVE,
    CODE_FILE_WRITE,
    FileCommit,
    FileListPage,
    FileOpen,
    FileState,
    FileWrite,
    decode_name,
    decode_result,
)
from danprobe.gateway_mgmt import (
    CALL_DONE,
    CALL_PARAM_ERASE,
    CALL_PARAM_GET_INDEX,
    CALL_PARAM_GET_NAME,
    CALL_PARAM_SAVE,
    CALL_PARAM_SET,
    CALL_RESTART,
    CALL_TIMEOUT,
    DNA_END,
    RESTART_MAGIC,
    RESULT_CHUNK_MAX,
    CallResultRequest,
    CallResultResponse,
    CallState,
    DnaEntry,
    DnaPage,
    Health,
    NodeCall,
    Value,
)
from danprobe.gateway_msgs import (
    ARM_FULLY_ARMED,
    CAN_FRAMES_MAX,
    CAN_RESYNC,
    CODE_ARM,
    CODE_CALL_RESULT,
    CODE_CAN_FILTER,
    CODE_CAN_RECV,
    CODE_CAN_SEND,
    CODE_CONFIG,
    CODE_DNA,
    CODE_ESC_CMD,
    CODE_ESC_TELEM,
    CODE_HEALTH,
    CODE_NODE_CALL,
    CODE_NODE_INFO,
    CODE_NODES,
    CODE_STATS,
    CODE_TUN_OPEN,
    CODE_TUN_XFER,
    FILTER_READ,
    FILTER_REPLACE,
    NONE,
    REQUEST,
    RESPONSE,
    TELEM_STATUS,
    TUN_CHUNK_MAX,
    ConfigRequest,
    ConfigResponse,
    NodeEntry,
    NodeInfo,
    NodesPage,
    Telemetry,
    TelemRecord,
    TunOpen,
    TunOpenResult,
    TunXferRequest,
    TunXferResponse,
    check_range,
    decode_esc_cmd,
    decode_stats,
    decode_u8,
    encode_esc_cmd,
    flags_dict,
    off_diff,
    reply_check,
    seal,
    stats_dict,
    unseal,
)
from danprobe.gateway_out import (
    CODE_BEEP,
    CODE_LIGHTS,
    CODE_SAFETY,
    CODE_SERVO,
    CODE_SERVO_FAILSAFE,
    SAFETY_OFF,
    SAFETY_ON,
    Beep,
    Light,
    LightsRequest,
    ServoFailsafe,
    ServoFailsafeTable,
    ServoRequest,
    decode_safety,
    encode_safety,
    safety_dict,
    servo_commands,
)
from danprobe.master import Malformed, Master, Nack

# ---- names for sniff and error messages ----


def _describer(code: int, direction: int, fn: Callable) -> Callable[[bytes], dict]:
    """A registry describer: unseals a wire payload, decodes the inner one
    (fn returns a dict or an object with as_dict())."""

    def describe(payload: bytes) -> dict:
        v = fn(unseal(code, direction, payload))
        return v.as_dict() if hasattr(v, "as_dict") else v

    return describe


def register_names():
    """Names codes 0x42..0x4F and 0x52..0x5F in the registry, with describers
    of the sealed payloads, so sniff shows and decodes them (the CLI calls
    this at start). A CAN_RECV response is decoded with the opts of the last
    CAN_RECV request described (its layout depends on them)."""
    u8 = decode_u8
    recv_opts = [0]

    def flags(p):
        return flags_dict(u8(p))

    def kept(p):
        return {"kept": u8(p)}

    def fast_req(p):
        return {"values": decode_esc_fast(p)}

    def commit_req(p):
        return {"crc32": f"0x{FileCommit.decode_request(p).crc:08x}"}

    def file_req(p):
        return {"name": decode_name(p).decode()}

    def recv_req(p):
        q = CanRecvRequest.decode(p)
        recv_opts[0] = q.opts
        return q

    for code, name, req, rsp in (
        (CODE_ESC_CMD, "ESC_CMD", lambda p: {"values": decode_esc_cmd(p)}, Telemetry.decode),
        (CODE_ESC_TELEM, "ESC_TELEM", lambda p: {"first": u8(p)}, Telemetry.decode),
        (CODE_ARM, "ARM", lambda p: {"status": u8(p)}, flags),
        (CODE_CONFIG, "CONFIG", ConfigRequest.decode, ConfigResponse.decode),
        (CODE_STATS, "STATS", registry.describe_empty, lambda p: stats_dict(decode_stats(p))),
        (CODE_NODES, "NODES", lambda p: {"first": u8(p)}, NodesPage.decode),
        (CODE_NODE_INFO, "NODE_INFO", lambda p: {"node": u8(p)}, NodeInfo.decode),
        (CODE_TUN_OPEN, "TUN_OPEN", TunOpen.decode, TunOpenResult.decode),
        (CODE_TUN_XFER, "TUN_XFER", TunXferRequest.decode, TunXferResponse.decode),
        (CODE_CAN_SEND, "CAN_SEND", CanSendRequest.decode, CanSendResponse.decode),
        (CODE_CAN_RECV, "CAN_RECV", recv_req, lambda p: CanRecvResponse.decode(p, recv_opts[0])),
        (CODE_CAN_FILTER, "CAN_FILTER", FilterTable.decode, FilterTable.decode),
        (CODE_NODE_CALL, "NODE_CALL", NodeCall.decode, CallState.decode),
        (CODE_CALL_RESULT, "CALL_RESULT", CallResultRequest.decode, CallResultResponse.decode),
        (CODE_HEALTH, "HEALTH", registry.describe_empty, Health.decode),
        (CODE_DNA, "DNA", lambda p: {"first": u8(p)}, DnaPage.decode),
        (CODE_SAFETY, "SAFETY", lambda p: safety_dict(decode_safety(p)), flags),
        (CODE_SERVO, "SERVO", ServoRequest.decode, flags),
        (CODE_SERVO_FAILSAFE, "SERVO_FAILSAFE", ServoFailsafeTable.decode, kept),
        (CODE_LIGHTS, "LIGHTS", LightsRequest.decode, flags),
        (CODE_BEEP, "BEEP", Beep.decode, flags),
        (CODE_ESC_FAST, "ESC_FAST", fast_req, FastResponse.decode),
        (CODE_ESC_FAST_T, "ESC_FAST_T", fast_req, FastResponse.decode),
        (CODE_FILE_OPEN, "FILE_OPEN", FileOpen.decode, FileState.decode),
        (CODE_FILE_WRITE, "FILE_WRITE", FileWrite.decode, FileState.decode),
        (CODE_FILE_COMMIT, "FILE_COMMIT", commit_req, FileCommit.decode),
        (CODE_FILE_LIST, "FILE_LIST", lambda p: {"first": u8(p)}, FileListPage.decode),
        (CODE_FILE_REMOVE, "FILE_REMOVE", file_req, lambda p: {"result": decode_result(p)}),
    ):
        registry.register_message(
            code,
            name,
            request=_describer(code, REQUEST, req),
            response=_describer(code, RESPONSE, rsp),
        )


# ---- the client ----


@dataclass
class TunnelState:
    wr_offset: int = 0  # bytes of ours the gateway has accepted
    rd_offset: int = 0  # bytes we have received
    wr_space: int = 0  # gateway buffer space, last seen
    rd_dropped: int = 0  # bytes the gateway dropped (CAN -> DAN)
    rd_lost: int = 0  # bytes skipped here (the gateway dropped them)
    accepted: int = 0  # of the last xfer's data


class GatewayClient:
    """Typed gateway calls over a Master whose bus has the gateway at
    master.baud. Each call is one transaction (the master retries lost
    ones) and raises the master's DanError on failure; a response that does
    not decode raises Malformed (counted in decode_errors)."""

    def __init__(self, master: Master, seed: Optional[int] = None):
        self.m = master
        master.reply_check = reply_check
        self.flags = 0  # from the last response that carries them
        self.escs_known = 0  # ESCs the gateway knows (ESC_CMD response)
        self.esc: dict[int, TelemRecord] = {}  # newest telemetry per ESC index
        self.config: Optional[ConfigResponse] = None
        self.stats: list[int] = []
        self.tun: dict[int, TunnelState] = {}
        self.can_seq: Optional[int] = None  # last CAN_SEND sequence number used
        self._unsent: Optional[CanSendRequest] = None  # a CAN_SEND whose transaction failed
        self.can_accepted = 0
        self.can_queue_free = 0
        self.can_rx_next: Optional[int] = None  # next raw frame sequence number wanted
        self.can_rx_dropped = 0
        self.can_rx_lost = 0
        self.can_rx_resyncs = 0
        self.recv_opts = 0  # of the last CAN_RECV
        self.recv_times: list[int] = []  # its frames' receive times (gateway clock, us)
        self.decode_errors = 0
        self._rng = random.Random(seed)
        self.call_id = self._rng.randrange(1 << 16)  # the last call_id used
        self.call: Optional[CallState] = None  # the last NODE_CALL response
        self.stale_calls = 0  # our call_id and content were someone else's call
        self.health_state: Optional[Health] = None  # the last HEALTH response
        self.servo_fs_kept = 0  # entries of the last SERVO_FAILSAFE table kept

    def _call(self, code: int, payload: bytes, decode: Callable):
        """One transaction: the request sealed, the reply unsealed (the
        master's reply check already refused a bad seal) and decoded."""
        reply = self.m.request(code, seal(code, REQUEST, payload))
        try:
            return decode(unseal(code, RESPONSE, reply))
        except (MalformedError, ValueError) as e:
            self.decode_errors += 1
            raise Malformed(f"{registry.code_name(code)}: bad response: {e}") from None

    def _malformed(self, code: int, why: str):
        self.decode_errors += 1
        return Malformed(f"{registry.code_name(code)}: {why}")

    # ---- ESCs, arming, settings, counters ----

    def esc_command(self, values: Sequence[int]) -> Optional[TelemRecord]:
        """Sends RawCommand values; returns the telemetry record that came
        back (round robin over the ESCs), also kept in self.esc."""
        t = self._call(CODE_ESC_CMD, encode_esc_cmd(values), Telemetry.decode)
        self.flags, self.escs_known = t.flags, t.aux
        for r in t.records:
            self.esc[r.esc_index] = r
        return t.records[0] if t.records else None

    def esc_fast(self, values: Sequence[int], telem: bool = False) -> Optional[FastRecord]:
        """The compact exchange: ESC_FAST, or ESC_FAST_T when telem. Returns
        the record that came back (ESC_FAST_T, once an ESC reported); its
        esc.Status fields also update self.esc (the others stay)."""
        code = CODE_ESC_FAST_T if telem else CODE_ESC_FAST
        rsp = self._call(code, encode_esc_fast(values), FastResponse.decode)
        self.flags = rsp.flags
        rec = rsp.record
        if rec is not None:
            old = self.esc.get(rec.esc_index) or TelemRecord(rec.esc_index)
            self.esc[rec.esc_index] = replace(
                old,
                flags=old.flags | TELEM_STATUS,
                age_ms=rec.age_ms,
                voltage_f16=rec.voltage_f16,
                current_f16=rec.current_f16,
                temperature_f16=rec.temperature_f16,
                rpm=rec.rpm,
            )
        return rec

    def telemetry_page(self, first: int = 0) -> Telemetry:
        t = self._call(CODE_ESC_TELEM, bytes([first]), Telemetry.decode)
        self.flags = t.flags
        for r in t.records:
            self.esc[r.esc_index] = r
        return t

    def telemetry(self) -> list[TelemRecord]:
        """Every ESC's newest telemetry, page by page, in index order."""
        out, first = [], 0
        while True:
            t = self.telemetry_page(first)
            out += t.records
            if t.aux == NONE:
                return out
            if t.aux <= first:
                raise self._malformed(CODE_ESC_TELEM, f"next page {t.aux} does not advance")
            first = t.aux

    def arm(self, status: int = ARM_FULLY_ARMED) -> int:
        """ArmingStatus value (0 disarmed, 255 fully armed); returns the flags."""
        self.flags = self._call(
            CODE_ARM, bytes([check_range(status, 0, 255, "arming status")]), decode_u8
        )
        return self.flags

    def read_config(self, set_req: Optional[ConfigRequest] = None) -> ConfigResponse:
        self.config = self._call(
            CODE_CONFIG, (set_req or ConfigRequest()).encode(), ConfigResponse.decode
        )
        self.flags = self.config.flags
        return self.config

    def read_stats(self) -> dict[str, int]:
        self.stats = self._call(CODE_STATS, b"", decode_stats)
        return stats_dict(self.stats)

    # ---- DroneCAN nodes ----

    def nodes_page(self, first: int = 1) -> NodesPage:
        return self._call(CODE_NODES, bytes([first]), NodesPage.decode)

    def nodes(self) -> list[NodeEntry]:
        out, first = [], 1
        while True:
            p = self.nodes_page(first)
            out += p.entries
            if p.next == 0:
                return out
            if p.next <= first:
                raise self._malformed(CODE_NODES, f"next page {p.next} does not advance")
            first = p.next

    def node_info(self, node_id: int) -> NodeInfo:
        i = self._call(CODE_NODE_INFO, bytes([node_id]), NodeInfo.decode)
        if i.node_id != node_id:
            raise self._malformed(CODE_NODE_INFO, f"answer for node {i.node_id}, not {node_id}")
        return i

    # ---- tunnels ----

    def tunnel_open(self, cfg: TunOpen) -> None:
        """Opens, reconfigures or (mode TUN_CLOSED) closes a port; both
        offsets restart at 0. Raises Nack if the gateway refused."""
        r = self._call(CODE_TUN_OPEN, cfg.encode(), TunOpenResult.decode)
        if r.port != cfg.port:
            raise self._malformed(CODE_TUN_OPEN, f"answer for port {r.port}, not {cfg.port}")
        if r.result != 0:
            raise Nack(f"the gateway refused tunnel port {cfg.port} ({cfg})")
        self.tun[cfg.port] = TunnelState()

    def tunnel_xfer(self, port: int, data: bytes = b"", rd_max: int = TUN_CHUNK_MAX) -> bytes:
        """Writes the first up to 128 bytes of data (the bytes from our write
        offset on: drop .tun[port].accepted of them afterwards and pass the
        rest again) and returns the new bytes read (up to rd_max)."""
        t = self.tun.setdefault(port, TunnelState())
        data = bytes(data[:TUN_CHUNK_MAX])
        req = TunXferRequest(port, t.wr_offset, t.rd_offset, min(rd_max, TUN_CHUNK_MAX), data)
        t.accepted = 0
        x = self._call(CODE_TUN_XFER, req.encode(), TunXferResponse.decode)
        if x.port != port:
            raise self._malformed(CODE_TUN_XFER, f"answer for port {x.port}, not {port}")
        adv = off_diff(x.wr_next, t.wr_offset)
        if not 0 <= adv <= len(data):
            raise self._malformed(CODE_TUN_XFER, f"took {adv} of {len(data)} bytes")
        skip = off_diff(x.rd_offset, t.rd_offset)
        if skip < 0:
            raise self._malformed(CODE_TUN_XFER, "data older than what we acknowledged")
        t.accepted, t.wr_offset = adv, x.wr_next
        t.wr_space, t.rd_dropped = x.wr_space, x.rd_dropped
        t.rd_lost += skip
        t.rd_offset = (x.rd_offset + len(x.data)) & 0xFFFFFFFF
        return x.data

    # ---- raw frames ----

    def _can_sync(self):
        """An empty CAN_SEND makes its sequence number the gateway's last
        accepted one, so our next (different) number is never taken for a
        retry of an earlier client's request."""
        self.can_seq = self._rng.randrange(256)
        self._call(CODE_CAN_SEND, CanSendRequest(self.can_seq).encode(), CanSendResponse.decode)

    def _can_send(self, req: CanSendRequest) -> int:
        self._unsent = req
        rsp = self._call(CODE_CAN_SEND, req.encode(), CanSendResponse.decode)
        self._unsent = None
        if rsp.seq != req.seq:
            raise self._malformed(CODE_CAN_SEND, f"answer for seq {rsp.seq}, not {req.seq}")
        self.can_accepted, self.can_queue_free = rsp.accepted, rsp.queue_free
        return rsp.accepted

    def can_send(self, frames: Sequence[CanFrame]) -> int:
        """Sends up to 11 frames, all or nothing: returns how many the
        gateway took (0: its queue was full, send them again later)."""
        if len(frames) > CAN_FRAMES_MAX:
            raise ValueError(f"at most {CAN_FRAMES_MAX} frames per CAN_SEND")
        if self.can_seq is None:
            self._can_sync()
        # a new number per call, not per attempt: the master's retries repeat it
        self.can_seq = (self.can_seq + 1) & 0xFF
        return self._can_send(CanSendRequest(self.can_seq, list(frames)))

    @property
    def can_send_failed(self) -> bool:
        """The last CAN_SEND's transaction failed: can_send_again() repeats it."""
        return self._unsent is not None

    def can_send_again(self) -> int:
        """Sends the CAN_SEND whose transaction failed again, with its
        sequence number: if the gateway took it before, it is not sent twice."""
        if self._unsent is None:
            raise ValueError("no failed CAN_SEND to repeat")
        return self._can_send(self._unsent)

    def can_recv(self, max_frames: int = CAN_FRAMES_MAX, opts: int = 0) -> list[CanFrame]:
        """The next frames that passed the filter (acknowledging the ones
        received before). opts RECV_TIMES: their receive times (the
        gateway's microsecond clock, low 32 bits, t0 not unwrapped) land in
        .recv_times."""
        first = self.can_rx_next is None
        req = CanRecvRequest(
            0 if first else self.can_rx_next, min(max_frames, CAN_FRAMES_MAX), opts
        )
        q = self._call(CODE_CAN_RECV, req.encode(), lambda p: CanRecvResponse.decode(p, opts))
        self.recv_opts = opts
        self.recv_times = q.times_us() if opts & RECV_TIMES else []
        if not first:
            skip = off_diff(q.first_seq, self.can_rx_next)
            if skip < 0 or skip > CAN_RESYNC:
                # not where we left off: the gateway restarted (its sequence
                # starts elsewhere each boot); follow it, as the C client does
                self.can_rx_resyncs += 1
            else:
                self.can_rx_lost += skip
        self.can_rx_next = (q.first_seq + len(q.frames)) & 0xFFFFFFFF
        self.can_rx_dropped = q.dropped
        return q.frames

    def can_listen(self, filters: Sequence[Filter]) -> list[Filter]:
        """Starts receiving with our filter: empties the filter, drops the
        frames still waiting in the gateway (they passed someone else's
        filter, earlier), then sets filters. Returns the table it replaced,
        for can_filter(FILTER_REPLACE, previous) at the end. Cut short
        after the table was read (a transaction failed, --timeout, Ctrl-C),
        it puts that table back (best effort) before it raises."""
        previous = self.can_filter(FILTER_READ).filters
        try:
            self.can_filter(FILTER_REPLACE, [])
            while self.can_recv():
                pass
            if self.can_filter(FILTER_REPLACE, filters).op != 0:
                raise Nack("the gateway's filter table is full")
        except BaseException:
            recover = getattr(self.m, "time_to_recover", nullcontext)
            with recover():
                try:
                    self.can_filter(FILTER_REPLACE, previous)
                except Exception:
                    pass  # the gateway or the port is gone: the cause is what counts
            raise
        return previous

    def can_filter(self, op: int, filters: Sequence[Filter] = ()) -> FilterTable:
        """Changes (or, FILTER_READ, reads) the receive filter; returns the
        result (0 OK, 1 table full) and the gateway's table."""
        return self._call(
            CODE_CAN_FILTER, FilterTable(op, list(filters)).encode(), FilterTable.decode
        )

    # ---- bus management: service calls, health, allocation table ----

    def new_call_id(self) -> int:
        self.call_id = (self.call_id + 1) & 0xFFFF
        return self.call_id

    def node_call(self, call: NodeCall, fresh: bool = True) -> CallState:
        """Starts a service call (call.call_id: from new_call_id()); returns
        the gateway's state of it (PENDING, or BUSY: nothing was sent). A
        fresh call (fresh: this call_id was never sent before; not so when
        a failed transaction is repeated) found finished at the first
        attempt was someone else's: it is started again under a new id."""
        for _ in range(4):
            stats = getattr(self.m, "stats", None)
            retries = stats.retries if stats is not None else 0
            st = self._call(CODE_NODE_CALL, call.encode(), CallState.decode)
            if st.call_id != call.call_id:
                raise self._malformed(
                    CODE_NODE_CALL, f"answer for call {st.call_id}, not {call.call_id}"
                )
            first_attempt = stats is None or stats.retries == retries
            if not fresh or st.state not in (CALL_DONE, CALL_TIMEOUT) or not first_attempt:
                self.call = st
                return st
            self.stale_calls += 1  # a fresh call is never finished at once
            call.call_id = self.new_call_id()
        raise self._malformed(CODE_NODE_CALL, "every call_id tried was finished already")

    def _start(self, node_id: int, op: int, **kw) -> CallState:
        return self.node_call(NodeCall(self.new_call_id(), node_id, op, **kw))

    def param_get_index(self, node_id: int, index: int) -> CallState:
        return self._start(node_id, CALL_PARAM_GET_INDEX, index=index)

    def param_get(self, node_id: int, name) -> CallState:
        return self._start(node_id, CALL_PARAM_GET_NAME, name=_name(name))

    def param_set(self, node_id: int, name, value: Value) -> CallState:
        return self._start(node_id, CALL_PARAM_SET, name=_name(name), value=value)

    def param_save(self, node_id: int) -> CallState:
        return self._start(node_id, CALL_PARAM_SAVE)

    def param_erase(self, node_id: int) -> CallState:
        return self._start(node_id, CALL_PARAM_ERASE)

    def restart(self, node_id: int, magic: int = RESTART_MAGIC, force: bool = False) -> CallState:
        """RestartNode; the gateway refuses (RemoteError) a magic other than
        RESTART_MAGIC unless force."""
        return self._start(node_id, CALL_RESTART, magic=magic, force=force)

    def call_result(
        self, call_id: int, offset: int = 0, max_bytes: int = RESULT_CHUNK_MAX
    ) -> CallResultResponse:
        """A call's state and up to max_bytes of its result from offset (a
        call the gateway does not hold: RemoteError)."""
        q = self._call(
            CODE_CALL_RESULT,
            CallResultRequest(call_id, offset, min(max_bytes, RESULT_CHUNK_MAX)).encode(),
            CallResultResponse.decode,
        )
        if q.call_id != call_id or (q.state == CALL_DONE and q.offset != offset):
            raise self._malformed(
                CODE_CALL_RESULT, f"answer for call {q.call_id} at {q.offset}, not {call_id}"
            )
        return q

    def health(self) -> Health:
        self.health_state = self._call(CODE_HEALTH, b"", Health.decode)
        return self.health_state

    def dna_page(self, first: int = 0) -> DnaPage:
        return self._call(CODE_DNA, bytes([first]), DnaPage.decode)

    def dna(self) -> tuple[DnaPage, list[DnaEntry]]:
        """The allocation table, page by page: (the last page's header, every entry)."""
        out, first = [], 0
        while True:
            p = self.dna_page(first)
            out += p.items
            if p.next == DNA_END:
                return p, out
            if p.next <= first:
                raise self._malformed(CODE_DNA, f"next page {p.next} does not advance")
            first = p.next

    # ---- outputs: safety state, servos, lights, buzzer ----

    def _flags_call(self, code: int, payload: bytes) -> int:
        self.flags = self._call(code, payload, decode_u8)
        return self.flags

    def safety(self, off: bool) -> int:
        """SafetyState 255 (off: outputs may move) or 0 (on: locked), kept
        and broadcast by the gateway; returns the flags (FLAG_SAFETY_OFF)."""
        return self._flags_call(CODE_SAFETY, encode_safety(SAFETY_OFF if off else SAFETY_ON))

    def servo(self, commands: Sequence) -> int:
        """ArrayCommand: ServoCommands or (actuator_id, command_type, value)
        tuples, 1..32; the gateway keeps each actuator's latest. Returns the flags."""
        return self._flags_call(CODE_SERVO, ServoRequest(servo_commands(commands)).encode())

    def servo_failsafe(self, entries: Sequence[ServoFailsafe]) -> int:
        """Replaces the servo failsafe table (0..32 entries; an actuator not
        listed holds its last command); returns the entries kept."""
        self.servo_fs_kept = self._call(
            CODE_SERVO_FAILSAFE, ServoFailsafeTable(list(entries)).encode(), decode_u8
        )
        return self.servo_fs_kept

    def lights(self, lights: Sequence[Light]) -> int:
        """LightsCommand (1..20 lights, RGB565); returns the flags."""
        return self._flags_call(CODE_LIGHTS, LightsRequest(list(lights)).encode())

    def beep(self, frequency_hz: int, duration_ms: int) -> int:
        """BeepCommand (1..65504 Hz, 0..65504000 ms); returns the flags."""
        return self._flags_call(CODE_BEEP, Beep(frequency_hz, duration_ms).encode())


def _name(name) -> bytes:
    return name.encode("utf-8") if isinstance(name, str) else bytes(name)
