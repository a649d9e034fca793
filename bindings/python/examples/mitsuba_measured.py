"""Measured RGL materials in Mitsuba 3 at equal time: Mitsuba's `measured` BSDF with its own
sampler against the same BSDF wrapped by the neusample plugin (`"bsdf": {...}`), which
samples it with a neusample blob trained on the file.

Scene: a sphere of the measured material under uniform white light (`constant`) or the sky
with a sun of `mitsuba_scene.py`, `path` integrator (MIS), max depth 3, `llvm_ad_rgb`. The
plain BSDF renders with `mi.render` (Mitsuba's default symbolic mode, its fastest path for a
built-in BSDF), the wrapped ones with `neusample.mitsuba.render` (evaluated flags, the
plugin's fastest path on a CPU). Each configuration gets the same wall-clock budget (its spp
from the median of --timing-rounds timed renders, interleaved with the other
configurations', each scene alive only for its render), and is compared by relMSE × its
renders' own seconds; errors against a reference rendered with the data's own sampler at
--ref-spp: the error of a render against it is its own variance plus the reference's, so the
reference needs many times the spp of any configuration (the table prints the ratio) or it
levels the comparison.

    # blobs: <dir>/<file stem without _rgb>/<method>.nsb, e.g. for each material file
    neusample train --material fixtures/measured/chm_mint.toml \\
        --method baseline,analytic,flow,disk-flow,histogram-mixture,reparam --out-dir blobs/chm_mint
    # or the blobs a `neusample demo --train` run wrote (<out>/blobs)
    python bindings/python/examples/mitsuba_measured.py --blobs blobs [--budget 1] [--res 96] [--ref-spp 8192]
        → docs/measured/mitsuba_equal_time.md
"""

import argparse
import gc
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import mitsuba_scene as ms  # noqa: E402  (sets llvm_ad_rgb, registers the plugin)

import mitsuba as mi  # noqa: E402
import neusample.drjit as ndj  # noqa: E402
import neusample.mitsuba as nsm  # noqa: E402

ROOT = ms.ROOT
# The default --methods: the baseline and the learned samplers (the paper's comparison
# baselines, affine flow and direct histogram, on request).
METHODS = ["baseline", "analytic", "flow", "disk-flow", "histogram-mixture", "reparam"]
# Samples per pixel of a timing render.
TIMING_SPP = 16


def scene_dict(bsdf, light, res):
    w, h = res, res * 3 // 4
    emitter = ({"type": "constant", "radiance": {"type": "rgb", "value": 1.0}} if light == "uniform"
               else {"type": "envmap", "bitmap": ms.envmap(),
                     "to_world": mi.ScalarTransform4f().rotate([1, 0, 0], 90)})
    return {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 3},
        "sensor": {
            "type": "perspective", "fov": 30,
            "to_world": mi.ScalarTransform4f().look_at(origin=[0, -4.2, 2.2], target=[0, 0, 0], up=[0, 0, 1]),
            "film": {"type": "hdrfilm", "width": w, "height": h, "pixel_format": "rgb"},
            "sampler": {"type": "independent"},
        },
        "emitter": emitter,
        "ball": {"type": "sphere", "bsdf": bsdf},
    }


def configs(path, blobs, methods):
    plain = {"type": "measured", "filename": str(path)}
    out = [("measured (data's sampler)", plain, mi.render)]
    stem = path.name.removesuffix("_rgb.bsdf")
    for m in methods:
        blob = blobs / stem / f"{m}.nsb"
        if not blob.exists():
            raise SystemExit(f"{blob}: missing (see the module doc for the training command)")
        d = {"type": "neusample", "sampler": str(blob), "bsdf": plain}
        if m not in ndj.KINDS:
            d["mode"] = "evaluated"  # the Rust plugin: the kinds Dr.Jit does not implement
        out.append((m, d, nsm.render))
    return out


def render(scene, spp, seed, fn):
    t = time.perf_counter()
    img = np.array(fn(scene, spp=spp, seed=seed), dtype=np.float64)
    return img, time.perf_counter() - t


def relmse(img, ref):
    return float((((img - ref) ** 2) / (ref ** 2 + 1e-2)).mean())


def rotated(n, r):
    """`range(n)` starting at `r mod n`: each round visits the configurations in another order."""
    return [(r + i) % n for i in range(n)]


def run_file(path, light, a):
    """Each configuration's (name, spp, seconds per spp, relMSEs, render seconds), one per seed.

    The timing renders and the seeds' renders go round the configurations in turn (a rotated
    order each round), so that a shared machine's changing load falls on all of them alike.
    Each render loads its scene and drops it after: a symbolic render traces every live BSDF
    of the variant, so another configuration's scene alive beside it would slow it."""
    cfgs = configs(path, a.blobs, a.methods)
    n = len(cfgs)

    def alone(i, spp, seed):
        sc = mi.load_dict(scene_dict(cfgs[i][1], light, a.res))
        out = render(sc, spp, seed, cfgs[i][2])
        del sc
        gc.collect()
        return out

    alone(0, 4, 0)  # compile
    ref, ref_secs = alone(0, a.ref_spp, 12345)
    for i in range(1, n):
        alone(i, 4, 0)  # compile
    costs = [[] for _ in cfgs]
    for r in range(a.timing_rounds):
        for i in rotated(n, r):
            costs[i].append(alone(i, TIMING_SPP, 100 + r)[1] / TIMING_SPP)
    spps = [max(1, int(a.budget / statistics.median(c))) for c in costs]
    for i in range(n):
        alone(i, spps[i], 1)  # untimed: the evaluated flags' kernels compile again for a new spp
    errs, secs = [[] for _ in cfgs], [[] for _ in cfgs]
    for k in range(a.seeds):
        for i in rotated(n, k):
            img, t = alone(i, spps[i], 7 + 1000 * k + a.seed)
            errs[i].append(relmse(img, ref))
            secs[i].append(t)
    rows = []
    for i, (name, _, _) in enumerate(cfgs):
        rows.append((name, spps[i], statistics.median(costs[i]), errs[i], secs[i]))
        print(f"{path.name} {light} {name:<26} spp {spps[i]:>5} relMSE {errs[i]} s {secs[i]}",
              flush=True)
    return rows, ref_secs


def fmt_ratio(base, errs):
    med = statistics.median(errs)
    return f"{base / med:.2f}× [{base / max(errs):.2f}–{base / min(errs):.2f}]"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blobs", type=Path, required=True, help="<dir>/<material>/<method>.nsb")
    ap.add_argument("--budget", type=float, default=1.0, help="seconds per configuration and render")
    ap.add_argument("--res", type=int, default=96)
    ap.add_argument("--ref-spp", type=int, default=8192)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--timing-rounds", type=int, default=5,
                    help="timing renders per configuration (median), interleaved")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--lights", default="uniform,sky")
    ap.add_argument("--methods", default=",".join(METHODS),
                    help="comma-separated sampler blobs of each folder (baseline among them)")
    ap.add_argument("--files", nargs="*", type=Path,
                    default=sorted((ROOT / "fixtures" / "measured").glob("*_rgb.bsdf")))
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "measured" / "mitsuba_equal_time.md")
    a = ap.parse_args()
    if a.budget <= 0 or a.res < 8 or a.ref_spp < 1 or a.seeds < 1 or a.timing_rounds < 1:
        ap.error("--budget, --res, --ref-spp, --seeds and --timing-rounds must be positive (res ≥ 8)")
    a.methods = [m for m in a.methods.split(",") if m]
    if "baseline" not in a.methods:
        ap.error("--methods must include baseline (every speed-up is against it)")
    lights = a.lights.split(",")
    for light in lights:
        if light not in ("uniform", "sky"):
            ap.error(f"--lights: 'uniform' or 'sky', not {light!r}")
    for f in a.files:
        configs(f, a.blobs, a.methods)  # every blob present before any render
    lines = [
        "# Measured materials in Mitsuba 3 at equal time",
        "",
        "A sphere of each RGL file, `path` (MIS, max depth 3), `llvm_ad_rgb`: Mitsuba's `measured`",
        "BSDF with its own sampler (`mi.render`, symbolic) against the same BSDF wrapped by the",
        "neusample plugin and sampled by a blob trained on the file (`neusample.mitsuba.render`).",
        f"{a.res}×{a.res * 3 // 4}, budget {a.budget:g} s per render, {ms.machine()}; relMSE = mean",
        "of (image − reference)² / (reference² + 0.01); reference: the data's sampler at",
        f"{a.ref_spp} spp. Each configuration's spp: the budget over its median time per spp in",
        f"{a.timing_rounds} timing renders of {TIMING_SPP} spp; then {a.seeds} seeds' renders. Timing and",
        "seeds' renders go round the configurations in turn (a rotated order each round; each",
        "scene loaded for its render alone), so that the shared machine's load falls on all of",
        "them alike. Speed-up at equal time = the other",
        "configuration's median of relMSE × the render's seconds ÷ this one's (the work each needs",
        "for an error, from the renders' own times; the bracket divides by this one's max and",
        "min). Equal spp: the same against the data's sampler with each relMSE times its spp (the",
        "error of one sample per pixel, which the timings do not move).",
        "",
    ]
    lines_ref = []
    for light in lights:
        lines += [f"## {'uniform white light' if light == 'uniform' else 'sky with a sun'}", "",
                  "| file | configuration | spp | ms/spp | s/render | relMSE | vs baseline "
                  "| vs data's sampler | vs data's sampler, equal spp |",
                  "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
        for f in a.files:
            rows, _ = run_file(f, light, a)
            most = max(r[1] for r in rows)
            lines_ref.append(f"{f.name.removesuffix('_rgb.bsdf')} ({light}): {a.ref_spp / most:.1f}×")
            by = {r[0]: r for r in rows}

            def work(row):
                return [e * t for e, t in zip(row[3], row[4])]

            base = statistics.median(work(by["baseline"]))
            data_row = by["measured (data's sampler)"]
            data = statistics.median(work(data_row))
            data_spp = statistics.median(data_row[3]) * data_row[1]
            for row in rows:
                name, spp, cost, errs, secs = row
                med = statistics.median(errs)
                lines.append(f"| {f.name.removesuffix('_rgb.bsdf')} | {name} | {spp} | {cost * 1e3:.1f} | "
                             f"{statistics.median(secs):.2f} | "
                             f"{med:.2e} [{min(errs):.2e}–{max(errs):.2e}] | {fmt_ratio(base, work(row))} | "
                             f"{fmt_ratio(data, work(row))} | "
                             f"{fmt_ratio(data_spp, [e * spp for e in errs])} |")
        lines.append("")
    lines += ["The reference's spp over the most any configuration got: " + ", ".join(lines_ref) + ".", ""]
    cmd = (f"python bindings/python/examples/mitsuba_measured.py --blobs <dir> --budget {a.budget:g} "
           f"--res {a.res} --ref-spp {a.ref_spp} --seeds {a.seeds} --timing-rounds {a.timing_rounds} "
           f"--lights {a.lights} "
           f"--methods {','.join(a.methods)}")
    lines += ["Reproduce (blobs: the module doc's `neusample train` loop):", "", "```sh", cmd, "```", ""]
    text = "\n".join(lines)
    a.out.parent.mkdir(parents=True, exist_ok=True)
    tmp = a.out.with_suffix(".md.tmp")
    tmp.write_text(text)
    os.replace(tmp, a.out)
    print(text)


if __name__ == "__main__":
    sys.exit(main())
