"""DroneCAN service calls made by the gateway for us (NODE_CALL, then
CALL_RESULT until the call is finished), pipelined: up to `window` calls
in flight, each polled in turn, so a parameter list does not wait a
DroneCAN round trip per parameter.

What can go wrong, and what happens:
- the node never answers: the gateway makes 3 attempts, 1 s each, and the
  state becomes TIMEOUT: NoAnswer (a DanTimeout) names the node and call;
- every gateway slot is busy (BUSY, nothing sent): started again a little
  later, the same call;
- a transaction fails after the master's retries: repeated, since both
  messages are safe to repeat (a NODE_CALL with the same call_id and
  content is a retry to the gateway, a CALL_RESULT only reads); a call
  whose transactions keep failing raises that error;
- the gateway no longer holds the call (CALL_RESULT answered with an error
  frame: it restarted, or made room for newer calls): a parameter call is
  started again under a new id, a RestartNode or
  BeginFirmwareUpdate is not (it may have run);
- the gateway keeps a call PENDING past `patience_s`: NoAnswer as well.
"""

from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any, Callable, Optional

from danprobe.gateway_client import GatewayClient
from danprobe.gateway_mgmt import (
    CALL_BUSY,
    CALL_DONE,
    CALL_FW_BEGIN,
    CALL_OP_NAMES,
    CALL_PARAM_GET_INDEX,
    CALL_PENDING,
    CALL_RESTART,
    CALL_TIMEOUT,
    PARAM_INDEX_MAX,
    NodeCall,
    OpcodeResult,
    ParamResult,
)
from danprobe.master import DanError, DanTimeout, Malformed, OperationTimeout, RemoteError
from danprobe.port import now

WINDOW = 5  # calls in flight (the gateway holds 8)
PATIENCE_S = 12.0  # the gateway gives up after 3 attempts of 1 s; this is ours
BUSY_PAUSE_S = 0.05
FAILURES_MAX = 4  # failed transactions in a row for one call
RESTARTS_MAX = 2  # times a forgotten call is started again


class NoAnswer(DanTimeout):
    """The node did not answer the call (every attempt of the gateway timed out)."""


class CallLost(DanError):
    """The gateway no longer holds a call we started."""

    code, reason = -9, "not found"


def describe(call: NodeCall) -> str:
    """ "param get 'esc_rate'", "param get (index) 7", "restart"."""
    what = CALL_OP_NAMES[call.op]
    if call.op == CALL_PARAM_GET_INDEX:
        what += f" {call.index}"
    elif call.name:
        what += f" {call.name.decode('utf-8', 'backslashreplace')!r}"
    return what


@dataclass
class Call:
    key: Any
    req: NodeCall
    started: float = 0.0
    state: int = CALL_PENDING
    result: bytearray = field(default_factory=bytearray)
    result_len: int = 0
    failures: int = 0
    restarts: int = 0
    not_before: float = 0.0  # BUSY: wait before starting again
    sent: bool = False  # the gateway took it (PENDING)
    tried: bool = False  # a NODE_CALL with this call_id went out (its answer may be lost)


class Pipeline:
    """Calls in flight through one GatewayClient. start() a call while not
    full(); step() polls one in-flight call and returns it once finished
    (state DONE, result complete), else None."""

    def __init__(self, gw: GatewayClient, window: int = WINDOW, patience_s: float = PATIENCE_S):
        self.gw = gw
        self.window = window
        self.patience_s = patience_s
        self.flight: deque[Call] = deque()
        self.transactions = 0

    def full(self) -> bool:
        return len(self.flight) >= self.window

    @property
    def pending(self) -> int:
        return len(self.flight)

    def start(self, key, req: NodeCall):
        """Starts req (its call_id is set here: a new one)."""
        req.call_id = self.gw.new_call_id()
        c = Call(key, req)
        self.flight.append(c)
        self._send(c)

    def _guard(self, c: Call, fn: Callable):
        """fn(), counting a transaction; a failed one is tolerated a few
        times in a row per call (the caller tries again later)."""
        self.transactions += 1
        try:
            out = fn()
        except (OperationTimeout, RemoteError):
            raise
        except DanError:
            c.failures += 1
            if c.failures > FAILURES_MAX:
                raise
            return None
        c.failures = 0
        return out

    def _send(self, c: Call):
        fresh, c.tried = not c.tried, True
        st = self._guard(c, lambda: self.gw.node_call(c.req, fresh))
        if st is None:
            return  # NODE_CALL again with the same id and content: a retry to the gateway
        c.req.call_id = st.call_id  # node_call() may have moved to a fresh id
        if st.state == CALL_BUSY:
            c.not_before = now() + BUSY_PAUSE_S
            return
        c.sent, c.started, c.state = True, now(), st.state

    def step(self) -> Optional[Call]:
        c = self.flight[0]
        self.flight.rotate(-1)  # the next poll is another call's
        if not c.sent:
            if now() >= c.not_before:
                self._send(c)
            return None
        try:
            q = self._guard(c, lambda: self.gw.call_result(c.req.call_id, len(c.result)))
        except RemoteError:
            return self._forgotten(c)
        if q is None:
            return None
        if q.state == CALL_TIMEOUT:
            raise NoAnswer(
                f"node {c.req.node_id} did not answer {describe(c.req)} (the gateway's 3 attempts)"
            )
        if q.state == CALL_PENDING:
            if now() - c.started > self.patience_s:
                raise NoAnswer(
                    f"no result for {describe(c.req)} to node {c.req.node_id} after "
                    f"{self.patience_s:g} s"
                )
            return None
        if q.state != CALL_DONE or q.offset != len(c.result):
            raise Malformed(f"CALL_RESULT: state {q.state} at offset {q.offset}")
        c.result += q.data
        c.result_len = q.result_len
        if len(c.result) < q.result_len:
            if not q.data:
                raise Malformed(f"CALL_RESULT: no data at {q.offset} of {q.result_len}")
            return None  # the rest on the next poll of this call
        c.state = CALL_DONE
        self.flight.remove(c)
        return c

    def _forgotten(self, c: Call) -> None:
        """The gateway does not hold the call any more."""
        if c.req.op in (CALL_RESTART, CALL_FW_BEGIN) or c.restarts >= RESTARTS_MAX:
            raise CallLost(
                f"the gateway no longer holds {describe(c.req)} to node {c.req.node_id} (it "
                "restarted, or made room for newer calls)"
            )
        c.restarts += 1
        c.req.call_id, c.sent, c.tried = self.gw.new_call_id(), False, False
        c.result.clear()
        self._send(c)
        return None

    def drain(self) -> Iterator[Call]:
        """Every call in flight, finished, in the order they finish."""
        while self.flight:
            c = self.step()
            if c is not None:
                yield c


def call(gw: GatewayClient, req: NodeCall, patience_s: float = PATIENCE_S) -> bytes:
    """One call, to the end: its result bytes."""
    p = Pipeline(gw, 1, patience_s)
    p.start(None, req)
    return bytes(next(p.drain()).result)


def param_list(
    gw: GatewayClient, node_id: int, window: int = WINDOW, progress: Callable = None
) -> list[tuple[int, ParamResult]]:
    """Every parameter of a node, by index from 0 until the node says there
    is none (an empty name), with `window` calls in flight."""
    p = Pipeline(gw, window)
    found: dict[int, ParamResult] = {}
    end = PARAM_INDEX_MAX + 1  # the first index without a parameter
    nxt = 0
    while True:
        while not p.full() and nxt < end:
            p.start(nxt, NodeCall(0, node_id, CALL_PARAM_GET_INDEX, index=nxt))
            nxt += 1
        if not p.pending:
            break
        c = p.step()
        if c is None:
            continue
        r = ParamResult.decode(bytes(c.result))
        if not r.exists:
            end = min(end, c.key)
        elif c.key < end:
            found[c.key] = r
            if progress:
                progress(c.key, r)
    return sorted((i, r) for i, r in found.items() if i < end)


def param_result(gw: GatewayClient, req: NodeCall) -> ParamResult:
    return ParamResult.decode(call(gw, req))


def opcode_result(gw: GatewayClient, req: NodeCall) -> OpcodeResult:
    return OpcodeResult.decode(call(gw, req))
