"""A Fig. 11-style Mitsuba 3 scene with several neural materials, rendered in Mitsuba's default
symbolic mode (llvm_ad_rgb: the samplers and the materials compiled into Mitsuba's own
kernel by neusample.drjit), and the speed figures of the symbolic plugin.

Scene: three neural materials (goat leather, brushed metal and Victorian fabric, each with its
own fixture sampler of the chosen method) on two spheres and a cube, standing on a built-in
`roughplastic` floor with a `diffuse` back wall, under an environment map with a sun (the
`path` integrator, MIS, max depth 6: multi-bounce global illumination).

    python bindings/python/examples/mitsuba_scene.py equal-time [--budget 20] [--res 160]
        → docs/mitsuba_scene.png, docs/mitsuba_scene.md (equal-time table)
    python bindings/python/examples/mitsuba_scene.py speed [--repeats 5] [--res 96] [--spp 8]
        → docs/mitsuba_speed.md (symbolic vs evaluated vs roughconductor; Table 1 in Mitsuba)
"""

import argparse
import gc
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[3]
DOCS = ROOT / "docs"

import drjit as dr  # noqa: E402
import mitsuba as mi  # noqa: E402

mi.set_variant("llvm_ad_rgb")
import neusample.mitsuba as nsm  # noqa: E402

nsm.register()

METHODS = ["cosine", "baseline", "analytic", "flow", "histogram-mixture", "reparam"]
OBJECTS = [
    # (name, material, shape, transform, uv_scale)
    ("leather", "goat_leather_neural", "sphere", dict(translate=[-1.25, 0.2, 0.55], scale=0.55), 3.0),
    ("metal", "brushed_metal_neural", "sphere", dict(translate=[0.05, -0.45, 0.55], scale=0.55), 2.0),
    ("fabric", "victorian_fabric_neural", "cube", dict(translate=[1.3, 0.45, 0.45], scale=0.45), 1.0),
]


def envmap(h=128, w=256):
    """A sky gradient with a warm sun (the light of the scene, sampled by MIS)."""
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    theta = (y + 0.5) / h * np.pi
    phi = (x + 0.5) / w * 2 * np.pi
    up = np.clip(np.cos(theta), 0, 1)
    sky = np.stack([0.25 + 0.35 * up, 0.35 + 0.35 * up, 0.6 + 0.3 * up], -1) * (theta < np.pi / 2 + 0.1)[..., None]
    ground = np.array([0.12, 0.11, 0.1]) * (theta >= np.pi / 2 + 0.1)[..., None]
    sun = np.exp(-((theta - 0.75) ** 2 + (phi - 2.2) ** 2) / 0.004)[..., None] * np.array([300.0, 270.0, 220.0])
    return mi.Bitmap((sky + ground + sun).astype(np.float32))


def neural_bsdf(material, method, mode, uv_scale):
    d = {"type": "neusample", "mode": mode, "uv_scale": uv_scale,
         "material": str(ROOT / "fixtures" / "materials" / "neural" / f"{material}.nsb")}
    if method != "cosine":
        d["sampler"] = str(ROOT / "fixtures" / "blobs" / material / f"{method}.nsb")
    return d


def scene_dict(method, mode="symbolic", res=160, builtin=False, max_depth=6):
    """The scene with every neural material sampled by `method` (`builtin`: Mitsuba's own
    `roughconductor` in their place, for scale)."""
    w, h = res, res * 3 // 4
    d = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": max_depth},
        "sensor": {
            "type": "perspective", "fov": 38,
            "to_world": mi.ScalarTransform4f().look_at(origin=[0.3, -5.2, 2.3], target=[0.05, 0.1, 0.45], up=[0, 0, 1]),
            "film": {"type": "hdrfilm", "width": w, "height": h, "pixel_format": "rgb"},
            "sampler": {"type": "independent"},
        },
        "sky": {"type": "envmap", "bitmap": envmap(),
                "to_world": mi.ScalarTransform4f().rotate([1, 0, 0], 90)},
        "floor": {"type": "rectangle",
                  "to_world": mi.ScalarTransform4f().scale([6, 6, 1]),
                  "bsdf": {"type": "roughplastic", "alpha": 0.3,
                           "diffuse_reflectance": {"type": "rgb", "value": [0.35, 0.33, 0.3]}}},
        "wall": {"type": "rectangle",
                 "to_world": mi.ScalarTransform4f().translate([0, 2.5, 2]).rotate([1, 0, 0], 90).scale([6, 2.5, 1]),
                 "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.5, 0.45, 0.4]}}},
    }
    for name, material, shape, tr, uv_scale in OBJECTS:
        bsdf = ({"type": "roughconductor", "alpha": 0.2} if builtin
                else neural_bsdf(material, method, mode, uv_scale))
        d[name] = {"type": shape,
                   "to_world": mi.ScalarTransform4f().translate(tr["translate"]).scale(tr["scale"]),
                   "bsdf": bsdf}
    return d


def patch_dict(method, mode="symbolic", res=160, builtin=False):
    """The test suite's render scene: one neural patch (goat leather) under a small
    environment map, `path` max depth 3."""
    sys.path.insert(0, str(ROOT / "bindings" / "python" / "tests"))
    from test_mitsuba import envmap_bitmap

    bsdf = ({"type": "roughconductor", "alpha": 0.2} if builtin
            else neural_bsdf("goat_leather_neural", method, mode, 2.0))
    return {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 3},
        "sensor": {
            "type": "perspective", "fov": 40,
            "to_world": mi.ScalarTransform4f().look_at(origin=[0, -2.2, 2.0], target=[0, 0, 0], up=[0, 0, 1]),
            "film": {"type": "hdrfilm", "width": res, "height": res * 3 // 4, "pixel_format": "rgb"},
            "sampler": {"type": "independent"},
        },
        "emitter": {"type": "envmap", "bitmap": envmap_bitmap()},
        "patch": {"type": "rectangle", "to_world": mi.ScalarTransform4f().scale([1.2, 1.2, 1.0]), "bsdf": bsdf},
    }


class Flags:
    """Mitsuba's evaluated mode for a block (what the evaluated plugin needs)."""

    def __init__(self, evaluated):
        self.evaluated = evaluated

    def __enter__(self):
        self.saved = (dr.flag(dr.JitFlag.SymbolicLoops), dr.flag(dr.JitFlag.SymbolicCalls))
        if self.evaluated:
            nsm.evaluated_mode()

    def __exit__(self, *exc):
        dr.set_flag(dr.JitFlag.SymbolicLoops, self.saved[0])
        dr.set_flag(dr.JitFlag.SymbolicCalls, self.saved[1])


def timed_render(scene, spp, seed, evaluated=False, render=None):
    with Flags(evaluated):
        t = time.perf_counter()
        img = (render or mi.render)(scene, spp=spp, seed=seed)
        img = np.array(img, dtype=np.float64)
        return img, time.perf_counter() - t


def to_srgb(img):
    x = np.clip(img, 0, None)
    x = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return np.clip(x, 0, 1)


def machine():
    import os
    return f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, mitsuba {mi.__version__}, drjit {dr.__version__}"


def equal_time(a):
    res = a.res

    def load(method, mode):
        with Flags(mode == "evaluated"):
            return mi.load_dict(scene_dict(method, mode, res))

    # The reference through the evaluated plugin (the Rust runtime; faster on this CPU),
    # its scene deleted before any symbolic render (which would try to trace it).
    sc = load("histogram-mixture", "evaluated")
    t = time.perf_counter()
    ref, _ = timed_render(sc, a.ref_spp, 12345, evaluated=True)
    ref_secs = time.perf_counter() - t
    del sc
    gc.collect()
    rows, tiles = [], [to_srgb(ref)]
    for m in METHODS:
        # One symbolic scene alive at a time; cost per spp: median of three timed renders
        # after a warm-up (compile) render.
        sc = load(m, "symbolic")
        timed_render(sc, 4, 0)
        cost = statistics.median(timed_render(sc, 4, 100 + r)[1] / 4 for r in range(3))
        spp = max(1, int(a.budget / cost))
        errs, secs_all = [], []
        for k in range(a.seeds):
            img, secs = timed_render(sc, spp, 7 + 1000 * k + a.seed)
            errs.append(float((((img - ref) ** 2) / (ref ** 2 + 1e-2)).mean()))
            secs_all.append(secs)
            if k == 0:
                tiles.append(to_srgb(img))
        del sc
        gc.collect()
        rows.append((m, spp, statistics.median(secs_all), cost, errs))
        print(f"{m:<18} spp {spp:>5} time {statistics.median(secs_all):6.2f} s  relMSE {errs}", flush=True)
    base = statistics.median({r[0]: r for r in rows}["baseline"][4])
    DOCS.mkdir(exist_ok=True)
    # Rows of four tiles (the reference, then the samplers in METHODS' order), black padding.
    tiles += [np.zeros_like(tiles[0])] * (-len(tiles) % 4)
    grid = np.concatenate([np.concatenate(tiles[i:i + 4], axis=1) for i in range(0, len(tiles), 4)], axis=0)
    mi.util.write_bitmap(str(DOCS / "mitsuba_scene.png"), (grid * 255).astype(np.uint8), write_async=False)
    h, w = ref.shape[:2]
    lines = [
        "# Neural materials in Mitsuba 3's symbolic kernels, equal time",
        "",
        "Three neural materials (goat leather, brushed metal, Victorian fabric) on two spheres and a cube,",
        "a built-in `roughplastic` floor and `diffuse` wall, an environment map with a sun; `path`",
        "integrator with MIS, max depth 6 (multi-bounce GI). `llvm_ad_rgb` in Mitsuba's default",
        "**symbolic** mode: the samplers and the materials are Dr.Jit code (`neusample.drjit`) compiled",
        "into Mitsuba's own kernel. Each sampler gets the same wall-clock budget; its spp come from",
        "the median of three timed renders; errors against a",
        f"{a.ref_spp}-spp reference (histogram mixture through the evaluated plugin, {ref_secs:.0f} s).",
        "Speed-up = baseline relMSE ÷ method relMSE (equal time).",
        "",
        "![equal time](mitsuba_scene.png)",
        "",
        "Top: reference, cosine, improved baseline, analytic mixture. Bottom: flow, histogram mixture,",
        "reparameterization sampler.",
        "",
        f"{w}×{h}, budget {a.budget:g} s per sampler, {machine()}.",
        "",
        f"relMSE = mean of (image − reference)² / (reference² + 0.01) over pixels and channels;",
        f"median of {a.seeds} renders with different seeds at the calibrated spp, [min–max].",
        "",
        "| sampler | spp | time (s) | ms/spp | relMSE | speed-up vs baseline |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for m, spp, secs, cost, errs in rows:
        med = statistics.median(errs)
        lines.append(f"| {m} | {spp} | {secs:.2f} | {cost * 1e3:.1f} | {med:.2e} [{min(errs):.2e}–{max(errs):.2e}] | "
                     f"{base / med:.2f}× [{base / max(errs):.2f}–{base / min(errs):.2f}] |")
    lines += ["", "Reproduce:", "", "```sh",
              f"python bindings/python/examples/mitsuba_scene.py equal-time --budget {a.budget:g} --res {a.res} --ref-spp {a.ref_spp} --seeds {a.seeds}",
              "```", "", "The speed-up's bracket divides the baseline's median by the method's max and min. The",
              "machine is shared: the spp each sampler gets depend on its load during the calibration.", ""]
    (DOCS / "mitsuba_scene.md").write_text("\n".join(lines))


def speed(a):
    """ns per sample (per camera path) of the whole render, symbolic vs evaluated, the
    built-in roughconductor for scale; interleaved repeats, medians."""
    res, spp = a.res, a.spp
    w, h = res, res * 3 // 4
    samples = w * h * spp
    builders = {"objects": scene_dict, "patch": patch_dict}
    configs = []
    for kind, build in builders.items():
        for m in METHODS + ["roughconductor"]:
            builtin = m == "roughconductor"
            for mode in ("symbolic", "jit-evaluated", "evaluated"):
                if builtin and mode == "jit-evaluated":
                    continue
                plugin = "symbolic" if mode == "jit-evaluated" else mode
                configs.append((kind, m, mode, build("cosine" if builtin else m, plugin, res, builtin=builtin)))

    def run(d, mode, seed):
        # A symbolic render traces every live BSDF instance (evaluated-mode ones cannot be
        # traced) and compiles them all: each scene lives only for its own render. Freed
        # instance slots are reused in the same order, so the kernels of the repeats are
        # the warm-up's (cache hits).
        # `jit-evaluated`: Mitsuba's default flags, `neusample.mitsuba.render` sets its own.
        flags = mode == "evaluated"
        with Flags(flags):
            sc = mi.load_dict(d)
        secs = timed_render(sc, spp, seed, evaluated=flags,
                            render=nsm.render if mode == "jit-evaluated" else None)[1]
        del sc
        gc.collect()
        return secs

    compiled = {}
    for kind, m, mode, d in configs:  # warm-up: compile (kernel history: size, LLVM time)
        dr.set_flag(dr.JitFlag.KernelHistory, True)
        dr.kernel_history()  # clears it
        run(d, mode, 0)
        hist = [k for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]
        dr.set_flag(dr.JitFlag.KernelHistory, False)
        built = [k for k in hist if not k["cache_hit"] and not k["cache_disk"]]
        compiled[(kind, m, mode)] = (
            max((k["operation_count"] for k in hist), default=0),
            sum(k["backend_time"] + k["codegen_time"] for k in built) / 1e3, len(built))
    times = {}
    for r in range(a.repeats):
        for kind, m, mode, d in configs:
            times.setdefault((kind, m, mode), []).append(run(d, mode, 1 + r))
        print(f"repeat {r + 1}/{a.repeats}", flush=True)
    med = {k: statistics.median(v) for k, v in times.items()}
    rng = {k: (min(v), max(v)) for k, v in times.items()}

    def ns(k):
        lo, hi = rng[k]
        return f"{med[k] / samples * 1e9:.0f} [{lo / samples * 1e9:.0f}–{hi / samples * 1e9:.0f}]"

    lines = [
        "# Speed of the symbolic Mitsuba plugin",
        "",
        f"{w}×{h}, {spp} spp ({samples} camera samples per render), `llvm_ad_rgb`, {machine()}.",
        "**objects**: the scene of `mitsuba_scene.md` (three neural materials on two spheres and a",
        "cube, built-in floor and wall, envmap, `path` max depth 6). **patch**: the test suite's",
        "render scene (one goat-leather patch under a small envmap, max depth 3).",
        "**symbolic**: Mitsuba's default mode, the plugin's Dr.Jit code compiled into Mitsuba's",
        "kernel; **evaluated**: symbolic loops and calls off, every bounce a numpy round trip to the",
        "Rust runtime (the previous plugin). `roughconductor`: Mitsuba's built-in BSDF in place of",
        f"the neural materials. Median of {a.repeats} renders (min–max in brackets), all",
        "configurations interleaved in one process; compile time excluded (warm-up render), the",
        "Python tracing of the plugin included (Mitsuba traces it again at every `mi.render`).",
        "The machine is shared with other jobs: compare within a row (ratios), not across runs.",
        "",
        "**`neusample.mitsuba.render`**: the same Dr.Jit plugin rendered under the evaluated",
        "mode's flags for that call (Mitsuba then calls it once per bounce and BSDF with",
        "compacted, concrete arrays, outside any symbolic call); for `roughconductor`, Mitsuba's",
        "evaluated mode. Speed-ups are the evaluated Rust plugin's time ÷ the column's.",
        "",
        "| scene | sampler | symbolic ns/sample | `render` ns/sample | evaluated (Rust) ns/sample | symbolic speed-up | `render` speed-up | symbolic s/spp | sampler share (symbolic) |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for kind in builders:
        cos = med[(kind, "cosine", "symbolic")]
        for m in METHODS + ["roughconductor"]:
            s, e = med[(kind, m, "symbolic")], med[(kind, m, "evaluated")]
            share = "—" if m in ("cosine", "roughconductor") else f"{max(s - cos, 0) / s * 100:.0f} %"
            if (kind, m, "jit-evaluated") in med:
                j = med[(kind, m, "jit-evaluated")]
                cols = f"{ns((kind, m, 'jit-evaluated'))} | {ns((kind, m, 'evaluated'))} | {e / s:.2f}× | {e / j:.2f}×"
            else:  # roughconductor: Mitsuba's evaluated mode in the `render` column
                cols = f"{ns((kind, m, 'evaluated'))} | — | — | —"
            lines.append(f"| {kind} | {m} | {ns((kind, m, 'symbolic'))} | {cols} | {s / spp:.4f} | {share} |")
    lines += [
        "",
        "Compilation (the warm-up render of each configuration, Dr.Jit's kernel history): the",
        "largest kernel's operation count and the LLVM time of the kernels not found in Dr.Jit's",
        "cache (0 where the cache had them: run with an empty `~/.drjit` for cold figures).",
        "",
        "| scene | sampler | symbolic: ops, compile s | `render`: ops, compile s | evaluated (Rust): ops, compile s |",
        "|---|---|---:|---:|---:|",
    ]

    def comp(k):
        if k not in compiled:
            return "—"
        ops, secs, n = compiled[k]
        return f"{ops}, {secs:.1f} ({n} kernels)"

    for kind in builders:
        for m in METHODS + ["roughconductor"]:
            lines.append(f"| {kind} | {m} | {comp((kind, m, 'symbolic'))} | {comp((kind, m, 'jit-evaluated'))} | "
                         f"{comp((kind, m, 'evaluated'))} |")
    lines += decoder_bench(a.repeats)
    lines += [
        "",
        "Sampler share: (render time with the sampler − with cosine sampling) ÷ render time: the",
        "cost of its `sample` and of its `pdf` for MIS, the paper's Table 1 'Sampling' row over",
        "'Rendering' (the paper's figures are on an NVIDIA GPU with the scene of its Fig. 1:",
        "rendering 0.0412–0.0553 s/spp, sampling 0.0001–0.0065 s/spp, 2–12 %).",
        "No NVIDIA GPU was available: `cuda_ad_rgb` was not measured (the code has no LLVM-only",
        "calls; on CUDA the networks run as f16 cooperative vectors, the OptiX requirement).",
        "",
        "Reproduce:",
        "",
        "```sh",
        f"python bindings/python/examples/mitsuba_scene.py speed --repeats {a.repeats} --res {a.res} --spp {a.spp}",
        "```",
        "",
    ]
    DOCS.mkdir(exist_ok=True)
    (DOCS / "mitsuba_speed.md").write_text("\n".join(lines))
    print("\n".join(lines))


def decoder_bench(repeats, n=1 << 16):
    """The neural material's decoder (14-64-64-64-3) alone: the Rust batched kernel on one
    thread, the Dr.Jit code on concrete arrays (both cores), and the same inside a Dr.Jit
    symbolic call (`dr.switch`, as Mitsuba calls a BSDF): ns per lane, medians."""
    import neusample
    import neusample.drjit as nd

    path = str(ROOT / "fixtures" / "materials" / "neural" / "goat_leather_neural.nsb")
    rust = neusample.NeuralMaterial(path)
    jit = nd.NeuralMaterial(path, mi.Float)
    rng = np.random.default_rng(0)
    wi = np.tile(np.array([[0.3], [0.2], [0.93]], np.float32), n)
    wo = np.tile(np.array([[-0.3], [0.1], [0.95]], np.float32), n)

    def f(*a):
        r = jit.eval(list(a[:8]), a[8:11], a[11:14])
        return r[0], r[1], r[2]

    times = {"rust": [], "direct": [], "call": [], "call-coop": []}
    for r in range(repeats + 1):
        phi = rng.normal(size=(8, n)).astype(np.float32)
        t = time.perf_counter()
        rust.eval(phi, wi, wo)
        times["rust"].append(time.perf_counter() - t)
        args = [mi.Float(x) for x in phi] + [mi.Float(x) for x in wi] + [mi.Float(x) for x in wo]
        dr.eval(args)
        t = time.perf_counter()
        np.array(f(*args)[0])
        times["direct"].append(time.perf_counter() - t)
        args = [x + 0.0 for x in args]  # new variables: nothing is reused
        dr.eval(args)
        t = time.perf_counter()
        np.array(dr.switch(dr.zeros(mi.UInt32, n), [f], *args)[0])
        times["call"].append(time.perf_counter() - t)
        args = [x + 0.0 for x in args]
        dr.eval(args)
        nd.LITERAL_WEIGHTS_IN_SYMBOLIC_CALLS = False
        t = time.perf_counter()
        np.array(dr.switch(dr.zeros(mi.UInt32, n), [f], *args)[0])
        times["call-coop"].append(time.perf_counter() - t)
        nd.LITERAL_WEIGHTS_IN_SYMBOLIC_CALLS = True
    med = {k: statistics.median(v[1:]) / n * 1e9 for k, v in times.items()}  # first: compile
    return [
        "",
        f"The decoder alone ({n} lanes, median of {repeats}, goat leather): Rust batched kernel on one",
        f"thread {med['rust']:.0f} ns/lane; the Dr.Jit code on concrete arrays (both cores)",
        f"{med['direct']:.0f} ns/lane; inside a symbolic call (`dr.switch`) with literal weights, the",
        f"plugin's path, {med['call']:.0f} ns/lane, with cooperative vectors there {med['call-coop']:.0f} ns/lane.",
        "Dr.Jit's LLVM fallback for cooperative vectors stores the input vector to the stack and",
        "loops over the weights; inside a call (Mitsuba's BSDF dispatch) it loads each weight with",
        "a masked vector gather, which literal weights avoid. What remains of the symbolic mode's",
        "cost: a call runs on whole packets for every instance present in the packet, and a",
        "symbolic loop keeps finished paths in their packet, where the evaluated mode compacts",
        "the lanes per bounce and per BSDF. The built-in BSDFs alone gain from symbolic mode",
        "(`roughconductor` rows).",
    ]


def main():
    ap = argparse.ArgumentParser()
    sub = ap.add_subparsers(dest="cmd", required=True)
    e = sub.add_parser("equal-time")
    e.add_argument("--budget", type=float, default=20.0, help="seconds per sampler")
    e.add_argument("--res", type=int, default=160)
    e.add_argument("--ref-spp", type=int, default=2048)
    e.add_argument("--seed", type=int, default=0)
    e.add_argument("--seeds", type=int, default=3, help="renders per sampler (different seeds)")
    s = sub.add_parser("speed")
    s.add_argument("--repeats", type=int, default=5)
    s.add_argument("--res", type=int, default=128)
    s.add_argument("--spp", type=int, default=16)
    a = ap.parse_args()
    if a.cmd == "equal-time":
        equal_time(a)
    else:
        speed(a)


if __name__ == "__main__":
    sys.exit(main())
