"""danprobe param: a DroneCAN node's parameters, through the gateway's
service calls (NODE_CALL / CALL_RESULT)."""

import argparse

from danprobe import gateway_calls, gateway_mgmt
from danprobe.commands.common import (
    UsageError,
    format_table,
    gateway_actions,
    gateway_operation,
    gateway_report,
    int_range,
    positive_int,
)
from danprobe.gateway_mgmt import NodeCall, ParamResult, Value
from danprobe.master import NotFound

NAME = "param"
HELP = "CAN gateway: a DroneCAN node's parameters: 'param list|get|set|save|erase --node N'"
DESCRIPTION = (
    "Reads and writes a DroneCAN node's parameters (uavcan.protocol.param.GetSet and "
    "ExecuteOpcode), made by the gateway for us. 'list' reads every parameter by index until "
    "the node says there is none, several calls in flight; 'get NAME'; 'set NAME VALUE' (the "
    "type is the parameter's own unless --type says it); 'save' and 'erase' (the node's "
    "stored parameters; erase takes effect at its next start on most nodes). Values show "
    "their type, default, min and max when the node gives them. A node that does not answer "
    "fails after the gateway's 3 attempts (about 3 s per call)."
)

TYPES = {
    "int": gateway_mgmt.VALUE_INTEGER,
    "real": gateway_mgmt.VALUE_REAL,
    "bool": gateway_mgmt.VALUE_BOOLEAN,
    "string": gateway_mgmt.VALUE_STRING,
}
TRUE = ("1", "true", "yes", "on")
FALSE = ("0", "false", "no", "off")


def add_node_option(p, what: str = "the node"):
    p.add_argument(
        "--node",
        type=int_range(1, gateway_mgmt.NODE_ID_MAX, "--node"),
        required=True,
        metavar="N",
        help=f"{what}'s DroneCAN node ID",
    )


def param_name(s: str) -> str:
    """An argument type: a parameter name of 1..92 bytes (DroneCAN's)."""
    if not 1 <= len(s.encode()) <= gateway_mgmt.PARAM_NAME_MAX:
        raise argparse.ArgumentTypeError(
            f"a parameter name is 1..{gateway_mgmt.PARAM_NAME_MAX} bytes: {s[:20]!r}..."
        )
    return s


def add_arguments(p):
    helps = {
        "list": "every parameter, by index",
        "get": "one parameter by name",
        "set": "set a parameter",
        "save": "ExecuteOpcode SAVE: the node stores its parameters",
        "erase": "ExecuteOpcode ERASE: the node erases its stored parameters",
    }
    for name, g in gateway_actions(p, "param", helps, DESCRIPTION):
        add_node_option(g)
        if name in ("get", "set"):
            g.add_argument("name", metavar="NAME", type=param_name, help="the parameter's name")
        if name == "set":
            g.add_argument("value", metavar="VALUE", help="the new value")
            g.add_argument(
                "--type",
                choices=sorted(TYPES),
                help="the value's type (default: the parameter's, read first)",
            )
        if name == "list":
            g.add_argument(
                "--window",
                type=positive_int,
                default=gateway_calls.WINDOW,
                metavar="N",
                help=f"calls in flight (default {gateway_calls.WINDOW}, at most 8)",
            )


def parse_value(text: str, tag: int) -> Value:
    """VALUE as a parameter value of type tag; ValueError says why not."""
    if tag == gateway_mgmt.VALUE_INTEGER:
        try:
            return Value.integer(int(text, 0))
        except ValueError:
            raise ValueError(f"{text!r} is not an integer") from None
    if tag == gateway_mgmt.VALUE_REAL:
        try:
            return Value.real(float(text))
        except (ValueError, OverflowError):
            raise ValueError(f"{text!r} is not a real number") from None
    if tag == gateway_mgmt.VALUE_BOOLEAN:
        if text.lower() not in TRUE + FALSE:
            raise ValueError(f"{text!r} is not a boolean ({'/'.join(TRUE)} or {'/'.join(FALSE)})")
        return Value.boolean(text.lower() in TRUE)
    if tag == gateway_mgmt.VALUE_STRING:
        return Value.string(text)
    raise ValueError("the parameter has no value (empty): give --type")


def param_row(index, p: ParamResult) -> dict:
    return {**({"index": index} if index is not None else {}), **p.as_dict()}


def describe(p: ParamResult) -> str:
    """ "esc_rate = 400 (integer; default 400, min 50, max 500)"."""
    extra = ", ".join(
        f"{k} {v.text()}"
        for k, v in (("default", p.default), ("min", p.min), ("max", p.max))
        if v is not None
    )
    inner = p.value.type_name + (f"; {extra}" if extra else "")
    return f"{p.name_text} = {p.value.text()} ({inner})"


def table(rows: list[tuple[int, ParamResult]]) -> str:
    out = [("index", "name", "type", "value", "default", "min", "max")]
    for i, p in rows:
        opt = [v.text() if v is not None else "" for v in (p.default, p.min, p.max)]
        out.append((str(i), p.name_text, p.value.type_name, p.value.text(), *opt))
    return format_table(out)


def _list(ctx, gw, res):
    a = ctx.args
    rows = gateway_calls.param_list(gw, a.node, min(a.window, 8))
    res["params"] = [param_row(i, p) for i, p in rows]
    res["human"] = lambda: print(
        f"param list: node {a.node}: {len(rows)} parameter(s)\n" + (table(rows) if rows else "")
    )


def _get(ctx, gw, name: str) -> ParamResult:
    p = gateway_calls.param_result(
        gw, NodeCall(0, ctx.args.node, gateway_mgmt.CALL_PARAM_GET_NAME, name=name.encode())
    )
    if not p.exists:
        raise NotFound(f"node {ctx.args.node} has no parameter {name!r}")
    return p


def _set(ctx, gw, res):
    a = ctx.args
    tag = TYPES[a.type] if a.type else _get(ctx, gw, a.name).value.tag
    try:
        value = parse_value(a.value, tag)
    except ValueError as e:
        raise UsageError(f"param set: {a.name}: {e}") from None
    call = NodeCall(0, a.node, gateway_mgmt.CALL_PARAM_SET, name=a.name.encode(), value=value)
    try:
        call.encode()
    except ValueError as e:
        raise UsageError(f"param set: {a.name}: {e}") from None
    p = gateway_calls.param_result(gw, call)
    if not p.exists:
        raise NotFound(f"node {a.node} has no parameter {a.name!r}")
    res["param"] = param_row(None, p)
    res["requested"] = value.plain()
    if p.value != value:
        raise Kept(f"node {a.node} kept {describe(p)} (asked {value.text()})")
    res["human"] = lambda: print(f"param set: node {a.node}: {describe(p)}")


def _opcode(ctx, gw, res):
    a = ctx.args
    op = (
        gateway_mgmt.CALL_PARAM_SAVE if a.param_command == "save" else gateway_mgmt.CALL_PARAM_ERASE
    )
    r = gateway_calls.opcode_result(gw, NodeCall(0, a.node, op))
    res.update(ok=r.ok, argument=r.argument)
    if not r.ok:
        raise Kept(f"node {a.node} answered {a.param_command}: not ok (argument {r.argument})")
    res["human"] = lambda: print(f"param {a.param_command}: node {a.node}: ok")


class Kept(NotFound):
    """The node answered, but did not do what was asked."""

    code, reason = -11, "refused"


def run(ctx) -> int:
    a = ctx.args
    if a.param_command == "set" and a.type:
        try:
            parse_value(a.value, TYPES[a.type])  # a bad VALUE is found before the bus is
        except ValueError as e:
            raise UsageError(f"param set: {e}") from None
    res = {}

    def op(m, gw):
        if a.param_command == "list":
            _list(ctx, gw, res)
        elif a.param_command == "get":
            p = _get(ctx, gw, a.name)
            res["param"] = param_row(None, p)
            res["human"] = lambda: print(f"param get: node {a.node}: {describe(p)}")
        elif a.param_command == "set":
            _set(ctx, gw, res)
        else:
            _opcode(ctx, gw, res)

    m, failure, ms = gateway_operation(ctx, op)
    human = res.pop("human", lambda: None)
    return gateway_report(
        ctx, m, failure, ms, {"action": a.param_command, "node": a.node, **res}, human
    )
