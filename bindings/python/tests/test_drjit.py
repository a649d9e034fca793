"""The Dr.Jit runtime (`neusample.drjit`) against the Rust scalar runtime, on every fixture
blob of the kinds it implements (and the f16/compact blobs in tests/data), on Dr.Jit's LLVM
backend: pdfs at the same directions, samples, features and BRDF values.

Tolerances (the measured worst cases are printed at the end of the run):
- pdf at the same direction, relative: PDF_RTOL on every lane (f32 networks; Dr.Jit's
  exp/log/sin/cos are its own few-ulp approximations, not libm's). The flows' steep splines
  (slopes up to e⁴ and more) amplify f32 rounding beyond that on a few lanes, where the Rust
  runtime is itself as far from the f64 evaluation of the same model
  (`f64_errors` measures it): for flows at most FLOW_OUTLIERS of the lanes may exceed
  PDF_RTOL, and a flow with a lane beyond FLOW_RTOL must be no farther from its f64
  evaluation than 1.5× the Rust runtime is;
- samples: the sampling maps are discontinuous (mixture component choice, histogram cell
  search), so a lane whose uniform lies within rounding of a boundary can land elsewhere:
  at most SAMPLE_OUTLIERS of the lanes may differ by more than SAMPLE_ATOL (scaled by N/32
  for histogram tables finer than 32², whose cell boundaries are denser); every Dr.Jit
  sample's pdf must equal the Rust pdf of that direction within PDF_RTOL;
- the histogram mixture's nearest latent level is a step in the network's output: a lane
  whose level lies within f32 rounding of a half-integer may read the neighbouring slice, so
  at most HM_LEVEL_FLIPS of its lanes may exceed PDF_RTOL;
- the reparameterization sampler's samples carry the warp's own density N(z)/det J, compared
  with the Rust sample's at the same uniforms within REPARAM_Q_RTOL (det J is a difference of
  products of tangents, so f32 rounding reaches ~5·10⁻⁴ relative on the sharper warps trained
  with 3× steps; measured worst is printed; a Jacobian off by 1 % fails);
  its pdf network (the MIS density, `pdf` and the fourth value of `sample_mis`) is held to
  PDF_RTOL like every other pdf.
"""

import functools
from pathlib import Path

import numpy as np
import pytest

import neusample
from conftest import FIXTURES, material_path, optional



def _llvm():
    import drjit as dr
    from drjit.llvm.ad import Float

    if not dr.has_backend(dr.JitBackend.LLVM):
        raise RuntimeError("Dr.Jit's LLVM backend is unavailable (libLLVM ≥ 15 missing)")
    return dr, Float


_got, _why = optional(_llvm)
if _got is None:
    pytest.skip(f"drjit llvm unavailable: {_why}", allow_module_level=True)
dr, Float = _got

import neusample.drjit as nd  # noqa: E402

DATA = Path(__file__).with_name("data")
LANES = 4096
PDF_RTOL = 1e-4
FLOW_RTOL = 3e-3
FLOW_OUTLIERS = 1e-2
SAMPLE_ATOL = 1e-4
SAMPLE_OUTLIERS = 2e-3
HM_LEVEL_FLIPS = 1e-3
REPARAM_Q_RTOL = 1e-3
# An isotropic blob's directions are turned about the normal and back: an ulp or two of the
# disk point, which a lobe of width σ at distance x from its mean turns into ~x/σ² ulps of
# relative density (the mint's narrow lobes: up to 5e-4, the Rust runtime's sample pdf
# against its own pdf included).
ISOTROPIC_RTOL = 1e-3
ISOTROPIC_OUTLIERS = 1e-3
EVAL_RTOL = 1e-4

SAMPLER_BLOBS = sorted(
    str(p) for p in FIXTURES.glob("blobs/*/*.nsb") if neusample.Blob(str(p)).kind in nd.KINDS
) + sorted(str(p) for p in DATA.glob("*.nsb")) + sorted(
    # Isotropic samplers (trained on a measured file: wi turned to azimuth 0).
    str(p) for p in FIXTURES.glob("measured/blobs/chm_mint/*.nsb")
)
MATERIAL_BLOBS = sorted(str(p) for p in FIXTURES.glob("materials/neural/*.nsb"))

RESULTS = []  # rows printed by conftest.pytest_terminal_summary


def lanes(n=LANES, seed=0):
    """Random conditions: φ of a fixture material at random uv, cosine-distributed wi with a
    few below the horizon and not normalised, uniforms with both ends."""
    rng = np.random.default_rng(seed)
    m = neusample.NeuralMaterial(material_path("goat_leather_neural"))
    uv = (rng.random((2, n)) * 3 - 1).astype(np.float32)
    phi = m.features_scalar(uv)
    cos = np.sqrt(rng.random(n))
    ang = rng.random(n) * 2 * np.pi
    sin = np.sqrt(1 - cos * cos)
    wi = np.stack([sin * np.cos(ang), sin * np.sin(ang), cos]).astype(np.float32)
    wi[2, : n // 64] *= -1  # below the horizon: refused
    wi[:, n // 64 : n // 32] *= 1.5  # not unit length: normalised
    u = rng.random((2, n)).astype(np.float32)
    u[:, :4] = [[0.0, 1.0, 0.0, 0.5], [0.0, 0.5, 1.0, 0.0]]
    return uv, np.ascontiguousarray(phi), wi, u


def jit(a):
    return [Float(np.ascontiguousarray(r)) for r in a]


def numpy(vals):
    dr.eval(vals)
    return np.stack([np.array(v) for v in vals])


def rel_errs(a, b):
    """|a − b| / |b| per lane where b > 0; a must be 0 where b is."""
    pos = b > 0
    assert np.array_equal(a > 0, pos), f"zero pattern differs on {((a > 0) != pos).sum()} lanes"
    return np.abs(a[pos] - b[pos]) / b[pos] if pos.any() else np.zeros(1)


def rel_err(a, b):
    return float(np.max(rel_errs(a, b)))


def short(path):
    return str(Path(path).relative_to(FIXTURES.parent)) if FIXTURES.parent in Path(path).parents else path


@pytest.fixture(scope="module")
def conditions():
    return lanes()


@pytest.mark.parametrize("path", SAMPLER_BLOBS + [None], ids=lambda p: short(p) if p else "cosine")
def test_sampler_matches_the_rust_scalar_runtime(path, conditions):
    _, phi, wi, u = conditions
    rust = neusample.Sampler(path) if path else neusample.Sampler()
    d = nd.Sampler(path, Float)
    assert d.alpha == pytest.approx(rust.alpha)
    wo_r, pdf_r, mis_r = rust.sample_scalar(phi, wi, u)
    st, ok = d.prepare(jit(phi), jit(wi))
    wo_d, pdf_d, ok_d, mis_d = d.sample_mis(st, ok, jit(u))
    wo_d, pdf_d, ok_d, mis_d = numpy(wo_d), np.array(pdf_d), np.array(ok_d), np.array(mis_d)

    # Densities at the same directions: Rust's samples, and cosine directions (some below
    # the horizon).
    q_r = np.array(d.pdf(jit(phi), jit(wi), jit(wo_r)))
    at_samples = rel_errs(q_r, rust.pdf_scalar(phi, wi, wo_r))
    probe = neusample.Sampler().sample_scalar(phi, wi, np.ascontiguousarray(u[::-1]))[0]
    probe[2, ::7] *= -1
    probe = np.ascontiguousarray(probe)
    at_probe = rel_errs(np.array(d.pdf(jit(phi), jit(wi), jit(probe))), rust.pdf_scalar(phi, wi, probe))

    # Samples: the same lanes refused or drawn, the same directions up to the boundary
    # outliers, and every Dr.Jit sample's pdf is the Rust density of its direction.
    agree = np.mean(ok_d == (pdf_r > 0))
    both = ok_d & (pdf_r > 0)
    far = np.max(np.abs(wo_d - wo_r), axis=0)[both] > SAMPLE_ATOL
    pdf_at_own = rust.pdf_scalar(phi, wi, np.ascontiguousarray(wo_d))
    mis_err = rel_errs(np.where(ok_d, mis_d, 0), pdf_at_own)
    # Rust's samples say whether the kind's samples carry its pdf (every kind but reparam).
    exact = np.array_equal(pdf_r, mis_r)
    assert d.kind.exact == exact
    if exact:
        assert np.array_equal(mis_d, pdf_d), "an exact kind's MIS density is its sample's"
        at_own = rel_errs(np.where(ok_d, pdf_d, 0), pdf_at_own)
    else:
        # The sample's own density (the warp's, from its Jacobian) against the Rust
        # sample's at the same uniforms; the MIS density is the pdf network's, as Rust's pdf.
        same = np.zeros_like(both)
        same[both] = ~far
        q_err = float(rel_errs(pdf_d[same], pdf_r[same]).max())
        REPARAM_Q.append((short(path), q_err))
        assert q_err <= REPARAM_Q_RTOL, f"the warp's sample density differs by {q_err:.2e}"
        at_own = mis_err
    assert np.all(pdf_d[~ok_d] == 0) and np.all(wo_d[:, ~ok_d] == 0) and np.all(mis_d[~ok_d] == 0)
    assert not ok_d[: LANES // 64].any(), "a below-horizon wi must be refused"
    errs = np.concatenate([at_samples, at_probe, at_own])
    above = float(np.mean(errs > PDF_RTOL))
    RESULTS.append((short(path) if path else "cosine", d.alpha, float(errs.max()), above,
                    1 - agree, far.mean()))
    moved = SAMPLE_OUTLIERS
    if d.name == "flow":
        assert above <= FLOW_OUTLIERS
        if errs.max() > FLOW_RTOL:
            # Steeper splines than FLOW_RTOL allows for: the difference must be f32 rounding,
            # i.e. the Rust runtime as far from the f64 evaluation as Dr.Jit is.
            rust_err, drjit_err, _ = f64_errors(path)
            assert drjit_err <= 1.5 * rust_err
    elif d.name == "histogram-mixture" and not d.kind.linear:
        assert above <= HM_LEVEL_FLIPS
        moved *= max(1.0, d.kind.n / 32)
    elif d.isotropic:
        assert errs.max() <= ISOTROPIC_RTOL and above <= ISOTROPIC_OUTLIERS
    else:
        assert errs.max() <= PDF_RTOL
    assert 1 - agree <= SAMPLE_OUTLIERS and far.mean() <= moved


@functools.lru_cache(maxsize=None)
def f64_errors(path):
    """The largest relative pdf differences of the Rust f32 runtime and of Dr.Jit's f32 from
    the f64 evaluation of the same model (explicit sums on Float64), and the 99.9 % quantiles
    of both, at the Rust samples of :func:`lanes`. Costs ~15 s per blob (tracing the unrolled
    f64 networks)."""
    from drjit.llvm.ad import Float64

    _, phi, wi, u = lanes()
    rust = neusample.Sampler(path)
    wo, pdf, _ = rust.sample_scalar(phi, wi, u)
    q32 = np.array(nd.Sampler(path, Float).pdf(jit(phi), jit(wi), jit(wo)))
    j64 = lambda a: [Float64(np.asarray(r, dtype=np.float64)) for r in a]  # noqa: E731
    q64 = np.array(nd.Sampler(path, Float64, precision="plain").pdf(j64(phi), j64(wi), j64(wo)))
    rust_err = rel_errs(pdf, q64)
    drjit_err = rel_errs(q32, q64)
    FLOW_F64.append((short(path), float(rust_err.max()), float(drjit_err.max()),
                     float(rel_errs(q32, pdf).max())))
    return (float(rust_err.max()), float(drjit_err.max()),
            (float(np.quantile(rust_err, 0.999)), float(np.quantile(drjit_err, 0.999))))


def test_flow_outliers_are_f32_rounding():
    """The flow lanes beyond PDF_RTOL: on the fixture flow with the largest difference, the
    f64 evaluation of the same model is as far from the Rust f32 runtime as from the Dr.Jit
    one; a real difference in definition would show up as Dr.Jit alone being far from it."""
    rust_err, drjit_err, (rust_q, drjit_q) = f64_errors(str(FIXTURES / "blobs" / "goat_leather" / "flow.nsb"))
    assert drjit_err <= 1.5 * rust_err
    assert drjit_q <= 2 * rust_q


FLOW_F64 = []  # (blob, Rust f32 vs f64, Dr.Jit f32 vs f64, Dr.Jit vs Rust)
REPARAM_Q = []  # (blob, largest relative difference of the warp's sample density)


@pytest.mark.parametrize("path", MATERIAL_BLOBS, ids=short)
def test_neural_material_matches_the_rust_scalar_runtime(path, conditions):
    uv, _, wi, u = conditions
    rust = neusample.NeuralMaterial(path)
    d = nd.NeuralMaterial(path, Float)
    phi_r = rust.features_scalar(uv)
    phi_d = numpy(d.features(*jit(uv)))
    phi_err = float(np.max(np.abs(phi_d - phi_r)) / np.max(np.abs(phi_r)))
    wo = neusample.Sampler().sample_scalar(phi_r, wi, u)[0]
    wo[2, ::5] *= -1  # below the horizon: f = 0
    wo = np.ascontiguousarray(wo)
    f_r = rust.eval_scalar(phi_r, wi, wo)
    f_d = numpy(d.eval(jit(phi_r), jit(wi), jit(wo)))
    f_err = rel_err(f_d, f_r)
    RESULTS.append((short(path), 0.0, max(f_err, phi_err), 0.0, 0.0, 0.0))
    assert phi_err <= 1e-6 and f_err <= EVAL_RTOL


def test_a_wrong_weight_is_detected():
    """Control: the comparison fails when one network weight differs by 1 %."""
    path = str(FIXTURES / "blobs" / "goat_leather_neural" / "analytic.nsb")
    _, phi, wi, u = lanes(512, seed=5)
    d = nd.Sampler(path, Float)
    params = neusample.Blob(path).tensor("params").copy()
    params[-2] += 0.01  # the logit of the first Gaussian
    d.kind = nd.AnalyticMixture(d.t, params, "f32")  # an array stands for the blob's params
    wo_r, _, _ = neusample.Sampler(path).sample_scalar(phi, wi, u)
    q = np.array(d.pdf(jit(phi), jit(wi), jit(wo_r)))
    with pytest.raises(AssertionError):
        assert rel_err(q, neusample.Sampler(path).pdf_scalar(phi, wi, wo_r)) <= PDF_RTOL


def test_half_precision_networks_are_self_consistent():
    """precision="f16" (what CUDA's cooperative vectors need), run on the LLVM backend: the
    pdf a sample reports is the pdf of its direction, and both stay near the f32 runtime."""
    path = str(FIXTURES / "blobs" / "goat_leather_neural" / "flow.nsb")
    _, phi, wi, u = lanes(1024, seed=2)
    d = nd.Sampler(path, Float, precision="f16")
    wo, pdf, ok = d.sample(jit(phi), jit(wi), jit(u))
    wo, pdf, ok = numpy(wo), np.array(pdf), np.array(ok)
    again = np.array(d.pdf(jit(phi), jit(wi), jit(wo)))
    assert ok.mean() > 0.9
    assert np.max(np.abs(again[ok] - pdf[ok]) / pdf[ok]) < 1e-3
    ref = neusample.Sampler(path).pdf_scalar(phi, wi, np.ascontiguousarray(wo))
    assert np.median(np.abs(pdf[ok] - ref[ok]) / ref[ok]) < 0.05


def test_refused_inputs_do_not_disturb_other_lanes():
    path = str(FIXTURES / "blobs" / "brushed_metal_neural" / "histogram-mixture.nsb")
    _, phi, wi, u = lanes(256, seed=9)
    d = nd.Sampler(path, Float)
    clean = numpy(d.sample(jit(phi), jit(wi), jit(u))[0])
    phi2, wi2, u2 = phi.copy(), wi.copy(), u.copy()
    phi2[3, 0] = np.nan
    wi2[:, 1] = np.inf
    u2[0, 2] = 1.5
    wi2[:, 3] = 0
    wo, pdf, ok = d.sample(jit(phi2), jit(wi2), jit(u2))
    wo, pdf, ok = numpy(wo), np.array(pdf), np.array(ok)
    assert not ok[:4].any() and np.all(pdf[:4] == 0) and np.all(np.isfinite(wo))
    np.testing.assert_array_equal(wo[:, 4:], clean[:, 4:])


def test_unimplemented_kinds_are_refused():
    path = str(FIXTURES / "blobs" / "goat_leather_neural" / "affine-flow.nsb")
    with pytest.raises(ValueError, match="not implemented"):
        nd.Sampler(path, Float)
    with pytest.raises(ValueError, match="not a neural material"):
        nd.NeuralMaterial(path, Float)
