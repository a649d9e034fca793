"""The neusample runtime in Dr.Jit: the samplers and the neural material as traced array code.

Everything here is written with Dr.Jit operations on JIT arrays (``drjit.llvm.ad.Float``,
``drjit.cuda.ad.Float``, or Mitsuba's ``mi.Float``), so it can run inside Mitsuba's compiled
kernels in its default *symbolic* mode (symbolic loops and calls), as well as on concrete
arrays. The definitions are those of ``core/ARCHITECTURES.md``, operation for operation, and
the weights and tables come from the Rust blob reader (:meth:`neusample.Blob.tensor`): no blob
is parsed here. ::

    import drjit as dr, neusample.drjit as nd
    from drjit.llvm.ad import Float
    material = nd.NeuralMaterial("fixtures/materials/neural/goat_leather_neural.nsb", Float)
    sampler = nd.load_sampler("fixtures/blobs/goat_leather_neural/flow.nsb", Float)
    phi = material.features(u, v)                  # 8 Floats
    wo, pdf, ok = sampler.sample(phi, wi, (u0, u1)) # wo: 3 Floats; solid-angle pdf; refused: ok False, pdf 0
    f = material.eval(phi, wi, wo)                 # 3 Floats, RGB BRDF without the cosine

Directions are ``(x, y, z)`` tuples (or Dr.Jit 3-vectors) in the local shading frame; pdfs
are densities with respect to **solid angle** (`sample`, `pdf`) or area on the **projected
disk** (`pdf_disk`, ``core/ARCHITECTURES.md``). Refused lanes (below-horizon or non-finite
``wi``, samples outside the disk) give ``pdf = 0``, ``f = 0`` and never disturb other lanes.
A sample's pdf is the density it was drawn with (divide ``f·cos θo`` by it); for the
reparameterization sampler that is its warp's own density, while ``pdf`` is its pdf network,
the density MIS must use: :meth:`Sampler.sample_mis` returns both.

Networks run as cooperative-vector matrix products (``drjit.nn.matvec``). Their precision is
``"f32"`` by default on the LLVM backend (the Rust runtime's arithmetic; agreement is tested)
and ``"f16"`` on CUDA, where OptiX's cooperative vectors need half-precision matrices.

A sampler kind is one :class:`Kind` subclass (``prepare``, ``sample_point``, ``pdf_disk``)
and one entry of :data:`KIND_CLASSES`; the defensive mixture (α of version-2 blobs) wraps
any of them (:class:`Sampler`).

On the LLVM backend Dr.Jit's CPU fallback for cooperative vectors evaluates a matrix product
as a loop over the weights, and inside a symbolic call (Mitsuba's BSDF dispatch) it would
load every weight with a masked gather per lane: there the f32 networks are traced as fused
multiply-adds with the weights as literal constants instead (:meth:`Mlp.literal`;
``docs/mitsuba_speed.md``).
"""

from __future__ import annotations

import math
import numpy as np

import drjit as dr
from drjit import nn

from . import Blob

# --- constants (as f32, the values the Rust runtime uses) ---------------------------------

_F = np.float32
PI = float(_F(math.pi))
INV_PI = float(_F(1.0 / math.pi))
TWO_PI = float(_F(2.0) * _F(math.pi))
INV_TWO_PI = float(_F(0.5) * _F(1.0 / math.pi))
LN_TWO_PI = float(_F(1.8378771))
ONE_MINUS_EPSILON = float(_F(1.0) - _F(np.finfo(np.float32).eps) / _F(2.0))
F32_MAX = float(np.finfo(np.float32).max)
MIN_COS_THETA = 1e-6
LOG_SIGMA_MIN, LOG_SIGMA_MAX = -7.0, 1.0
LOGIT_BOUND = 1e30
MEAN_BOUND = 1e4
LEAKY_SLOPE = 0.01
# Splines (distrib/spline.rs).
MIN_BIN_WIDTH = MIN_BIN_HEIGHT = MIN_DERIVATIVE = 1e-3
RAW_LIMIT = 1e6
SPLINE_BINS = 20
# Histogram mixture.
BASES = 10
CDF_UNITS = 65535.0
MIN_ROTATION_NORM2 = 1e-24
# Neural material.
LOG_F_MIN, LOG_F_MAX = -20.0, 12.0

# Sampler kinds implemented here: KIND_CLASSES / KINDS below (affine-flow and
# direct-histogram, the paper's comparison baselines, stay on the Rust path).


# Whether f32 networks traced inside a symbolic region on the LLVM backend take their
# weights as literal constants (:meth:`Mlp.literal`); False keeps cooperative vectors there
# (the comparison of ``examples/mitsuba_scene.py speed``).
LITERAL_WEIGHTS_IN_SYMBOLIC_CALLS = True

# --- types ----------------------------------------------------------------------------------


class Types:
    """The Dr.Jit types that go with a JIT ``Float`` type (``mi.Float``, ``dr.llvm.ad.Float``)."""

    def __init__(self, Float):
        if not dr.is_jit_v(Float):
            raise TypeError(f"neusample.drjit needs a JIT array type (llvm or cuda), not {Float}")
        self.Float = Float
        self.UInt32 = dr.uint32_array_t(Float)
        self.Float32 = dr.float32_array_t(Float)
        self.Bool = dr.mask_t(Float)
        self.TensorXf = dr.tensor_t(Float)
        self.Float16 = dr.float16_array_t(Float)
        self.TensorXf16 = dr.tensor_t(self.Float16)
        self.cuda = dr.backend_v(Float) == dr.JitBackend.CUDA

    def buffer(self, values: np.ndarray):
        """A flat, evaluated Float buffer of ``values`` (for ``dr.gather``)."""
        b = self.Float(np.ascontiguousarray(values, dtype=np.float32).astype(
            np.float64 if dr.type_v(self.Float) == dr.VarType.Float64 else np.float32))
        dr.make_opaque(b)
        return b


# --- elementary functions --------------------------------------------------------------------


def is_finite(x):
    return dr.abs(x) < dr.inf


def clamp(x, lo, hi):
    """``x`` clamped to ``[lo, hi]``, NaN → ``lo`` (``math::clamp``)."""
    return dr.select(x >= lo, dr.select(x <= hi, x, hi), lo)


def safe_sqrt(x):
    return dr.sqrt(dr.select(x > 0, x, 0))


def log1p(x):
    """ln(1 + x) accurate near 0 (Goldberg's form)."""
    u = 1.0 + x
    d = u - 1.0
    return dr.select(d == 0, x, dr.log(u) * (x / dr.select(d == 0, 1.0, d)))


def softplus(x):
    """ln(1 + eˣ): ``x`` above 20, else ``log1p(exp(x))`` (``math::softplus``)."""
    return dr.select(x > 20.0, x, log1p(dr.exp(dr.minimum(x, 20.0))))


def sigmoid(x):
    e = dr.exp(-dr.abs(x))
    return dr.select(x >= 0, 1.0 / (1.0 + e), e / (1.0 + e))


def finite_density(p):
    return dr.select((p >= 0) & is_finite(p), p, 0.0)


def softmax(xs, bound=LOGIT_BOUND):
    """``gaussian::softmax`` of a list of Floats: inputs clamped to ±bound (NaN → −bound),
    0 for inputs more than 80 below the maximum, uniform when the sum is not positive."""
    xs = [clamp(x, -bound, bound) for x in xs]
    m = xs[0]
    for x in xs[1:]:
        m = dr.select(x > m, x, m)
    floor = m - 80.0
    es = [dr.select(x >= floor, dr.exp(dr.minimum(x - m, 0.0)), 0.0) for x in xs]
    s = es[0]
    for e in es[1:]:
        s = s + e
    pos = s > 0
    return [dr.select(pos, e / s, 1.0 / len(xs)) for e in es]


def select_component(weights, u):
    """``gaussian::select_component``: the first component whose running sum exceeds ``u``
    (zero weights skipped) and ``u`` remapped into it. Returns (index as UInt32-like list of
    masks per component, remapped u)."""
    n = len(weights)
    lo = dr.zeros(type(u), dr.width(u))
    found = dr.zeros(dr.mask_t(u), dr.width(u))
    chosen = [None] * n
    last = [None] * n
    r = dr.zeros(type(u), dr.width(u)) + ONE_MINUS_EPSILON
    any_pos = dr.zeros(dr.mask_t(u), dr.width(u))
    for i, w in enumerate(weights):
        pos = w > 0
        hi = lo + w
        take = pos & ~found & (u < hi)
        r = dr.select(take, clamp((u - lo) / w, 0.0, ONE_MINUS_EPSILON), r)
        chosen[i] = take
        found = found | take
        last[i] = pos
        lo = dr.select(pos, hi, lo)
        any_pos = any_pos | pos
    # Rounding left u above the last running sum: the last non-zero component.
    later = dr.zeros(dr.mask_t(u), dr.width(u))
    for i in reversed(range(n)):
        is_last = last[i] & ~later
        later = later | last[i]
        chosen[i] = chosen[i] | (~found & is_last)
    # No positive weight at all: component 0 (as the Rust loop's `last = 0`).
    chosen[0] = chosen[0] | ~any_pos
    return chosen, r


def pick(masks, values):
    """The value of the chosen component (``masks`` one-hot)."""
    out = values[0]
    for m, v in zip(masks[1:], values[1:]):
        out = dr.select(m, v, out)
    return out


def sanitize_u(u):
    ok = (u >= 0) & (u <= 1)
    return dr.select(u < ONE_MINUS_EPSILON, u, ONE_MINUS_EPSILON), ok


def upper_hemisphere(w):
    """``warp::upper_hemisphere``: ``w`` normalised (kept as is when unit to rounding) and
    whether it is finite and above the horizon."""
    x, y, z = w
    len2 = x * x + y * y + z * z
    ok = (len2 > 0) & is_finite(len2)
    unit = dr.abs(len2 - 1.0) <= 4.0 * float(np.finfo(np.float32).eps)
    inv = 1.0 / dr.sqrt(dr.select(ok, len2, 1.0))
    x, y, z = (dr.select(unit, c, c * inv) for c in (x, y, z))
    ok = ok & (z > MIN_COS_THETA) & is_finite(z)
    return (x, y, z), ok


def align_azimuth(wi):
    """``Turn::aligning``: ``((cos, sin), wi')`` with ``wi' = (|wi⊥|, 0, wi.z)``, the turn
    that carries ``wi'`` back to ``wi``; the identity and ``wi`` where the azimuth is undefined
    (on the pole, non-finite ``wi``)."""
    x, y, z = wi
    r = dr.sqrt(x * x + y * y)
    good = (r > 1e-20) & (r < float("inf"))
    rs = dr.select(good, r, 1.0)
    turn = (dr.select(good, x / rs, 1.0), dr.select(good, y / rs, 0.0))
    return turn, (dr.select(good, r, x), dr.select(good, 0.0, y), z)


def turn_to_world(turn, px, py):
    """``Turn::to_world_2d``: a disk point of the learned part's frame in the shading frame."""
    c, s = turn
    return c * px - s * py, s * px + c * py


def turn_to_local(turn, px, py):
    """``Turn::to_local_2d``: a shading-frame disk point in the learned part's frame."""
    c, s = turn
    return c * px + s * py, c * py - s * px


def check_condition(phi, wi):
    wi, ok = upper_hemisphere(wi)
    for p in phi:
        ok = ok & is_finite(p)
    return wi, ok


def encode_scalar(x, bands):
    """``[x, sin(πx), cos(πx), …, sin(2^(B−1)πx), cos(2^(B−1)πx)]`` by the double-angle
    recurrences from ``sincos(πx)`` (``nn::encode_scalar``)."""
    s, c = dr.sincos(PI * x)
    out = [x]
    for _ in range(bands):
        out += [s, c]
        s, c = 2.0 * s * c, c * c - s * s
    return out


def encode_condition(phi, wi):
    return list(phi) + encode_scalar(wi[0], 5) + encode_scalar(wi[1], 5)


def concentric(u0, u1):
    """Shirley–Chiu concentric map ``[0, 1)² → disk``."""
    ox = 2.0 * u0 - 1.0
    oy = 2.0 * u1 - 1.0
    zero = (ox == 0) & (oy == 0)
    wide = dr.abs(ox) > dr.abs(oy)
    r = dr.select(wide, ox, oy)
    safe_x = dr.select(ox == 0, 1.0, ox)
    safe_y = dr.select(oy == 0, 1.0, oy)
    theta = dr.select(wide, (PI / 4.0) * (oy / safe_x), PI / 2.0 - (PI / 4.0) * (ox / safe_y))
    s, c = dr.sincos(theta)
    return dr.select(zero, 0.0, r * c), dr.select(zero, 0.0, r * s)


def box_muller(u0, u1):
    r = safe_sqrt(-2.0 * log1p(-u0))
    s, c = dr.sincos(TWO_PI * u1)
    return r * c, r * s


def normal_pdf(px, py, mx, my, sx, sy):
    dx = (px - mx) / sx
    dy = (py - my) / sy
    return dr.exp(-0.5 * (dx * dx + dy * dy)) * (INV_TWO_PI / (sx * sy))


def sigma_from_log(v):
    return dr.exp(clamp(v, LOG_SIGMA_MIN, LOG_SIGMA_MAX))


def inside_disk(px, py):
    return px * px + py * py < 1.0


# --- networks -------------------------------------------------------------------------------


class Mlp:
    """Dense layers from a flat parameter array (``core/ARCHITECTURES.md``: each layer's
    weights input-major ``W[i][o]`` then its bias ``b[o]``), packed for ``nn.matvec``.

    ``layers`` lists ``(inputs, outputs)``; ``split`` gives the first layer's input count
    that :meth:`first_share` evaluates once per condition (the flows' coupling networks: the
    condition's share of the first layer, bias included)."""

    def __init__(self, t: Types, params: np.ndarray, offset: int, layers, precision="f32",
                 split=None):
        self.t = t
        self.precision = precision
        self.layers = list(layers)
        mats = []
        at = offset
        for li, (i, o) in enumerate(self.layers):
            w = params[at:at + i * o].reshape(i, o).T  # (O, I): y = A x + b
            b = params[at + i * o:at + i * o + o]
            at += i * o + o
            if li == 0 and split is not None:
                mats += [w[:, :split], w[:, split:], b]
            else:
                mats += [w, b]
        self.end = at
        self.split = split
        # Explicit sums with the weights as literal constants: the Float64 reference
        # ("plain") and, on the LLVM backend, the f32 networks inside symbolic regions.
        self.mats = [np.asarray(m, dtype=np.float64) for m in mats]
        if precision == "plain":
            self.dtype = t.Float
            return
        T = t.TensorXf16 if precision == "f16" else t.TensorXf
        tensors = [T(np.ascontiguousarray(m, dtype=np.float32)) for m in mats]
        self.views = nn.pack(*tensors, layout="inference")
        self.dtype = t.Float16 if precision == "f16" else t.Float

    def _vec(self, xs):
        return nn.CoopVec(*[self.dtype(x) for x in xs])

    def literal(self) -> bool:
        """Whether the networks traced now take their weights as literal constants: always
        for ``"plain"``; for ``"f32"`` on the LLVM backend inside a symbolic region (a
        Mitsuba BSDF call), where a cooperative vector's weights are loaded with a masked
        gather per lane, and literals compile one kernel per material instance, as Mitsuba
        compiles one callable per BSDF instance."""
        return self.precision == "plain" or (
            self.precision == "f32" and not self.t.cuda and LITERAL_WEIGHTS_IN_SYMBOLIC_CALLS
            and dr.flag(dr.JitFlag.SymbolicScope))

    @staticmethod
    def _plain(a, xs, b=None):
        """``A x + b`` as fused multiply-adds with literal weights (a list of Floats): each
        output from its bias over the inputs in order, as the Rust kernel accumulates."""
        out = []
        for o in range(a.shape[0]):
            y = float(b[o]) if b is not None else 0.0
            for i, x in enumerate(xs):
                y = dr.fma(x, float(a[o, i]), y)
            out.append(y)
        return out

    def first_share(self, xs):
        """The first layer's condition share ``b + A[:, :split] x`` (a cooperative vector,
        or a list of Floats where :meth:`literal`)."""
        if self.literal():
            return self._plain(self.mats[0], xs, self.mats[2])
        return nn.matvec(self.views[0], self._vec(xs), self.views[2])

    def product(self, k, xs, bias=None):
        """``A_k x`` (plus bias ``b_bias``) with the ``k``-th packed matrix, as a list of
        Floats: one layer's pieces, for code that needs more than the forward pass (the
        reparameterization sampler's tangents pass each hidden layer without its bias)."""
        if self.literal():
            b = None if bias is None else self.mats[bias]
            return [self.t.Float(y) for y in self._plain(self.mats[k], xs, b)]
        b = None if bias is None else self.views[bias]
        v = nn.matvec(self.views[k], self._vec(xs), b) if b is not None \
            else nn.matvec(self.views[k], self._vec(xs))
        return [self.t.Float(c) for c in v]

    def _call_plain(self, xs, act, share):
        v = list(xs)
        k = 0
        for li in range(len(self.layers)):
            if li == 0 and self.split is not None:
                v = [a + c for a, c in zip(self._plain(self.mats[1], v), share)]
                k = 3
            else:
                v = self._plain(self.mats[k], v, self.mats[k + 1])
                k += 2
            if li + 1 < len(self.layers):
                if act == "relu":
                    v = [dr.maximum(x, 0) for x in v]
                else:
                    v = [dr.maximum(x, 0) + dr.minimum(x, 0) * LEAKY_SLOPE for x in v]
        return [self.t.Float(x) for x in v]

    def __call__(self, xs, act="relu", share=None):
        """The network on inputs ``xs`` (a list of Floats); hidden activations ``act``
        (``"relu"`` or ``"leaky"``), identity output. With ``share``, ``xs`` are the first
        layer's inputs after the split."""
        if self.literal():
            return self._call_plain(xs, act, share)
        v = self._vec(xs)
        k = 0
        for li in range(len(self.layers)):
            if li == 0 and self.split is not None:
                v = nn.matvec(self.views[1], v) + share
                k = 3
            else:
                v = nn.matvec(self.views[k], v, self.views[k + 1])
                k += 2
            if li + 1 < len(self.layers):
                if act == "relu":
                    v = dr.maximum(v, 0)
                else:
                    v = dr.maximum(v, 0) + dr.minimum(v, 0) * LEAKY_SLOPE
        return [self.t.Float(c) for c in v]


def _default_precision(t: Types) -> str:
    return "f16" if t.cuda else "f32"


# --- samplers ---------------------------------------------------------------------------------


class Kind:
    """One sampler kind on the projected disk. ``prepare(phi, wi)`` gives ``(state, ok)``;
    ``sample_point(state, u0, u1)`` a disk-plane point and whether it was drawn (before the
    unit-disk test); ``pdf_disk(state, px, py)`` the density with respect to disk area (0
    outside the open unit disk). The reported pdf of a sample is ``pdf_disk`` at its point,
    as in the Rust runtime."""

    name = ""
    # Whether a sample's density is ``pdf_disk`` at its point. Kinds where it is not (the
    # reparameterization sampler) implement ``sample_point_density``, which also returns the
    # density the sample was drawn with; ``pdf_disk`` is then the density MIS uses.
    exact = True

    def prepare(self, phi, wi):
        raise NotImplementedError

    def sample_point(self, st, u0, u1):
        raise NotImplementedError

    def sample_point_density(self, st, u0, u1):
        """:meth:`sample_point` and the density the point was drawn with on the projected
        disk; ``None`` for exact kinds (it is ``pdf_disk`` there)."""
        px, py, ok = self.sample_point(st, u0, u1)
        return px, py, ok, None

    def pdf_disk(self, st, px, py):
        raise NotImplementedError


class Cosine(Kind):
    name = "cosine"

    def __init__(self, t: Types, blob=None, precision=None):
        self.t = t

    def prepare(self, phi, wi):
        _, ok = check_condition(phi, wi)
        return None, ok

    def sample_point(self, st, u0, u1):
        px, py = concentric(u0, u1)
        return px, py, dr.full(dr.mask_t(px), True, dr.width(px))

    def pdf_disk(self, st, px, py):
        return dr.select(inside_disk(px, py), INV_PI, 0.0)


class ImprovedBaseline(Kind):
    """Paper Eq. 1: Lambert + one isotropic Gaussian (``ARCHITECTURES.md`` §1)."""

    name = "baseline"

    def __init__(self, t: Types, blob, precision):
        self.t = t
        params = _params(blob)
        self.net = Mlp(t, params, 0, [(30, 32), (32, 32), (32, 32), (32, 5)], precision)

    def prepare(self, phi, wi):
        wi, ok = check_condition(phi, wi)
        o = self.net(encode_condition(phi, wi))
        w = softmax([clamp(o[3], -LOGIT_BOUND, LOGIT_BOUND), clamp(o[4], -LOGIT_BOUND, LOGIT_BOUND)])
        mu = (clamp(o[0], -MEAN_BOUND, MEAN_BOUND), clamp(o[1], -MEAN_BOUND, MEAN_BOUND))
        return (w, mu, sigma_from_log(o[2])), ok

    def sample_point(self, st, u0, u1):
        w, mu, s = st
        masks, v0 = select_component(w, u0)
        cx, cy = concentric(v0, u1)
        gx, gy = box_muller(v0, u1)
        gauss = masks[1]
        px = dr.select(gauss, mu[0] + s * gx, cx)
        py = dr.select(gauss, mu[1] + s * gy, cy)
        return px, py, dr.full(dr.mask_t(px), True, dr.width(px))

    def pdf_disk(self, st, px, py):
        w, mu, s = st
        p = w[0] * INV_PI + w[1] * normal_pdf(px, py, mu[0], mu[1], s, s)
        return dr.select(inside_disk(px, py), finite_density(p), 0.0)


class AnalyticMixture(Kind):
    """Paper Eq. 2: Lambert + two axis-aligned Gaussians (``ARCHITECTURES.md`` §2)."""

    name = "analytic"

    def __init__(self, t: Types, blob, precision):
        self.t = t
        params = _params(blob)
        self.net = Mlp(t, params, 0, [(30, 32), (32, 11)], precision)

    def prepare(self, phi, wi):
        wi, ok = check_condition(phi, wi)
        o = self.net(encode_condition(phi, wi))
        w = softmax([clamp(o[8 + i], -LOGIT_BOUND, LOGIT_BOUND) for i in range(3)])
        mu = [(clamp(o[2 * g], -MEAN_BOUND, MEAN_BOUND), clamp(o[2 * g + 1], -MEAN_BOUND, MEAN_BOUND))
              for g in range(2)]
        sg = [(sigma_from_log(o[4 + 2 * g]), sigma_from_log(o[5 + 2 * g])) for g in range(2)]
        return (w, mu, sg), ok

    def sample_point(self, st, u0, u1):
        w, mu, sg = st
        masks, v0 = select_component(w, u0)
        cx, cy = concentric(v0, u1)
        gx, gy = box_muller(v0, u1)
        second = masks[2]
        mx = dr.select(second, mu[1][0], mu[0][0])
        my = dr.select(second, mu[1][1], mu[0][1])
        sx = dr.select(second, sg[1][0], sg[0][0])
        sy = dr.select(second, sg[1][1], sg[0][1])
        lam = masks[0]
        px = dr.select(lam, cx, mx + sx * gx)
        py = dr.select(lam, cy, my + sy * gy)
        return px, py, dr.full(dr.mask_t(px), True, dr.width(px))

    def pdf_disk(self, st, px, py):
        w, mu, sg = st
        p = (w[0] * INV_PI
             + w[1] * normal_pdf(px, py, mu[0][0], mu[0][1], sg[0][0], sg[0][1])
             + w[2] * normal_pdf(px, py, mu[1][0], mu[1][1], sg[1][0], sg[1][1]))
        return dr.select(inside_disk(px, py), finite_density(p), 0.0)


class Spline:
    """A K-bin rational-quadratic spline on ``[−1, 1]`` from raw network outputs, identity
    outside (``distrib/spline.rs``: nflows' constraints, evaluation from the nearer knot)."""

    def __init__(self, raw, bound=1.0):
        k = SPLINE_BINS
        raw = [clamp(r, -RAW_LIMIT, RAW_LIMIT) for r in raw]
        w = softmax(raw[:k], bound=1e30)
        h = softmax(raw[k:2 * k], bound=1e30)
        scale_w = float(_F(1.0) - _F(MIN_BIN_WIDTH) * _F(k))
        scale_h = float(_F(1.0) - _F(MIN_BIN_HEIGHT) * _F(k))
        b = bound
        xs = [None] * k
        ys = [None] * k
        xs[0] = dr.zeros(type(raw[0]), dr.width(raw[0])) - b
        ys[0] = xs[0]
        cw = ch = 0.0
        for i in range(1, k):
            cw = cw + (MIN_BIN_WIDTH + scale_w * w[i - 1])
            xs[i] = (2.0 * b) * cw - b
            ch = ch + (MIN_BIN_HEIGHT + scale_h * h[i - 1])
            ys[i] = (2.0 * b) * ch - b
        self.x, self.y = xs, ys
        self.raw_d = [None] + raw[2 * k:]  # raw_d[j] for interior knot j = 1..K−1
        self.bound = bound

    def _bin(self, knots, v):
        """Parameters of the last bin whose left knot is ≤ v: (x0, x1, y0, y1, d0, d1)."""
        k = SPLINE_BINS
        b = self.bound
        x0, x1, y0, y1 = self.x[0], self.x[1], self.y[0], self.y[1]
        rd1 = self.raw_d[1]
        first = dr.full(dr.mask_t(v), True, dr.width(v))
        last = dr.full(dr.mask_t(v), False, dr.width(v))
        rd0 = rd1
        for j in range(1, k):
            m = v >= knots[j]
            nx = self.x[j + 1] if j + 1 < k else b
            ny = self.y[j + 1] if j + 1 < k else b
            x0 = dr.select(m, self.x[j], x0)
            x1 = dr.select(m, nx, x1)
            y0 = dr.select(m, self.y[j], y0)
            y1 = dr.select(m, ny, y1)
            rd0 = dr.select(m, self.raw_d[j], rd0)
            if j + 1 < k:
                rd1 = dr.select(m, self.raw_d[j + 1], rd1)
            first = first & ~m
            last = (last | m) if j + 1 == k else (last & ~m)
        d0 = dr.select(first, 1.0, MIN_DERIVATIVE + softplus(rd0))
        d1 = dr.select(last, 1.0, MIN_DERIVATIVE + softplus(rd1))
        return x0, x1, y0, y1, d0, d1

    @staticmethod
    def _log_derivative(xi, s, d0, d1):
        t = xi * (1.0 - xi)
        om = 1.0 - xi
        den = s + (d1 + d0 - 2.0 * s) * t
        num = s * s * (d1 * xi * xi + 2.0 * s * t + d0 * om * om)
        return dr.log(num / (den * den))

    def _in_bounds(self, x):
        x = clamp(x, -F32_MAX, F32_MAX)
        return x, (x >= -self.bound) & (x <= self.bound)

    def forward(self, x):
        """``(RQ(x), ln RQ'(x))`` (Eq. 4)."""
        x, inside = self._in_bounds(x)
        x0, x1, y0, y1, d0, d1 = self._bin(self.x, x)
        w, h = x1 - x0, y1 - y0
        s = h / w
        xi = clamp((x - x0) / w, 0.0, 1.0)
        t = xi * (1.0 - xi)
        den = s + (d1 + d0 - 2.0 * s) * t
        om = 1.0 - xi
        from_left = y0 + h * (s * xi * xi + d0 * t) / den
        from_right = y1 - h * (s * om * om + d1 * t) / den
        y = clamp(dr.select(xi <= 0.5, from_left, from_right), y0, y1)
        ld = self._log_derivative(xi, s, d0, d1)
        return dr.select(inside, y, x), dr.select(inside, ld, 0.0)

    def inverse(self, y):
        """``RQ⁻¹(y)`` (the root nflows solves, from the nearer knot)."""
        y, inside = self._in_bounds(y)
        x0, x1, y0, y1, d0, d1 = self._bin(self.y, y)
        w, h = x1 - x0, y1 - y0
        s = h / w
        e = d1 + d0 - 2.0 * s
        lower = (y - y0) <= (y1 - y)
        dy = dr.select(lower, y - y0, y1 - y)
        da = dr.select(lower, d0, d1)
        a = h * (s - da) + dy * e
        b = h * da - dy * e
        c = -s * dy
        root = safe_sqrt(b * b - 4.0 * a * c)
        eta = dr.select(b >= 0, 2.0 * c / (-b - root), (root - b) / (2.0 * a))
        eta = clamp(eta, 0.0, 1.0)
        x = dr.select(lower, x0 + eta * w, x1 - eta * w)
        return dr.select(inside, clamp(x, x0, x1), y)


class Flow(Kind):
    """The paper's conditional RQ-spline flow (Eq. 3–4, ``ARCHITECTURES.md`` §3)."""

    name = "flow"
    HIDDEN = 32
    RAW = 3 * SPLINE_BINS - 1

    def __init__(self, t: Types, blob, precision):
        self.t = t
        params = _params(blob)
        self.base = Mlp(t, params, 0, [(30, 32), (32, 4)], precision)
        c0 = self.base.end
        self.coupling = []
        for _ in range(2):
            net = Mlp(t, params, c0, [(39, 32), (32, 32), (32, self.RAW)], precision, split=30)
            self.coupling.append(net)
            c0 = net.end

    def prepare(self, phi, wi):
        wi, ok = check_condition(phi, wi)
        c = encode_condition(phi, wi)
        o = self.base(c)
        for v in o:
            ok = ok & is_finite(v)
        shares = [net.first_share(c) for net in self.coupling]
        sx, sy = sigma_from_log(o[2]), sigma_from_log(o[3])
        return ((o[0], o[1]), (sx, sy), dr.log(sx * sy), shares), ok

    def _spline(self, st, i, v):
        raw = self.coupling[i](encode_scalar(v, 4), act="leaky", share=st[3][i])
        return Spline(raw)

    def sample_point(self, st, u0, u1):
        mu, sg, _, _ = st
        nx, ny = box_muller(u0, u1)
        zx = mu[0] + sg[0] * nx
        zy = mu[1] + sg[1] * ny
        x = self._spline(st, 0, zy).inverse(zx)
        y = self._spline(st, 1, x).inverse(zy)
        return x, y, dr.full(dr.mask_t(x), True, dr.width(x))

    def pdf_disk(self, st, px, py):
        mu, sg, ln_sigma, _ = st
        yl, ld1 = self._spline(st, 1, px).forward(py)
        xl, ld0 = self._spline(st, 0, yl).forward(px)
        dx = (xl - mu[0]) / sg[0]
        dy = (yl - mu[1]) / sg[1]
        log_p = -0.5 * (dx * dx + dy * dy) - LN_TWO_PI - ln_sigma + (ld0 + ld1)
        p = dr.exp(dr.select(dr.isnan(log_p), -dr.inf, log_p))
        p = dr.select((p > 0) & is_finite(p), p, 0.0)
        return dr.select(inside_disk(px, py), p, 0.0)


class HistogramMixture(Kind):
    """The paper's histogram mixture (Eq. 5–6, ``ARCHITECTURES.md`` §6): rotated, blended
    basis tables read with ``dr.gather`` (values or compact layout)."""

    name = "histogram-mixture"
    SEARCH_STEPS = 7
    SNAP_STEPS = 4

    def __init__(self, t: Types, blob: Blob, precision):
        self.t = t
        params = _params(blob)
        h = blob.header
        self.T = int(h["t_levels"])
        self.n = int(h["resolution"])
        self.linear = h["interpolation"] == "linear"
        self.net = Mlp(t, params, 0, [(10, 32), (32, 32), (32, 32), (32, 40)], precision)
        self.mass = t.buffer(blob.tensor("mass"))
        self.marginal = t.buffer(blob.tensor("marginal"))
        self.conditional = t.buffer(blob.tensor("conditional"))
        table = blob.tensor("table")
        self.compact = table is None
        self.values = None if self.compact else t.buffer(table)
        hh = _F(2.0) / _F(self.n)
        self.cell_area = float(hh * hh)
        self.h = float(hh)
        self.half_n = float(_F(0.5) * _F(self.n))

    # -- table reads --------------------------------------------------------------------
    def _g(self, buf, i):
        return dr.gather(self.t.Float, buf, i)

    def _blend(self, tab, f):
        """``f(slice)`` of the table's two slices blended with weights ``(1 − a, a)``."""
        s0, s1, a = tab
        v0 = f(s0)
        if not self.linear:
            return v0
        return dr.select(a > 0, (1.0 - a) * v0 + a * f(s1), v0)

    def _marginal(self, tab, r):
        n = self.n
        return self._blend(tab, lambda s: self._g(self.marginal, s * n + r))

    def _row_total(self, s, r):
        n = self.n
        m1 = self._g(self.marginal, s * n + r)
        m0 = dr.select(r > 0, self._g(self.marginal, s * n + dr.maximum(r, 1) - 1), 0.0)
        return m1 - m0

    def _slice_conditional(self, s, r, c):
        n = self.n
        i = s * (n * n) + r * n + c
        if not self.compact:
            return self._g(self.conditional, i)
        return self._row_total(s, r) * (self._g(self.conditional, i) / CDF_UNITS)

    def _slice_value(self, s, r, c):
        n = self.n
        i = s * (n * n) + r * n + c
        if not self.compact:
            return self._g(self.values, i)
        c1 = self._g(self.conditional, i)
        c0 = dr.select(c > 0, self._g(self.conditional, dr.maximum(i, 1) - 1), 0.0)
        return self._row_total(s, r) * ((c1 - c0) / CDF_UNITS)

    def _conditional(self, tab, r, c):
        return self._blend(tab, lambda s: self._slice_conditional(s, r, c))

    def _cell_index(self, x):
        v = clamp((x + 1.0) * self.half_n, 0.0, float(self.n - 1))
        return self.t.UInt32(v)

    def _search(self, target, f):
        U = self.t.UInt32
        lo = dr.zeros(U, dr.width(target))
        hi = lo + (self.n - 1)
        for _ in range(self.SEARCH_STEPS):
            go = lo < hi
            mid = lo + (hi - lo) // 2
            above = f(mid) > target
            hi = dr.select(go & above, mid, hi)
            lo = dr.select(go & ~above, mid + 1, lo)
        return lo

    def _snap(self, x, cell):
        U = self.t.UInt32
        for _ in range(self.SNAP_STEPS):
            i = self._cell_index(x)
            bits = dr.reinterpret_array(U, x)
            neg = x < 0
            # next_down: 0 → −min; x > 0 → bits − 1; x < 0 → bits + 1 (next_up symmetric).
            down = dr.select(x == 0, -dr.reinterpret_array(self.t.Float, U(1)),
                             dr.reinterpret_array(self.t.Float, dr.select(neg, bits + 1, bits - 1)))
            up = dr.select(x == 0, dr.reinterpret_array(self.t.Float, U(1)),
                           dr.reinterpret_array(self.t.Float, dr.select(neg, bits - 1, bits + 1)))
            x = dr.select(i == cell, x, dr.select(i > cell, down, up))
        return x

    # -- the sampler ----------------------------------------------------------------------
    def prepare(self, phi, wi):
        t = self.t
        wi, ok = check_condition(phi, wi)
        o = self.net(list(phi) + [wi[0], wi[1]])
        soft = softmax([clamp(o[4 * k], -LOGIT_BOUND, LOGIT_BOUND) for k in range(BASES)])
        T = self.T
        top = float(T - 1)
        bases = []
        for k in range(BASES):
            rx, ry = o[4 * k + 1], o[4 * k + 2]
            len2 = rx * rx + ry * ry
            rot_ok = (len2 >= MIN_ROTATION_NORM2) & is_finite(len2)
            inv = 1.0 / dr.sqrt(dr.select(rot_ok, len2, 1.0))
            rc = dr.select(rot_ok, rx * inv, 1.0)
            rs = dr.select(rot_ok, ry * inv, 0.0)
            s = clamp(sigmoid(o[4 * k + 3]) * top, 0.0, top)
            base = k * T
            if self.linear and T >= 2:
                l0 = t.UInt32(clamp(s, 0.0, float(T - 2)))
                a = clamp(s - t.Float(l0), 0.0, 1.0)
                l1 = l0 + 1
            elif self.linear:
                l0 = l1 = dr.zeros(t.UInt32, dr.width(s))
                a = dr.zeros(t.Float, dr.width(s))
            else:
                l0 = l1 = t.UInt32(clamp(s + 0.5, 0.0, top))
                a = dr.zeros(t.Float, dr.width(s))
            tab = (base + l0, base + l1, a)
            m0 = self._g(self.mass, base + l0)
            mass = dr.select(a > 0, (1.0 - a) * m0 + a * self._g(self.mass, base + l1), m0)
            total = self._marginal(tab, self.n - 1)
            integral = total * self.cell_area
            good = (total > 0) & is_finite(total) & (integral > 0)
            total = dr.select(good, total, 0.0)
            inv_int = dr.select(good, 1.0 / dr.select(good, integral, 1.0), 0.0)
            w = soft[k] * mass
            usable = total > 0
            w = dr.select(usable & (w > 0) & is_finite(w), w, 0.0)
            bases.append(dict(rot=(rc, rs), tab=tab, total=total, inv=inv_int, w=w, usable=usable))
        s = bases[0]["w"]
        for b in bases[1:]:
            s = s + b["w"]
        fallback = ~((s > 0) & is_finite(s))
        s2 = dr.select(bases[0]["usable"], soft[0], 0.0)
        for k in range(1, BASES):
            s2 = s2 + dr.select(bases[k]["usable"], soft[k], 0.0)
        ok = ok & (~fallback | (s2 > 0))
        inv = 1.0 / dr.select(fallback, dr.select(s2 > 0, s2, 1.0), s)
        for k, b in enumerate(bases):
            w = dr.select(fallback, dr.select(b["usable"], soft[k], 0.0), b["w"])
            b["w"] = w * inv
        return bases, ok

    def _density_at(self, b, qx, qy):
        """Basis ``b``'s table density at rotated point ``q`` (0 outside the square)."""
        n = self.n
        inside = (qx >= -1.0) & (qx <= 1.0) & (qy >= -1.0) & (qy <= 1.0)
        r, c = self._cell_index(qy), self._cell_index(qx)
        v = self._blend(b["tab"], lambda s: self._slice_value(s, r, c))
        return dr.select(inside, finite_density(v * b["inv"]), 0.0)

    def pdf_disk(self, bases, px, py):
        total = 0.0
        for b in bases:
            rc, rs = b["rot"]
            qx = rc * px + rs * py
            qy = -rs * px + rc * py
            d = self._density_at(b, qx, qy)
            total = total + dr.select(b["w"] > 0, b["w"] * d, 0.0)
        return dr.select(inside_disk(px, py), finite_density(total), 0.0)

    def sample_point(self, bases, u0, u1):
        t = self.t
        masks, v0 = select_component([b["w"] for b in bases], u0)
        tab = tuple(pick(masks, [b["tab"][i] for b in bases]) for i in range(3))
        total = pick(masks, [b["total"] for b in bases])
        inv = pick(masks, [b["inv"] for b in bases])
        rc = pick(masks, [b["rot"][0] for b in bases])
        rs = pick(masks, [b["rot"][1] for b in bases])
        n = self.n
        # Table2D::sample.
        ty = v0 * total
        ok = (total > 0) & (ty < total)
        r = self._search(ty, lambda i: self._marginal(tab, i))
        m0 = dr.select(r > 0, self._marginal(tab, dr.maximum(r, 1) - 1), 0.0)
        dm = self._marginal(tab, r) - m0
        ok = ok & (dm > 0)
        dy = clamp((ty - m0) / dm, 0.0, ONE_MINUS_EPSILON)
        row_total = self._conditional(tab, r, n - 1)
        tx = u1 * row_total
        ok = ok & (row_total > 0) & (tx < row_total)
        c = self._search(tx, lambda i: self._conditional(tab, r, i))
        c0 = dr.select(c > 0, self._conditional(tab, r, dr.maximum(c, 1) - 1), 0.0)
        dc = self._conditional(tab, r, c) - c0
        ok = ok & (dc > 0)
        dx = clamp((tx - c0) / dc, 0.0, ONE_MINUS_EPSILON)
        h = self.h
        qx = self._snap((t.Float(c) * h - 1.0) + dx * h, c)
        qy = self._snap((t.Float(r) * h - 1.0) + dy * h, r)
        # The table's own density at q must be positive (Table2D::sample).
        chosen = dict(tab=tab, inv=inv)
        ok = ok & (self._density_at(chosen, qx, qy) > 0)
        px = rc * qx - rs * qy
        py = rs * qx + rc * qy
        return px, py, ok


def silu_slope(a):
    """``(silu(a), silu'(a))`` from one sigmoid (``reparam::silu_from_sigmoid``)."""
    s = sigmoid(a)
    return a * s, s * (1.0 + a * (1.0 - s))


def warp_density(zx, zy, det):
    """``N(z; 0, I) / det`` on the projected disk, 0 unless ``det > 0`` and the density is
    finite and positive (``reparam::sample_density``: a folded warp refuses the sample)."""
    p = dr.exp(-0.5 * (zx * zx + zy * zy) - LN_TWO_PI - dr.log(dr.select(det > 0, det, 1.0)))
    ok = (det > 0) & (det <= F32_MAX) & (p > 0) & (p <= F32_MAX)
    return dr.select(ok, p, 0.0)


class Reparam(Kind):
    """The reparameterization sampler (``ARCHITECTURES.md`` §8; Wu et al. 2025): a warp MLP
    ``T(z; c)`` (32 → 16 → 16 → 3, SiLU) from a standard-normal ``z`` to the projected disk,
    the sample's exact density ``N(z) / det ∂T/∂z`` by forward-mode tangents through the
    warp, and a pdf network ``p̂`` (32 → 16 → 1, ReLU, ``exp`` of a clamped log-density) for
    MIS. ``pdf_disk`` is ``p̂``; samples carry the warp's own density (``exact = False``)."""

    name = "reparam"
    exact = False
    HIDDEN = 16
    LOG_DENSITY_MIN, LOG_DENSITY_MAX = -16.0, 16.0

    def __init__(self, t: Types, blob, precision):
        self.t = t
        params = _params(blob)
        h = self.HIDDEN
        self.warp = Mlp(t, params, 0, [(32, h), (h, h), (h, 3)], precision, split=30)
        self.density = Mlp(t, params, self.warp.end, [(32, h), (h, 1)], precision, split=30)
        # ∂(first layer)/∂z.k: the first layer's input row 30 + k (weights are input-major):
        # literals where the networks' weights are, else opaque values so that blobs of this
        # kind share compiled kernels (as the packed matrices do).
        rows = [params[(30 + k) * h:(31 + k) * h] for k in range(2)]
        self.literal_rows = [[float(x) for x in r] for r in rows]
        self.opaque_rows = None if precision == "plain" else \
            [[dr.opaque(t.Float, float(x)) for x in r] for r in rows]

    def prepare(self, phi, wi):
        wi, ok = check_condition(phi, wi)
        c = encode_condition(phi, wi)
        warp = [self.t.Float(v) for v in self.warp.first_share(c)]
        density = self.density.first_share(c)
        for v in warp + [self.t.Float(v) for v in density]:
            ok = ok & is_finite(v)
        return (warp, density), ok

    def warp_at(self, st, zx, zy):
        """``T(z)``: the direction ``(vx, vy, vz)`` above the disk point ``(vx, vy)`` and
        ``det ∂T/∂z`` (signed), with the tangents ``∂/∂z.x``, ``∂/∂z.y`` carried alongside."""
        r0, r1 = self.literal_rows if self.warp.literal() else self.opaque_rows
        h1, t0, t1 = [], [], []
        for j, s in enumerate(st[0]):
            y, d = silu_slope(s + zx * r0[j] + zy * r1[j])
            h1.append(y)
            t0.append(d * r0[j])
            t1.append(d * r1[j])
        m = self.warp
        a2, u0, u1 = m.product(3, h1, 4), m.product(3, t0), m.product(3, t1)
        h2, t0, t1 = [], [], []
        for a, g0, g1 in zip(a2, u0, u1):
            y, d = silu_slope(a)
            h2.append(y)
            t0.append(d * g0)
            t1.append(d * g1)
        o, d0, d1 = m.product(5, h2, 6), m.product(5, t0), m.product(5, t1)
        # v = (a, b, softplus(w)) / |·|; d(u/|u|) = (du − v (v·du)) / |u| (`finish_warp`).
        s, ds = softplus(o[2]), sigmoid(o[2])
        inv = 1.0 / safe_sqrt(o[0] * o[0] + o[1] * o[1] + s * s)
        v = (o[0] * inv, o[1] * inv, s * inv)
        k0 = v[0] * d0[0] + v[1] * d0[1] + v[2] * (ds * d0[2])
        k1 = v[0] * d1[0] + v[1] * d1[1] + v[2] * (ds * d1[2])
        x0 = (d0[0] - v[0] * k0) * inv
        y0 = (d0[1] - v[1] * k0) * inv
        x1 = (d1[0] - v[0] * k1) * inv
        y1 = (d1[1] - v[1] * k1) * inv
        return v, x0 * y1 - x1 * y0

    def sample_point_density(self, st, u0, u1):
        """The disk point, whether it was drawn, and its density on the projected disk (the
        warp's own, ``N(z)/det``; 0 where refused)."""
        zx, zy = box_muller(u0, u1)
        v, det = self.warp_at(st, zx, zy)
        q = warp_density(zx, zy, det)
        return v[0], v[1], (q > 0) & (v[2] > 0), q

    def sample_point(self, st, u0, u1):
        px, py, ok, _ = self.sample_point_density(st, u0, u1)
        return px, py, ok

    def pdf_disk(self, st, px, py):
        o = self.density([px, py], act="relu", share=st[1])[0]
        p = dr.exp(clamp(o, self.LOG_DENSITY_MIN, self.LOG_DENSITY_MAX))
        return dr.select(inside_disk(px, py), p, 0.0)


def _params(blob):
    """The network parameters: a blob's `params` tensor, or a float32 array as is (tests)."""
    return blob if isinstance(blob, np.ndarray) else blob.tensor("params")


KIND_CLASSES = {
    "cosine": Cosine,
    "baseline": ImprovedBaseline,
    "analytic": AnalyticMixture,
    "flow": Flow,
    "histogram-mixture": HistogramMixture,
    "reparam": Reparam,
}
"""Blob kind name → its :class:`Kind` (a new kind is one class and one entry here)."""
KINDS = tuple(KIND_CLASSES)


# --- the sampler with its defensive weight ------------------------------------------------------


class Sampler:
    """A sampler blob (or cosine) in Dr.Jit: the kind with the blob's defensive weight α
    (``p = (1 − α)·p_kind + α·cos θ/π``; α = 0 is the kind itself); an isotropic blob's kind
    sees ``wi`` turned to azimuth 0, its directions turned back (``samplers/defensive.rs``)."""

    def __init__(self, path=None, Float=None, precision=None, blob=None):
        if Float is None:
            raise TypeError("Sampler(path, Float): give the JIT Float type (e.g. mi.Float)")
        t = Types(Float)
        self.t = t
        self.precision = precision or _default_precision(t)
        if blob is None and path is not None:
            blob = Blob(str(path))
        self.path = None if path is None else str(path)
        self.isotropic = False
        if blob is None:
            self.kind = Cosine(t)
            self.alpha = 0.0
            self._alpha = None
            return
        kind = blob.kind
        self.alpha = float(blob.header["defensive"])
        self.isotropic = bool(blob.header.get("isotropic", False))
        # α as an opaque value, so that samplers differing only in α share compiled kernels.
        self._alpha = dr.opaque(t.Float, self.alpha)
        if kind == "neural-material" or kind not in KINDS:
            raise ValueError(
                f"neusample.drjit: sampler kind {kind!r} is not implemented in Dr.Jit "
                f"(kinds: {', '.join(KINDS)}); use the evaluated-mode plugin for it")
        self.kind = KIND_CLASSES[kind](t, blob, self.precision)

    @property
    def name(self):
        return self.kind.name

    def prepare(self, phi, wi):
        """The per-condition state (the kind's and the turn of an isotropic blob, else
        ``None``) and a validity mask."""
        wi = _vec3(wi)
        turn = None
        if self.isotropic:
            turn, wi = align_azimuth(wi)
        st, ok = self.kind.prepare(list(phi), wi)
        return (st, turn), ok

    def sample_prepared(self, st, ok, u):
        """``(wo, pdf, valid)`` from a prepared state: ``wo`` a tuple of 3 Floats, ``pdf``
        the solid-angle density the sample was drawn with (0 where refused), as the Rust
        runtime's ``Sample::pdf``: divide ``f·cos θo`` by it."""
        wo, pdf, valid, _ = self.sample_mis(st, ok, u)
        return wo, pdf, valid

    def sample_mis(self, st, ok, u):
        """``(wo, pdf, valid, mis_pdf)``: :meth:`sample_prepared` and the density MIS weighs
        the sample with (``Sample::mis_pdf``: :meth:`pdf_prepared` at ``wo``). The two
        differ only for kinds whose samples carry their own density (``Kind.exact`` false,
        the reparameterization sampler); with a defensive weight such a kind is combined
        with cosine by one-sample MIS over its ``pdf_disk`` (``samplers/defensive.rs``)."""
        st, turn = st
        u0, ok0 = sanitize_u(u[0])
        u1, ok1 = sanitize_u(u[1])
        valid = ok & ok0 & ok1
        alpha = self._alpha
        exact = self.kind.exact
        if self.alpha > 0:
            cos_lane = u0 < alpha
            v0 = dr.select(cos_lane, u0 / alpha, (u0 - alpha) / (1.0 - alpha))
            v0 = dr.select(v0 < ONE_MINUS_EPSILON, v0, ONE_MINUS_EPSILON)
            lx, ly, lok, q = self.kind.sample_point_density(st, v0, u1)
            cx, cy = concentric(v0, u1)
            px = dr.select(cos_lane, cx, lx)
            py = dr.select(cos_lane, cy, ly)
            valid = valid & (cos_lane | lok)
        else:
            px, py, lok, q = self.kind.sample_point_density(st, u0, u1)
            valid = valid & lok
        r2 = px * px + py * py
        z = dr.sqrt(dr.maximum(1.0 - r2, 0.0))
        valid = valid & (r2 < 1.0) & (z > MIN_COS_THETA)
        p_disk = self.kind.pdf_disk(st, px, py)
        if self.alpha > 0:
            p_learned = p_disk * z
            mis = (1.0 - alpha) * p_learned + alpha * (z * INV_PI)
            if exact:
                # A lane the learned part drew must have a positive learned density, as alone.
                valid = valid & (cos_lane | ((p_learned > 0) & is_finite(p_learned)))
                pdf = mis
            else:
                q_learned = q * z
                valid = valid & (cos_lane | ((q_learned > 0) & is_finite(q_learned)))
                # Learned lanes divide by mix(p̂)·q/p̂ (0, refused, where p̂ is not positive).
                divisor = dr.select(p_learned > 0,
                                    mis / dr.select(p_learned > 0, p_learned, 1.0) * q_learned, 0.0)
                pdf = dr.select(cos_lane, mis, divisor)
        else:
            mis = p_disk * z
            pdf = mis if exact else q * z
        valid = valid & (pdf > 0) & is_finite(pdf)
        if turn is not None:
            px, py = turn_to_world(turn, px, py)
        zero = 0.0
        wo = (dr.select(valid, px, zero), dr.select(valid, py, zero), dr.select(valid, z, zero))
        return wo, dr.select(valid, pdf, zero), valid, dr.select(valid, mis, zero)

    def pdf_prepared(self, st, ok, wo):
        """The solid-angle density of ``wo`` (0 below the horizon and for refused lanes)."""
        st, turn = st
        w, wok = upper_hemisphere(_vec3(wo))
        px, py = w[0], w[1]
        if turn is not None:
            px, py = turn_to_local(turn, px, py)
        p = self.kind.pdf_disk(st, px, py)
        if self.alpha > 0:
            pdf = (1.0 - self._alpha) * (p * w[2]) + self._alpha * (w[2] * INV_PI)
        else:
            pdf = p * w[2]
        return dr.select(ok & wok, pdf, 0.0)

    def sample(self, phi, wi, u):
        st, ok = self.prepare(phi, wi)
        return self.sample_prepared(st, ok, u)

    def pdf(self, phi, wi, wo):
        st, ok = self.prepare(phi, wi)
        return self.pdf_prepared(st, ok, wo)

    def pdf_disk(self, phi, wi, p):
        """The density of disk point ``p`` with respect to projected-disk area (the
        defensive mixture included)."""
        (st, turn), ok = self.prepare(phi, wi)
        px, py = p[0], p[1]
        if turn is not None:
            px, py = turn_to_local(turn, px, py)
        d = self.kind.pdf_disk(st, px, py)
        if self.alpha > 0:
            d = dr.select(inside_disk(p[0], p[1]), (1.0 - self._alpha) * d + self._alpha * INV_PI, 0.0)
        return dr.select(ok, d, 0.0)


def load_sampler(path, Float, precision=None) -> Sampler:
    """:class:`Sampler` of the blob at ``path`` (``None``: cosine)."""
    return Sampler(path, Float, precision)


# --- the neural material ---------------------------------------------------------------------------


class NeuralMaterial:
    """A neural-material blob in Dr.Jit (``ARCHITECTURES.md`` §7): the wrapping bilinear
    feature texture and the decoder ``14 → 64 → 64 → 64 → 3``."""

    def __init__(self, path, Float, precision=None, blob=None):
        t = Types(Float)
        self.t = t
        self.path = str(path)
        blob = blob if blob is not None else Blob(self.path)
        if blob.kind != "neural-material":
            raise ValueError(f"{path}: not a neural material ({blob.kind})")
        h = blob.header
        self.width = int(h["resolution"])
        self.height = int(h["t_levels"])
        self.precision = precision or _default_precision(t)
        self.texture = t.buffer(blob.tensor("features"))
        self.decoder = Mlp(t, blob.tensor("params"), 0, [(14, 64), (64, 64), (64, 64), (64, 3)],
                           self.precision)

    def _wrap(self, v, n):
        t = self.t
        v = dr.select(is_finite(v), v, 0.0)
        f = v - dr.floor(v)
        x = f * float(n) - 0.5
        x0 = dr.floor(x)
        w = clamp(x - x0, 0.0, 1.0)
        i0 = dr.select(x0 < 0, n - 1, t.UInt32(clamp(x0, 0.0, float(n - 1))))
        i1 = dr.select(i0 + 1 >= n, 0, i0 + 1)
        return i0, i1, w

    def features(self, u, v):
        """φ(uv): 8 Floats."""
        i0, i1, wx = self._wrap(u, self.width)
        j0, j1, wy = self._wrap(v, self.height)
        w = self.width
        b00 = (j0 * w + i0) * 8
        b10 = (j0 * w + i1) * 8
        b01 = (j1 * w + i0) * 8
        b11 = (j1 * w + i1) * 8
        a00, a10 = (1.0 - wx) * (1.0 - wy), wx * (1.0 - wy)
        a01, a11 = (1.0 - wx) * wy, wx * wy
        F = self.t.Float
        tex = self.texture
        out = []
        for k in range(8):
            out.append(a00 * dr.gather(F, tex, b00 + k) + a10 * dr.gather(F, tex, b10 + k)
                       + a01 * dr.gather(F, tex, b01 + k) + a11 * dr.gather(F, tex, b11 + k))
        return out

    def eval(self, phi, wi, wo):
        """The RGB BRDF ``f(φ, wi, wo)`` without the cosine (3 Floats); 0 where either
        direction is at or below the horizon or an input is not finite."""
        phi = list(phi)
        wi, ok = check_condition(phi, _vec3(wi))
        wo, ok2 = upper_hemisphere(_vec3(wo))
        ok = ok & ok2
        sx, sy, sz = wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]
        inv = 1.0 / dr.sqrt(dr.select(ok, sx * sx + sy * sy + sz * sz, 1.0))
        o = self.decoder(phi + [wi[0], wi[1], wo[0], wo[1], sx * inv, sy * inv])
        f = [dr.select(dr.isnan(c), 0.0, dr.exp(clamp(c, LOG_F_MIN, LOG_F_MAX))) for c in o]
        return [dr.select(ok, c, 0.0) for c in f]


def _vec3(v):
    if isinstance(v, (tuple, list)):
        return tuple(v)
    return (v.x, v.y, v.z)
