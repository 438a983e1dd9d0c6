#!/usr/bin/env python3
"""Line coverage of the fuzz corpus (make fuzz-cov, tests/fuzz/fuzz.mk).

Prints a table per source file (code lines, lines missed, percent) and the
total, and writes OUT/uncovered.txt (each missed line range with its first
source line) and OUT/report.txt (the table). --fail-under P exits 1 when
the total is below P percent (0: never).

    cov_report.py --llvm-cov llvm-cov-14 --profdata P --out DIR \
        --object BIN [--object BIN ...] SOURCE...
"""

import argparse
import json
import subprocess
import sys
from pathlib import Path


def llvm_cov(args, cmd, extra):
    objs = []
    for i, o in enumerate(args.object):
        objs += [o] if i == 0 else ["-object", o]
    run = [args.llvm_cov, cmd, *objs, f"-instr-profile={args.profdata}", *extra, *args.sources]
    return subprocess.run(run, check=True, capture_output=True, text=True).stdout


def summaries(args):
    data = json.loads(llvm_cov(args, "export", ["-format=text", "-summary-only"]))
    return {f["filename"]: f["summary"]["lines"] for f in data["data"][0]["files"]}


def uncovered(args):
    """{file: [(first, last, text of first)]} from llvm-cov show's text."""
    out, cur, run = {}, None, None
    for line in llvm_cov(args, "show", ["-show-line-counts"]).splitlines():
        if line.endswith(":") and "|" not in line:
            cur = line[:-1]
            out[cur] = []
            run = None
            continue
        parts = line.split("|", 2)
        if cur is None or len(parts) < 3 or not parts[0].strip().isdigit():
            continue
        num, count, text = int(parts[0]), parts[1].strip(), parts[2]
        if count == "0":
            if run is not None and run[1] == num - 1:
                run[1] = num
            else:
                run = [num, num, text.strip()]
                out[cur].append(run)
        elif count:
            run = None
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--llvm-cov", required=True)
    ap.add_argument("--profdata", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--object", action="append", required=True)
    ap.add_argument("--fail-under", type=float, default=0.0)
    ap.add_argument("sources", nargs="+")
    args = ap.parse_args()
    root = str(Path.cwd()) + "/"
    sums = summaries(args)
    gaps = uncovered(args)
    rows, total, covered = [], 0, 0
    for name in sorted(sums):
        s = sums[name]
        total += s["count"]
        covered += s["covered"]
        short = name.replace(root, "")
        rows.append(
            f"{short:48s} {s['count']:6d} {s['count'] - s['covered']:6d} {s['percent']:6.1f} %"
        )
    pct = 100.0 * covered / total if total else 100.0
    table = [f"{'file':48s} {'lines':>6s} {'missed':>6s} {'cover':>8s}", *rows]
    table.append(f"{'TOTAL':48s} {total:6d} {total - covered:6d} {pct:6.1f} %")
    out = Path(args.out)
    (out / "report.txt").write_text("\n".join(table) + "\n")
    with open(out / "uncovered.txt", "w") as f:
        for name in sorted(gaps):
            if gaps[name]:
                f.write(f"{name.replace(root, '')}:\n")
                for a, b, text in gaps[name]:
                    span = f"{a}" if a == b else f"{a}-{b}"
                    f.write(f"  {span:>9s}  {text[:90]}\n")
    print("\n".join(table))
    print(f"\nmissed lines: {out / 'uncovered.txt'}")
    if args.fail_under > 0 and pct < args.fail_under:
        print(f"coverage {pct:.1f} % is below {args.fail_under} %", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
