"""Unit tests of the Python bindings: values against the Rust scalar API (golden.txt),
consistency of sample and pdf, threads, and every kind of bad input."""

from pathlib import Path

import numpy as np
import pytest

import neusample
from conftest import MATERIALS, METHODS, material_path, sampler_path

GOLDEN = Path(__file__).with_name("golden.txt")


def golden_rows():
    rows = []
    for line in GOLDEN.read_text().splitlines():
        if line.startswith("#"):
            continue
        head, phi, sample, f = line.split("|")
        fields = head.split()
        rows.append(
            dict(
                material=fields[0],
                method=fields[1],
                uv=np.array(fields[2:4], dtype=np.float32),
                wi=np.array(fields[4:7], dtype=np.float32),
                u=np.array(fields[7:9], dtype=np.float32),
                phi=np.array(phi.split(), dtype=np.float32),
                wo=np.array(sample.split()[:3], dtype=np.float32),
                pdf=np.float32(sample.split()[3]),
                f=np.array(f.split(), dtype=np.float32),
            )
        )
    return rows


def col(v):
    """A (k,) vector as a (k, 1) float32 array."""
    return np.ascontiguousarray(np.asarray(v, dtype=np.float32).reshape(-1, 1))


def test_golden_values_from_the_rust_scalar_api():
    rows = golden_rows()
    assert len(rows) == 3 * 7 * 3
    materials = {m: neusample.NeuralMaterial(material_path(m)) for m in MATERIALS}
    for r in rows:
        m = materials[r["material"]]
        s = neusample.Sampler(sampler_path(r["material"], r["method"]))
        assert s.kind == ("cosine" if r["method"] == "cosine" else r["method"])
        phi = m.features(col(r["uv"]))
        np.testing.assert_array_equal(phi[:, 0], r["phi"])
        # The batched runtime agrees with the scalar API within its tolerances (fused
        # multiply-adds in the networks): 5e-4 relative on a pdf at one direction, 1e-3 on a
        # sampled direction, 1e-4 relative on the material's eval.
        wo, pdf, _ = s.sample(phi, col(r["wi"]), col(r["u"]))
        np.testing.assert_allclose(wo[:, 0], r["wo"], rtol=0, atol=1e-3)
        golden_wo = col(r["wo"])
        np.testing.assert_allclose(s.pdf(phi, col(r["wi"]), golden_wo)[0], r["pdf"], rtol=5e-4)
        f = m.eval(phi, col(r["wi"]), golden_wo)
        np.testing.assert_allclose(f[:, 0], r["f"], rtol=1e-4)


def random_lanes(n, seed=1):
    rng = np.random.default_rng(seed)
    uv = rng.random((2, n), dtype=np.float32)
    wi = rng.normal(size=(3, n)).astype(np.float32)
    wi[2] = np.abs(wi[2]) + 0.05
    wi /= np.linalg.norm(wi, axis=0)
    u = rng.random((2, n), dtype=np.float32)
    return uv, np.ascontiguousarray(wi), u


@pytest.mark.parametrize("method", ["cosine", "disk-flow"] + METHODS)
def test_sample_pdf_agree_and_threads_are_bit_identical(method):
    m = neusample.NeuralMaterial(material_path("goat_leather_neural"))
    s = neusample.Sampler(sampler_path("goat_leather_neural", method))
    uv, wi, u = random_lanes(3000)
    phi = m.features(uv)
    wo, pdf, _ = s.sample(phi, wi, u)
    ok = pdf > 0
    assert ok.mean() > 0.9
    np.testing.assert_array_equal(s.pdf(phi, wi, wo)[ok], pdf[ok])
    assert np.all(wo[:, ~ok] == 0)
    np.testing.assert_allclose(np.linalg.norm(wo[:, ok], axis=0), 1, atol=1e-5)
    wo2, pdf2, _ = s.sample(phi, wi, u, threads=2)
    np.testing.assert_array_equal(wo2, wo)
    np.testing.assert_array_equal(pdf2, pdf)
    np.testing.assert_array_equal(s.pdf(phi, wi, wo, threads=0), s.pdf(phi, wi, wo))
    np.testing.assert_array_equal(m.eval(phi, wi, wo, threads=3), m.eval(phi, wi, wo))
    np.testing.assert_array_equal(m.features(uv, threads=2), phi)


def test_cosine_is_cos_over_pi():
    s = neusample.Sampler.cosine()
    _, wi, u = random_lanes(500)
    phi = np.zeros((8, 500), np.float32)
    wo, pdf, _ = s.sample(phi, wi, u)
    np.testing.assert_allclose(pdf, wo[2] / np.pi, rtol=1e-6)


def test_nan_and_below_horizon_lanes_are_refused_without_disturbing_others():
    m = neusample.NeuralMaterial(material_path("brushed_metal_neural"))
    s = neusample.Sampler(sampler_path("brushed_metal_neural", "flow"))
    uv, wi, u = random_lanes(64)
    phi = m.features(uv)
    _, ref_pdf, _ = s.sample(phi, wi, u)
    wi_bad = wi.copy()
    wi_bad[0, 3] = np.nan
    wi_bad[2, 5] = -0.5
    phi_bad = phi.copy()
    phi_bad[4, 7] = np.inf
    wo, pdf, _ = s.sample(phi_bad, wi_bad, u)
    assert pdf[3] == 0 and pdf[5] == 0 and pdf[7] == 0
    assert np.all(wo[:, [3, 5, 7]] == 0)
    keep = np.setdiff1d(np.arange(64), [3, 5, 7])
    np.testing.assert_array_equal(pdf[keep], ref_pdf[keep])
    f = m.eval(phi_bad, wi_bad, wo)
    assert np.all(f[:, [3, 5, 7]] == 0) and np.all(np.isfinite(f))


def test_empty_batches():
    m = neusample.NeuralMaterial(material_path("goat_leather_neural"))
    s = neusample.Sampler.cosine()
    phi = m.features(np.zeros((2, 0), np.float32))
    assert phi.shape == (8, 0) and phi.dtype == np.float32
    wo, pdf, _ = s.sample(phi, np.zeros((3, 0), np.float32), np.zeros((2, 0), np.float32))
    assert wo.shape == (3, 0) and pdf.shape == (0,)


def test_open_errors_are_typed(tmp_path):
    with pytest.raises(FileNotFoundError) as e:
        neusample.Sampler(str(tmp_path / "missing.nsb"))
    assert "missing.nsb" in str(e.value)
    data = bytearray(Path(sampler_path("goat_leather_neural", "analytic")).read_bytes())
    data[len(data) // 2] ^= 0x10
    bad = tmp_path / "corrupted.nsb"
    bad.write_bytes(bytes(data))
    with pytest.raises(neusample.BlobError) as e:
        neusample.Sampler(str(bad))
    assert e.value.kind == "checksum_mismatch"
    assert e.value.path == str(bad)
    assert isinstance(e.value, ValueError)
    with pytest.raises(neusample.BlobError) as e:
        neusample.Blob.from_bytes(b"definitely not a blob")
    assert e.value.kind == "bad_magic" and e.value.path is None
    with pytest.raises(neusample.BlobError) as e:
        neusample.Blob.from_bytes(bytes(data[:100]))
    assert e.value.kind == "truncated"
    with pytest.raises(neusample.BlobError) as e:
        neusample.Sampler(material_path("goat_leather_neural"))
    assert e.value.kind == "not_a_sampler"
    with pytest.raises(neusample.BlobError) as e:
        neusample.NeuralMaterial(sampler_path("goat_leather_neural", "flow"))
    assert e.value.kind == "wrong_kind"


def test_wrong_arrays_raise_never_crash():
    s = neusample.Sampler(sampler_path("victorian_fabric_neural", "histogram-mixture"))
    phi = np.zeros((8, 4), np.float32)
    wi = np.tile(np.array([[0], [0], [1]], np.float32), 4)
    u = np.full((2, 4), 0.5, np.float32)
    with pytest.raises(TypeError, match="float32"):
        s.sample(phi.astype(np.float64), wi, u)
    with pytest.raises(TypeError, match="numpy.ndarray"):
        s.sample(phi.tolist(), wi, u)
    with pytest.raises(ValueError, match=r"shape \(3, N\)"):
        s.sample(phi, wi.T.copy(), u)
    with pytest.raises(ValueError, match=r"shape \(3, N\)"):
        s.pdf(phi, wi[0], wi)
    with pytest.raises(ValueError, match="C-contiguous"):
        s.sample(phi, np.asfortranarray(wi), u)
    with pytest.raises(ValueError, match="C-contiguous"):
        s.pdf(phi, wi, np.tile(np.array([[0], [0], [1]], np.float32), 8)[:, ::2])
    with pytest.raises(ValueError, match="N = 3"):
        s.sample(phi, wi, u[:, :3].copy())
    with pytest.raises(OverflowError):
        s.sample(phi, wi, u, threads=-1)
    m = neusample.NeuralMaterial(material_path("victorian_fabric_neural"))
    with pytest.raises(ValueError):
        m.features(np.zeros((3, 4), np.float32))
    with pytest.raises(TypeError):
        m.eval(phi, wi, wi.astype(np.float16))


def test_inspect_and_header():
    info = neusample.inspect(sampler_path("goat_leather_neural", "histogram-mixture"))
    assert info["kind"] == "histogram-mixture"
    assert info["checksum"] == "ok" and info["feature_dim"] == neusample.FEATURE_DIM
    roles = [t["role"] for t in info["tensors"]]
    # Both table layouts have the marginal and conditional CDFs (values: also "table").
    assert roles[0] == "params" and {"marginal", "conditional"} <= set(roles)
    blob = neusample.Blob(material_path("goat_leather_neural"))
    assert blob.kind == "neural-material"
    assert blob.header["resolution"] == blob.neural_material().width
    assert len(blob) == Path(material_path("goat_leather_neural")).stat().st_size
    assert blob.sampler.__doc__
    # The Mitsuba suites' METHODS leave out the disk flow (its χ² runs in the Rust suites) and
    # the reparameterization sampler (an inexact pdf: its own test below).
    assert set(neusample.SAMPLER_KINDS) == {"cosine", "disk-flow", "reparam", *METHODS}
    # A version-1 blob has no defensive weight; the committed flows carry one (version 2).
    assert info["format_version"] == 1 and info["defensive"] == 0.0
    flow = neusample.inspect(sampler_path("goat_leather_neural", "flow"))
    assert flow["format_version"] == 2 and 0.0 < flow["defensive"] < 1.0
    assert not info["isotropic"] and not flow["isotropic"]
    # A sampler trained on an isotropic measured file: version 3, turned to wi's azimuth.
    mint = sampler_path("../measured/blobs/chm_mint", "analytic")
    iso = neusample.inspect(mint)
    assert iso["format_version"] == 3 and iso["isotropic"] and iso["defensive"] == 0.0
    assert neusample.Sampler(sampler_path("goat_leather_neural", "flow")).alpha == flow["defensive"]
    assert neusample.Sampler.cosine().alpha == 0.0


def test_reparam_samples_carry_their_own_density():
    """The reparameterization sampler divides by its warp's density and reports its pdf
    network for MIS (`mis_pdf`: its pdf at the sample, `pdf` for every other kind), the two
    densities differ, and the sample weights estimate the albedo that cosine sampling
    estimates."""
    m = neusample.NeuralMaterial(material_path("goat_leather_neural"))
    s = neusample.Sampler(sampler_path("goat_leather_neural", "reparam"))
    assert s.kind == "reparam"
    n = 200_000
    rng = np.random.default_rng(3)
    uv = np.tile(np.array([[0.3], [0.6]], np.float32), n)
    wi = np.tile(col([0.36, -0.48, 0.8]), n)
    phi = m.features(uv)
    for exact in (neusample.Sampler(sampler_path("goat_leather_neural", "flow")),
                  neusample.Sampler.cosine()):
        few = np.ascontiguousarray(phi[:, :64]), np.ascontiguousarray(wi[:, :64])
        _, e_pdf, e_mis = exact.sample(*few, np.full((2, 64), 0.3, np.float32))
        assert np.array_equal(e_pdf, e_mis)
    wo, pdf, mis = s.sample(phi, wi, rng.random((2, n), dtype=np.float32))
    ok = pdf > 0
    assert ok.mean() > 0.95
    assert np.array_equal(s.pdf(phi, wi, wo), mis)
    assert not np.array_equal(mis[ok], pdf[ok])
    w = np.where(ok, m.eval(phi, wi, wo)[1] * wo[2] / np.where(ok, pdf, 1.0), 0.0)
    c = neusample.Sampler.cosine()
    wo_c, pdf_c, _ = c.sample(phi, wi, rng.random((2, n), dtype=np.float32))
    w_c = m.eval(phi, wi, wo_c)[1] * wo_c[2] / pdf_c
    se = np.hypot(w.std() / np.sqrt(n), w_c.std() / np.sqrt(n))
    assert abs(w.mean() - w_c.mean()) < 5 * se, (w.mean(), w_c.mean(), se)
