"""`neusample.MeasuredMaterial.from_blob`: every RGL fixture file written as a measured blob
(`to_blob`, built here: no blob is committed) gives bit for bit the eval, pdf and samples of
the material read from the `.bsdf` file, opened from bytes, from a file or through
`Blob.measured()`; bad blobs raise `BlobError` with the runtime's error kind."""

from pathlib import Path

import numpy as np
import pytest

import neusample
from conftest import FIXTURES, sampler_path

MEASURED = sorted((FIXTURES / "measured").glob("*_rgb.bsdf"))
LANES = 4000


def directions(rng, n):
    """Random directions, some below the horizon, a few not finite."""
    z = rng.uniform(-0.2, 1.0, n)
    phi = rng.uniform(0.0, 2.0 * np.pi, n)
    s = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    d = np.stack([s * np.cos(phi), s * np.sin(phi), z]).astype(np.float32)
    d[:, 7] = np.nan
    return np.ascontiguousarray(d)


def outputs(m, wi, wo, u, threads=1):
    f = m.eval(wi, wo, threads=threads)
    pdf = m.pdf(wi, wo, threads=threads)
    swo, spdf, w = m.sample(wi, u, threads=threads)
    return [f, pdf, swo, spdf, w]


def same_bits(a, b):
    return all(x.dtype == y.dtype and x.shape == y.shape and np.array_equal(x.view(np.uint32), y.view(np.uint32))
               for x, y in zip(a, b))


@pytest.mark.parametrize("path", MEASURED, ids=[p.stem for p in MEASURED])
def test_blob_matches_file_bit_for_bit(path, tmp_path):
    file_m = neusample.MeasuredMaterial(path)
    data = file_m.to_blob()
    assert data[:8] == b"NEUSAMP\0"
    stem = path.stem
    blob_m = neusample.MeasuredMaterial.from_blob(data)
    assert blob_m.path is None
    assert blob_m.label.startswith(f"name={stem} source={path.name} description: ")
    assert blob_m.description == file_m.description.strip()
    assert blob_m.isotropic == file_m.isotropic
    assert blob_m.to_blob() == data
    out = tmp_path / f"{stem}.nsb"
    out.write_bytes(data)
    from_file = neusample.MeasuredMaterial.from_blob(out)
    assert from_file.path == str(out)
    blob = neusample.Blob(out)
    assert blob.kind == "measured"
    assert blob.tensor("shape").shape == (11,)
    via_blob = blob.measured()

    rng = np.random.default_rng(17)
    wi, wo = directions(rng, LANES), directions(rng, LANES)
    u = np.ascontiguousarray(rng.uniform(0.0, 1.0, (2, LANES)).astype(np.float32))
    want = outputs(file_m, wi, wo, u)
    assert np.count_nonzero(want[3]) > LANES // 2
    for m in (blob_m, from_file, via_blob):
        assert same_bits(want, outputs(m, wi, wo, u))
    assert same_bits(want, outputs(blob_m, wi, wo, u, threads=3))
    for a in want:
        assert np.all(np.isfinite(a))


def test_bad_blobs_raise_blob_error(tmp_path):
    data = neusample.MeasuredMaterial(MEASURED[0]).to_blob(name="felt")
    assert b"name=felt " in data
    bad = bytearray(data)
    bad[len(bad) // 2] ^= 0x10
    with pytest.raises(neusample.BlobError) as e:
        neusample.MeasuredMaterial.from_blob(bytes(bad))
    assert e.value.kind == "checksum_mismatch"
    with pytest.raises(neusample.BlobError) as e:
        neusample.MeasuredMaterial.from_blob(data[:-5])
    assert e.value.kind == "truncated"
    # A sampler blob is not a measured material, and a measured blob is not a sampler.
    with pytest.raises(neusample.BlobError) as e:
        neusample.MeasuredMaterial.from_blob(sampler_path("goat_leather_neural", "flow"))
    assert e.value.kind == "wrong_kind"
    blob = neusample.Blob.from_bytes(data)
    with pytest.raises(neusample.BlobError) as e:
        blob.sampler()
    assert e.value.kind == "not_a_sampler"
    with pytest.raises(neusample.BlobError) as e:
        blob.neural_material()
    assert e.value.kind == "wrong_kind"
    with pytest.raises(FileNotFoundError):
        neusample.MeasuredMaterial.from_blob(tmp_path / "missing.nsb")
    with pytest.raises(TypeError):
        neusample.MeasuredMaterial.from_blob(12)
    with pytest.raises(ValueError):
        neusample.MeasuredMaterial(MEASURED[0]).to_blob(name="two words")
