"""Type stubs of the neusample extension module.

Arrays are float32 numpy arrays of shape ``(k, N)``: one row per component, one column per
shading point, C-contiguous. Pass an ``(N, k)`` array ``a`` as ``np.ascontiguousarray(a.T)``.
Directions are in the local shading frame (z = normal, both pointing away from the
surface); pdfs are densities with respect to solid angle. ``threads``: 1 runs on the
calling thread, 0 on every thread of rayon's pool, k > 1 in k chunks on that pool; the GIL
is released in every case.
"""

from os import PathLike
from typing import Any, Dict, List, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

F32 = npt.NDArray[np.float32]
StrPath = Union[str, PathLike[str]]

__version__: str
FEATURE_DIM: int
"""Length of the feature vector φ (8)."""
SAMPLER_KINDS: List[str]
"""Every sampler kind: "cosine", "baseline", "analytic", "flow", "affine-flow",
"direct-histogram", "histogram-mixture", "reparam"."""
HAS_TRAINING: bool
"""Whether the module was built with the ``train`` cargo feature."""

class BlobError(ValueError):
    """A blob could not be opened or used. ``kind`` names the typed error of the runtime
    ("truncated", "bad_magic", "unsupported_version", "checksum_mismatch", "header_decode",
    "header_invalid", "wrong_kind", "not_a_sampler", "dimension_mismatch",
    "tensor_missing", "tensor_shape", "tensor_bounds", "tensor_dtype", "non_finite",
    "table_not_normalized", "other"); ``path`` the file, or None."""

    kind: str
    path: Optional[str]

class Blob:
    """A validated blob (a sampler of any kind, a neural or a measured material) owning its
    bytes.
    Raises FileNotFoundError / OSError for a missing file, BlobError for bad bytes."""

    def __init__(self, path: StrPath) -> None: ...
    @staticmethod
    def from_bytes(data: bytes) -> "Blob": ...
    @property
    def kind(self) -> str: ...
    @property
    def path(self) -> Optional[str]: ...
    @property
    def header(self) -> Dict[str, Any]: ...
    def sampler(self) -> "Sampler":
        """The sampler it holds (BlobError "not_a_sampler" for a material)."""
    def neural_material(self) -> "NeuralMaterial":
        """The material it holds (BlobError "wrong_kind" for a sampler)."""
    def measured(self) -> "MeasuredMaterial":
        """The measured material it holds (BlobError "wrong_kind" for any other kind)."""
    def tensor(self, role: str) -> Optional[F32]:
        """The tensor `role` ("params", "mass", "table", "marginal", "conditional",
        "features", "shape", "tables") as float32 values, as the runtime reads them; None when absent."""
    def __len__(self) -> int: ...

class Sampler:
    """A learned sampler (``Sampler(path)``) or cosine sampling (``Sampler()``)."""

    def __init__(self, path: Optional[StrPath] = None) -> None: ...
    @staticmethod
    def cosine() -> "Sampler": ...
    @property
    def kind(self) -> str: ...
    @property
    def alpha(self) -> float:
        """The defensive weight: the density is (1 − α)·p_learned + α·cos θ/π."""
    def sample(self, phi: F32, wi: F32, u: F32, *, threads: int = 1) -> Tuple[F32, F32, F32]:
        """phi (8, N), wi (3, N), u (2, N) in [0, 1) → (wo (3, N), pdf (N,), mis_pdf (N,)):
        divide f·cos by ``pdf`` (the density the sample was drawn with), weigh MIS with
        ``mis_pdf`` (``pdf(wo)``; equal to ``pdf`` for every kind but "reparam"). Refused
        lanes (wi below the horizon, NaN, sample outside the support) are all zeros."""
    def sample_scalar(self, phi: F32, wi: F32, u: F32) -> Tuple[F32, F32, F32]:
        """`sample` through the scalar API, one lane at a time (the reference)."""
    def pdf_scalar(self, phi: F32, wi: F32, wo: F32) -> F32:
        """`pdf` through the scalar API, one lane at a time (the reference)."""
    def pdf(self, phi: F32, wi: F32, wo: F32, *, threads: int = 1) -> F32:
        """phi (8, N), wi (3, N), wo (3, N) → solid-angle pdf (N,); 0 below the horizon."""

class NeuralMaterial:
    """A neural material (feature texture + decoder) from a neural-material blob."""

    def __init__(self, path: StrPath) -> None: ...
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    def features(self, uv: F32, *, threads: int = 1) -> F32:
        """uv (2, N) → φ (8, N): bilinear, wrapping texture lookup."""
    def features_scalar(self, uv: F32) -> F32:
        """`features` through the scalar API, one lane at a time (the reference)."""
    def eval_scalar(self, phi: F32, wi: F32, wo: F32) -> F32:
        """`eval` through the scalar API, one lane at a time (the reference)."""
    def eval(self, phi: F32, wi: F32, wo: F32, *, threads: int = 1) -> F32:
        """phi (8, N), wi, wo (3, N) → RGB BRDF (3, N) without the cosine; 0 below the
        horizon or for non-finite input."""

class MeasuredFileError(ValueError):
    """A measured-material file (``.bsdf``) could not be read: truncated, not a tensor file,
    or a field missing, of the wrong type or shape, or holding non-finite or negative values.
    The message names the file and the field. ``field`` is the field at fault (None for the
    file as a whole: truncated header, wrong magic or version); ``path`` the file."""

    field: Optional[str]
    path: str

class MeasuredMaterial:
    """A measured BRDF of the RGL material database (Dupuy & Jakob 2018) read from an RGB or
    spectral ``.bsdf`` file (Mitsuba's ``measured`` format; spectra are read in linear sRGB,
    integrated against the CIE 1931 observer under D65) or from a measured blob (``from_blob``;
    written by ``to_blob`` or ``neusample measured-blob``: the same values bit for bit),
    evaluated and sampled as Mitsuba 3's ``measured`` BSDF does (the data's visible-normal
    sampler warped through its luminance). Raises FileNotFoundError / OSError for a missing
    file, MeasuredFileError for a bad ``.bsdf`` file, BlobError for a bad blob.

    The array methods run the runtime's batched calls. Directions are normalised here; a lane
    whose input is not finite, of zero length or at or below the horizon gives 0 (never NaN)
    and does not affect the other lanes."""

    def __init__(self, path: StrPath) -> None: ...
    @staticmethod
    def from_blob(source: Union[StrPath, bytes]) -> "MeasuredMaterial":
        """Opens a measured blob (kind "measured") from a file or from bytes; BlobError
        ("wrong_kind" for a blob of another kind, "checksum_mismatch", …) for bad bytes."""
    def to_blob(self, *, name: Optional[str] = None) -> bytes:
        """The material as a measured blob (label ``name=… source=… description: …``;
        ``name`` defaults to the file's stem). A blob-opened material returns its bytes."""
    @property
    def description(self) -> str:
        """The file's description of the material (for a blob: the one in its label)."""
    @property
    def label(self) -> Optional[str]:
        """The blob's label; None for a material read from a ``.bsdf`` file."""
    @property
    def wavelengths(self) -> Optional[List[float]]:
        """The wavelengths (nm) of a spectral ``.bsdf`` file; None for an RGB file or a blob."""
    @property
    def isotropic(self) -> bool:
        """Whether the data is isotropic (at most two φi nodes)."""
    @property
    def path(self) -> Optional[str]:
        """The file it was read from; None for a blob from bytes."""
    def eval(self, wi: F32, wo: F32, *, threads: int = 1) -> F32:
        """wi, wo (3, N) → the BRDF f(wi, wo) (3, N) in linear RGB, **without** the cosine
        (Mitsuba's ``eval`` / cos θo); 0 below the horizon or for non-finite input."""
    def pdf(self, wi: F32, wo: F32, *, threads: int = 1) -> F32:
        """wi, wo (3, N) → (N,) the density of ``sample`` at wo with respect to **solid
        angle** (Mitsuba's ``pdf``); 0 below the horizon or for non-finite input."""
    def sample(self, wi: F32, u: F32, *, threads: int = 1) -> Tuple[F32, F32, F32]:
        """wi (3, N), u (2, N) in [0, 1) (Mitsuba's ``sample2``) → (wo (3, N), pdf (N,),
        weight (3, N)): the sampled direction, its density with respect to **solid angle**,
        and f · cos θo / pdf in RGB (Mitsuba's returned weight). Refused lanes (wi below the
        horizon or not finite, u outside [0, 1], a sample below the horizon or of zero
        density) are wo = 0, pdf = 0, weight = 0."""

def inspect(path: StrPath) -> Dict[str, Any]:
    """The header and tensors of a blob, as ``neusample inspect --json`` prints them."""

def train_sampler(
    material: StrPath,
    method: str,
    out: StrPath,
    *,
    seed: int = 0,
    steps_scale: float = 1.0,
    quick: bool = False,
    f16: bool = False,
) -> Dict[str, Any]:
    """Trains, bakes and verifies a sampler for a material file (TOML/JSON) or a
    neural-material blob (or a built-in material's name) and writes its blob to ``out``;
    returns ``out``, ``bytes``, ``seconds``, ``final_loss``, ``max_relative``, ``tolerance``.
    Only with the ``train`` cargo feature (``HAS_TRAINING``)."""
