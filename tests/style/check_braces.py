#!/usr/bin/env python3
"""Braces always in C (make style): every if/else/for/while/do body is a block.

    check_braces.py [FILE ...]

clang-format 14 (Debian 12) has no InsertBraces, so this check stands in for
it. Comments, strings and preprocessor lines are skipped. Default files: the
C files git tracks. Prints each brace-less body; exit 1 if there is one.
"""

import re
import subprocess
import sys
from pathlib import Path

from check_functions import strip_c

KEYWORD = re.compile(r"\b(if|for|while|else|do)\b")


def close_paren(text, i):
    """Index just past the parenthesis that closes the one at text[i]."""
    depth = 0
    for j in range(i, len(text)):
        if text[j] == "(":
            depth += 1
        elif text[j] == ")":
            depth -= 1
            if depth == 0:
                return j + 1
    return len(text)


def next_code(text, i):
    """Index of the first non-space character at or after i."""
    while i < len(text) and text[i].isspace():
        i += 1
    return i


def braceless(path):
    """Line numbers of the bodies in a C file that are not blocks."""
    text = strip_c(path.read_text(errors="replace"))
    text = re.sub(
        r"(?m)^[ \t]*#(?:[^\n]*\\\n)*[^\n]*", lambda m: re.sub(r"[^\n]", " ", m.group(0)), text
    )
    found = []
    for m in KEYWORD.finditer(text):
        word, at = m.group(1), m.end()
        if word in ("if", "for", "while"):
            paren = next_code(text, at)
            if paren >= len(text) or text[paren] != "(":
                continue
            body = next_code(text, close_paren(text, paren))
            before = text[: m.start()].rstrip()
            if word == "while" and before.endswith("}") and text[body : body + 1] == ";":
                continue  # the end of a do { } while (...);
        else:
            body = next_code(text, at)
            if word == "else" and text.startswith("if", body):
                continue
        if text[body : body + 1] != "{":
            found.append(text.count("\n", 0, m.start()) + 1)
    return found


def main():
    top = Path(__file__).resolve().parents[2]
    if sys.argv[1:]:
        files = [Path(n) for n in sys.argv[1:]]
    else:
        listed = subprocess.run(
            ["git", "ls-files", "*.c", "*.h"], cwd=top, capture_output=True, text=True, check=True
        )
        files = [top / n for n in listed.stdout.split()]
    bad = 0
    for f in files:
        for line in braceless(f):
            print(f"{f}:{line}: body without braces", file=sys.stderr)
            bad += 1
    if not bad:
        print(f"style: braces always ({len(files)} C files)")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
