"""`neusample.MeasuredMaterial` against Mitsuba 3's `measured` BSDF (scalar_rgb, the reference
of `tools/measured_reference.py`): eval, pdf and sample on 10 000 random direction pairs per
RGL fixture file and per anisotropic file built here with numpy; bad files; lane isolation,
threads and array checks.

The Mitsuba comparisons need `mitsuba==3.9.1`; without it they are skipped, unless
NEUSAMPLE_REQUIRE_MITSUBA=1 (CI), which makes them fail. The rest needs only numpy.

Tolerances (each on at least 99.9 % of the pairs of a file):
- eval: the BRDF without the cosine, per RGB channel, |ours − ref| ≤ 1e-3 · max(ref, floor)
  with ref = max(Mitsuba's value, 0) (the reader reads the data's slightly negative RGB noise
  as 0) and floor = 1e-6 × the largest reference value of the file;
- pdf: |ours − ref| ≤ 1e-3 · max(ref, floor) (solid angle), floor = 1e-6 × the file's
  largest reference pdf: at grazing pairs (θi or θo ≥ 84°) whose pdf is ~1e-5 of the peak,
  f32 rounding moves Mitsuba's own pdf by up to 6e-2 from a float64 evaluation of the same
  tables (and ours by up to 3e-2), so 1e-3 there measures rounding, not the method;
- sample, same (u1, u2): the same direction within 1e-3 (largest component difference; a
  sample refused by one side and not the other counts as a miss) and the same pdf within
  1e-3 relative.
Besides, at our own sampled directions, pdf(wo) is the sample's pdf and the weight is
eval(wo)·cos θo / pdf within 1e-3 on 99 % and 1e-2 on 99.9 % of the samples (the VNDF's
inversion is ill-conditioned where the tables are steep: Mitsuba's own round trip needs as
much on the anisotropic files).
"""

import struct
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import neusample
from conftest import FIXTURES, ROOT, optional


def _scalar_rgb():
    import mitsuba as mi

    # Checked, not set: the reference sets scalar_rgb while it runs and `mitsuba_reference`
    # restores the variant that other modules (test_mitsuba: llvm_ad_rgb) set at import.
    if "scalar_rgb" not in mi.variants():
        raise ImportError(f"mitsuba {mi.__version__} lacks the scalar_rgb variant")
    return mi


mi, _why = optional(_scalar_rgb)
HAVE_MITSUBA = mi is not None
WHY = f"mitsuba scalar_rgb unavailable: {_why}"

needs_mitsuba = pytest.mark.skipif(not HAVE_MITSUBA, reason=WHY)

sys.path.insert(0, str(ROOT / "tools"))
from measured_reference import directions, reference  # noqa: E402

MEASURED = sorted((FIXTURES / "measured").glob("*.bsdf"))
PAIRS = 10_000
RTOL = 1e-3
FLOOR = 1e-6  # × the file's largest reference value (eval and pdf)
SAMPLE_ATOL = 1e-3
SHARE = 0.999  # of the pairs within tolerance

# ---------------------------------------------------------------------------------------------
# Tensor files (Mitsuba's `tensor_file` format, see bindings/owned/src/measured.rs)

U8, F32 = 1, 10


def write_tensor_file(path, fields):
    """Writes `fields` ({name: uint8 or float32 array}, in order) as a tensor file, each
    field's data at an 8-byte-aligned offset."""
    header_len = 12 + 2 + 4
    for name, a in fields.items():
        header_len += 2 + len(name.encode()) + 2 + 1 + 8 + 8 * a.ndim
    offset = (header_len + 7) // 8 * 8
    header = bytearray(b"tensor_file\0" + bytes([1, 0]) + struct.pack("<I", len(fields)))
    data = bytearray()
    for name, a in fields.items():
        code = {np.dtype(np.uint8): U8, np.dtype(np.float32): F32}[a.dtype]
        raw = np.ascontiguousarray(a).astype(a.dtype.newbyteorder("<")).tobytes()
        header += struct.pack("<H", len(name.encode())) + name.encode()
        header += struct.pack("<HBQ", a.ndim, code, offset + len(data))
        header += struct.pack(f"<{a.ndim}Q", *a.shape)
        data += raw + bytes(-len(raw) % 8)
    assert len(header) == header_len
    header += bytes(offset - header_len)
    Path(path).write_bytes(bytes(header + data))


def smooth_table(rng, shape, base=0.05):
    """A smooth positive random-ish table over the last two axes (low-frequency cosines of
    random phases and amplitudes, per leading index, plus a Gaussian bump at a random place)."""
    *lead, h, w = shape
    y = np.linspace(0, 1, h)[:, None]
    x = np.linspace(0, 1, w)[None, :]
    out = np.empty(shape, np.float64)
    for idx in np.ndindex(*lead):
        v = np.full((h, w), 1.0)
        for _ in range(3):
            kx, ky = rng.integers(0, 3, size=2)
            px, py = rng.random(2) * 2 * np.pi
            v += 0.3 * rng.random() * np.cos(kx * np.pi * x + px) * np.cos(ky * np.pi * y + py)
        cx, cy, s = rng.random(), rng.random(), 0.1 + 0.3 * rng.random()
        v += 3 * rng.random() * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * s * s))
        out[idx] = np.maximum(v, 0) + base
    return out.astype(np.float32)


def anisotropic_fields(seed, phi_nodes, n_theta=4, jacobian=1, negative_rgb=False):
    """The fields of an anisotropic measured material with `phi_nodes` incident azimuths."""
    rng = np.random.default_rng(seed)
    n_phi = len(phi_nodes)
    theta = np.linspace(0.0, 1.45, n_theta).astype(np.float32)
    n = 12  # luminance / rgb slices: n × n
    rgb = smooth_table(rng, (n_phi, n_theta, 3, n, n))
    if negative_rgb:
        # Measurement noise: a few slightly negative values (read as 0).
        mask = rng.random(rgb.shape) < 0.02
        rgb[mask] = -0.01 * rng.random(mask.sum()).astype(np.float32)
    desc = f"synthetic anisotropic material, seed {seed}".encode()
    return {
        "description": np.frombuffer(desc, np.uint8).copy(),
        "phi_i": np.asarray(phi_nodes, np.float32),
        "theta_i": theta,
        "ndf": smooth_table(rng, (20, 16)),
        "sigma": smooth_table(rng, (10, 18), base=0.5),
        "vndf": smooth_table(rng, (n_phi, n_theta, 24, 20)),
        "luminance": smooth_table(rng, (n_phi, n_theta, n, n)),
        "rgb": rgb,
        "jacobian": np.array([jacobian], np.uint8),
    }


# (name, φi nodes, jacobian, negative rgb values): no symmetry (reduction 1), mirrored in y
# (reduction 2: φi ∈ [−π, 0]), mirrored in x and y (reduction 4, φi ∈ [−π, −π/2] where the
# folded wi lies, and [0, π/2], whose nodes the folded wi lies outside of).
ANISOTROPIC = [
    ("full", np.linspace(-np.pi, np.pi, 5), 1, False),
    ("half", np.linspace(-np.pi, 0.0, 5), 0, True),
    ("quarter", np.linspace(-np.pi, -np.pi / 2, 3), 1, False),
    ("quarter-first-quadrant", np.linspace(0.0, np.pi / 2, 3), 1, True),
]

# ---------------------------------------------------------------------------------------------
# Comparison with Mitsuba


def mitsuba_reference(path, wi, wo, u):
    """`reference` in scalar_rgb, leaving Mitsuba's variant as it was (other test modules set
    llvm_ad_rgb at import)."""
    previous = mi.variant()
    try:
        return reference(path, wi, wo, u)
    finally:
        if previous is not None and previous != mi.variant():
            mi.set_variant(previous)


def compare(path, seed, capsys):
    """Compares eval, pdf and sample with Mitsuba on PAIRS pairs; asserts the tolerances and
    prints the worst errors."""
    rng = np.random.default_rng(seed)
    wi, wo, u = directions(rng, PAIRS)
    t0 = time.perf_counter()
    f_ref, pdf_ref, swo_ref, spdf_ref = mitsuba_reference(path, wi, wo, u)
    t_ref = time.perf_counter() - t0

    t0 = time.perf_counter()
    m = neusample.MeasuredMaterial(path)
    t_open = time.perf_counter() - t0
    wi_t, wo_t, u_t = (np.ascontiguousarray(a.T) for a in (wi, wo, u))
    t0 = time.perf_counter()
    f = m.eval(wi_t, wo_t).T.astype(np.float64)
    pdf = m.pdf(wi_t, wo_t).astype(np.float64)
    swo, spdf, sweight = m.sample(wi_t, u_t)
    t_ours = time.perf_counter() - t0
    swo, spdf = swo.T.astype(np.float64), spdf.astype(np.float64)

    # eval (no cosine), RGB
    ref = np.maximum(f_ref, 0.0)
    floor = FLOOR * ref.max()
    f_err = (np.abs(f - ref) / np.maximum(ref, floor)).max(axis=1)
    # pdf (solid angle)
    pdf_floor = FLOOR * pdf_ref.max()
    pdf_err = np.abs(pdf - pdf_ref) / np.maximum(pdf_ref, pdf_floor)
    pdf_err[(pdf_ref == 0) & (pdf != 0)] = np.inf
    # sample: direction and pdf; refused on one side only is a miss
    ours_ok, ref_ok = spdf > 0, spdf_ref > 0
    dir_err = np.abs(swo - swo_ref).max(axis=1)
    spdf_err = np.abs(spdf - spdf_ref) / np.where(spdf_ref > 0, spdf_ref, 1.0)
    dir_err[ours_ok != ref_ok] = np.inf
    spdf_err[ours_ok != ref_ok] = np.inf

    rows = [
        ("eval", f_err, RTOL),
        ("pdf", pdf_err, RTOL),
        ("sample wo", dir_err, SAMPLE_ATOL),
        ("sample pdf", spdf_err, RTOL),
    ]
    with capsys.disabled():
        print(
            f"\n{Path(path).name}: {PAIRS} pairs, Mitsuba scalar_rgb {t_ref:.2f} s, "
            f"neusample open {t_open * 1e3:.0f} ms + eval/pdf/sample {t_ours * 1e3:.1f} ms; "
            f"max f {ref.max():.4g}, sampled {ours_ok.mean():.4f} (Mitsuba {ref_ok.mean():.4f})"
        )
        for name, err, tol in rows:
            worst = int(np.argmax(err))
            print(
                f"  {name:<10} worst {err[worst]:.3e} (pair {worst}), "
                f"99.9th pct {np.quantile(err, SHARE):.3e}, "
                f"> {tol:g}: {int((err > tol).sum())} of {PAIRS}"
            )

    # Self-consistency of our sampler, at the sampled directions: pdf(wo) is the sample's pdf
    # and the weight is eval(wo)·cos θo / pdf. Both go through the VNDF's inversion, which is
    # ill-conditioned where the tables are steep: Mitsuba's own round trip (its pdf and eval at
    # its sampled wo) differs by more than 1e-3 on up to 0.3 % of the samples of the
    # anisotropic files here (99.9th percentile 1.2e-3 to 2.8e-3), ours on up to 0.6 % (4.6e-3 to
    # 5.1e-3); hence 1e-3 on 99 % and 1e-2 on 99.9 %.
    ok = ours_ok
    wo_s = np.ascontiguousarray(swo.T.astype(np.float32))
    p_s = m.pdf(wi_t, wo_s).astype(np.float64)
    f_s = m.eval(wi_t, wo_s).T.astype(np.float64)
    w_expect = f_s[ok] * swo[ok, 2:3] / spdf[ok, None]
    w = sweight.T[ok].astype(np.float64)
    scale = np.abs(w_expect).max() if ok.any() else 1.0
    w_rt = (np.abs(w - w_expect) / np.maximum(np.abs(w_expect), FLOOR * scale)).max(axis=1)
    p_rt = np.abs(p_s[ok] - spdf[ok]) / spdf[ok]
    with capsys.disabled():
        for name, err in (("pdf", p_rt), ("weight", w_rt)):
            print(
                f"  round trip {name:<6}: 99th pct {np.quantile(err, 0.99):.2e}, "
                f"99.9th pct {np.quantile(err, SHARE):.2e}, > 1e-3: {int((err > 1e-3).sum())} "
                f"of {ok.sum()}"
            )
    for err in (p_rt, w_rt):
        assert np.quantile(err, 0.99) <= 1e-3 and np.quantile(err, SHARE) <= 1e-2
    assert np.all(sweight[:, ~ok] == 0) and np.all(swo[~ok] == 0)
    assert np.all(np.isfinite(sweight)) and np.all(sweight >= 0)

    for name, err, tol in rows:
        assert np.mean(err <= tol) >= SHARE, (
            f"{Path(path).name}: {name}: {int((err > tol).sum())} of {PAIRS} pairs above {tol}, "
            f"worst {err.max():.3e}"
        )


@needs_mitsuba
@pytest.mark.parametrize("path", MEASURED, ids=[p.stem for p in MEASURED])
def test_rgl_files_agree_with_mitsuba(path, capsys):
    assert len(MEASURED) == 5
    m = neusample.MeasuredMaterial(path)
    assert m.isotropic and m.description
    compare(path, seed=7 + MEASURED.index(path), capsys=capsys)


@needs_mitsuba
@pytest.mark.parametrize("name,phi,jacobian,negative", ANISOTROPIC, ids=[a[0] for a in ANISOTROPIC])
def test_anisotropic_file_agrees_with_mitsuba(tmp_path, capsys, name, phi, jacobian, negative):
    path = tmp_path / f"aniso_{name}.bsdf"
    write_tensor_file(path, anisotropic_fields(11, phi, jacobian=jacobian, negative_rgb=negative))
    m = neusample.MeasuredMaterial(path)
    assert not m.isotropic
    assert m.description == "synthetic anisotropic material, seed 11"
    compare(str(path), seed=101, capsys=capsys)


# ---------------------------------------------------------------------------------------------
# Bad files


def test_bad_files_raise_measured_file_error(tmp_path):
    with pytest.raises(FileNotFoundError) as e:
        neusample.MeasuredMaterial(tmp_path / "missing.bsdf")
    assert "missing.bsdf" in str(e.value)

    def refused(fields_or_bytes, name):
        path = tmp_path / f"{name}.bsdf"
        if isinstance(fields_or_bytes, bytes):
            path.write_bytes(fields_or_bytes)
        else:
            write_tensor_file(path, fields_or_bytes)
        with pytest.raises(neusample.MeasuredFileError) as e:
            neusample.MeasuredMaterial(path)
        assert isinstance(e.value, ValueError)
        assert e.value.path == str(path)
        assert str(e.value).startswith(str(path) + ": ")
        return e.value

    good = anisotropic_fields(3, np.linspace(-np.pi, np.pi, 5))
    ok = tmp_path / "good.bsdf"
    write_tensor_file(ok, good)
    neusample.MeasuredMaterial(ok)
    data = ok.read_bytes()

    # Truncated inside the data: the first field that runs past the end is named (an RGL
    # file's `vndf` takes up 80 % of it; the fields before it stay whole).
    rgl = Path(MEASURED[-1]).read_bytes()
    e = refused(rgl[: len(rgl) // 2], "truncated")
    assert e.field == "vndf" and "truncated" in str(e), str(e)
    # Truncated inside the header: the file as a whole.
    e = refused(data[:40], "truncated_header")
    assert e.field is None and "truncated header" in str(e), str(e)
    e = refused(b"tensor_filX\0" + data[12:], "magic")
    assert e.field is None and "not a tensor file" in str(e), str(e)
    e = refused({k: v for k, v in good.items() if k != "vndf"}, "no_vndf")
    assert e.field == "vndf" and "field `vndf`: missing" in str(e), str(e)
    nan = dict(good, rgb=good["rgb"].copy())
    nan["rgb"][2, 1, 0, 3, 4] = np.nan
    e = refused(nan, "nan_rgb")
    assert e.field == "rgb" and "finite" in str(e), str(e)
    e = refused(dict(good, rgb=good["rgb"][:, :, :2].copy()), "two_channels")
    assert e.field == "rgb" and "three channels" in str(e), str(e)
    e = refused(dict(good, luminance=-good["luminance"]), "negative_luminance")
    assert e.field == "luminance" and "negative" in str(e), str(e)

    # The fixtures' RGL files read.
    for p in MEASURED:
        assert neusample.MeasuredMaterial(str(p)).path == str(p)


# ---------------------------------------------------------------------------------------------
# Lanes, threads, arrays


def lanes(n, seed=5):
    rng = np.random.default_rng(seed)
    wi, wo, u = directions(rng, n)
    return tuple(np.ascontiguousarray(a.T) for a in (wi, wo, u))


def test_bad_lanes_give_zero_and_never_disturb_others():
    m = neusample.MeasuredMaterial(MEASURED[0])
    wi, wo, u = lanes(64)
    f_ref, pdf_ref = m.eval(wi, wo), m.pdf(wi, wo)
    s_ref = m.sample(wi, u)
    wi_b, wo_b, u_b = wi.copy(), wo.copy(), u.copy()
    wi_b[0, 3] = np.nan
    wi_b[2, 5] = -0.5
    wi_b[:, 7] = 0.0
    wo_b[1, 9] = np.inf
    wo_b[2, 11] = -0.2
    u_b[0, 13] = 1.5
    u_b[1, 15] = np.nan
    bad_eval = [3, 5, 7, 9, 11]
    bad_sample = [3, 5, 7, 13, 15]
    f, pdf = m.eval(wi_b, wo_b), m.pdf(wi_b, wo_b)
    wo_s, pdf_s, w_s = m.sample(wi_b, u_b)
    assert np.all(f[:, bad_eval] == 0) and np.all(pdf[bad_eval] == 0)
    assert np.all(wo_s[:, bad_sample] == 0) and np.all(pdf_s[bad_sample] == 0)
    assert np.all(w_s[:, bad_sample] == 0)
    for a in (f, pdf, wo_s, pdf_s, w_s):
        assert np.all(np.isfinite(a))
    keep = np.setdiff1d(np.arange(64), bad_eval)
    np.testing.assert_array_equal(f[:, keep], f_ref[:, keep])
    np.testing.assert_array_equal(pdf[keep], pdf_ref[keep])
    keep = np.setdiff1d(np.arange(64), bad_sample)
    for a, b in zip((wo_s, pdf_s, w_s), s_ref):
        np.testing.assert_array_equal(a[..., keep], b[..., keep])
    # Directions need not be unit length (normalised here; power-of-two scales are exact).
    np.testing.assert_array_equal(m.eval(4 * wi, 0.5 * wo), f_ref)
    np.testing.assert_array_equal(m.pdf(0.25 * wi, 8 * wo), pdf_ref)
    for a, b in zip(m.sample(2 * wi, u), s_ref):
        np.testing.assert_array_equal(a, b)


def test_threads_are_bit_identical_and_samples_consistent():
    m = neusample.MeasuredMaterial(MEASURED[-1])
    wi, wo, u = lanes(3000, seed=9)
    f, pdf = m.eval(wi, wo), m.pdf(wi, wo)
    assert f.shape == (3, 3000) and f.dtype == np.float32 and pdf.shape == (3000,)
    np.testing.assert_array_equal(m.eval(wi, wo, threads=2), f)
    np.testing.assert_array_equal(m.eval(wi, wo, threads=0), f)
    np.testing.assert_array_equal(m.pdf(wi, wo, threads=3), pdf)
    s = m.sample(wi, u)
    assert s[0].shape == (3, 3000) and s[1].shape == (3000,) and s[2].shape == (3, 3000)
    for a, b in zip(m.sample(wi, u, threads=2), s):
        np.testing.assert_array_equal(a, b)
    wo_s, pdf_s, _ = s
    ok = pdf_s > 0
    assert ok.mean() > 0.9
    np.testing.assert_allclose(np.linalg.norm(wo_s[:, ok], axis=0), 1, atol=1e-5)
    assert np.all(wo_s[2, ok] > 0)


def test_empty_batches_and_wrong_arrays():
    m = neusample.MeasuredMaterial(MEASURED[0])
    z3, z2 = np.zeros((3, 0), np.float32), np.zeros((2, 0), np.float32)
    assert m.eval(z3, z3).shape == (3, 0) and m.pdf(z3, z3).shape == (0,)
    wo, pdf, w = m.sample(z3, z2)
    assert wo.shape == (3, 0) and pdf.shape == (0,) and w.shape == (3, 0)
    wi, wo, u = lanes(4)
    with pytest.raises(TypeError, match="float32"):
        m.eval(wi.astype(np.float64), wo)
    with pytest.raises(ValueError, match=r"shape \(3, N\)"):
        m.pdf(wi.T.copy(), wo)
    with pytest.raises(ValueError, match=r"shape \(2, N\)"):
        m.sample(wi, wi)
    with pytest.raises(ValueError, match="N = 3"):
        m.sample(wi, u[:, :3].copy())
    with pytest.raises(ValueError, match="C-contiguous"):
        m.eval(np.asfortranarray(wi), wo)
    assert "MeasuredMaterial" in repr(m)
    assert m.eval.__doc__ and "without" in m.eval.__doc__
    assert "solid angle" in m.pdf.__doc__ and "solid angle" in m.sample.__doc__
