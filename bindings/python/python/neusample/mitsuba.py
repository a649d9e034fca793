"""A Mitsuba 3 BSDF plugin: a neural material sampled by a neusample sampler.

::

    import mitsuba as mi
    mi.set_variant("llvm_ad_rgb")            # or "scalar_rgb"
    import neusample.mitsuba
    neusample.mitsuba.register()             # BSDF type "neusample"
    bsdf = mi.load_dict({
        "type": "neusample",
        "material": "fixtures/materials/neural/goat_leather_neural.nsb",
        "sampler": "fixtures/blobs/goat_leather_neural/flow.nsb",   # optional: cosine
    })

Properties:

``material`` (string, required)
    A neural-material blob: the feature texture φ(uv) and the decoder giving the BRDF.
``sampler`` (string, optional)
    A sampler blob of any kind; without it, cosine-hemisphere sampling.
``uv_scale``, ``uv_offset`` (float, optional; 1 and 0)
    Texture coordinates are ``si.uv * uv_scale + uv_offset`` (the texture wraps).
``threads`` (int, optional; 1)
    Threads of each batched call (0: rayon's pool; Mitsuba's own threads are not used by
    the evaluated wavefront mode).

The plugin evaluates whole wavefronts: ``si.wi``, ``wo`` (already in the local shading
frame, ``si.sh_frame``), ``si.uv`` and the sample are converted to numpy once per call, the
batched neusample calls run with the GIL released, and the results come back as Dr.Jit
arrays. ``eval`` returns ``f · cos θo``; ``pdf`` the solid-angle density; ``sample`` the
direction, its pdf and the weight ``f · cos θo / pdf``; a refused sample is invalid (pdf 0,
weight 0). Reflection only, front side only.

In ``llvm_ad_rgb`` the wavefronts must be concrete: call :func:`evaluated_mode` (it turns
off ``dr.JitFlag.SymbolicLoops`` and ``dr.JitFlag.SymbolicCalls``) before rendering.
``scalar_rgb`` works as is (one lane per call).
"""

from __future__ import annotations

import numpy as np

from . import NeuralMaterial, Sampler

_CLASSES: dict = {}


def evaluated_mode() -> None:
    """Let Python BSDFs see concrete wavefronts in the JIT variants (``llvm_ad_rgb``).

    Mitsuba traces Python plugins into symbolic kernels by default; their arrays cannot be
    read. With both flags off, the path integrator calls the plugin once per bounce with the
    active lanes. This makes every BSDF (built-in ones too) slower, by about 4–6× here;
    compare samplers within the same mode.
    """
    import drjit as dr

    dr.set_flag(dr.JitFlag.SymbolicLoops, False)
    dr.set_flag(dr.JitFlag.SymbolicCalls, False)


def _flat(x, n: int) -> np.ndarray:
    """One component of a Dr.Jit value (or a Python float) as a float32 vector of n lanes."""
    if hasattr(x, "numpy"):
        a = np.asarray(x.numpy(), dtype=np.float32).reshape(-1)
    else:
        a = np.asarray([x], dtype=np.float32)
    if a.size == n:
        return a
    return np.full(n, a[0] if a.size else 0.0, dtype=np.float32)


def _width(*values) -> int:
    import drjit as dr

    return max(max(dr.width(v), 1) for v in values)


def bsdf_class():
    """The plugin's class for the current Mitsuba variant (subclass it to change a method,
    e.g. in a test). :func:`register` calls this."""
    import drjit as dr
    import mitsuba as mi

    variant = mi.variant()
    if variant is None:
        raise RuntimeError("call mitsuba.set_variant(...) before neusample.mitsuba.register()")
    if variant in _CLASSES:
        return _CLASSES[variant]
    jit = dr.is_jit_v(mi.Float)

    def to_float(a: np.ndarray):
        return mi.Float(a) if jit else float(a[0])

    def to_vec3(a: np.ndarray):
        if jit:
            return mi.Vector3f(mi.Float(a[0]), mi.Float(a[1]), mi.Float(a[2]))
        return mi.Vector3f(float(a[0, 0]), float(a[1, 0]), float(a[2, 0]))

    def to_color(a: np.ndarray):
        if jit:
            return mi.Color3f(mi.Float(a[0]), mi.Float(a[1]), mi.Float(a[2]))
        return mi.Color3f(float(a[0, 0]), float(a[1, 0]), float(a[2, 0]))

    flags = (
        mi.BSDFFlags.GlossyReflection
        | mi.BSDFFlags.FrontSide
        | mi.BSDFFlags.SpatiallyVarying
    )

    class NeuSampleBSDF(mi.BSDF):
        """A neural material (``material``) importance-sampled by a neusample ``sampler``."""

        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            self.material_path = str(props["material"])
            self.material = NeuralMaterial(self.material_path)
            if "sampler" in props:
                self.sampler_path = str(props["sampler"])
                self.sampler = Sampler(self.sampler_path)
            else:
                self.sampler_path = None
                self.sampler = Sampler.cosine()
            self.uv_scale = float(props["uv_scale"]) if "uv_scale" in props else 1.0
            self.uv_offset = float(props["uv_offset"]) if "uv_offset" in props else 0.0
            self.threads = int(props["threads"]) if "threads" in props else 1
            self.m_components = [flags]
            self.m_flags = flags

        # -- conversions: one numpy round trip per call -----------------------------------
        def _inputs(self, si, n: int):
            wi = np.stack([_flat(si.wi.x, n), _flat(si.wi.y, n), _flat(si.wi.z, n)])
            uv = np.stack([_flat(si.uv.x, n), _flat(si.uv.y, n)])
            uv = uv * np.float32(self.uv_scale) + np.float32(self.uv_offset)
            phi = self.material.features(np.ascontiguousarray(uv, dtype=np.float32), threads=self.threads)
            return phi, wi

        @staticmethod
        def _vec3(v, n: int) -> np.ndarray:
            return np.stack([_flat(v.x, n), _flat(v.y, n), _flat(v.z, n)])

        def _pdf(self, phi, wi, wo) -> np.ndarray:
            """The sampler's solid-angle pdf: the one helper `pdf` and `eval_pdf` share."""
            return self.sampler.pdf(phi, wi, wo, threads=self.threads)

        def _f_cos(self, phi, wi, wo) -> np.ndarray:
            f = self.material.eval(phi, wi, wo, threads=self.threads)
            return f * np.maximum(wo[2], 0.0)

        # -- the BSDF interface -----------------------------------------------------------
        def sample(self, ctx, si, sample1, sample2, active=True):
            n = _width(si.wi, si.uv, sample2)
            phi, wi = self._inputs(si, n)
            u = np.stack([_flat(sample2.x, n), _flat(sample2.y, n)])
            wo, pdf = self.sampler.sample(phi, wi, u, threads=self.threads)
            f_cos = self._f_cos(phi, wi, wo)
            ok = pdf > 0
            weight = np.where(ok, f_cos / np.where(ok, pdf, 1.0), 0.0).astype(np.float32)
            enabled = ctx.is_enabled(mi.BSDFFlags.GlossyReflection)
            if not self.sampler.exact_pdf:
                # Mitsuba weighs MIS with bs.pdf and the estimate with the weight: the
                # sampler's MIS density (its pdf at wo) there, the sample's own density here.
                pdf = np.where(ok, self._pdf(phi, wi, wo), 0.0).astype(np.float32)
            bs = dr.zeros(mi.BSDFSample3f, n if jit else 1)
            bs.wo = to_vec3(wo)
            bs.pdf = to_float(pdf)
            bs.eta = 1.0
            bs.sampled_type = mi.UInt32(+mi.BSDFFlags.GlossyReflection)
            bs.sampled_component = mi.UInt32(0)
            valid = active & (bs.pdf > 0) & enabled
            bs.pdf = dr.select(valid, bs.pdf, 0.0)
            return bs, dr.select(valid, to_color(weight), 0.0)

        def eval(self, ctx, si, wo, active=True):
            n = _width(si.wi, si.uv, wo)
            phi, wi = self._inputs(si, n)
            value = to_color(self._f_cos(phi, wi, self._vec3(wo, n)).astype(np.float32))
            enabled = ctx.is_enabled(mi.BSDFFlags.GlossyReflection)
            return dr.select(active & enabled, value, 0.0)

        def pdf(self, ctx, si, wo, active=True):
            n = _width(si.wi, si.uv, wo)
            phi, wi = self._inputs(si, n)
            value = to_float(self._pdf(phi, wi, self._vec3(wo, n)))
            enabled = ctx.is_enabled(mi.BSDFFlags.GlossyReflection)
            return dr.select(active & enabled, value, 0.0)

        def eval_pdf(self, ctx, si, wo, active=True):
            n = _width(si.wi, si.uv, wo)
            phi, wi = self._inputs(si, n)
            w = self._vec3(wo, n)
            value = to_color(self._f_cos(phi, wi, w).astype(np.float32))
            pdf = to_float(self._pdf(phi, wi, w))
            enabled = ctx.is_enabled(mi.BSDFFlags.GlossyReflection)
            return (
                dr.select(active & enabled, value, 0.0),
                dr.select(active & enabled, pdf, 0.0),
            )

        def to_string(self):
            return (
                f"NeuSampleBSDF[material={self.material_path!r}, "
                f"sampler={self.sampler_path!r} ({self.sampler.kind})]"
            )

    _CLASSES[variant] = NeuSampleBSDF
    return NeuSampleBSDF


def register(name: str = "neusample", cls=None) -> None:
    """Registers the BSDF plugin as ``name`` for the current Mitsuba variant (or ``cls``, a
    subclass of :func:`bsdf_class`)."""
    import mitsuba as mi

    cls = cls or bsdf_class()
    mi.register_bsdf(name, lambda props: cls(props))
