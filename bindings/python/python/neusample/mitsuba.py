"""Mitsuba 3 BSDF plugins: a neural material importance-sampled by a neusample sampler.

::

    import mitsuba as mi
    mi.set_variant("llvm_ad_rgb")            # or "cuda_ad_rgb", "scalar_rgb"
    import neusample.mitsuba
    neusample.mitsuba.register()             # BSDF type "neusample"
    bsdf = mi.load_dict({
        "type": "neusample",
        "material": "fixtures/materials/neural/goat_leather_neural.nsb",
        "sampler": "fixtures/blobs/goat_leather_neural/flow.nsb",   # optional: cosine
    })
    # in a scene: img = neusample.mitsuba.render(scene, spp=16), the fastest path on a CPU

Properties:

``material`` (string; this or ``bsdf``)
    A neural-material blob: the feature texture φ(uv) and the decoder giving the BRDF.
``bsdf`` (nested BSDF; this or ``material``)
    Any Mitsuba BSDF evaluated in place of a neural material (e.g. ``{"type": "measured",
    "filename": "chm_mint_rgb.bsdf"}``): ``eval`` and the sample weight come from it, the
    direction and the pdf from ``sampler`` with the condition φ = 0 (the samplers trained
    on a measured material, whose p* has no latent). A user with an RGL file gets our
    sampler in one line.
``sampler`` (string, optional)
    A sampler blob; without it, cosine-hemisphere sampling.
``uv_scale``, ``uv_offset`` (float, optional; 1 and 0)
    Texture coordinates are ``si.uv * uv_scale + uv_offset`` (the texture wraps).
``mode`` (string, optional; ``"symbolic"``)
    ``"symbolic"``: the sampler and the material run as Dr.Jit code
    (:mod:`neusample.drjit`) traced into Mitsuba's own kernels, in its default symbolic
    mode, on the LLVM and CUDA variants (on LLVM, inside Mitsuba's symbolic calls, the
    networks take their weights as literal constants: one compiled callable per instance).
    ``"evaluated"``: whole wavefronts leave the kernel for the Rust runtime (numpy round
    trip, any sampler kind); it needs :func:`evaluated_mode`. Traced in a symbolic render
    (Dr.Jit traces every live BSDF of the variant, whichever scene holds it) it returns
    zeros with a warning, so symbolic renders of other scenes still run. The symbolic
    plugin works under those flags too, and on the LLVM backend that is the fastest configuration:
    :func:`render` renders a scene that way (``docs/mitsuba_speed.md``).
``precision`` (string, optional; symbolic mode)
    The networks' arithmetic: ``"f32"`` (default on LLVM) or ``"f16"`` (default on CUDA,
    where cooperative vectors need it).
``threads`` (int, optional; 1; evaluated mode)
    Threads of each batched Rust call (0: rayon's pool).

``eval`` returns ``f · cos θo``; ``pdf`` the solid-angle density; ``sample`` the direction,
its pdf and the weight ``f · cos θo / pdf``; a refused sample is invalid (pdf 0, weight 0).
Reflection only, front side only. In ``scalar_rgb`` both modes call the Rust runtime once
per ray (there is no kernel to trace into).
"""

from __future__ import annotations

import warnings

import numpy as np

from . import NeuralMaterial, Sampler

FEATURE_DIM = 8  # φ: the condition's latent part (zero for a nested BSDF)

_CLASSES: dict = {}


def evaluated_mode() -> None:
    """Mitsuba's evaluated mode for the JIT variants (``llvm_ad_rgb``, ``cuda_ad_rgb``).

    Mitsuba traces BSDFs into symbolic kernels by default; their arrays cannot be read. With
    both flags off, the path integrator calls each BSDF once per bounce with the lanes that
    hit it, as concrete arrays: the Rust wavefront plugin (``"mode": "evaluated"``) needs
    this, and the Dr.Jit plugin runs fastest this way on a CPU. Mitsuba's own BSDFs become
    slower (1.4–2.3× here, ``docs/mitsuba_speed.md``).
    """
    import drjit as dr

    dr.set_flag(dr.JitFlag.SymbolicLoops, False)
    dr.set_flag(dr.JitFlag.SymbolicCalls, False)


def render(scene, *args, **kwargs):
    """``mi.render(scene, …)`` on the fastest path for neusample BSDFs: on the LLVM
    variants under Mitsuba's evaluated flags for this call only (the caller's flags are
    restored after it, so other renders keep Mitsuba's default), elsewhere unchanged.

    On a CPU the path integrator then calls each BSDF once per bounce with the lanes that
    hit it, and the networks run as cooperative vectors on those lanes; in Mitsuba's
    default symbolic mode every packet runs the callable of each instance present in it
    and keeps finished paths, which costs more than the evaluated mode's kernel launches
    for networks of this size (``docs/mitsuba_speed.md``). Mitsuba's own BSDFs in the scene
    run evaluated too. Under a ``dr.scoped_set_flag`` of its own the caller decides."""
    import drjit as dr
    import mitsuba as mi

    if not dr.is_jit_v(mi.Float) or dr.backend_v(mi.Float) != dr.JitBackend.LLVM:
        return mi.render(scene, *args, **kwargs)
    with dr.scoped_set_flag(dr.JitFlag.SymbolicLoops, False), \
            dr.scoped_set_flag(dr.JitFlag.SymbolicCalls, False):
        return mi.render(scene, *args, **kwargs)


def _flat(x, n: int) -> np.ndarray:
    """One component of a Dr.Jit value (or a Python float) as a float32 vector of n lanes."""
    if hasattr(x, "numpy"):
        a = np.asarray(x.numpy(), dtype=np.float32).reshape(-1)
    else:
        a = np.asarray([x], dtype=np.float32)
    if a.size == n:
        return a
    return np.full(n, a[0] if a.size else 0.0, dtype=np.float32)


def _source(props):
    """``(material path, nested BSDF)``: exactly one of the ``material`` and ``bsdf``
    properties."""
    has_material, has_bsdf = "material" in props, "bsdf" in props
    if has_material == has_bsdf:
        raise ValueError("neusample: give exactly one of 'material' (a neural-material blob) "
                         "and 'bsdf' (a nested BSDF to evaluate)")
    if has_bsdf:
        return None, props["bsdf"]
    return str(props["material"]), None


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
            self.material_path, self.nested = _source(props)
            self.material = None if self.nested is not None else NeuralMaterial(self.material_path)
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
        def _traced(self) -> bool:
            """Whether Dr.Jit is tracing this call symbolically, where arrays cannot be read.

            A symbolic call traces every live BSDF of the variant, not only those of the
            scene it renders: a symbolic render of another scene must not fail because this
            one exists. The call then returns zeros and warns once (its code runs only for
            lanes that hit this BSDF: if it is in the scene, those lanes render black)."""
            if not (jit and dr.flag(dr.JitFlag.SymbolicScope)):
                return False
            warnings.warn(
                f"neusample: the evaluated plugin (sampler {self.sampler_path!r}) was traced in "
                "Mitsuba's symbolic mode, where it returns zeros; if it is in the scene being "
                "rendered, "
                "render with neusample.mitsuba.render(...) or call evaluated_mode() first "
                "(otherwise Dr.Jit only traced it as a live BSDF of the variant: ignore this)",
                RuntimeWarning,
                stacklevel=3,
            )
            return True

        def _inputs(self, si, n: int):
            wi = np.stack([_flat(si.wi.x, n), _flat(si.wi.y, n), _flat(si.wi.z, n)])
            if self.material is None:
                return np.zeros((FEATURE_DIM, n), dtype=np.float32), wi
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

        def _f_cos(self, ctx, si, phi, wi, wo) -> np.ndarray:
            if self.nested is not None:
                n = wo.shape[1]
                value = self.nested.eval(ctx, si, to_vec3(wo), True)
                return np.stack([_flat(value[0], n), _flat(value[1], n), _flat(value[2], n)])
            f = self.material.eval(phi, wi, wo, threads=self.threads)
            return f * np.maximum(wo[2], 0.0)

        # -- the BSDF interface -----------------------------------------------------------
        def sample(self, ctx, si, sample1, sample2, active=True):
            if self._traced():
                return dr.zeros(mi.BSDFSample3f), mi.Color3f(0.0)
            n = _width(si.wi, si.uv, sample2)
            phi, wi = self._inputs(si, n)
            u = np.stack([_flat(sample2.x, n), _flat(sample2.y, n)])
            # Mitsuba weighs MIS with bs.pdf and the estimate with the weight: the sample's
            # MIS density (the sampler's pdf at wo) there, its own density here.
            wo, pdf, mis = self.sampler.sample(phi, wi, u, threads=self.threads)
            f_cos = self._f_cos(ctx, si, phi, wi, wo)
            ok = pdf > 0
            weight = np.where(ok, f_cos / np.where(ok, pdf, 1.0), 0.0).astype(np.float32)
            enabled = ctx.is_enabled(mi.BSDFFlags.GlossyReflection)
            bs = dr.zeros(mi.BSDFSample3f, n if jit else 1)
            bs.wo = to_vec3(wo)
            bs.pdf = to_float(mis)  # 0 at refused lanes, as pdf
            bs.eta = 1.0
            bs.sampled_type = mi.UInt32(+mi.BSDFFlags.GlossyReflection)
            bs.sampled_component = mi.UInt32(0)
            valid = active & (bs.pdf > 0) & enabled
            bs.pdf = dr.select(valid, bs.pdf, 0.0)
            return bs, dr.select(valid, to_color(weight), 0.0)

        def eval(self, ctx, si, wo, active=True):
            if self._traced():
                return mi.Color3f(0.0)
            n = _width(si.wi, si.uv, wo)
            phi, wi = self._inputs(si, n)
            value = to_color(self._f_cos(ctx, si, phi, wi, self._vec3(wo, n)).astype(np.float32))
            enabled = ctx.is_enabled(mi.BSDFFlags.GlossyReflection)
            return dr.select(active & enabled, value, 0.0)

        def pdf(self, ctx, si, wo, active=True):
            if self._traced():
                return mi.Float(0.0)
            n = _width(si.wi, si.uv, wo)
            phi, wi = self._inputs(si, n)
            value = to_float(self._pdf(phi, wi, self._vec3(wo, n)))
            enabled = ctx.is_enabled(mi.BSDFFlags.GlossyReflection)
            return dr.select(active & enabled, value, 0.0)

        def eval_pdf(self, ctx, si, wo, active=True):
            if self._traced():
                return mi.Color3f(0.0), mi.Float(0.0)
            n = _width(si.wi, si.uv, wo)
            phi, wi = self._inputs(si, n)
            w = self._vec3(wo, n)
            value = to_color(self._f_cos(ctx, si, phi, wi, w).astype(np.float32))
            pdf = to_float(self._pdf(phi, wi, w))
            enabled = ctx.is_enabled(mi.BSDFFlags.GlossyReflection)
            return (
                dr.select(active & enabled, value, 0.0),
                dr.select(active & enabled, pdf, 0.0),
            )

        def to_string(self):
            return (
                f"NeuSampleBSDF[material={self.material_path!r}, bsdf={self.nested}, "
                f"sampler={self.sampler_path!r} ({self.sampler.kind})]"
            )

    _CLASSES[variant] = NeuSampleBSDF
    return NeuSampleBSDF


def symbolic_bsdf_class():
    """The symbolic-mode plugin class (:mod:`neusample.drjit`) for the current JIT variant."""
    import drjit as dr
    import mitsuba as mi

    from . import drjit as nd

    variant = mi.variant()
    if variant is None:
        raise RuntimeError("call mitsuba.set_variant(...) before neusample.mitsuba.register()")
    key = ("symbolic", variant)
    if key in _CLASSES:
        return _CLASSES[key]
    if not dr.is_jit_v(mi.Float):
        raise RuntimeError(f"the symbolic plugin needs a JIT variant (llvm_*, cuda_*), not {variant}")

    flags = (
        mi.BSDFFlags.GlossyReflection
        | mi.BSDFFlags.FrontSide
        | mi.BSDFFlags.SpatiallyVarying
    )

    class NeuSampleJitBSDF(mi.BSDF):
        """A neural material (``material``) importance-sampled by a neusample ``sampler``,
        both as Dr.Jit code traced into Mitsuba's kernels."""

        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            self.material_path, self.nested = _source(props)
            self.sampler_path = str(props["sampler"]) if "sampler" in props else None
            precision = str(props["precision"]) if "precision" in props else None
            self.material = None if self.nested is not None else \
                nd.NeuralMaterial(self.material_path, mi.Float, precision)
            self.sampler = nd.Sampler(self.sampler_path, mi.Float, precision)
            self.uv_scale = float(props["uv_scale"]) if "uv_scale" in props else 1.0
            self.uv_offset = float(props["uv_offset"]) if "uv_offset" in props else 0.0
            self.m_components = [flags]
            self.m_flags = flags

        def _features(self, si):
            if self.material is None:
                return [mi.Float(0.0) for _ in range(FEATURE_DIM)]
            u = si.uv.x * self.uv_scale + self.uv_offset
            v = si.uv.y * self.uv_scale + self.uv_offset
            return self.material.features(u, v)

        def _f_cos(self, ctx, phi, si, wo):
            if self.nested is not None:
                return self.nested.eval(ctx, si, mi.Vector3f(wo[0], wo[1], wo[2]), True)
            f = self.material.eval(phi, si.wi, wo)
            c = dr.maximum(wo[2], 0.0)
            return mi.Color3f(f[0] * c, f[1] * c, f[2] * c)

        def _pdf(self, phi, si, wo):
            """The sampler's solid-angle pdf: the one helper `pdf` and `eval_pdf` share."""
            st, ok = self.sampler.prepare(phi, si.wi)
            return self.sampler.pdf_prepared(st, ok, wo)

        def sample(self, ctx, si, sample1, sample2, active=True):
            phi = self._features(si)
            st, ok = self.sampler.prepare(phi, si.wi)
            # The weight divides by the sample's own density, MIS weighs with `mis` (they
            # differ for the reparameterization sampler: its warp's density and p̂).
            wo, pdf, valid, mis = self.sampler.sample_mis(st, ok, (sample2.x, sample2.y))
            valid = valid & active & ctx.is_enabled(mi.BSDFFlags.GlossyReflection)
            f_cos = self._f_cos(ctx, phi, si, wo)
            bs = dr.zeros(mi.BSDFSample3f)
            bs.wo = mi.Vector3f(wo[0], wo[1], wo[2])
            bs.pdf = dr.select(valid, mis, 0.0)
            bs.eta = 1.0
            bs.sampled_type = mi.UInt32(+mi.BSDFFlags.GlossyReflection)
            bs.sampled_component = mi.UInt32(0)
            weight = f_cos / dr.select(valid, pdf, 1.0)
            return bs, dr.select(valid, weight, 0.0)

        def eval(self, ctx, si, wo, active=True):
            enabled = active & ctx.is_enabled(mi.BSDFFlags.GlossyReflection)
            w = (wo.x, wo.y, wo.z)
            return dr.select(enabled, self._f_cos(ctx, self._features(si), si, w), 0.0)

        def pdf(self, ctx, si, wo, active=True):
            enabled = active & ctx.is_enabled(mi.BSDFFlags.GlossyReflection)
            w = (wo.x, wo.y, wo.z)
            return dr.select(enabled, self._pdf(self._features(si), si, w), 0.0)

        def eval_pdf(self, ctx, si, wo, active=True):
            enabled = active & ctx.is_enabled(mi.BSDFFlags.GlossyReflection)
            w = (wo.x, wo.y, wo.z)
            phi = self._features(si)
            return (
                dr.select(enabled, self._f_cos(ctx, phi, si, w), 0.0),
                dr.select(enabled, self._pdf(phi, si, w), 0.0),
            )

        def to_string(self):
            return (
                f"NeuSampleJitBSDF[material={self.material_path!r}, bsdf={self.nested}, "
                f"sampler={self.sampler_path!r} ({self.sampler.name}, α = {self.sampler.alpha})]"
            )

    _CLASSES[key] = NeuSampleJitBSDF
    return NeuSampleJitBSDF


def plugin_class(mode: str = "symbolic"):
    """The plugin class of ``mode`` for the current variant: the symbolic one in JIT
    variants, the Rust per-ray one in scalar variants (either mode)."""
    import drjit as dr
    import mitsuba as mi

    if mode not in ("symbolic", "evaluated"):
        raise ValueError(f"neusample: mode must be 'symbolic' or 'evaluated', not {mode!r}")
    if mode == "evaluated" or not dr.is_jit_v(mi.Float):
        return bsdf_class()
    return symbolic_bsdf_class()


def register(name: str = "neusample", cls=None) -> None:
    """Registers the BSDF plugin as ``name`` for the current Mitsuba variant. The scene's
    ``mode`` property picks the symbolic (default) or evaluated plugin; with ``cls`` (a
    subclass of :func:`symbolic_bsdf_class` or :func:`bsdf_class`) every instance is a
    ``cls``."""
    import mitsuba as mi

    def make(props):
        # Read here, so that Mitsuba never reports them unreferenced (each class uses its own).
        mode = str(props["mode"]) if "mode" in props else "symbolic"
        for name in ("precision", "threads"):
            if name in props:
                props[name]
        if cls is not None:
            return cls(props)
        return plugin_class(mode)(props)

    mi.register_bsdf(name, make)
