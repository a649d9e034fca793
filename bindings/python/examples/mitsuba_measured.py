"""Measured RGL materials in Mitsuba 3 at equal time: Mitsuba's `measured` BSDF with its own
sampler against the same BSDF wrapped by the neusample plugin (`"bsdf": {...}`), which
samples it with a neusample blob trained on the file.

Scene: a sphere of the measured material under uniform white light (`constant`) or the sky
with a sun of `mitsuba_scene.py`, `path` integrator (MIS), max depth 3, `llvm_ad_rgb`. The
plain BSDF renders with `mi.render` (Mitsuba's default symbolic mode, its fastest path for a
built-in BSDF), the wrapped ones with `neusample.mitsuba.render` (evaluated flags, the
plugin's fastest path on a CPU). Each configuration gets the same wall-clock budget (its spp
from the median of three timed renders); errors against a reference rendered with the
data's own sampler at --ref-spp: the error of a render against it is its own variance plus
the reference's, so the reference needs many times the spp of any configuration (the table
prints the ratio) or it levels the comparison.

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


def run_file(path, light, a):
    cfgs = configs(path, a.blobs, a.methods)
    sc = mi.load_dict(scene_dict(cfgs[0][1], light, a.res))
    render(sc, 4, 0, mi.render)  # compile
    ref, ref_secs = render(sc, a.ref_spp, 12345, mi.render)
    del sc
    gc.collect()
    rows = []
    for name, bsdf, fn in cfgs:
        sc = mi.load_dict(scene_dict(bsdf, light, a.res))
        render(sc, 4, 0, fn)  # compile
        cost = statistics.median(render(sc, 4, 100 + r, fn)[1] / 4 for r in range(3))
        spp = max(1, int(a.budget / cost))
        errs = [relmse(render(sc, spp, 7 + 1000 * k + a.seed, fn)[0], ref) for k in range(a.seeds)]
        del sc
        gc.collect()
        rows.append((name, spp, cost, errs))
        print(f"{path.name} {light} {name:<26} spp {spp:>5} relMSE {errs}", flush=True)
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
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--lights", default="uniform,sky")
    ap.add_argument("--methods", default=",".join(METHODS),
                    help="comma-separated sampler blobs of each folder (baseline among them)")
    ap.add_argument("--files", nargs="*", type=Path,
                    default=sorted((ROOT / "fixtures" / "measured").glob("*_rgb.bsdf")))
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "measured" / "mitsuba_equal_time.md")
    a = ap.parse_args()
    if a.budget <= 0 or a.res < 8 or a.ref_spp < 1 or a.seeds < 1:
        ap.error("--budget, --res, --ref-spp and --seeds must be positive (res ≥ 8)")
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
        "of (image − reference)² / (reference² + 0.01); median of",
        f"{a.seeds} seeds [min–max]; reference: the data's sampler at {a.ref_spp} spp. Speed-up = the",
        "other configuration's median relMSE ÷ this one's (the bracket divides it by this one's max",
        "and min). Equal spp: the same against the data's sampler with each relMSE times its spp (the",
        "error of one sample per pixel, which the timings do not move; a verdict near a threshold at",
        "equal time can be read against it, as timings on a shared machine vary between runs).",
        "",
    ]
    lines_ref = []
    for light in lights:
        lines += [f"## {'uniform white light' if light == 'uniform' else 'sky with a sun'}", "",
                  "| file | configuration | spp | ms/spp | relMSE | vs baseline | vs data's sampler "
                  "| vs data's sampler, equal spp |",
                  "|---|---|---:|---:|---:|---:|---:|---:|"]
        for f in a.files:
            rows, _ = run_file(f, light, a)
            most = max(r[1] for r in rows)
            lines_ref.append(f"{f.name.removesuffix('_rgb.bsdf')} ({light}): {a.ref_spp / most:.1f}×")
            by = {r[0]: r for r in rows}
            base = statistics.median(by["baseline"][3])
            data_row = by["measured (data's sampler)"]
            data = statistics.median(data_row[3])
            for name, spp, cost, errs in rows:
                med = statistics.median(errs)
                lines.append(f"| {f.name.removesuffix('_rgb.bsdf')} | {name} | {spp} | {cost * 1e3:.1f} | "
                             f"{med:.2e} [{min(errs):.2e}–{max(errs):.2e}] | {fmt_ratio(base, errs)} | "
                             f"{fmt_ratio(data, errs)} | "
                             f"{fmt_ratio(data * data_row[1], [e * spp for e in errs])} |")
        lines.append("")
    lines += ["The reference's spp over the most any configuration got: " + ", ".join(lines_ref) + ".", ""]
    cmd = (f"python bindings/python/examples/mitsuba_measured.py --blobs <dir> --budget {a.budget:g} "
           f"--res {a.res} --ref-spp {a.ref_spp} --seeds {a.seeds} --lights {a.lights} "
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
