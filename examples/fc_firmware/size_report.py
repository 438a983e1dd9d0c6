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
import re
import subprocess
import sys

PARTS = [
    ("codec", ("common.o", "crc8.o", "frame.o", "payloads.o")),
    ("master engine", ("link.o", "master.o", "master_seq.o", "master_fast.o")),
    ("gateway client", ("gw_client.o", "gw_msgs.o", "gw_msgs_fast.o", "f16.o", "crc16.o")),
]
LIB_PARTS = [p for p, _ in PARTS]


def part_of(obj):
    name = obj.rsplit("/", 1)[-1]
    if "(" in obj or obj.startswith("/usr"):
        return "libc/libgcc (memcpy, 64-bit division, ...)"
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
    return syms


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--base", required=True)
    ap.add_argument("--image", required=True)
    ap.add_argument("--full")
    ap.add_argument("--elf", required=True)
    ap.add_argument("--nm", default="arm-none-eabi-nm")
    ap.add_argument("--flash-budget", type=int, required=True)
    ap.add_argument("--ram-budget", type=int, required=True)
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
    print(f"{'part':<44} {'flash':>6} {'RAM':>5}")
    for part in LIB_PARTS + [p for p in img if p not in LIB_PARTS and p != "probe"]:
        f, r = img.get(part, (0, 0))
        print(f"{part:<44} {f:>6} {r:>5}")
    lf, lr = total(img, LIB_PARTS)
    print(f"{'libdan total (codec + master + gateway)':<44} {lf:>6} {lr:>5}")
    print(
        f"{'image delta over a minimal image':<44} {tf - bf:>6} {tr - br:>5}"
        "   (includes the per-bus state below)"
    )
    print(f"{'per bus: dan_master_t (caller-owned)':<44} {'':>6} {master_ram:>5}")
    print(f"{'per bus: dan_gw_t (caller-owned)':<44} {'':>6} {gw_ram:>5}")
    if a.full:
        full, _ = parse_map(a.full)
        ff, fr = full.get("gateway client", (0, 0))
        print(f"{'gateway client, whole API (tunnels, CAN, ...)':<44} {ff:>6} {fr:>5}")
    print("biggest libdan symbols (flash):")
    lib_secs = sorted(
        ((sz, part, name) for (part, name), sz in secs.items() if part in LIB_PARTS), reverse=True
    )[:12]
    for sz, part, name in lib_secs:
        sym = re.sub(r"^\.(text|rodata|data|bss)\.", "", name)
        print(f"  {sz:>5}  {sym:<36} {part}")
    ram_bus = lr + master_ram + gw_ram
    ok = True
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
