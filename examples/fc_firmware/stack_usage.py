"""Worst-case stack of libdan's public calls, from GCC's -fcallgraph-info=su.

Each object's .ci file (VCG) names its functions with their own frame
("N bytes (static)") and their direct calls. The worst case of a call is
its frame plus the deepest path below it. Calls through a pointer are
resolved with INDIRECT (the library's own callbacks); the rest are the
caller's port callbacks (write, set_baud, ...), whose stack is the
firmware's and not counted. Functions with no .ci node (libc's mem*, in
assembly) get their frame from the image's disassembly (push + sub sp).
Recursion would make the sum unbounded: it is reported as an error.
"""

import glob
import os
import re
import subprocess

# Pointer calls inside the library: caller -> the functions it may reach.
# deliver_frames calls link.on_frame (the master's on_frame); on_frame calls
# the reply check the gateway client installs (check_seal); probe_accept
# (inlined into dan_mst_seq_txn_done) the identity decoder
# dan_master_set_identities() installs;
# dan_gw_complete the decoder the call in flight named (gw_client_internal.h).
GW_DONE = ("telem", "fast", "flags", "config", "stats", "tun_open", "xfer", "can_send")
GW_DONE += ("can_recv", "call", "health")
INDIRECT = {
    "link.c:deliver_frames": ["master.c:on_frame"],
    "master.c:on_frame": ["gw_client.c:check_seal"],
    "master_seq.c:probe_accept": ["dan_identity_decode"],
    "dan_mst_seq_txn_done": ["dan_identity_decode"],
    "dan_gw_complete": ["dan_gwc_done_" + d for d in GW_DONE],
}

NODE_RE = re.compile(r'^node: \{ title: "([^"]+)" label: "([^"]*)"')
EDGE_RE = re.compile(r'^edge: \{ sourcename: "([^"]+)" targetname: "([^"]+)"')
FRAME_RE = re.compile(r"\\n(\d+) bytes \((static|dynamic[^)]*)\)")


def short(title):
    """'src/link.c:end_tx' -> 'link.c:end_tx'; 'dan_link_rx' stays."""
    if ":" not in title:
        return title
    path, name = title.rsplit(":", 1)
    return os.path.basename(path) + ":" + name


def read_ci(ci_dir):
    """frames {fn: (bytes, static?)}, calls {fn: set(callees)}, indirect {fn: n}."""
    frames, calls, indirect = {}, {}, {}
    for path in glob.glob(os.path.join(ci_dir, "**", "*.ci"), recursive=True):
        for line in open(path):
            m = NODE_RE.match(line)
            if m:
                f = FRAME_RE.search(m.group(2))
                if f:
                    frames[short(m.group(1))] = (int(f.group(1)), f.group(2) == "static")
                continue
            m = EDGE_RE.match(line)
            if m:
                src, dst = short(m.group(1)), short(m.group(2))
                if dst == "__indirect_call":
                    indirect[src] = indirect.get(src, 0) + 1
                else:
                    calls.setdefault(src, set()).add(dst)
    for src, dsts in INDIRECT.items():
        calls.setdefault(src, set()).update(dsts)
    return frames, calls, indirect


def asm_frames(objdump, elf, names):
    """Frames of assembly functions (libc) from the image: push + sub sp."""
    out = subprocess.run([objdump, "-d", elf], capture_output=True, text=True, check=True).stdout
    frames, cur = {}, None
    for line in out.splitlines():
        m = re.match(r"^[0-9a-f]+ <(\S+)>:$", line)
        if m:
            cur = m.group(1) if m.group(1) in names else None
            continue
        if cur is None:
            continue
        m = re.search(r"\tpush(?:\.w)?\t\{([^}]*)\}", line)
        if m:
            frames[cur] = frames.get(cur, 0) + 4 * len(m.group(1).split(","))
        m = re.search(r"\tsub(?:\.w)?\tsp, #(\d+)", line)
        if m:
            frames[cur] = frames.get(cur, 0) + int(m.group(1))
    return frames


def worst_case(frames, calls, linked):
    """{fn: (worst bytes, path)} for every linked function; raises on recursion."""
    memo = {}

    def walk(fn, stack):
        if fn in memo:
            return memo[fn]
        if fn in stack:
            raise ValueError("recursion: " + " -> ".join(stack + [fn]))
        own = frames.get(fn, (0, True))[0]
        best, path = 0, []
        for callee in sorted(calls.get(fn, ())):
            if callee.split(":")[-1] not in linked:
                continue
            sub, sub_path = walk(callee, stack + [fn])
            if sub > best:
                best, path = sub, sub_path
        memo[fn] = (own + best, [fn] + path)
        return memo[fn]

    return {fn: walk(fn, []) for fn in frames if fn.split(":")[-1] in linked}


# Internal functions shared by the library's files, not public calls.
INTERNAL_PREFIXES = ("dan_mst_", "dan_gwc_")


def report(ci_dir, objdump, elf, linked, public_prefixes=("dan_",)):
    """(rows sorted worst first [(fn, bytes, path)], port-callback call count, notes)."""
    frames, calls, indirect = read_ci(ci_dir)
    notes = [f"{fn}: dynamic frame" for fn, (_, st) in frames.items() if not st and fn in linked]
    helpers = {c for cs in calls.values() for c in cs if c not in frames and c in linked}
    for fn, size in asm_frames(objdump, elf, helpers).items():
        frames[fn] = (size, True)
    worst = worst_case(frames, calls, linked)
    rows = sorted(
        (
            (fn, n, p)
            for fn, (n, p) in worst.items()
            if ":" not in fn
            and fn.startswith(public_prefixes)
            and not fn.startswith(INTERNAL_PREFIXES)
        ),
        key=lambda r: -r[1],
    )
    port_calls = sum(
        n for fn, n in indirect.items() if fn not in INDIRECT and fn.split(":")[-1] in linked
    )
    return rows, port_calls, notes
