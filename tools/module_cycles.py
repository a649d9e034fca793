#!/usr/bin/env python3
"""Module-level dependency graph of a Rust crate, and its cycles.

Usage: python3 tools/module_cycles.py CRATE_SRC_DIR [CRATE_SRC_DIR ...] [--graph]

A node is a module: a file (`foo.rs`, `foo/mod.rs`); an inline `mod name { ... }` is
folded into the file that holds it (its `super::` paths resolve from the inline module). An edge M -> N means that M names an item of N through
`crate::...`, `super::...` or `self::...` paths (in `use` items or in expressions). Paths
through a module's `pub use` re-exports are followed to the module that defines the item, so
`use crate::Error` from inside the crate counts as an edge to `error`, not to the crate root.
A parent that merely declares `mod child;` does not depend on it. Test code (from a
`#[cfg(test)]` line to the end of the file) is ignored.

Exit status 1 when any crate has a cycle (each strongly connected component is printed),
0 otherwise.
"""
import os
import re
import sys

IDENT = r"[A-Za-z_][A-Za-z0-9_]*"
PATH_RE = re.compile(r"\b(crate|super|self)((?:\s*::\s*(?:" + IDENT + r"|\{))+)")


def module_files(src):
    """Map module path tuple -> file path for every .rs file under src."""
    mods = {}
    for root, _, files in os.walk(src):
        for f in files:
            if not f.endswith(".rs"):
                continue
            full = os.path.join(root, f)
            rel = os.path.relpath(full, src)
            parts = rel[:-3].split(os.sep)
            if parts[-1] in ("mod", "lib", "main"):
                parts = parts[:-1]
            if parts and parts[0] == "bin":
                continue  # binaries are separate crates
            mods[tuple(parts)] = full
    return mods


def blank(text):
    """`text` with comments and literals replaced by spaces (newlines kept, so line numbers
    stay)."""
    out = []
    i, n = 0, len(text)

    def skip(j):
        out.extend("\n" if c == "\n" else " " for c in text[i:j])

    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            skip(j)
            i = j
        elif text.startswith("/*", i):
            depth, j = 1, i + 2
            while j < n and depth:
                if text.startswith("/*", j):
                    depth, j = depth + 1, j + 2
                elif text.startswith("*/", j):
                    depth, j = depth - 1, j + 2
                else:
                    j += 1
            skip(j)
            i = j
        elif c in "rb" and (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == "_")) \
                and re.match(r'b?r(#*)"', text[i:i + 12]):
            m = re.match(r'b?r(#*)"', text[i:])
            end = text.find('"' + m.group(1), i + len(m.group(0)))
            j = n if end < 0 else end + 1 + len(m.group(1))
            skip(j)
            i = j
        elif c == '"':
            j = i + 1
            while j < n and text[j] != '"':
                j += 2 if text[j] == "\\" else 1
            skip(j + 1)
            i = j + 1
        elif c == "'" and re.match(r"'(\\[^']{1,10}|[^\\'])'", text[i:i + 14]):
            j = i + len(re.match(r"'(\\[^']{1,10}|[^\\'])'", text[i:i + 14]).group(0))
            skip(j)
            i = j
        else:
            out.append(c)
            i += 1
    return "".join(out)


def strip(text):
    """Source without comments, string and char literals (blanked), and test code."""
    text = blank(text)
    m = re.search(r"#\[cfg\(test\)\]", text)
    if m:
        text = text[: m.start()]
    return text


def expand_use_tree(prefix, tree):
    """Expand a `use` tree body like `a::{b, c::d}` into full paths."""
    tree = tree.strip()
    out = []
    depth = 0
    start = 0
    parts = []
    for i, ch in enumerate(tree):
        if ch == "{":
            depth += 1
        elif ch == "}":
            depth -= 1
        elif ch == "," and depth == 0:
            parts.append(tree[start:i])
            start = i + 1
    parts.append(tree[start:])
    for p in parts:
        p = p.strip()
        if not p:
            continue
        if "{" in p:
            head, _, rest = p.partition("{")
            rest = rest[: rest.rfind("}")]
            head = [h for h in head.split("::") if h.strip()]
            out.extend(expand_use_tree(prefix + [h.strip() for h in head], rest))
        else:
            p = re.sub(r"\s+as\s+" + IDENT, "", p)
            out.append(prefix + [s.strip() for s in p.split("::") if s.strip()])
    return out


def referenced_paths(text):
    """Every crate/super/self path in the text, as lists of segments."""
    paths = []
    for m in re.finditer(r"\buse\s+((?:crate|super|self)\b[^;]*);", text):
        body = m.group(1)
        paths.extend(expand_use_tree([], body))
    for m in PATH_RE.finditer(text):
        segs = [m.group(1)]
        tail = m.group(2)
        grouped = False
        for s in re.split(r"\s*::\s*", tail):
            s = s.strip()
            if not s:
                continue
            if s == "{":
                grouped = True  # `use a::{...}`: the use-tree expansion above names the items
                break
            segs.append(s)
        if not grouped:
            paths.append(segs)
    return paths


def inline_modules(text):
    """Split a file's text into (relative module path, text) pieces: each inline
    `mod name { ... }` (nested ones too) is its own piece, so that its `super::` and `self::`
    resolve from the inline module; the rest of the file is the piece with path []."""
    pieces = []

    def walk(rel, body):
        out, i = [], 0
        for m in re.finditer(r"\bmod\s+(" + IDENT + r")\s*\{", body):
            if m.start() < i:
                continue
            depth, j = 1, m.end()
            while j < len(body) and depth:
                if body[j] == "{":
                    depth += 1
                elif body[j] == "}":
                    depth -= 1
                j += 1
            out.append(body[i : m.start()])
            walk(rel + [m.group(1)], body[m.end() : j - 1])
            i = j
        out.append(body[i:])
        pieces.append((rel, "".join(out)))

    walk([], text)
    return pieces


def resolve(current, segs):
    """Absolute segment list of a crate/super/self path from module `current`."""
    if not segs:
        return None
    head = segs[0]
    if head == "crate":
        return list(segs[1:])
    base = list(current)
    i = 0
    while i < len(segs) and segs[i] in ("super", "self"):
        if segs[i] == "super":
            if not base:
                return None
            base = base[:-1]
        i += 1
    return base + list(segs[i:])


def main(argv):
    show_graph = "--graph" in argv
    srcs = [a for a in argv if not a.startswith("--")]
    if not srcs:
        print(__doc__)
        return 2
    bad = False
    for src in srcs:
        mods = module_files(src)
        texts = {m: strip(open(f, encoding="utf-8").read()) for m, f in mods.items()}
        # Re-exports: module -> {name: absolute path of the item}.
        reexports = {m: {} for m in mods}
        for m, t in texts.items():
            for u in re.finditer(r"\bpub(?:\([^)]*\))?\s+use\s+([^;]*);", t):
                for p in expand_use_tree([], u.group(1)):
                    if not p or p[-1] in ("*",):
                        continue
                    if p[0] in ("crate", "super", "self"):
                        ab = resolve(m, p)
                    elif p[0] in [k[-1] for k in mods if len(k) == len(m) + 1 and k[:-1] == m]:
                        ab = list(m) + p
                    else:
                        continue  # an external crate
                    if ab:
                        reexports[m][p[-1]] = ab

        def owner(path, seen=0):
            """The module that defines the item named by an absolute path."""
            best = ()
            for k in range(len(path), -1, -1):
                if tuple(path[:k]) in mods:
                    best = tuple(path[:k])
                    break
            rest = path[len(best):]
            if rest and rest[0] in reexports.get(best, {}) and seen < 16:
                return owner(reexports[best][rest[0]] + rest[1:], seen + 1)
            return best

        edges = {m: set() for m in mods}
        for m, t in texts.items():
            # Sub-modules declared here: bare `child::x` paths count as edges too.
            children = {k[-1] for k in mods if len(k) == len(m) + 1 and k[:-1] == m}
            for rel, piece in inline_modules(t):
                here = tuple(list(m) + rel)
                for segs in referenced_paths(piece):
                    ab = resolve(here, segs)
                    if ab is None:
                        continue
                    o = owner(ab)
                    if o != m and not (len(o) > len(m) and o[: len(m)] == m and len(ab) == len(o)):
                        edges[m].add(o)
            for c in children:
                for u in re.finditer(r"(?<![:\w])" + c + r"\s*::\s*(" + IDENT + ")", t):
                    o = owner(list(m) + [c, u.group(1)])
                    if o != m:
                        edges[m].add(o)
        # Tarjan's strongly connected components.
        index, low, stack, on, comps = {}, {}, [], set(), []
        counter = [0]

        def visit(v):
            index[v] = low[v] = counter[0]
            counter[0] += 1
            stack.append(v)
            on.add(v)
            for w in edges[v]:
                if w not in index:
                    visit(w)
                    low[v] = min(low[v], low[w])
                elif w in on:
                    low[v] = min(low[v], index[w])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                comps.append(comp)

        sys.setrecursionlimit(10000)
        for v in mods:
            if v not in index:
                visit(v)
        name = lambda m: "::".join(m) or "<root>"
        cycles = [c for c in comps if len(c) > 1]
        if show_graph:
            for m in sorted(mods):
                print(f"{src}: {name(m)} -> {', '.join(sorted(name(e) for e in edges[m]))}")
        if cycles:
            bad = True
            for c in cycles:
                members = set(c)
                print(f"{src}: cycle of {len(c)} modules: {', '.join(sorted(name(x) for x in c))}")
                for x in sorted(c):
                    inner = sorted(name(e) for e in edges[x] if e in members)
                    print(f"    {name(x)} -> {', '.join(inner)}")
        else:
            print(f"{src}: {len(mods)} modules, no cycle")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
