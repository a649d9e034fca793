//! Neural materials: the NeuMIP-style BRDF the samplers are trained for (paper §1, Fig. 2b,
//! "simplified to 2D feature textures").
//!
//! A neural material is a learned **feature texture** of `W × H` texels with
//! [`FEATURE_DIM`] = 8 channels and a small **decoder** MLP:
//!
//! ```text
//! φ(uv)          = bilinear lookup of the texture at uv (wrapping)      (latent, no physical meaning)
//! f(φ, wi, wo)   = exp(decoder(φ, wi.xy, wo.xy, h.xy))  ∈ RGB          (BRDF without the cosine)
//! h              = normalize(wi + wo)                                    (half vector)
//! ```
//!
//! The samplers are conditioned on the same φ ([`crate::Sampler::prepare`]), which is why a
//! renderer needs both: [`NeuralMaterial::features`] once per shading point, then
//! [`NeuralMaterial::eval`] for every direction pair, and a sampler prepared with the same φ.
//! The exact layer layout is `core/ARCHITECTURES.md` §7.
//!
//! Like the samplers, everything here is total: non-finite or below-horizon inputs give 0,
//! never NaN or a panic, and nothing allocates.

use glam::{Vec2, Vec3};

use crate::math;
use crate::nn::{self, ReluMlp, FEATURE_DIM};
use crate::warp;
use crate::weights::Weights;

/// Inputs of the decoder: `[φ₀ … φ₇, wi.x, wi.y, wo.x, wo.y, h.x, h.y]`.
pub const DECODER_INPUTS: usize = FEATURE_DIM + 6;
/// Width of the decoder's three hidden layers.
pub const DECODER_HIDDEN: usize = 64;
/// Outputs of the decoder: `ln f` per RGB channel.
pub const DECODER_OUTPUTS: usize = 3;
/// Lower clamp of the decoder's log output: `f ≥ e⁻²⁰ ≈ 2·10⁻⁹`.
pub const LOG_F_MIN: f32 = -20.0;
/// Upper clamp of the decoder's log output: `f ≤ e¹² ≈ 1.6·10⁵` (no overflow to ∞).
pub const LOG_F_MAX: f32 = 12.0;
/// Largest texture width or height a blob may declare.
pub const MAX_TEXTURE_SIZE: u32 = 4096;

type Decoder = ReluMlp<DECODER_INPUTS, DECODER_HIDDEN, DECODER_OUTPUTS, 4>;

/// Number of decoder parameters: `dense(14,64) dense(64,64) dense(64,64) dense(64,3)` = 9475.
pub const DECODER_PARAM_COUNT: usize = Decoder::LEN;

/// Number of texture values of a `width × height` feature texture (`width·height·8`).
#[inline]
#[must_use]
pub const fn texture_len(width: u32, height: u32) -> usize {
    width as usize * height as usize * FEATURE_DIM
}

/// The decoder input for a direction pair, or `None` when `wi` or `wo` is at or below the
/// horizon, of zero length or not finite, or `phi` is not finite. Both directions are
/// normalised here (local shading frame, z = normal, both pointing away from the surface):
///
/// ```text
/// [φ₀ … φ₇, wi.x, wi.y, wo.x, wo.y, h.x, h.y]      h = normalize(wi + wo)
/// ```
#[inline]
#[must_use]
pub fn decoder_input(
    phi: &[f32; FEATURE_DIM],
    wi: Vec3,
    wo: Vec3,
) -> Option<[f32; DECODER_INPUTS]> {
    // Index loops, no slices or iterators: this compiles for rust-gpu.
    let (d, ok) = direction_inputs(wi, wo);
    if !ok || !nn::features_finite(phi) {
        return None;
    }
    let mut x = [0.0f32; DECODER_INPUTS];
    let mut k = 0;
    while k < FEATURE_DIM {
        x[k] = phi[k];
        k += 1;
    }
    while k < DECODER_INPUTS {
        x[k] = d[k - FEATURE_DIM];
        k += 1;
    }
    Some(x)
}

/// The direction part of [`decoder_input`], `[wi.x, wi.y, wo.x, wo.y, h.x, h.y]`, and whether
/// both directions are accepted (the values are meaningless where not), without branches:
/// a loop of it over lanes vectorises.
#[inline(always)]
fn direction_inputs(wi: Vec3, wo: Vec3) -> ([f32; 6], bool) {
    let (wi, ok_i) = warp::upper_hemisphere_lane(wi);
    let (wo, ok_o) = warp::upper_hemisphere_lane(wo);
    // wi.z + wo.z > 0 where both are accepted, so the half vector is not zero.
    let s = wi + wo;
    let inv = 1.0 / math::sqrt(s.x * s.x + s.y * s.y + s.z * s.z);
    ([wi.x, wi.y, wo.x, wo.y, s.x * inv, s.y * inv], ok_i & ok_o)
}

/// `exp(clamp(o, LOG_F_MIN, LOG_F_MAX))`, and 0 for a NaN output.
#[inline(always)]
#[must_use]
pub fn output_to_brdf(o: f32) -> f32 {
    // libm's expf, bit for bit, with less work on this clamped range.
    let f = math::exp_in_range(math::clamp(o, LOG_F_MIN, LOG_F_MAX));
    if o.is_nan() {
        0.0
    } else {
        f
    }
}

/// Wraps a texture coordinate into `[0, n)` texel space and returns the two texels that
/// bracket it and the weight of the second: texel centres at `(i + 0.5)/n`. Non-finite `t`
/// reads as 0. `n ≥ 1`.
#[inline(always)]
#[must_use]
pub fn wrap_bilinear(t: f32, n: u32) -> (u32, u32, f32) {
    let t = if math::is_finite(t) { t } else { 0.0 };
    // Fractional part in [0, 1]; it can round to exactly 1 for tiny negative t.
    let f = t - math::floor(t);
    let x = f * n as f32 - 0.5;
    let x0 = math::floor(x);
    let w = math::clamp(x - x0, 0.0, 1.0);
    let i0 = if x0 < 0.0 {
        n - 1
    } else {
        math::clamp_index(x0, n)
    };
    let i1 = if i0 + 1 >= n { 0 } else { i0 + 1 };
    (i0, i1, w)
}

const fn clamp_dim(n: u32) -> u32 {
    if n == 0 {
        1
    } else if n > MAX_TEXTURE_SIZE {
        MAX_TEXTURE_SIZE
    } else {
        n
    }
}

/// A NeuMIP-style neural material (module docs): a `width × height × 8` feature texture and
/// the decoder MLP of `ARCHITECTURES.md` §7, both read in place through [`Weights`].
///
/// The texture is stored texel-major with channels last, rows along v:
/// value `c` of texel `(i, j)` (column `i` along u, row `j` along v) is at
/// `(j·width + i)·8 + c`, and texel `(i, j)` is centred at `((i + 0.5)/width, (j + 0.5)/height)`.
#[derive(Copy, Clone, Debug)]
pub struct NeuralMaterial<W> {
    texture: W,
    params: W,
    width: u32,
    height: u32,
}

impl<W: Weights> NeuralMaterial<W> {
    /// Number of decoder parameters ([`DECODER_PARAM_COUNT`]).
    pub const PARAM_COUNT: usize = DECODER_PARAM_COUNT;

    /// A material without the checks of [`Self::new`], for GPU shaders. Not `unsafe`: reads
    /// past the end of short arrays give 0.0 (wrong values, never a panic or NaN), and the
    /// dimensions are clamped to `1 ..= MAX_TEXTURE_SIZE` (so texel indices cannot overflow).
    /// Check the lengths on the host.
    #[inline]
    #[must_use]
    pub const fn new_unchecked(texture: W, params: W, width: u32, height: u32) -> Self {
        NeuralMaterial {
            texture,
            params,
            width: clamp_dim(width),
            height: clamp_dim(height),
        }
    }

    /// A material over a feature texture of `width × height` texels (`width·height·8`
    /// values, layout in the type docs) and the flat decoder parameters, or `None` when a
    /// dimension is 0 or above [`MAX_TEXTURE_SIZE`] or an array has the wrong length.
    #[must_use]
    pub fn new(texture: W, params: W, width: u32, height: u32) -> Option<Self> {
        let dims_ok =
            width >= 1 && height >= 1 && width <= MAX_TEXTURE_SIZE && height <= MAX_TEXTURE_SIZE;
        if dims_ok
            && texture.len() as usize == texture_len(width, height)
            && params.len() as usize == Self::PARAM_COUNT
        {
            Some(Self::new_unchecked(texture, params, width, height))
        } else {
            None
        }
    }

    /// Texture width (texels along u).
    #[must_use]
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Texture height (texels along v).
    #[must_use]
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The feature texture.
    #[must_use]
    pub fn texture(&self) -> &W {
        &self.texture
    }

    /// The decoder parameters.
    #[must_use]
    pub fn params(&self) -> &W {
        &self.params
    }

    /// The 8 features of texel `(i, j)` (indices wrap).
    #[inline]
    #[must_use]
    pub fn texel(&self, i: u32, j: u32) -> [f32; FEATURE_DIM] {
        let base = ((j % self.height) * self.width + i % self.width) * FEATURE_DIM as u32;
        let mut out = [0.0f32; FEATURE_DIM];
        let mut c = 0;
        while c < FEATURE_DIM {
            out[c] = self.texture.at(base + c as u32);
            c += 1;
        }
        out
    }

    /// φ(uv): bilinear interpolation of the four texels around `uv`, wrapping in both
    /// directions (the texture tiles; texel centres at `(i + 0.5)/width`). Non-finite
    /// coordinates read as 0.
    #[inline]
    #[must_use]
    pub fn features(&self, uv: Vec2) -> [f32; FEATURE_DIM] {
        let (i0, i1, wx) = wrap_bilinear(uv.x, self.width);
        let (j0, j1, wy) = wrap_bilinear(uv.y, self.height);
        let w = self.width;
        let c = FEATURE_DIM as u32;
        let b00 = (j0 * w + i0) * c;
        let b10 = (j0 * w + i1) * c;
        let b01 = (j1 * w + i0) * c;
        let b11 = (j1 * w + i1) * c;
        let (a00, a10) = ((1.0 - wx) * (1.0 - wy), wx * (1.0 - wy));
        let (a01, a11) = ((1.0 - wx) * wy, wx * wy);
        let t = &self.texture;
        let mut out = [0.0f32; FEATURE_DIM];
        let mut k = 0;
        while k < FEATURE_DIM {
            let kk = k as u32;
            out[k] = a00 * t.at(b00 + kk)
                + a10 * t.at(b10 + kk)
                + a01 * t.at(b01 + kk)
                + a11 * t.at(b11 + kk);
            k += 1;
        }
        out
    }

    /// The decoder's raw outputs `ln f` (before the clamp) for a decoder input
    /// ([`decoder_input`]).
    #[inline]
    #[must_use]
    pub fn forward(&self, x: &[f32; DECODER_INPUTS]) -> [f32; DECODER_OUTPUTS] {
        Decoder::forward(&self.params, x)
    }

    /// The BRDF `f(φ, wi, wo)` in linear RGB, **without** the cosine (multiply by `cos θo`
    /// for the rendering integrand; the samplers' target is `p*(ω⊥) ∝ Y(f)` on the projected
    /// disk). Local shading frame, both directions pointing away from the surface (normalised
    /// here). `[0, 0, 0]` when either direction is at or below the horizon, of zero length or
    /// not finite, or `phi` is not finite; otherwise every channel is finite and in
    /// `[e^LOG_F_MIN, e^LOG_F_MAX]`.
    #[inline]
    #[must_use]
    pub fn eval(&self, phi: &[f32; FEATURE_DIM], wi: Vec3, wo: Vec3) -> [f32; DECODER_OUTPUTS] {
        match decoder_input(phi, wi, wo) {
            Some(x) => {
                let o = self.forward(&x);
                [
                    output_to_brdf(o[0]),
                    output_to_brdf(o[1]),
                    output_to_brdf(o[2]),
                ]
            }
            None => [0.0; DECODER_OUTPUTS],
        }
    }

    /// `eval(features(uv), wi, wo)`.
    #[inline]
    #[must_use]
    pub fn eval_uv(&self, uv: Vec2, wi: Vec3, wo: Vec3) -> [f32; DECODER_OUTPUTS] {
        self.eval(&self.features(uv), wi, wo)
    }
}

#[cfg(not(target_arch = "spirv"))]
mod batch;
