"""The training entry point (only when the module was built with the `train` cargo feature;
CI's wheel is built without it, see bindings/python/README.md)."""

import numpy as np
import pytest

import neusample
from conftest import material_path

pytestmark = pytest.mark.skipif(
    not neusample.HAS_TRAINING, reason="built without the `train` cargo feature"
)


def test_train_sampler_quick_writes_a_verified_blob(tmp_path):
    out = tmp_path / "analytic.nsb"
    report = neusample.train_sampler(material_path("goat_leather_neural"), "analytic", out, quick=True)
    assert report["out"] == str(out) and report["max_relative"] <= report["tolerance"]
    s = neusample.Sampler(out)
    assert s.kind == "analytic"
    phi = np.zeros((8, 4), np.float32)
    wi = np.tile(np.array([[0], [0], [1]], np.float32), 4)
    wo, pdf, _ = s.sample(phi, wi, np.full((2, 4), 0.5, np.float32))
    assert np.all(pdf > 0)


def test_train_sampler_rejects_an_unknown_method(tmp_path):
    with pytest.raises(ValueError):
        neusample.train_sampler(material_path("goat_leather_neural"), "nope", tmp_path / "x.nsb")
