#!/usr/bin/env python3
"""No function over MAX lines in the product and its tools (make style).

    check_functions.py [--max N] [--top K] [PATH ...]

C: a function runs from the first line of its signature to its closing
brace (comments and strings are skipped when matching braces). Python:
from `def` to the function's last line; nested functions count on their
own. Prints the longest K and every function over the limit; exit 1 if
there is one.
"""

import argparse
import ast
import re
import sys
from pathlib import Path

ROOTS = ["src", "include", "peripherals", "host_tools", "tests/tools", "examples"]
MAX_LINES = 100
C_KEYWORDS = {"if", "while", "for", "switch", "return", "sizeof", "do"}


def strip_c(text):
    """The text with comments, strings and char literals blanked (newlines
    kept, so line numbers stay)."""
    out, i, n = [], 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append(re.sub(r"[^\n]", " ", text[i:j]))
            i = j
        elif text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            out.append(" " * (j - i))
            i = j
        elif c in "\"'":
            j = i + 1
            while j < n and text[j] != c:
                j += 2 if text[j] == "\\" else 1
            out.append(c + re.sub(r"[^\n]", " ", text[i + 1 : j]) + c)
            i = j + 1
        else:
            out.append(c)
            i += 1
    return "".join(out)


def c_functions(path):
    """(name, first line, last line) of each function defined in a C file."""
    text = strip_c(path.read_text(errors="replace"))
    # preprocessor lines, with their continuations, are not code
    text = re.sub(
        r"(?m)^[ \t]*#(?:[^\n]*\\\n)*[^\n]*", lambda m: re.sub(r"[^\n]", " ", m.group(0)), text
    )
    funcs, depth, head_start, i = [], 0, 0, 0
    line_of = [0] * (len(text) + 1)
    line = 1
    for k, ch in enumerate(text):
        line_of[k] = line
        if ch == "\n":
            line += 1
    start = None
    for i, ch in enumerate(text):
        if ch == "{":
            if depth == 0:
                head = text[head_start:i]
                m = re.search(r"([A-Za-z_]\w*)\s*\([^;{}]*\)\s*$", head)
                if (
                    m
                    and m.group(1) not in C_KEYWORDS
                    and "=" not in head.split("(")[0]
                    and not re.search(r"\b(struct|enum|union)\b\s*\w*\s*$", head)
                ):
                    first = head_start + len(head) - len(head.lstrip())
                    start = (m.group(1), line_of[first])
                else:
                    start = None
            depth += 1
        elif ch == "}":
            depth -= 1
            if depth == 0:
                if start:
                    funcs.append((start[0], start[1], line_of[i]))
                start = None
                head_start = i + 1
        elif ch == ";" and depth == 0:
            head_start = i + 1
    return funcs


def py_functions(path):
    tree = ast.parse(path.read_text(), str(path))
    return [
        (node.name, node.lineno, node.end_lineno)
        for node in ast.walk(tree)
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
    ]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--max", type=int, default=MAX_LINES)
    ap.add_argument("--top", type=int, default=0, help="also print the K longest")
    ap.add_argument("paths", nargs="*", help=f"files or folders (default: {' '.join(ROOTS)})")
    args = ap.parse_args()
    top = Path(__file__).resolve().parents[2]
    paths = [Path(p) for p in args.paths] or [top / r for r in ROOTS]
    files = []
    for p in paths:
        files += [p] if p.is_file() else sorted(p.rglob("*"))
    rows = []
    for f in files:
        if ".venv" in f.parts or "build" in f.parts:
            continue
        if f.suffix in (".c", ".h"):
            found = c_functions(f)
        elif f.suffix == ".py":
            found = py_functions(f)
        else:
            continue
        rel = f.resolve().relative_to(top) if f.resolve().is_relative_to(top) else f
        rows += [(last - first + 1, f"{rel}:{first}", name) for name, first, last in found]
    rows.sort(reverse=True)
    for n, where, name in rows[: args.top]:
        print(f"{n:5d}  {name}  {where}")
    over = [r for r in rows if r[0] > args.max]
    for n, where, name in over:
        print(f"function over {args.max} lines: {name} ({n} lines) at {where}", file=sys.stderr)
    if not over:
        print(f"style: no function over {args.max} lines ({len(rows)} functions)")
    return 1 if over else 0


if __name__ == "__main__":
    sys.exit(main())
