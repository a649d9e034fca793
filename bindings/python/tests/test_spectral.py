"""Spectral `.bsdf` files (`spectra` over `wavelengths` instead of `rgb`) in
`neusample.MeasuredMaterial`, which reads them in linear sRGB, against Mitsuba 3's own
spectral evaluation integrated over wavelength.

No spectral RGL file is committed: the files are built here, from the mint's tables (each
texel's spectrum a combination of three basis spectra weighted by its RGB values) and from
the anisotropic materials of `test_measured.py`, over irregular wavelengths that stop short of
the observer's range at both ends (Mitsuba clamps the spectrum outside them).

The reference: Mitsuba 3.9.1's RGB variants refuse spectral files, so `scalar_spectral`
evaluates the file at wavelengths. Its `eval` is linear in λ between the file's wavelengths
(and constant outside them), and its `cie1931_xyz` and `cie_d65` are linear between 5 nm
nodes, so `eval(λ) · (x̄, ȳ, z̄)(λ) · D65(λ)` is a cubic between consecutive nodes of the
merged set and Simpson's rule on that set integrates it exactly. XYZ / ∫ ȳ · D65 through
`mi.xyz_to_srgb`, divided by cos θo, is the reference for our `eval` (RGB without the cosine).
Tolerance as `test_measured.py`: relative 1e-3 (floor 1e-6 × the file's largest value) on
99.9 % of the pairs, for eval and pdf, and a median within 1e-5, which a systematic
difference (another table, normalisation or matrix) would exceed; the figures are printed.

The Mitsuba comparisons need `mitsuba==3.9.1` (skipped without it unless
NEUSAMPLE_REQUIRE_MITSUBA=1); the rest needs only numpy.
"""

import os
import struct
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import neusample
from conftest import FIXTURES, ROOT, optional
from test_measured import ANISOTROPIC, anisotropic_fields, write_tensor_file

sys.path.insert(0, str(ROOT / "tools"))
from measured_reference import directions  # noqa: E402


def _scalar_spectral():
    import mitsuba as mi

    if "scalar_spectral" not in mi.variants():
        raise ImportError(f"mitsuba {mi.__version__} lacks the scalar_spectral variant")
    return mi


mi, _why = optional(_scalar_spectral)
HAVE_MITSUBA = mi is not None
WHY = f"mitsuba scalar_spectral unavailable: {_why}"

needs_mitsuba = pytest.mark.skipif(not HAVE_MITSUBA, reason=WHY)

PAIRS = 1000
RTOL = 1e-3
MEDIAN = 1e-5  # the median relative error: a systematic difference (tables, normalisation)
FLOOR = 1e-6  # × the file's largest reference value
SHARE = 0.999
CIE_MIN, CIE_MAX, CIE_STEP = 360.0, 830.0, 5.0

# ---------------------------------------------------------------------------------------------
# Spectral files


def read_tensor_file(path):
    """The u8 and f32 fields of a tensor file ({name: array}); other types are skipped."""
    b = Path(path).read_bytes()
    (n,) = struct.unpack_from("<I", b, 14)
    p, out = 18, {}
    for _ in range(n):
        (length,) = struct.unpack_from("<H", b, p)
        name = b[p + 2 : p + 2 + length].decode()
        p += 2 + length
        ndim, code, offset = struct.unpack_from("<HBQ", b, p)
        p += 11
        shape = struct.unpack_from(f"<{ndim}Q", b, p)
        p += 8 * ndim
        dtype = {1: np.uint8, 10: np.float32}.get(code)
        if dtype is not None:
            count = int(np.prod(shape))
            out[name] = np.frombuffer(b, dtype, count, offset).reshape(shape).copy()
    return out


def wavelengths(rng):
    """33 irregular wavelengths from 390 to about 715 nm."""
    jitter = 3.0 * rng.random(33)
    jitter[0] = 0.0
    return (390.0 + 10.0 * np.arange(33) + jitter).astype(np.float32)


def basis(wl):
    """Three smooth spectra (reddish, greenish, bluish bumps over a floor) at `wl`, (3, n)."""
    wl = wl.astype(np.float64)
    return np.stack([0.05 + np.exp(-(((wl - mu) / s) ** 2))
                     for mu, s in ((610, 40), (540, 35), (450, 30))])


def spectral_fields(fields, wl):
    """`fields` with `rgb` replaced by `wavelengths` and `spectra`: each texel's spectrum is
    Σ_c rgb_c · basis_c."""
    out = {k: v for k, v in fields.items() if k != "rgb"}
    spectra = np.einsum("pqchw,ck->pqkhw", fields["rgb"].astype(np.float64), basis(wl))
    out["wavelengths"] = wl
    out["spectra"] = spectra.astype(np.float32)
    return out


def mint_fields():
    f = read_tensor_file(FIXTURES / "measured" / "chm_mint_rgb.bsdf")
    keep = ["description", "phi_i", "theta_i", "ndf", "sigma", "vndf", "luminance", "rgb",
            "jacobian"]
    return {k: f[k] for k in keep}


# (name, the RGB file's fields): the mint and the anisotropic materials of test_measured.
SOURCES = [("mint", None)] + [(f"aniso-{a[0]}", a) for a in ANISOTROPIC]


def source_fields(name, aniso):
    if aniso is None:
        return mint_fields()
    _, phi, jacobian, negative = aniso
    return anisotropic_fields(11, phi, jacobian=jacobian, negative_rgb=negative)


# ---------------------------------------------------------------------------------------------
# Mitsuba's spectral evaluation, integrated over wavelength


def mitsuba_rgb(path, wl, wi, wo):
    """Mitsuba's `eval` of the spectral file at each pair, integrated against the CIE 1931
    observer under D65 (its own tables) and converted to linear sRGB, divided by cos θo;
    its `pdf`. float64 arrays (n, 3) and (n,)."""
    previous = mi.variant()
    mi.set_variant("scalar_spectral")
    try:
        import drjit as dr

        bsdf = mi.load_dict({"type": "measured", "filename": os.fspath(path)})
        ctx = mi.BSDFContext()
        grid = CIE_MIN + CIE_STEP * np.arange(int((CIE_MAX - CIE_MIN) / CIE_STEP) + 1)
        inside = wl[(wl > CIE_MIN) & (wl < CIE_MAX)].astype(np.float64)
        nodes = np.unique(np.concatenate([grid, inside]))
        # Simpson on each piece: the nodes with weights h/6, h/6 and the midpoints with 4h/6.
        h = np.diff(nodes)
        lam = np.concatenate([nodes, 0.5 * (nodes[1:] + nodes[:-1])])
        weight = np.zeros(len(lam))
        weight[: len(nodes) - 1] += h / 6
        weight[1 : len(nodes)] += h / 6
        weight[len(nodes):] = 4 * h / 6
        cmf = np.array([list(mi.cie1931_xyz(float(x))) for x in lam])
        d65 = np.array([mi.cie_d65(float(x)) for x in lam])
        w_xyz = cmf * (d65 * weight)[:, None]  # (m, 3)
        w_xyz /= w_xyz[:, 1].sum()
        pad = -len(lam) % 4
        lam4 = np.concatenate([lam, np.full(pad, lam[-1])]).reshape(-1, 4)

        n = len(wi)
        rgb = np.zeros((n, 3))
        pdf = np.zeros(n)
        for i in range(n):
            si = dr.zeros(mi.SurfaceInteraction3f)
            si.wi = mi.Vector3f(*map(float, wi[i]))
            d = mi.Vector3f(*map(float, wo[i]))
            values = []
            for quad in lam4:
                si.wavelengths = mi.Spectrum(*map(float, quad))
                v = bsdf.eval(ctx, si, d)
                values.extend(v[j] for j in range(4))
            xyz = np.asarray(values[: len(lam)]) @ w_xyz
            c = mi.xyz_to_srgb(mi.Color3f(*map(float, xyz)))
            rgb[i] = [c[0], c[1], c[2]]
            rgb[i] /= float(wo[i][2])
            pdf[i] = bsdf.pdf(ctx, si, d)
        return rgb, pdf
    finally:
        if previous is not None and previous != mi.variant():
            mi.set_variant(previous)


@needs_mitsuba
@pytest.mark.parametrize("name,aniso", SOURCES, ids=[s[0] for s in SOURCES])
def test_spectral_files_agree_with_mitsuba(tmp_path, capsys, name, aniso):
    rng = np.random.default_rng(23)
    wl = wavelengths(rng)
    path = tmp_path / f"{name}_spec.bsdf"
    write_tensor_file(path, spectral_fields(source_fields(name, aniso), wl))
    m = neusample.MeasuredMaterial(path)
    np.testing.assert_array_equal(np.asarray(m.wavelengths, np.float32), wl)
    assert m.isotropic == (aniso is None)

    wi, wo, _ = directions(np.random.default_rng(31), PAIRS)
    t0 = time.perf_counter()
    f_ref, pdf_ref = mitsuba_rgb(path, wl, wi, wo)
    t_ref = time.perf_counter() - t0
    wi_t, wo_t = (np.ascontiguousarray(a.T) for a in (wi, wo))
    f = m.eval(wi_t, wo_t).T.astype(np.float64)
    pdf = m.pdf(wi_t, wo_t).astype(np.float64)

    # Mitsuba keeps the data's negative values (the mint's noise); ours read as 0.
    ref = np.maximum(f_ref, 0.0)
    floor = FLOOR * ref.max()
    f_err = (np.abs(f - ref) / np.maximum(ref, floor)).max(axis=1)
    pdf_err = np.abs(pdf - pdf_ref) / np.maximum(pdf_ref, FLOOR * pdf_ref.max())
    with capsys.disabled():
        print(f"\n{name} (spectral, {len(wl)} wavelengths): {PAIRS} pairs, Mitsuba "
              f"scalar_spectral integrated {t_ref:.2f} s; max f {ref.max():.4g}")
        for what, err in (("eval", f_err), ("pdf", pdf_err)):
            print(f"  {what:<4} worst {err.max():.3e}, median {np.median(err):.3e}, 99.9th pct "
                  f"{np.quantile(err, SHARE):.3e}, > {RTOL:g}: {int((err > RTOL).sum())} of "
                  f"{PAIRS}")
    for what, err in (("eval", f_err), ("pdf", pdf_err)):
        assert np.mean(err <= RTOL) >= SHARE, f"{name}: {what}: worst {err.max():.3e}"
        assert np.median(err) <= MEDIAN, f"{name}: {what}: median {np.median(err):.3e}"


# ---------------------------------------------------------------------------------------------
# Without Mitsuba


@pytest.mark.parametrize("name,aniso", SOURCES[:2], ids=[s[0] for s in SOURCES[:2]])
def test_flat_spectra_read_as_grey(tmp_path, name, aniso):
    """A texel whose spectrum is flat at its green value evaluates as the RGB file whose three
    channels hold that value, within 2e-4 (D65's white is (1, 1, 1) in linear sRGB up to the
    rounding of the tables and the matrix)."""
    fields = source_fields(name, aniso)
    g = fields["rgb"][:, :, 1:2]
    grey = dict(fields, rgb=np.repeat(g, 3, axis=2))
    flat = {k: v for k, v in fields.items() if k != "rgb"}
    wl = wavelengths(np.random.default_rng(5))
    flat["wavelengths"] = wl
    flat["spectra"] = np.repeat(g, len(wl), axis=2)
    write_tensor_file(tmp_path / "grey.bsdf", grey)
    write_tensor_file(tmp_path / "flat.bsdf", flat)
    a = neusample.MeasuredMaterial(tmp_path / "flat.bsdf")
    b = neusample.MeasuredMaterial(tmp_path / "grey.bsdf")
    assert b.wavelengths is None and len(a.wavelengths) == len(wl)
    wi, wo, _ = directions(np.random.default_rng(9), 2000)
    wi, wo = (np.ascontiguousarray(x.T) for x in (wi, wo))
    fa, fb = a.eval(wi, wo), b.eval(wi, wo)
    floor = 1e-6 * fb.max()
    assert np.all(np.abs(fa - fb) <= 2e-4 * np.maximum(fb, floor))
    np.testing.assert_array_equal(a.pdf(wi, wo), b.pdf(wi, wo))


def test_bad_spectral_files_name_the_field(tmp_path):
    fields = source_fields("mint", None)
    wl = wavelengths(np.random.default_rng(1))
    good = spectral_fields(fields, wl)

    def refused(f, name):
        path = tmp_path / f"{name}.bsdf"
        write_tensor_file(path, f)
        with pytest.raises(neusample.MeasuredFileError) as e:
            neusample.MeasuredMaterial(path)
        assert e.value.path == str(path) and str(e.value).startswith(str(path) + ": ")
        return e.value

    def without(k):
        return {n: v for n, v in good.items() if n != k}

    unsorted = wl.copy()
    unsorted[[3, 4]] = unsorted[[4, 3]]
    nan = wl.copy()
    nan[7] = np.nan
    cases = [
        ("missing_wavelengths", without("wavelengths"), "wavelengths", "missing"),
        ("missing_spectra", without("spectra"), "spectra", "missing"),
        ("unsorted", dict(good, wavelengths=unsorted), "wavelengths", "ascend"),
        ("nan", dict(good, wavelengths=nan), "wavelengths", "finite"),
        ("count", dict(good, spectra=good["spectra"][:, :, 1:].copy()), "spectra",
         "the length of wavelengths"),
        ("rank", dict(good, spectra=good["spectra"][0].copy()), "spectra", "dimensions"),
    ]
    for name, f, field, text in cases:
        e = refused(f, name)
        assert e.field == field and text in str(e), (name, str(e))
    write_tensor_file(tmp_path / "good.bsdf", good)
    neusample.MeasuredMaterial(tmp_path / "good.bsdf")
