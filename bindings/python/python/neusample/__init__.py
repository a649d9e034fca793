"""neusample: learned importance sampling for neural materials (NeuSample, SIGGRAPH 2023).

Batched calls on float32 numpy arrays of shape ``(k, N)`` (one row per component, one column
per shading point), in the local shading frame (z = normal, both directions pointing away
from the surface); every pdf is a density with respect to solid angle::

    import numpy as np, neusample
    material = neusample.NeuralMaterial("fixtures/materials/neural/goat_leather_neural.nsb")
    sampler = neusample.Sampler("fixtures/blobs/goat_leather_neural/flow.nsb")
    phi = material.features(uv)                 # (8, N)
    wo, pdf, mis_pdf = sampler.sample(phi, wi, u)  # (3, N), (N,), (N,)
    f = material.eval(phi, wi, wo)              # (3, N) RGB, no cosine
    weight = f * wo[2] / np.where(pdf > 0, pdf, 1)  # MIS weighs with mis_pdf

Measured materials (RGL database ``.bsdf`` files, RGB) with the data's own sampler, as
Mitsuba 3's ``measured`` BSDF evaluates and samples them::

    brdf = neusample.MeasuredMaterial("fixtures/measured/paper_white_rgb.bsdf")
    f = brdf.eval(wi, wo)                       # (3, N) RGB, no cosine
    wo, pdf, weight = brdf.sample(wi, u)        # weight = f · cos θo / pdf

The GIL is released during every batched call; ``threads=k`` splits a call over k threads
(0: all of rayon's pool). ``neusample.mitsuba.register()`` registers a Mitsuba 3 BSDF.
"""

from ._neusample import (
    FEATURE_DIM,
    SAMPLER_KINDS,
    Blob,
    BlobError,
    MeasuredFileError,
    MeasuredMaterial,
    NeuralMaterial,
    Sampler,
    __version__,
    inspect,
)

try:  # present when built with the `train` cargo feature
    from ._neusample import train_sampler  # noqa: F401

    HAS_TRAINING = True
except ImportError:
    HAS_TRAINING = False

__all__ = [
    "FEATURE_DIM",
    "SAMPLER_KINDS",
    "HAS_TRAINING",
    "Blob",
    "BlobError",
    "MeasuredFileError",
    "MeasuredMaterial",
    "NeuralMaterial",
    "Sampler",
    "inspect",
    "__version__",
]
