#!/usr/bin/env python3
"""Where the core's compile time goes: machine code per sampler and instruction set.

Builds `cargo build --release -p neusample` from an empty target directory (timed), with
Rust's v0 symbol mangling so that the generic arguments of every function are in its name,
and sums the sizes of the functions in the core's object files (`nm -S`, demangled) by the
type they belong to (a sampler, the neural material, the dense kernels) and by the
instruction set they were compiled for (`pulp`'s `V3` = AVX2 + FMA, `V4` = AVX-512, `base` =
the build's target). LLVM's time grows with the code it optimises, faster than linearly in
the size of a function, so the largest rows are where a build-time cut has to come from.

    python3 tools/core_code_size.py [--target-dir DIR] [--top N]

Needs GNU nm 2.36 or later (it demangles v0 symbols).
"""

import argparse
import collections
import glob
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time


def build(target_dir):
    env = dict(os.environ)
    env["CARGO_TARGET_DIR"] = target_dir
    env["RUSTFLAGS"] = (env.get("RUSTFLAGS", "") + " -Csymbol-mangling-version=v0").strip()
    env.setdefault("CARGO_PROFILE_RELEASE_DEBUG", "0")
    start = time.monotonic()
    subprocess.run(["cargo", "build", "--release", "-p", "neusample", "--quiet"], env=env, check=True)
    return time.monotonic() - start


def symbols(target_dir):
    rlibs = glob.glob(os.path.join(target_dir, "release", "deps", "libneusample-*.rlib"))
    if len(rlibs) != 1:
        sys.exit(f"expected one libneusample-*.rlib under {target_dir}, found {len(rlibs)}")
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run(["ar", "x", os.path.abspath(rlibs[0])], cwd=tmp, check=True)
        objects = [f for f in os.listdir(tmp) if f.endswith(".o")]
        out = subprocess.run(
            ["nm", "-S", "-C", "--defined-only", *objects],
            cwd=tmp, check=True, capture_output=True, text=True,
        ).stdout
    rows = []
    for line in out.splitlines():
        parts = line.split(None, 3)
        if len(parts) == 4 and parts[2].lower() == "t":
            rows.append((int(parts[1], 16), parts[3]))
    return rows


def classify(name):
    """(owner, instruction set) of a demangled function name."""
    isa = "V4" if "x86::v4::V4>::vectorize" in name else "V3" if "x86::v3::V3>::vectorize" in name else "base"
    if "dense::Tiled" in name:
        return "dense kernels (tiled)", isa
    if "wavefront::dense::" in name:
        return "dense kernels (portable)", isa
    owners = re.findall(r"\b([A-Z][A-Za-z0-9]+(?:Sampler|Material))\b", name)
    return (owners[0] if owners else "other"), isa


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--target-dir", help="build here (default: a fresh temporary directory)")
    ap.add_argument("--top", type=int, default=12, help="largest functions to list")
    a = ap.parse_args()
    if shutil.which("nm") is None or shutil.which("ar") is None:
        sys.exit("needs binutils (nm, ar)")
    tmp = None
    target = a.target_dir
    if target is None:
        tmp = tempfile.mkdtemp(prefix="neusample-core-size-")
        target = tmp
    try:
        secs = build(target)
        rows = symbols(target)
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
    total = sum(s for s, _ in rows)
    print(f"clean release build of the core (v0 mangling, no debug info): {secs:.1f} s")
    print(f"machine code in the core's objects: {total / 1024:.0f} KiB in {len(rows)} functions\n")
    by = collections.Counter()
    for size, name in rows:
        by[classify(name)] += size
    print(f"{'owner':32} {'isa':5} {'KiB':>7} {'share':>6}")
    for (owner, isa), size in by.most_common():
        if size * 200 < total:
            break
        print(f"{owner:32} {isa:5} {size / 1024:7.1f} {100 * size / total:5.1f}%")
    print(f"\nlargest functions:")
    for size, name in sorted(rows, reverse=True)[: a.top]:
        short = name.replace("neusample::", "").replace("pulp::x86::", "")
        print(f"{size / 1024:7.1f} KiB  {short[:150]}")


if __name__ == "__main__":
    main()
