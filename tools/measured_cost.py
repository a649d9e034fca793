"""Cost of a measured material: our runtime against Mitsuba 3's `measured` BSDF, one thread.

For each RGL file of fixtures/measured: Mitsuba 3.9.1's `measured` in `llvm_ad_rgb` with one
Dr.Jit thread on 2^20-lane arrays (eval, pdf, sample; the kernel compiled in a warm-up call,
each timed call a fresh kernel launch on new inputs) and neusample's `MeasuredMaterial`
(the Rust runtime's batched calls through the numpy API, `threads=1`) on the same
arrays; ns per lane, the median of --repeats interleaved runs. Ours includes the numpy
round trip, so it is an upper bound on the runtime's own cost. With --bench, each repeat also
runs `neusample bench --json --measured FILE` (the Rust batched calls at 64 lanes per call,
one thread, no Python) and reports its figures beside Mitsuba's.

    python tools/measured_cost.py [--lanes 1048576] [--repeats 5] [--bench target/release/neusample]
                                  [--out docs/measured/cost.md]

Needs mitsuba==3.9.1 (and a working LLVM for llvm_ad_rgb: Debian libllvm19) and the
neusample Python package (`pip install ./bindings/python`).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))
from ort_reference import cpu_model  # noqa: E402


def directions(rng, n):
    """Cosine-weighted upper-hemisphere directions (3, n), float32."""
    u1, u2 = rng.random(n), rng.random(n)
    r, phi = np.sqrt(u1), 2 * np.pi * u2
    return np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.maximum(1 - u1, 1e-8))]).astype(np.float32)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lanes", type=int, default=1 << 20)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", type=Path, help="write the Markdown table here (atomically)")
    ap.add_argument("--bench", type=Path, help="the neusample binary: also time its batched calls (N = 64)")
    a = ap.parse_args()
    if a.bench is not None and not a.bench.is_file():
        ap.error(f"--bench {a.bench}: no such file")
    if a.lanes <= 0 or a.repeats <= 0:
        ap.error("--lanes and --repeats must be positive")

    import drjit as dr
    import mitsuba as mi

    mi.set_variant("llvm_ad_rgb")
    dr.set_thread_count(1)
    import neusample

    files = sorted((ROOT / "fixtures" / "measured").glob("*_rgb.bsdf"))
    if not files:
        print("no fixtures/measured/*_rgb.bsdf", file=sys.stderr)
        return 1
    n = a.lanes
    rng = np.random.default_rng(7)
    ctx = mi.BSDFContext()
    rows = []
    for path in files:
        ours = neusample.MeasuredMaterial(str(path))
        theirs = mi.load_dict({"type": "measured", "filename": str(path)})
        keys = ["mi eval", "mi pdf", "mi sample", "ns eval", "ns pdf", "ns sample"]
        if a.bench:
            keys += ["b64 eval", "b64 pdf", "b64 sample"]
        times = {k: [] for k in keys}
        for r in range(a.repeats + 1):  # the first: Dr.Jit compiles its kernels
            wi, wo = directions(rng, n), directions(rng, n)
            u = rng.random((2, n)).astype(np.float32)
            si = dr.zeros(mi.SurfaceInteraction3f, n)
            si.wi = mi.Vector3f(wi)
            w = mi.Vector3f(wo)
            s2 = mi.Point2f(u)
            s1 = mi.Float(np.full(n, 0.5, np.float32))
            dr.eval(si, w, s2, s1)
            t = time.perf_counter()
            v = theirs.eval(ctx, si, w, True)
            dr.eval(v)
            times["mi eval"].append(time.perf_counter() - t)
            t = time.perf_counter()
            p = theirs.pdf(ctx, si, w, True)
            dr.eval(p)
            times["mi pdf"].append(time.perf_counter() - t)
            t = time.perf_counter()
            bs, weight = theirs.sample(ctx, si, s1, s2, True)
            dr.eval(bs, weight)
            times["mi sample"].append(time.perf_counter() - t)
            t = time.perf_counter()
            ours.eval(wi, wo, threads=1)
            times["ns eval"].append(time.perf_counter() - t)
            t = time.perf_counter()
            ours.pdf(wi, wo, threads=1)
            times["ns pdf"].append(time.perf_counter() - t)
            t = time.perf_counter()
            ours.sample(wi, u, threads=1)
            times["ns sample"].append(time.perf_counter() - t)
            if a.bench and r > 0:
                out = subprocess.run([str(a.bench), "bench", "--json", "--methods", "cosine",
                                      "--measured", str(path)], check=True, capture_output=True,
                                     text=True).stdout
                b = next(x for x in json.loads(out)["measured"]["batched"] if x["n"] == 64)
                for k in ("eval", "pdf", "sample"):
                    times[f"b64 {k}"].append(b[f"{k}_ns"] * n * 1e-9)
            elif a.bench:
                for k in ("eval", "pdf", "sample"):
                    times[f"b64 {k}"].append(0.0)
        med = {k: statistics.median(v[1:]) / n * 1e9 for k, v in times.items()}
        rng_ = {k: (min(v[1:]) / n * 1e9, max(v[1:]) / n * 1e9) for k, v in times.items()}
        rows.append((path.name, med, rng_))
        print(path.name, {k: f"{x:.1f}" for k, x in med.items()}, flush=True)

    def cell(med, rng_, k):
        lo, hi = rng_[k]
        return f"{med[k]:.1f} [{lo:.1f}–{hi:.1f}]"

    lines = [
        "# Measured materials: our runtime's cost against Mitsuba 3's `measured`",
        "",
        f"{n} lanes per call, one thread each: Mitsuba 3.9.1 `llvm_ad_rgb` "
        f"(`dr.set_thread_count(1)`, kernels compiled in a warm-up call) and neusample's "
        f"`MeasuredMaterial` array methods (Rust batched calls, numpy API, `threads=1`; the numpy "
        f"round trip included). ns per lane, median of {a.repeats} interleaved runs [min–max]. "
        f"{cpu_model()}, {os.cpu_count()} cores. `sample` is Mitsuba's `sample` (direction, pdf "
        f"and weight f·cos/pdf); ours returns the same three.",
        "",
        "| file | Mitsuba eval | ours eval | Mitsuba pdf | ours pdf | Mitsuba sample | ours sample | ours ÷ Mitsuba (eval, pdf, sample) |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for name, med, rng_ in rows:
        ratio = ", ".join(f"{med['ns ' + k] / med['mi ' + k]:.2f}" for k in ("eval", "pdf", "sample"))
        lines.append(f"| {name} | {cell(med, rng_, 'mi eval')} | {cell(med, rng_, 'ns eval')} | "
                     f"{cell(med, rng_, 'mi pdf')} | {cell(med, rng_, 'ns pdf')} | "
                     f"{cell(med, rng_, 'mi sample')} | {cell(med, rng_, 'ns sample')} | {ratio} |")
    if a.bench:
        lines += [
            "",
            "The Rust runtime's batched calls (`neusample bench --json --measured FILE`, 64 lanes "
            "per call, one thread, each call with its prepare; run between Mitsuba's timings of "
            "the same repeat). ns per lane, median [min–max]:",
            "",
            "| file | ours eval | ours pdf | ours sample | ours ÷ Mitsuba (eval, pdf, sample) |",
            "|---|---:|---:|---:|---:|",
        ]
        for name, med, rng_ in rows:
            ratio = ", ".join(f"{med['b64 ' + k] / med['mi ' + k]:.2f}" for k in ("eval", "pdf", "sample"))
            lines.append(f"| {name} | {cell(med, rng_, 'b64 eval')} | {cell(med, rng_, 'b64 pdf')} | "
                         f"{cell(med, rng_, 'b64 sample')} | {ratio} |")
    lines += ["", "Reproduce:", "", "```sh",
              f"python tools/measured_cost.py --lanes {n} --repeats {a.repeats}" +
              (f" --bench {a.bench}" if a.bench else "") +
              (f" --out {a.out}" if a.out else ""), "```", ""]
    text = "\n".join(lines)
    print(text)
    if a.out:
        tmp = a.out.with_suffix(a.out.suffix + ".tmp")
        tmp.write_text(text)
        os.replace(tmp, a.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
