#!/usr/bin/env python3
"""Flash and RAM of libdan's parts in a Cortex-M4 image, from GNU ld map files.

    size_report.py --base probe0.map --image probe2.map [--full probe3.map]
                   --nm NM --elf probe2.elf --flash-budget N --ram-budget N

Per part: the input sections the linker kept (--gc-sections) from the
part's objects, flash = .text/.rodata/.data init, RAM = .data + .bss.
The caller-owned state (one dan_master_t and one dan_gw_t per bus) is RAM
too; its sizes come from the probe's symbols. Exit 1 if over a budget.
"""

import argparse
import os
import re
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import stack_usage  # noqa: E402

PARTS = [
    ("codec", ("common.o", "crc8.o", "crc8_nibble.o", "frame.o", "payloads.o")),
    ("master engine", ("link.o", "master.o", "master_seq.o")),
    (
        "gateway client",
        ("gw_client.o", "gw_client_can.o", "gw_client_mgmt.o", "gw_client_out.o", "gw_client_any.o")
        + ("gw_msgs.o", "gw_msgs_fast.o", "gw_msgs_mgmt.o", "gw_msgs_out.o")
        + ("f16.o", "crc16.o", "gw_esc_map.o"),
    ),
]
LIB_PARTS = [p for p, _ in PARTS]
LIBC = "libc/libgcc helpers"
# Every firmware links these anyway (issue 17): any other helper (64-bit
# division, float, printf-like) the library pulls in fails the budget.
FAIR_HELPERS = ("memcpy", "memmove", "memset", "memcmp", "memchr")
# Issue 17's goals: what an FC links (codec, master, the ESC calls) in 4 KiB
# of flash, 640 B of RAM per bus (its caller-owned state, telemetry of 4
# ESCs), 256 B of stack for any public call.
GOALS = {"flash": 4096, "ram": 640, "stack": 256}
# ../shared/notes/size-anchors.md (same compiler, -Os, --gc-sections).
ANCHORS = [
    ("MAVLink2 parser only (common.xml, no signing)", 3392, 632),
    ("MAVLink2 parser + one send (no signing)", 3716, 632),
    ("libcanard DroneCAN transport + 1 KiB pool", 3992, 1072),
    ("bare DAN-style decoder, 256-byte crc8 table", 508, 272),
]


def part_of(obj):
    name = obj.rsplit("/", 1)[-1]
    if "(" in obj or obj.startswith("/usr"):
        return LIBC
    for part, objs in PARTS:
        if name in objs:
            return part
    return "probe"


def parse_map(path):
    """{part: [flash, ram]} and {(part, symbol-ish section): size}."""
    sizes, sections = {}, {}
    in_map, out_sec, pending = False, None, None
    sec_re = re.compile(r"^\s+(0x[0-9a-f]+)\s+(0x[0-9a-f]+)\s+(\S.*)$")
    for line in open(path):
        line = line.rstrip("\n")
        if line.startswith("Linker script and memory map"):
            in_map = True
            continue
        if not in_map:
            continue
        if line and not line[0].isspace():
            out_sec = line.split()[0]
            pending = None
            continue
        m = re.match(r"^ (\.\S+|COMMON)\s*$", line)
        if m:
            pending = m.group(1)
            continue
        m = re.match(r"^ (\.\S+|COMMON)\s+(0x[0-9a-f]+)\s+(0x[0-9a-f]+)\s+(\S.*)$", line)
        if m:
            name, size, obj = m.group(1), int(m.group(3), 16), m.group(4)
        else:
            m = sec_re.match(line)
            if not (m and pending):
                pending = None
                continue
            name, size, obj = pending, int(m.group(2), 16), m.group(3)
        pending = None
        if size == 0 or out_sec not in (".text", ".data", ".bss", ".ARM.exidx"):
            continue
        part = part_of(obj)
        s = sizes.setdefault(part, [0, 0])
        if out_sec in (".text", ".ARM.exidx", ".data"):
            s[0] += size
        if out_sec in (".data", ".bss"):
            s[1] += size
        if part == LIBC:  # one object per helper: lib_a-memcpy.o, _udivmoddi4.o
            name = re.sub(r"^(lib_a-|_arm_|_)|\.o\)$", "", obj.rsplit("(", 1)[-1])
        key = (part, name)
        sections[key] = sections.get(key, 0) + size
    return sizes, sections


def total(sizes, parts=None):
    f = r = 0
    for p, (a, b) in sizes.items():
        if parts is None or p in parts:
            f += a
            r += b
    return f, r


def symbol_sizes(nm, elf):
    out = subprocess.run(
        [nm, "--size-sort", "-S", "-C", elf], capture_output=True, text=True, check=True
    ).stdout
    syms = {}
    for line in out.splitlines():
        f = line.split()
        if len(f) == 4:
            syms[f[3]] = (int(f[1], 16), f[2])
    # absolute symbols (the probe's constants, e.g. probe_esc_slot): their value
    out = subprocess.run([nm, elf], capture_output=True, text=True, check=True).stdout
    for line in out.splitlines():
        f = line.split()
        if len(f) == 3 and f[1] in "aA":
            syms[f[2]] = (int(f[0], 16), f[1])
    return syms


def print_libc(secs):
    """Each helper the library pulls in; False if one is not fair."""
    helpers = sorted(
        ((sz, name) for (part, name), sz in secs.items() if part == LIBC), reverse=True
    )
    unfair = [n for _, n in helpers if n not in FAIR_HELPERS]
    print("  libc/libgcc: " + ", ".join(f"{n} {sz}" for sz, n in helpers))
    if unfair:
        print(f"FAIL: helpers beyond mem* pulled in: {', '.join(unfair)}", file=sys.stderr)
    return not unfair


def print_anchors(lib_flash, ram_bus):
    print("anchors (../shared/notes/size-anchors.md)           flash   RAM   libdan's / anchor")
    for name, f, r in ANCHORS:
        print(f"  {name:<48} {f:>6} {r:>5}   {lib_flash / f:4.1f}x / {ram_bus / r:4.1f}x")


def print_stack(a, syms):
    """Worst-case stack per public call; False over the budget or on recursion."""
    linked = {name for name, (_, kind) in syms.items() if kind.lower() == "t"}
    try:
        rows, port_calls, notes = stack_usage.report(a.ci_dir, a.objdump, a.elf, linked)
    except ValueError as e:
        print(f"FAIL: stack: {e}", file=sys.stderr)
        return False
    print(
        "worst-case stack per public call (-fcallgraph-info=su, call-graph sum; "
        f"the port callbacks' own stack not included, {port_calls} call sites):"
    )
    for fn, n, path in rows[:6]:
        print(f"  {n:>5}  {fn:<28} via {' > '.join(p.split(':')[-1] for p in path[1:4])}")
    for note in notes:
        print(f"  note: {note}")
    worst = rows[0][1] if rows else 0
    print(
        f"budget: stack {worst} / {a.stack_budget} bytes (worst public call; goal {GOALS['stack']})"
    )
    if worst > a.stack_budget:
        print(f"FAIL: stack {worst} > budget {a.stack_budget}", file=sys.stderr)
        return False
    return True


def print_parts(img, full_map, nibble_map):
    print(f"{'part':<44} {'flash':>6} {'RAM':>5}   goal")
    for part in LIB_PARTS + [p for p in img if p not in LIB_PARTS and p != "probe"]:
        f, r = img.get(part, (0, 0))
        print(f"{part:<44} {f:>6} {r:>5}")
    lf, lr = total(img, LIB_PARTS)
    print(f"{'libdan total (codec + master + gateway)':<44} {lf:>6} {lr:>5}   {GOALS['flash']}")
    if nibble_map:
        nib, _ = parse_map(nibble_map)
        nf, _ = total(nib, LIB_PARTS)
        cf = nib.get("codec", (0, 0))[0]
        print(f"{'  the same, DAN_CRC8_TABLE=0 (nibble table)':<44} {nf:>6}   (codec {cf})")
    if full_map:
        full, _ = parse_map(full_map)
        ff, fr = full.get("gateway client", (0, 0))
        print(f"{'gateway client, whole API (tunnels, CAN, ...)':<44} {ff:>6} {fr:>5}")
        print(
            f"{'  of it linked only when called':<44} {ff - img.get('gateway client', (0, 0))[0]:>6}"
        )
    return lf, lr


def print_symbols(secs):
    print("biggest libdan symbols (flash):")
    lib_secs = sorted(
        ((sz, part, name) for (part, name), sz in secs.items() if part in LIB_PARTS), reverse=True
    )[:12]
    for sz, part, name in lib_secs:
        sym = re.sub(r"^\.(text|rodata|data|bss)\.", "", name)
        print(f"  {sz:>5}  {sym:<36} {part}")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--base", required=True)
    ap.add_argument("--image", required=True)
    ap.add_argument("--full")
    ap.add_argument("--nibble", help="the image's map with DAN_CRC8_TABLE=0")
    ap.add_argument("--elf", required=True)
    ap.add_argument("--nm", default="arm-none-eabi-nm")
    ap.add_argument("--objdump", default="arm-none-eabi-objdump")
    ap.add_argument("--ci-dir", required=True, help="where the objects' .ci files are")
    ap.add_argument("--flash-budget", type=int, required=True)
    ap.add_argument("--ram-budget", type=int, required=True)
    ap.add_argument("--stack-budget", type=int, required=True)
    a = ap.parse_args()

    base, _ = parse_map(a.base)
    img, secs = parse_map(a.image)
    bf, br = total(base)
    tf, tr = total(img)
    syms = symbol_sizes(a.nm, a.elf)
    master_ram = syms.get("probe_master", (0, ""))[0]
    gw_ram = syms.get("probe_gw", (0, ""))[0]

    print(
        "libdan on Cortex-M4 (arm-none-eabi-gcc -mcpu=cortex-m4 -mthumb -Os, "
        "-ffunction-sections -fdata-sections, --gc-sections)"
    )
    lf, lr = print_parts(img, a.full, a.nibble)
    ok = print_libc(secs)
    print(
        f"{'image delta over a minimal image':<44} {tf - bf:>6} {tr - br:>5}"
        "   (includes the per-bus state below)"
    )
    slot = syms.get("probe_esc_slot", (0, ""))[0]
    print(f"{'per bus: dan_master_t (caller-owned)':<44} {'':>6} {master_ram:>5}")
    print(f"{'per bus: dan_gw_t (caller-owned)':<44} {'':>6} {gw_ram:>5}")
    print(f"{'  of it per ESC slot (DAN_GW_MAX_ESC: 4)':<44} {'':>6} {slot:>5}")
    ram_bus = lr + master_ram + gw_ram
    print(f"{'per bus, total':<44} {'':>6} {ram_bus:>5}   {GOALS['ram']}")
    print_symbols(secs)
    print_anchors(lf, ram_bus)
    ok = print_stack(a, syms) and ok
    print(
        f"budget: flash {lf} / {a.flash_budget} bytes, "
        f"RAM per bus {ram_bus} / {a.ram_budget} bytes (library static {lr} + state {master_ram + gw_ram})"
    )
    if lf > a.flash_budget:
        print(f"FAIL: libdan flash {lf} > budget {a.flash_budget}", file=sys.stderr)
        ok = False
    if ram_bus > a.ram_budget:
        print(f"FAIL: RAM per bus {ram_bus} > budget {a.ram_budget}", file=sys.stderr)
        ok = False
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
