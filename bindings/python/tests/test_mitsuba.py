"""Mitsuba 3 tests of the BSDF plugins: Mitsuba's own χ² test on every fixture sampler of the
three demo materials (and cosine) through the evaluated plugin, and in symbolic mode (the
plugin traced inside a symbolic loop, as the path integrator calls it: every sampler on one
material, on all three with NEUSAMPLE_FULL_TESTS=1); a deliberately
wrong pdf that the same test must reject; renders that converge to the same image with every
sampler; the symbolic render against the evaluated one; and the scalar variant.

Needs `mitsuba==3.9.1` and, for `llvm_ad_rgb`, a working LLVM (Debian: `libllvm19`). Without
them the module is skipped, unless NEUSAMPLE_REQUIRE_MITSUBA=1 (CI), which makes it fail.
"""

import os
import time

import numpy as np
import pytest

from conftest import FIXTURES, MATERIALS, METHODS, material_path, optional, sampler_path



def _llvm_ad_rgb():
    import drjit as dr
    import mitsuba as mi

    mi.set_variant("llvm_ad_rgb")
    return dr, mi


_got, _why = optional(_llvm_ad_rgb)
if _got is None:
    pytest.skip(f"mitsuba llvm_ad_rgb unavailable: {_why}", allow_module_level=True)
dr, mi = _got

import neusample.mitsuba as nsm  # noqa: E402
from mitsuba.chi2 import BSDFAdapter, ChiSquareTest, SphericalDomain  # noqa: E402

nsm.register()

# (wi, uv) per χ² run: normal, oblique and grazing incidence at three texels.
CONDITIONS = [
    ([0.0, 0.0, 1.0], [0.25, 0.5]),
    ([0.5, -0.3, 0.81240384], [0.77, 0.13]),
    ([-0.9, 0.2, 0.38729833], [0.5, 0.91]),
]
SAMPLES = 250_000
# Resolution of Mitsuba's pdf integration (ChiSquareTest `res`, `ires`). Its default, 101 × 4,
# integrates brushed metal's narrow lobe too coarsely: at res 101 its PDF sum came out
# 1.0086 against a histogram sum of 0.9944 (histogram mixture, normal incidence; rejected),
# at res 201, ires 8 both are 0.9944 (p = 0.10). The histograms themselves do not change.
RESOLUTION = {"brushed_metal_neural": (201, 8)}
DEFAULT_RESOLUTION = (101, 4)
# Šidák-corrected inside ChiSquareTest.run over every run of the suite.
SIGNIFICANCE = 0.01
SYMBOLIC_METHODS = ["baseline", "analytic", "flow", "histogram-mixture"]
# Nested BSDF: Mitsuba's `measured` on an RGL file, sampled by samplers trained on it
# (`neusample train --material fixtures/measured/<file>.toml`; all but the analytic mixture
# with --quick). The χ² runs on the white paper: the mint's samplers peak near
# 600 sr⁻¹ at the pole, where ChiSquareTest's (cos θ, φ) grid cannot integrate them (its PDF
# sum came out 12.96 at res 101, ires 4 and 1.3 % off at 401, 8 with 250 000 samples).
# Every sampler with an exact pdf, in each plugin that runs it (the symbolic plugin runs the
# kinds of `neusample.drjit.KINDS`). The reparameterization sampler is left out: its `pdf`
# is its pdf network's approximation of the density it samples, which a χ² test of samples
# against `pdf` rejects by design (`neusample reparam-exact` measures its exact density).
MEASURED = "paper_white"
MEASURED_SYMBOLIC = ["baseline", "analytic", "flow", "histogram-mixture"]
MEASURED_METHODS = MEASURED_SYMBOLIC + ["disk-flow", "affine-flow", "direct-histogram"]
MEASURED_RUNS = [(m, "symbolic") for m in MEASURED_SYMBOLIC] + [(m, "evaluated") for m in MEASURED_METHODS]
# The symbolic plugin's χ² runs: each sampler on every material with NEUSAMPLE_FULL_TESTS=1;
# otherwise (CI) each sampler on one material, a different one per sampler in turn (a symbolic
# run compiles its own Dr.Jit kernel: the flow's take 35-45 s per material).
FULL = os.environ.get("NEUSAMPLE_FULL_TESTS") == "1"
SYMBOLIC_RUNS = [
    (material, method)
    for k, method in enumerate(["cosine"] + SYMBOLIC_METHODS)
    for j, material in enumerate(MATERIALS)
    if FULL or j == k % len(MATERIALS)
]
TEST_COUNT = (len(MATERIALS) * (len(METHODS) + 1) + len(SYMBOLIC_RUNS)
              + len(MEASURED_RUNS)) * len(CONDITIONS)

CHI2_RESULTS = []  # rows printed by conftest.pytest_terminal_summary


def bsdf_dict(material, method, kind="neusample", mode="evaluated"):
    d = {"type": kind, "material": material_path(material), "mode": mode}
    path = sampler_path(material, method)
    if path is not None:
        d["sampler"] = path
    return d


def symbolic_adapter(bsdf, wi, uv):
    """sample/pdf functors for ChiSquareTest that call the plugin inside a symbolic loop of
    one iteration whose state holds the interaction and the samples, so that the plugin sees
    symbolic arrays, as in the path integrator's kernel (the evaluated plugin fails here)."""
    plugin = mi.load_dict(bsdf)
    ctx = mi.BSDFContext()

    def si_of(n):
        si = dr.zeros(mi.SurfaceInteraction3f, n)
        si.wi = wi
        si.uv = uv
        return si

    def sample_functor(sample, *args):
        n = dr.width(sample)

        def body(i, si, s, wo, w):
            bs, weight = plugin.sample(ctx, si, s[0], mi.Vector2f(s[1], s[2]), True)
            return i + 1, si, s, bs.wo, dr.select(dr.all(weight == 0), 0.0, 1.0)

        state = (dr.zeros(mi.UInt32, n), si_of(n), mi.Vector3f(sample),
                 dr.zeros(mi.Vector3f, n), dr.zeros(mi.Float, n))
        _, _, _, wo, w = dr.while_loop(state, lambda i, *_: i < 1, body, mode="symbolic")
        return wo, w

    def pdf_functor(wo, *args):
        n = dr.width(wo)

        def body(i, si, v, p):
            return i + 1, si, v, plugin.pdf(ctx, si, v, True)

        state = (dr.zeros(mi.UInt32, n), si_of(n), mi.Vector3f(wo), dr.zeros(mi.Float, n))
        return dr.while_loop(state, lambda i, *_: i < 1, body, mode="symbolic")[3]

    return sample_functor, pdf_functor


def measured_dict(method, mode, name=MEASURED):
    """The plugin wrapping Mitsuba's `measured` BSDF, sampled by the fixture blob of `method`."""
    return {"type": "neusample", "mode": mode,
            "sampler": str(FIXTURES / "measured" / "blobs" / name / f"{method}.nsb"),
            "bsdf": {"type": "measured",
                     "filename": str(FIXTURES / "measured" / f"{name}_rgb.bsdf")}}


def chi2(material, method, wi, uv, kind="neusample", samples=SAMPLES, mode="evaluated", d=None):
    if d is None:
        d = bsdf_dict(material, method, kind, "evaluated" if mode == "evaluated_in_symbolic" else mode)
    if mode in ("symbolic", "evaluated_in_symbolic"):
        sample_func, pdf_func = symbolic_adapter(d, wi, uv)
    else:
        sample_func, pdf_func = BSDFAdapter(kind, d, wi=wi, uv=uv)
    res, ires = RESOLUTION.get(material, DEFAULT_RESOLUTION)
    test = ChiSquareTest(
        domain=SphericalDomain(),
        sample_func=sample_func,
        pdf_func=pdf_func,
        sample_dim=3,
        sample_count=samples,
        res=res,
        ires=ires,
    )
    t = time.perf_counter()
    ok = test.run(SIGNIFICANCE, test_count=TEST_COUNT, quiet=True)
    return ok, float(test.p_value), time.perf_counter() - t, test


@pytest.mark.parametrize("material,method", SYMBOLIC_RUNS)
def test_chi2_symbolic_every_fixture_sampler(material, method):
    for k, (wi, uv) in enumerate(CONDITIONS):
        ok, p, secs, test = chi2(material, method, wi, uv, mode="symbolic")
        CHI2_RESULTS.append((material, f"{method} (symbolic)", k, wi, uv, p, ok, secs))
        assert ok, f"{material}/{method} wi={wi} uv={uv}: p = {p:.3g}\n{test.messages}"


def test_the_symbolic_adapter_really_traces_symbolically():
    """Control: the evaluated plugin cannot read symbolic arrays, so inside the adapter's
    symbolic loop it warns and returns zeros (no direction, weight 0, pdf 0)."""
    wi, uv = CONDITIONS[1]
    sample_func, pdf_func = symbolic_adapter(bsdf_dict("goat_leather_neural", "flow"), wi, uv)
    u = [mi.Float([0.3, 0.6]), mi.Float([0.2, 0.7]), mi.Float([0.4, 0.9])]
    with pytest.warns(RuntimeWarning, match="symbolic mode"):
        wo, w = sample_func(u)
        pdf = pdf_func(mi.Vector3f(0.0, 0.6, 0.8))
    assert np.all(np.array(w) == 0.0) and np.all(np.array(wo) == 0.0)
    assert np.all(np.array(pdf) == 0.0)


def test_a_live_evaluated_plugin_leaves_symbolic_renders_of_other_scenes_alone():
    """A symbolic call traces every live BSDF of the variant: with an evaluated-mode plugin
    alive in another scene, a symbolic render of a built-in BSDF still runs, to the same image."""
    def builtin_scene():
        d = scene_dict("goat_leather_neural", "flow", res=16)
        d["patch"]["bsdf"] = {"type": "roughconductor", "alpha": 0.3}
        return mi.load_dict(d)

    alone = np.array(mi.render(builtin_scene(), spp=8, seed=5), dtype=np.float64)
    other = mi.load_dict(scene_dict("goat_leather_neural", "flow", res=16, mode="evaluated"))
    with pytest.warns(RuntimeWarning, match="symbolic mode"):
        beside = np.array(mi.render(builtin_scene(), spp=8, seed=5), dtype=np.float64)
    assert other is not None
    assert np.allclose(alone, beside, rtol=1e-5, atol=1e-6)


@pytest.mark.parametrize("method", ["cosine"] + METHODS)
@pytest.mark.parametrize("material", MATERIALS)
def test_chi2_every_fixture_sampler(material, method):
    for k, (wi, uv) in enumerate(CONDITIONS):
        ok, p, secs, test = chi2(material, method, wi, uv)
        CHI2_RESULTS.append((material, method, k, wi, uv, p, ok, secs))
        assert ok, f"{material}/{method} wi={wi} uv={uv}: p = {p:.3g}\n{test.messages}"


@pytest.mark.parametrize("method,mode", MEASURED_RUNS)
def test_chi2_nested_measured_bsdf(method, mode):
    """The plugin around Mitsuba's `measured` BSDF: our sampler's directions against its pdf."""
    for k, (wi, _) in enumerate(CONDITIONS):
        ok, p, secs, test = chi2(MEASURED, method, wi, [0.5, 0.5], mode=mode, d=measured_dict(method, mode))
        CHI2_RESULTS.append((MEASURED, f"{method} (nested measured, {mode})", k, wi, [0.5, 0.5], p, ok, secs))
        assert ok, f"{MEASURED}/{method} ({mode}) wi={wi}: p = {p:.3g}\n{test.messages}"


@pytest.mark.parametrize("mode", ["symbolic", "evaluated"])
def test_nested_bsdf_eval_and_weight_come_from_it(mode):
    """eval is the nested BSDF's, pdf the sampler's at φ = 0 (the Dr.Jit flow
    within its agreement bound with the Rust runtime), and the sample weight the nested eval
    over the sampler's pdf; the mint's sharp lobe."""
    import neusample

    d = measured_dict("flow", mode, "chm_mint")
    plugin = mi.load_dict(d)
    plain = mi.load_dict(d["bsdf"])
    sampler = neusample.Sampler(d["sampler"])
    n = 4096
    rng = np.random.default_rng(5)
    ctx = mi.BSDFContext()
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    cos_i = rng.uniform(0.05, 1.0, n)
    phi_i = rng.uniform(0, 2 * np.pi, n)
    sin_i = np.sqrt(1 - cos_i ** 2)
    wi = np.stack([sin_i * np.cos(phi_i), sin_i * np.sin(phi_i), cos_i]).astype(np.float32)
    si.wi = mi.Vector3f(wi)
    u = rng.random((2, n)).astype(np.float32)
    with dr.scoped_set_flag(dr.JitFlag.SymbolicLoops, False), \
            dr.scoped_set_flag(dr.JitFlag.SymbolicCalls, False):
        bs, weight = plugin.sample(ctx, si, 0.5, mi.Point2f(u), True)
        wo = mi.Vector3f(np.array(bs.wo))  # concrete: both evals read the same bits
        f_nested = np.array(plain.eval(ctx, si, wo, True))
        f_plugin = np.array(plugin.eval(ctx, si, wo, True))
        pdf_plugin = np.array(plugin.pdf(ctx, si, wo, True))
    wo_np = np.array(bs.wo).astype(np.float32)
    pdf_ref = sampler.pdf(np.zeros((8, n), np.float32), wi, wo_np)
    ok = np.array(bs.pdf) > 0
    assert ok.mean() > 0.9
    # The same inputs in another compiled kernel: Mitsuba's `measured` eval rounds by an ulp
    # or so there (its RGB values cancel near zero, where that is 1e-3 relative).
    np.testing.assert_allclose(f_plugin, f_nested, rtol=1e-5, atol=1e-6 * np.abs(f_nested).max())
    np.testing.assert_allclose(pdf_plugin[ok], pdf_ref[ok], rtol=1e-3)
    np.testing.assert_allclose(np.array(bs.pdf)[ok], pdf_ref[ok], rtol=1e-3)
    expect = f_nested[:, ok] / pdf_ref[ok]
    np.testing.assert_allclose(np.array(weight)[:, ok], expect, rtol=1e-3, atol=1e-6 * np.abs(expect).max())


def test_the_plugin_needs_exactly_one_of_material_and_bsdf():
    d = measured_dict("flow", "symbolic")
    with pytest.raises(Exception, match="exactly one"):
        mi.load_dict({**d, "material": material_path("goat_leather_neural")})
    del d["bsdf"]
    with pytest.raises(Exception, match="exactly one"):
        mi.load_dict(d)


class WrongPdf(nsm.bsdf_class()):
    """The evaluated plugin with its pdf scaled by 1.05 (test only): χ² must reject it."""

    def _pdf(self, phi, wi, wo):
        return super()._pdf(phi, wi, wo) * np.float32(1.05)


class WrongPdfSymbolic(nsm.symbolic_bsdf_class()):
    """The symbolic plugin with its pdf scaled by 1.05 (test only): χ² must reject it."""

    def _pdf(self, phi, si, wo):
        return super()._pdf(phi, si, wo) * 1.05


nsm.register("neusample_wrongpdf", WrongPdf)
nsm.register("neusample_wrongpdf_symbolic", WrongPdfSymbolic)


@pytest.mark.parametrize("method", ["cosine", "flow", "histogram-mixture"])
def test_chi2_rejects_a_pdf_scaled_by_1_05(method):
    wi, uv = CONDITIONS[1]
    ok, p, secs, _ = chi2("goat_leather_neural", method, wi, uv, kind="neusample_wrongpdf")
    CHI2_RESULTS.append(("goat_leather_neural", f"{method} ×1.05 (control)", 1, wi, uv, p, ok, secs))
    assert not ok, f"the χ² test accepted a pdf scaled by 1.05 (p = {p:.3g})"
    ok, p, secs, _ = chi2("goat_leather_neural", method, wi, uv, kind="neusample_wrongpdf_symbolic",
                          mode="symbolic")
    CHI2_RESULTS.append(("goat_leather_neural", f"{method} ×1.05 (symbolic control)", 1, wi, uv, p, ok, secs))
    assert not ok, f"the χ² test accepted a symbolic pdf scaled by 1.05 (p = {p:.3g})"


# --- rendering -------------------------------------------------------------------------

def envmap_bitmap():
    """A small procedural sky: a bright warm sun patch over a blue gradient."""
    h, w = 32, 64
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    theta = (y + 0.5) / h * np.pi
    phi = (x + 0.5) / w * 2 * np.pi
    sky = np.stack([0.3 + 0.2 * np.cos(theta), 0.4 + 0.2 * np.cos(theta), 0.8 + 0.1 * np.cos(theta)], -1)
    sun = np.exp(-(((theta - 0.7) ** 2) + (phi - 2.0) ** 2) / 0.02)[..., None] * np.array([40.0, 36.0, 30.0])
    return mi.Bitmap((sky + sun).astype(np.float32))


def scene_dict(material, method, res=32, mode="evaluated"):
    return {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 3},
        "sensor": {
            "type": "perspective",
            "fov": 40,
            "to_world": mi.ScalarTransform4f().look_at(origin=[0, -2.2, 2.0], target=[0, 0, 0], up=[0, 0, 1]),
            "film": {"type": "hdrfilm", "width": res, "height": res, "pixel_format": "rgb"},
            "sampler": {"type": "independent"},
        },
        "emitter": {"type": "envmap", "bitmap": envmap_bitmap()},
        "patch": {
            "type": "rectangle",
            "to_world": mi.ScalarTransform4f().scale([1.2, 1.2, 1.0]),
            "bsdf": {**bsdf_dict(material, method, mode=mode), "uv_scale": 2.0},
        },
    }


def render(material, method, spp, seed=0, res=32, mode="evaluated"):
    scene = mi.load_dict(scene_dict(material, method, res, mode))
    img = mi.render(scene, spp=spp, seed=seed)
    return np.array(img, dtype=np.float64)


@pytest.fixture
def evaluated_flags():
    """Mitsuba's evaluated mode (symbolic loops and calls off) for one test, restored after."""
    loops = dr.flag(dr.JitFlag.SymbolicLoops)
    calls = dr.flag(dr.JitFlag.SymbolicCalls)
    nsm.evaluated_mode()
    yield
    dr.set_flag(dr.JitFlag.SymbolicLoops, loops)
    dr.set_flag(dr.JitFlag.SymbolicCalls, calls)



RENDER_BOUND = 0.01  # relative difference of image means allowed against the reference (largest seen: 0.0019)
SAME_SEED_BOUND = 1e-3  # symbolic vs evaluated render with the same samples
RENDER_RESULTS = []
REPARAM_RESULTS = []  # (material, weight rel. diff, bs.pdf rel. diff, share of lanes with p̂/q off by > 1 %)


def check_convergence(methods, mode):
    material = "goat_leather_neural"
    ref = render(material, "cosine", spp=256, seed=1000, mode=mode)
    ref_mean = ref.mean()
    assert np.isfinite(ref).all() and ref_mean > 0
    for method in methods:
        t = time.perf_counter()
        img = render(material, method, spp=64, seed=7, mode=mode)
        secs = time.perf_counter() - t
        rel = abs(img.mean() - ref_mean) / ref_mean
        rmse = float(np.sqrt(((img - ref) ** 2).mean()))
        RENDER_RESULTS.append((f"{method} ({mode})", img.mean(), ref_mean, rel, rmse, secs))
        assert np.isfinite(img).all()
        assert rel < RENDER_BOUND, f"{method}: image mean {img.mean():.5f} vs reference {ref_mean:.5f}"


def test_render_converges_to_the_same_image_with_every_sampler(evaluated_flags):
    check_convergence(["cosine"] + METHODS, "evaluated")


def test_symbolic_render_converges_to_the_same_image_with_every_sampler():
    check_convergence(["cosine"] + SYMBOLIC_METHODS + ["reparam"], "symbolic")


def test_render_helper_runs_under_evaluated_flags_and_restores_them():
    """`neusample.mitsuba.render`: the Rust plugin (which needs concrete arrays) renders
    through it under Mitsuba's default flags, which are the same afterwards. The control: a
    plain symbolic render traces the plugin, which warns and renders the patch black."""
    before = (dr.flag(dr.JitFlag.SymbolicLoops), dr.flag(dr.JitFlag.SymbolicCalls))
    scene = mi.load_dict(scene_dict("goat_leather_neural", "flow", 16, "evaluated"))
    img = np.array(nsm.render(scene, spp=4, seed=1))
    assert np.isfinite(img).all() and img.mean() > 0
    assert (dr.flag(dr.JitFlag.SymbolicLoops), dr.flag(dr.JitFlag.SymbolicCalls)) == before
    if all(before):
        with pytest.warns(RuntimeWarning, match="symbolic mode"):
            black = np.array(mi.render(scene, spp=4, seed=1))
        def dark(a):
            return float((a == 0).all(axis=-1).mean())  # share of pixels exactly black

        print(f"render helper: black pixels {dark(img):.3f}, symbolic render {dark(black):.3f}")
        assert dark(img) == 0.0 and dark(black) > 0.25


@pytest.mark.parametrize("method", ["flow", "histogram-mixture", "reparam"])
def test_symbolic_render_matches_the_evaluated_render(method):
    """The same scene, samples and seed in both modes (and the Dr.Jit plugin under the
    evaluated flags): the same image up to f32 rounding and the rare sample that lands across
    a discontinuity of the sampling map."""
    material = "goat_leather_neural"
    sym = render(material, method, spp=32, seed=3, mode="symbolic")
    loops, calls = dr.flag(dr.JitFlag.SymbolicLoops), dr.flag(dr.JitFlag.SymbolicCalls)
    nsm.evaluated_mode()
    try:
        ev = render(material, method, spp=32, seed=3, mode="evaluated")
        # The Dr.Jit plugin under the evaluated flags (called with concrete wavefronts).
        jit_ev = render(material, method, spp=32, seed=3, mode="symbolic")
    finally:
        dr.set_flag(dr.JitFlag.SymbolicLoops, loops)
        dr.set_flag(dr.JitFlag.SymbolicCalls, calls)
    for name, img in (("symbolic", sym), ("Dr.Jit plugin, evaluated flags", jit_ev)):
        rel = abs(img.mean() - ev.mean()) / ev.mean()
        rmse = float(np.sqrt(((img - ev) ** 2).mean()))
        RENDER_RESULTS.append((f"{method} {name} vs evaluated", img.mean(), ev.mean(), rel, rmse, 0.0))
        assert np.isfinite(img).all() and rel < SAME_SEED_BOUND


def test_symbolic_reparam_weighs_like_the_rust_plugin():
    """The reparameterization sampler, whose samples carry the warp's own density q while its
    pdf (for MIS) is the pdf network p̂: the symbolic plugin, called inside a symbolic loop,
    returns the same directions, weights f·cos/q and bs.pdf = p̂ as the evaluated (Rust)
    plugin on the same lanes, and bs.pdf is its own pdf() at the sampled direction."""
    n = 4096
    rng = np.random.default_rng(11)
    cos = np.sqrt(rng.random(n)).astype(np.float32)
    ang = (rng.random(n) * 2 * np.pi).astype(np.float32)
    sin = np.sqrt(1 - cos * cos)
    wi = mi.Vector3f(mi.Float(sin * np.cos(ang)), mi.Float(sin * np.sin(ang)), mi.Float(cos))
    uv = mi.Point2f(mi.Float(rng.random(n).astype(np.float32)), mi.Float(rng.random(n).astype(np.float32)))
    u = mi.Point2f(mi.Float(rng.random(n).astype(np.float32)), mi.Float(rng.random(n).astype(np.float32)))
    ctx = mi.BSDFContext()
    for material in MATERIALS:
        plugins = {mode: mi.load_dict(bsdf_dict(material, "reparam", mode=mode))
                   for mode in ("symbolic", "evaluated")}

        def si_of():
            si = dr.zeros(mi.SurfaceInteraction3f, n)
            si.wi, si.uv = wi, uv
            return si

        def body(i, si, s, wo, pdf, w, own):
            bs, weight = plugins["symbolic"].sample(ctx, si, 0.5, s, True)
            own = plugins["symbolic"].pdf(ctx, si, bs.wo, True)
            return i + 1, si, s, bs.wo, bs.pdf, weight, own

        state = (dr.zeros(mi.UInt32, n), si_of(), u, dr.zeros(mi.Vector3f, n), dr.zeros(mi.Float, n),
                 dr.zeros(mi.Color3f, n), dr.zeros(mi.Float, n))
        _, _, _, wo_s, pdf_s, w_s, own_s = dr.while_loop(state, lambda i, *_: i < 1, body, mode="symbolic")
        bs, w_e = plugins["evaluated"].sample(ctx, si_of(), 0.5, u, True)
        wo_s, wo_e = np.array(wo_s), np.array(bs.wo)
        pdf_s, pdf_e, own_s = np.array(pdf_s), np.array(bs.pdf), np.array(own_s)
        w_s, w_e = np.array(w_s)[0], np.array(w_e)[0]  # red; arrays are (3, n)
        drawn = (pdf_s > 0) & (pdf_e > 0)
        assert np.mean((pdf_s > 0) != (pdf_e > 0)) <= 2e-3
        same = drawn & (np.max(np.abs(wo_s - wo_e), axis=0) <= 1e-4)
        assert same.mean() >= 0.99 * drawn.mean()
        rel = lambda a, b: np.abs(a[same] - b[same]) / np.abs(b[same])  # noqa: E731
        lit = same & (w_e > 0)
        w_err = np.abs(w_s[lit] - w_e[lit]) / w_e[lit]
        # The weight is not f·cos/p̂: the two densities differ (else this test could not fail).
        value = np.array(plugins["evaluated"].eval(ctx, si_of(), mi.Vector3f(bs.wo), True))[0]
        ratio = w_e[lit] * pdf_e[lit] / value[lit]
        # p̂ at the same directions (the two plugins' directions differ by rounding, which a
        # sharp pdf network turns into ~4e-4 of p̂ between them).
        own_at_e = np.array(plugins["symbolic"].pdf(ctx, si_of(), mi.Vector3f(bs.wo), True))
        REPARAM_RESULTS.append((material, float(w_err.max()), float(rel(own_at_e, pdf_e).max()),
                                float(np.mean(np.abs(ratio - 1) > 1e-2))))
        assert rel(own_at_e, pdf_e).max() <= 1e-4, "bs.pdf is the pdf network's density, as in Rust"
        assert w_err.max() <= 1e-3, "the weight divides by the warp's own density, as in Rust"
        assert np.array_equal(pdf_s > 0, own_s > 0) and rel(pdf_s, own_s).max() <= 1e-6
        assert np.mean(np.abs(ratio - 1) > 1e-2) > 0.1


def test_scalar_rgb_variant_renders_and_samples():
    """The same plugin in `scalar_rgb` (Mitsuba calls it once per ray)."""
    mi.set_variant("scalar_rgb")
    try:
        nsm.register()
        bsdf = mi.load_dict(bsdf_dict("brushed_metal_neural", "flow", mode="symbolic"))
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(0.36, -0.48, 0.8)
        si.uv = mi.Point2f(0.3, 0.6)
        ctx = mi.BSDFContext()
        bs, weight = bsdf.sample(ctx, si, 0.5, mi.Point2f(0.3, 0.7))
        assert bs.pdf > 0 and bs.wo.z > 0
        value, pdf = bsdf.eval_pdf(ctx, si, bs.wo)
        assert abs(pdf - bs.pdf) <= 1e-6 * bs.pdf
        assert abs(bsdf.pdf(ctx, si, bs.wo) - bs.pdf) <= 1e-6 * bs.pdf
        np.testing.assert_allclose(np.array(weight), np.array(value) / pdf, rtol=1e-5)
        below = bsdf.eval(ctx, si, mi.Vector3f(0, 0.6, -0.8))
        assert np.all(np.array(below) == 0)
        img = np.array(mi.render(mi.load_dict(scene_dict("brushed_metal_neural", "flow", res=8)), spp=4))
        assert np.isfinite(img).all() and img.mean() > 0
    finally:
        mi.set_variant("llvm_ad_rgb")
