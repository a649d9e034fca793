#!/usr/bin/env python3
"""Functions longer than a limit in Rust sources.

Usage: python3 tools/long_fns.py [--max LINES] DIR [DIR ...]

A function runs from the line of its `fn` keyword to the line of its closing brace; comments,
string and character literals are read as blanks (`module_cycles.blank`), so braces inside
them do not count. Test code counts like any other. Prints every function longer than --max lines (default 120) as
`lines  file:line  name`, longest first, and exits 1 when there is one, 0 otherwise.
"""
import argparse
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from module_cycles import blank  # noqa: E402  (the one scanner of Rust source)

FN_RE = re.compile(r"\bfn\s+([A-Za-z_][A-Za-z0-9_]*)")


def functions(text):
    """`(name, first line, last line)` of every function with a body in `text`."""
    code = blank(text)
    line_at = [0] * (len(code) + 1)
    line = 1
    for k, c in enumerate(code):
        line_at[k] = line
        if c == "\n":
            line += 1
    line_at[len(code)] = line
    for m in FN_RE.finditer(code):
        # The body opens at the first `{` outside the signature's parentheses; a `;` first
        # means a declaration without a body (a trait method, an extern fn).
        depth, k = 0, m.end()
        while k < len(code):
            c = code[k]
            if c in "([<":
                depth += 1
            elif c in ")]>" and depth > 0:
                depth -= 1
            elif c == ";" and depth == 0:
                k = -1
                break
            elif c == "{" and depth == 0:
                break
            k += 1
        if k < 0 or k >= len(code):
            continue
        braces, j = 0, k
        while j < len(code):
            if code[j] == "{":
                braces += 1
            elif code[j] == "}":
                braces -= 1
                if braces == 0:
                    break
            j += 1
        yield m.group(1), line_at[m.start()], line_at[min(j, len(code))]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--max", type=int, default=120, help="longest allowed function, in lines")
    ap.add_argument("dirs", nargs="+")
    a = ap.parse_args()
    long = []
    for d in a.dirs:
        if not os.path.isdir(d):
            ap.error(f"{d}: not a folder")
        for root, _, files in os.walk(d):
            for f in sorted(files):
                if f.endswith(".rs"):
                    path = os.path.join(root, f)
                    with open(path, encoding="utf-8") as fh:
                        text = fh.read()
                    for name, first, last in functions(text):
                        if last - first + 1 > a.max:
                            long.append((last - first + 1, f"{path}:{first}", name))
    for n, at, name in sorted(long, reverse=True):
        print(f"{n:5}  {at}  {name}")
    print(f"{len(long)} functions over {a.max} lines in {', '.join(a.dirs)}")
    return 1 if long else 0


if __name__ == "__main__":
    sys.exit(main())
