//! Measured materials: the tabulated BRDFs of the RGL material database (Dupuy & Jakob, "An
//! Adaptive Parameterization for Efficient Material Acquisition and Rendering", SIGGRAPH Asia
//! 2018) — their evaluation and **their own sampler**, the visible-normal distribution (VNDF)
//! warped through the luminance table, with its exact density. The same arithmetic as
//! Mitsuba 3's `measured` BSDF, so that a renderer samples measured data as Mitsuba does.
//!
//! # Tables
//!
//! Every table is a [`Marginal2D`] over `[0, 1]²` (module [`crate::distrib::marginal2d`]);
//! the conditional ones have one slice per node of the incident angles `(φi, θi)` (`φi`
//! outermost; isotropic data has one `φi` node):
//!
//! | table | axes `(x, y)` | slices | what |
//! |---|---|---|---|
//! | `ndf` | `(u(θm), u(φm))` | 1 | microfacet normal distribution `D` (unnormalised) |
//! | `sigma` | `(u(θi), u(φi))` | 1 | projected microfacet area `σ` (unnormalised) |
//! | `vndf` | `(u(θm), u(φm))` | `n_φ · n_θ` | visible normals, normalised, with CDFs |
//! | `luminance` | sample space of `vndf` | `n_φ · n_θ` | luminance of the data, normalised, with CDFs |
//! | `rgb` | sample space of `vndf` | `n_φ · n_θ · 3` | the measured values per channel |
//!
//! with `u(θ) = √(2θ/π)` and `u(φ) = (φ + π)/(2π)` (for isotropic data `φm − φi`, wrapped).
//!
//! # Measures
//!
//! [`MeasuredPrepared::eval`] is the BRDF `f(wi, wo)` **without** the cosine (the tables hold
//! `f · cos θo`; [`MeasuredPrepared::eval_cos`] returns that product as Mitsuba's `eval`
//! does). [`MeasuredPrepared::pdf`] and [`MeasuredSample::pdf`] are densities with respect to
//! **solid angle** of `wo`.
//!
//! Everything is total: non-finite or below-horizon directions give `None` or 0, never NaN or
//! a panic, and nothing allocates.
//!
//! # On GPUs
//!
//! The scalar path compiles for SPIR-V (rust-gpu): a shader builds the material over its
//! storage buffers with [`MeasuredMaterial::new_unchecked`] (the host checks the same tables
//! with [`MeasuredMaterial::new`]) and prepares it with [`MeasuredMaterial::prepare_copied`],
//! whose state holds copies of the buffer handles rather than a reference to the material.
//! Only the shape says how many elements a table has: buffers may be padded. The batched
//! calls (`eval_batch`, `pdf_batch`, `sample_batch`) are CPU only.

use glam::{Vec2, Vec3};

use crate::distrib::marginal2d::{Marginal2D, SliceBlend, MAX_PARAM_NODES};
use crate::error::{Error, Result};
use crate::math::{self, PI};
use crate::samplers::Held;
use crate::weights::Weights;

#[cfg(not(target_arch = "spirv"))]
mod batch;

/// Largest table width or height a measured material may have.
pub const MAX_TABLE_SIZE: u32 = 1024;

/// The sizes of a measured material's tables: `[width, height]` of each, and the incident
/// angle nodes.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Default)]
pub struct MeasuredShape {
    /// Number of `φi` nodes (1 for isotropic data).
    pub n_phi: u32,
    /// Number of `θi` nodes.
    pub n_theta: u32,
    /// `[width, height]` of the NDF table.
    pub ndf: [u32; 2],
    /// `[width, height]` of the projected-area table.
    pub sigma: [u32; 2],
    /// `[width, height]` of each VNDF slice.
    pub vndf: [u32; 2],
    /// `[width, height]` of each luminance and RGB slice.
    pub rgb: [u32; 2],
}

impl MeasuredShape {
    /// Number of incident-angle slices, `n_phi · n_theta`.
    #[must_use]
    pub const fn slices(&self) -> u32 {
        self.n_phi * self.n_theta
    }

    /// The sizes as `[n_phi, n_theta, ndf w, ndf h, sigma w, sigma h, vndf w, vndf h, rgb w,
    /// rgb h]`.
    #[must_use]
    pub const fn values(&self) -> [u32; 10] {
        [
            self.n_phi,
            self.n_theta,
            self.ndf[0],
            self.ndf[1],
            self.sigma[0],
            self.sigma[1],
            self.vndf[0],
            self.vndf[1],
            self.rgb[0],
            self.rgb[1],
        ]
    }

    /// The element count of every table, in the order of [`MeasuredTables`]' fields.
    #[must_use]
    pub const fn lens(&self) -> [(&'static str, u32); 11] {
        let s = self.slices();
        let [vw, vh] = self.vndf;
        let [rw, rh] = self.rgb;
        [
            ("phi_i", self.n_phi),
            ("theta_i", self.n_theta),
            ("ndf", self.ndf[0] * self.ndf[1]),
            ("sigma", self.sigma[0] * self.sigma[1]),
            ("vndf", s * vw * vh),
            ("vndf_marginal", s * (vh - 1)),
            ("vndf_conditional", s * vh * (vw - 1)),
            ("luminance", s * rw * rh),
            ("luminance_marginal", s * (rh - 1)),
            ("luminance_conditional", s * rh * (rw - 1)),
            ("rgb", s * 3 * rw * rh),
        ]
    }
}

/// The tables of a measured material (module docs), each in any [`Weights`] storage: the
/// raw `ndf`, `sigma` and `rgb` values, and the normalised `vndf` and `luminance` slices with
/// their running integrals (from [`crate::distrib::marginal2d::build`]).
#[derive(Copy, Clone, Debug)]
pub struct MeasuredTables<W> {
    /// `φi` nodes, ascending (radians).
    pub phi_i: W,
    /// `θi` nodes, ascending (radians).
    pub theta_i: W,
    /// NDF values.
    pub ndf: W,
    /// Projected-area values.
    pub sigma: W,
    /// VNDF slices (normalised).
    pub vndf: W,
    /// Their marginal integrals.
    pub vndf_marginal: W,
    /// Their conditional integrals.
    pub vndf_conditional: W,
    /// Luminance slices (normalised).
    pub luminance: W,
    /// Their marginal integrals.
    pub luminance_marginal: W,
    /// Their conditional integrals.
    pub luminance_conditional: W,
    /// RGB slices, channel innermost among slices: slice `(φ, θ, c)` is `(φ·n_θ + θ)·3 + c`.
    pub rgb: W,
}

impl<W> MeasuredTables<W> {
    /// The tables in field order (that of [`MeasuredShape::lens`]).
    #[must_use]
    pub fn as_array(&self) -> [&W; 11] {
        [
            &self.phi_i,
            &self.theta_i,
            &self.ndf,
            &self.sigma,
            &self.vndf,
            &self.vndf_marginal,
            &self.vndf_conditional,
            &self.luminance,
            &self.luminance_marginal,
            &self.luminance_conditional,
            &self.rgb,
        ]
    }

    /// The tables from an array in field order (that of [`MeasuredShape::lens`]).
    #[must_use]
    pub fn from_array(tables: [W; 11]) -> Self {
        let [phi_i, theta_i, ndf, sigma, vndf, vndf_marginal, vndf_conditional, luminance, luminance_marginal, luminance_conditional, rgb] =
            tables;
        MeasuredTables {
            phi_i,
            theta_i,
            ndf,
            sigma,
            vndf,
            vndf_marginal,
            vndf_conditional,
            luminance,
            luminance_marginal,
            luminance_conditional,
            rgb,
        }
    }
}

/// A measured material: its tables, and whether the RGB values are to be multiplied by
/// `D / (4σ)` (the file's `jacobian` flag).
#[derive(Copy, Clone, Debug)]
pub struct MeasuredMaterial<W> {
    shape: MeasuredShape,
    tables: MeasuredTables<W>,
    jacobian: bool,
    /// The azimuthal symmetry of anisotropic data: 2 (mirror in y), 4 (mirror in x and y) or
    /// 0 (none, and isotropic data).
    reduction: u32,
}

impl<W: Weights> MeasuredMaterial<W> {
    /// Checks every table against `shape` (sizes within limits, element counts, finite
    /// values, non-negative distributions, ascending angle nodes) and builds the material.
    /// RGB values may be slightly negative (measurement noise): the material reads them as 0.
    ///
    /// # Errors
    /// [`Error::DimensionMismatch`] for a size out of range, [`Error::TensorShape`] for a
    /// table of the wrong length, [`Error::NonFinite`] for NaN or ±∞,
    /// [`Error::TableNotNormalized`] for a negative value or unordered nodes.
    pub fn new(shape: MeasuredShape, tables: MeasuredTables<W>, jacobian: bool) -> Result<Self> {
        for (what, n, lo, hi) in [
            ("n_phi", shape.n_phi, 1, MAX_PARAM_NODES),
            ("n_theta", shape.n_theta, 1, MAX_PARAM_NODES),
            ("ndf width", shape.ndf[0], 2, MAX_TABLE_SIZE),
            ("ndf height", shape.ndf[1], 2, MAX_TABLE_SIZE),
            ("sigma width", shape.sigma[0], 2, MAX_TABLE_SIZE),
            ("sigma height", shape.sigma[1], 2, MAX_TABLE_SIZE),
            ("vndf width", shape.vndf[0], 2, MAX_TABLE_SIZE),
            ("vndf height", shape.vndf[1], 2, MAX_TABLE_SIZE),
            ("rgb width", shape.rgb[0], 2, MAX_TABLE_SIZE),
            ("rgb height", shape.rgb[1], 2, MAX_TABLE_SIZE),
        ] {
            if n < lo || n > hi {
                return Err(Error::DimensionMismatch {
                    what,
                    expected: if n < lo { lo } else { hi },
                    found: n,
                });
            }
        }
        // In u64: n_phi · n_theta alone may pass u32's range.
        let slices = u64::from(shape.n_phi) * u64::from(shape.n_theta);
        if slices * 3 * u64::from(shape.rgb[0] * shape.rgb[1]) > u64::from(u32::MAX)
            || slices * u64::from(shape.vndf[0] * shape.vndf[1]) > u64::from(u32::MAX)
        {
            return Err(Error::DimensionMismatch {
                what: "table elements",
                expected: u32::MAX,
                found: u32::MAX,
            });
        }
        for ((role, expected), table) in shape.lens().into_iter().zip(tables.as_array()) {
            if table.len() != expected {
                return Err(Error::TensorShape {
                    role,
                    expected,
                    found: table.len(),
                });
            }
            for i in 0..table.len() {
                let v = table.at(i);
                if !math::is_finite(v) {
                    return Err(Error::NonFinite { role, index: i });
                }
                // Angle nodes ascend (φi may be negative); table values are not negative.
                let bad = if role == "phi_i" || role == "theta_i" {
                    (i > 0 && !(v > table.at(i - 1))) || (role == "theta_i" && v < 0.0)
                } else {
                    // RGB values may dip below zero (measurement noise): read as 0.
                    v < 0.0 && role != "rgb"
                };
                if bad {
                    return Err(Error::TableNotNormalized { role, index: i });
                }
            }
        }
        Ok(Self::new_unchecked(shape, tables, jacobian))
    }

    /// The material without the checks of [`Self::new`], for GPU shaders (`Result<Self>`
    /// with borrowed tables cannot be tested by rust-gpu): check the tables on the host. Not
    /// `unsafe`: tables that do not fit `shape` give wrong values, never a panic or NaN
    /// (reads past the end give 0). Tables may be longer than `shape` says (padded GPU
    /// buffers): only `shape` decides what is read.
    #[must_use]
    pub fn new_unchecked(shape: MeasuredShape, tables: MeasuredTables<W>, jacobian: bool) -> Self {
        let reduction = if shape.n_phi <= 2 {
            0
        } else {
            let span = tables.phi_i.at(shape.n_phi - 1) - tables.phi_i.at(0);
            math::round(2.0 * PI / span) as u32
        };
        MeasuredMaterial {
            shape,
            tables,
            jacobian,
            reduction,
        }
    }

    /// The same material viewing this one's tables (a `Copy` handle for owned storage).
    #[must_use]
    pub fn borrowed(&self) -> MeasuredMaterial<&W> {
        let t = &self.tables;
        MeasuredMaterial {
            shape: self.shape,
            tables: MeasuredTables {
                phi_i: &t.phi_i,
                theta_i: &t.theta_i,
                ndf: &t.ndf,
                sigma: &t.sigma,
                vndf: &t.vndf,
                vndf_marginal: &t.vndf_marginal,
                vndf_conditional: &t.vndf_conditional,
                luminance: &t.luminance,
                luminance_marginal: &t.luminance_marginal,
                luminance_conditional: &t.luminance_conditional,
                rgb: &t.rgb,
            },
            jacobian: self.jacobian,
            reduction: self.reduction,
        }
    }

    /// The tables' sizes.
    #[must_use]
    pub fn shape(&self) -> &MeasuredShape {
        &self.shape
    }

    /// The tables.
    #[must_use]
    pub fn tables(&self) -> &MeasuredTables<W> {
        &self.tables
    }

    /// Whether the data is isotropic (at most two `φi` nodes).
    #[must_use]
    pub fn isotropic(&self) -> bool {
        self.shape.n_phi <= 2
    }

    /// Whether the RGB values are multiplied by `D / (4σ)`.
    #[must_use]
    pub fn jacobian(&self) -> bool {
        self.jacobian
    }

    /// The material at one incident direction `wi` (local frame, z = normal, pointing away
    /// from the surface; normalised here), or `None` when `wi` is at or below the horizon, of
    /// zero length or not finite. The prepared state borrows the material; GPU shaders use
    /// [`Self::prepare_copied`].
    #[must_use]
    pub fn prepare(&self, wi: Vec3) -> Option<MeasuredPrepared<'_, W>> {
        Some(MeasuredPrepared {
            m: self,
            at: self.borrowed().incident(wi)?,
        })
    }
}

impl<W: Weights + Copy> MeasuredMaterial<W> {
    /// [`Self::prepare`] for tables held by `Copy` handles (`&[f32]` storage buffers, blob
    /// tensors): the prepared state keeps a copy of the handles instead of a reference to the
    /// material, as GPU shaders need (a reference to a local material holding buffer
    /// pointers is a pointer-to-pointer that Vulkan drivers fail on). The same numbers.
    #[must_use]
    pub fn prepare_copied(&self, wi: Vec3) -> Option<MeasuredPreparedCopied<W>> {
        Some(MeasuredPreparedCopied {
            m: Held::new(*self),
            at: self.incident(wi)?,
        })
    }

    /// What [`Self::prepare`] computes at `wi`, without a handle.
    fn incident(&self, wi: Vec3) -> Option<Incident> {
        let wi = normalize(wi)?;
        if !(wi.z > 0.0) {
            return None;
        }
        // Anisotropic data with symmetry stores one half (quarter) of the azimuths: fold wi
        // into it; wo follows with the same signs.
        let mut flip = Vec2::ONE;
        if self.reduction >= 2 {
            flip.y = fold_sign(wi.y);
            flip.x = if self.reduction == 4 {
                fold_sign(wi.x)
            } else {
                flip.y
            };
        }
        let wi = Vec3::new(wi.x * flip.x, wi.y * flip.y, wi.z);
        let theta_i = elevation(wi);
        let phi_i = azimuth(wi);
        let t = &self.tables;
        let s = &self.shape;
        let blend = SliceBlend::new(&t.phi_i, s.n_phi, &t.theta_i, s.n_theta, [phi_i, theta_i]);
        let u_wi = Vec2::new(theta2u(theta_i), phi2u(phi_i));
        let sigma = Marginal2D::new(t.sigma, t.sigma, t.sigma, s.sigma[0], s.sigma[1])
            .eval(&SliceBlend::single(0), u_wi);
        Some(Incident {
            wi,
            flip,
            phi_i,
            blend,
            inv_4sigma: if sigma > 0.0 { 0.25 / sigma } else { 0.0 },
        })
    }
}

/// `−1` for `s ≥ +0`, `+1` for negative `s` (Dr.Jit's `mulsign_neg` factor).
#[inline]
fn fold_sign(s: f32) -> f32 {
    if s.is_sign_negative() {
        1.0
    } else {
        -1.0
    }
}

/// `d / |d|`, or `None` for a zero-length or non-finite `d`.
#[inline]
fn normalize(d: Vec3) -> Option<Vec3> {
    let (v, ok) = normalize_lane(d);
    if ok {
        Some(v)
    } else {
        None
    }
}

/// `d / |d|` and whether `d` has a finite, non-zero length (the direction is meaningless
/// where it has not): [`normalize`] without a branch, for loops over lanes.
#[inline(always)]
fn normalize_lane(d: Vec3) -> (Vec3, bool) {
    let len2 = d.length_squared();
    let ok = (len2 > 0.0) & math::is_finite(len2);
    (d * (1.0 / math::sqrt(len2)), ok)
}

/// The azimuth of `d` in [−π, π], 0 on the pole (where `atan2` is undefined).
#[inline]
fn azimuth(d: Vec3) -> f32 {
    let phi = math::poly::atan2(d.y, d.x);
    if d.x == 0.0 && d.y == 0.0 {
        0.0
    } else {
        phi
    }
}

/// The polar angle of a unit vector, accurate near the pole: `2 asin(|d − z|/2)`.
#[inline]
fn elevation(d: Vec3) -> f32 {
    let dz = d.z - 1.0;
    let dist = math::sqrt(d.x * d.x + d.y * d.y + dz * dz);
    2.0 * math::poly::asin(math::clamp(0.5 * dist, -1.0, 1.0))
}

#[inline]
fn theta2u(theta: f32) -> f32 {
    math::sqrt(theta * (2.0 / PI))
}

#[inline]
fn phi2u(phi: f32) -> f32 {
    (phi + PI) * math::INV_TWO_PI
}

/// `u − ⌊u⌋` for `u` in [−1, 2) (the coordinate of an azimuth difference), by selects: the
/// same bits as through `floor`.
#[inline(always)]
fn wrap_unit(u: f32) -> f32 {
    if u < 0.0 {
        u + 1.0
    } else if u >= 1.0 {
        u - 1.0
    } else {
        u
    }
}

#[inline]
fn u2theta(u: f32) -> f32 {
    u * u * (PI / 2.0)
}

#[inline]
fn u2phi(u: f32) -> f32 {
    (2.0 * u - 1.0) * PI
}

/// A direction drawn by the data's own sampler.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct MeasuredSample {
    /// The outgoing direction (unit length, above the horizon).
    pub wo: Vec3,
    /// Its density with respect to solid angle.
    pub pdf: f32,
    /// `f(wi, wo) · cos θo / pdf` per RGB channel.
    pub weight: [f32; 3],
}

/// A [`MeasuredMaterial`] at one incident direction, borrowing it: eval, sample and pdf.
#[derive(Copy, Clone, Debug)]
pub struct MeasuredPrepared<'a, W> {
    m: &'a MeasuredMaterial<W>,
    at: Incident,
}

/// A [`MeasuredMaterial`] at one incident direction, with a copy of its table handles
/// ([`MeasuredMaterial::prepare_copied`]): the same methods and numbers as
/// [`MeasuredPrepared`].
#[derive(Debug)]
pub struct MeasuredPreparedCopied<W> {
    /// A copy of the material (see `Held`).
    m: Held<MeasuredMaterial<W>>,
    at: Incident,
}

impl<W: Copy> Clone for MeasuredPreparedCopied<W> {
    fn clone(&self) -> Self {
        MeasuredPreparedCopied {
            m: self.m.clone(),
            at: self.at,
        }
    }
}

/// The methods of both prepared states, over the material `$m` (a `MeasuredMaterial<V>`
/// with `Copy` handles `V`).
macro_rules! prepared_methods {
    ($self:ident => $m:expr) => {
        /// The measured `f(wi, wo) · cos θo` in linear RGB (Mitsuba's `eval`); 0 when `wo`
        /// is at or below the horizon or not finite.
        #[must_use]
        pub fn eval_cos(&$self, wo: Vec3) -> [f32; 3] {
            $self.at.eval_cos(&$m, wo)
        }

        /// The BRDF `f(wi, wo)` in linear RGB, **without** the cosine; 0 when `wo` is at or
        /// below the horizon or not finite.
        #[must_use]
        pub fn eval(&$self, wo: Vec3) -> [f32; 3] {
            $self.at.eval(&$m, wo)
        }

        /// The density of the data's sampler at `wo`, with respect to solid angle; 0 when
        /// `wo` is at or below the horizon or not finite.
        #[must_use]
        pub fn pdf(&$self, wo: Vec3) -> f32 {
            $self.at.pdf(&$m, wo)
        }

        /// A direction drawn by the data's sampler from the uniform variates `u` (Mitsuba's
        /// `sample2`, the same direction for the same `u`), or `None` when it falls at or
        /// below the horizon or its density is zero.
        #[must_use]
        pub fn sample(&$self, u: Vec2) -> Option<MeasuredSample> {
            $self.at.sample(&$m, u)
        }
    };
}

impl<W: Weights> MeasuredPrepared<'_, W> {
    prepared_methods!(self => self.m.borrowed());
}

impl<W: Weights + Copy> MeasuredPreparedCopied<W> {
    prepared_methods!(self => self.m.get());
}

/// A measured material at one incident direction, without its tables: what both prepared
/// states hold beside their handle.
#[derive(Copy, Clone, Debug)]
struct Incident {
    /// `wi`, folded into the stored azimuths.
    wi: Vec3,
    /// The signs that fold directions into the stored azimuths.
    flip: Vec2,
    phi_i: f32,
    blend: SliceBlend,
    inv_4sigma: f32,
}

// rust-gpu: index loops, no iterators or `array::map`; the tables are read through `Copy`
// handles held by value (`Marginal2D<V>`), never through references to them.
impl Incident {
    fn vndf<V: Weights + Copy>(m: &MeasuredMaterial<V>) -> Marginal2D<V> {
        let t = &m.tables;
        let [w, h] = m.shape.vndf;
        Marginal2D::new(t.vndf, t.vndf_marginal, t.vndf_conditional, w, h)
    }

    fn luminance<V: Weights + Copy>(m: &MeasuredMaterial<V>) -> Marginal2D<V> {
        let t = &m.tables;
        let [w, h] = m.shape.rgb;
        Marginal2D::new(
            t.luminance,
            t.luminance_marginal,
            t.luminance_conditional,
            w,
            h,
        )
    }

    /// The RGB values at `sample` (the VNDF's sample space), times `D/(4σ)` when the data
    /// asks for it: `f · cos θo`.
    fn rgb<V: Weights + Copy>(&self, m: &MeasuredMaterial<V>, sample: Vec2, u_m: Vec2) -> [f32; 3] {
        let t = &m.tables;
        let [w, h] = m.shape.rgb;
        let rgb = Marginal2D::new(t.rgb, t.rgb, t.rgb, w, h);
        let scale = if m.jacobian {
            let [nw, nh] = m.shape.ndf;
            Marginal2D::new(t.ndf, t.ndf, t.ndf, nw, nh).eval(&SliceBlend::single(0), u_m)
                * self.inv_4sigma
        } else {
            1.0
        };
        let mut out = [0.0; 3];
        let mut c = 0;
        while c < 3 {
            // The channel is the innermost slice index: blend the (φ, θ) slices of channel c.
            let mut b = self.blend;
            b.slice = b.slice * 3 + c as u32;
            b.stride = [b.stride[0] * 3, b.stride[1] * 3];
            out[c] = math::finite_density(rgb.eval(&b, sample) * scale);
            c += 1;
        }
        out
    }

    /// `wo` folded like `wi`, the half vector and its table coordinates, or `None` below the
    /// horizon or for a non-finite `wo`.
    fn half(&self, isotropic: bool, wo: Vec3) -> Option<(Vec3, Vec3, Vec2)> {
        let wo = normalize(wo)?;
        if !(wo.z > 0.0) {
            return None;
        }
        let wo = Vec3::new(wo.x * self.flip.x, wo.y * self.flip.y, wo.z);
        let m = normalize(self.wi + wo)?;
        let theta_m = elevation(m);
        let phi_m = azimuth(m);
        let rel = if isotropic { phi_m - self.phi_i } else { phi_m };
        let uy = wrap_unit(phi2u(rel));
        Some((wo, m, Vec2::new(theta2u(theta_m), uy)))
    }

    fn eval_cos<V: Weights + Copy>(&self, m: &MeasuredMaterial<V>, wo: Vec3) -> [f32; 3] {
        let Some((_, _, u_m)) = self.half(m.isotropic(), wo) else {
            return [0.0; 3];
        };
        let (sample, _) = Self::vndf(m).invert(&self.blend, u_m);
        self.rgb(m, sample, u_m)
    }

    fn eval<V: Weights + Copy>(&self, m: &MeasuredMaterial<V>, wo: Vec3) -> [f32; 3] {
        let Some(wo) = normalize(wo) else {
            return [0.0; 3];
        };
        if !(wo.z > 0.0) {
            return [0.0; 3];
        }
        let inv_cos = 1.0 / wo.z;
        let mut f = self.eval_cos(m, wo);
        let mut c = 0;
        while c < 3 {
            f[c] = math::finite_density(f[c] * inv_cos);
            c += 1;
        }
        f
    }

    fn pdf<V: Weights + Copy>(&self, m: &MeasuredMaterial<V>, wo: Vec3) -> f32 {
        let Some((_, h, u_m)) = self.half(m.isotropic(), wo) else {
            return 0.0;
        };
        let (sample, vndf_pdf) = Self::vndf(m).invert(&self.blend, u_m);
        let lum_pdf = Self::luminance(m).eval(&self.blend, sample);
        // sin θm from the tangent components: 1 − cos² cancels near the pole.
        let sin_theta_m = math::sqrt(h.x * h.x + h.y * h.y);
        let jacobian = jacobian(u_m.x, sin_theta_m, self.wi.dot(h));
        math::finite_density(vndf_pdf * lum_pdf / jacobian)
    }

    fn sample<V: Weights + Copy>(
        &self,
        m: &MeasuredMaterial<V>,
        u: Vec2,
    ) -> Option<MeasuredSample> {
        let u = Vec2::new(math::sanitize_u(u.y)?, math::sanitize_u(u.x)?);
        let (sample, lum_pdf) = Self::luminance(m).sample(&self.blend, u);
        let (u_m, vndf_pdf) = Self::vndf(m).sample(&self.blend, sample);
        let mut phi_m = u2phi(u_m.y);
        if m.isotropic() {
            phi_m += self.phi_i;
        }
        let theta_m = u2theta(u_m.x);
        let (sin_phi, cos_phi) = math::sin_cos(phi_m);
        let (sin_theta, cos_theta) = math::sin_cos(theta_m);
        let h = Vec3::new(cos_phi * sin_theta, sin_phi * sin_theta, cos_theta);
        let dot = h.dot(self.wi);
        let pdf = vndf_pdf * lum_pdf / jacobian(u_m.x, sin_theta, dot);
        let wo = h * (2.0 * dot) - self.wi;
        let wo = Vec3::new(wo.x * self.flip.x, wo.y * self.flip.y, wo.z);
        if !(wo.z > 0.0) || !(pdf > 0.0) || !math::is_finite(pdf) {
            return None;
        }
        let mut weight = self.rgb(m, sample, u_m);
        let inv_pdf = 1.0 / pdf;
        let mut c = 0;
        while c < 3 {
            weight[c] = math::finite_density(weight[c] * inv_pdf);
            c += 1;
        }
        Some(MeasuredSample { wo, pdf, weight })
    }
}

/// `|∂(u_θ, u_φ)/∂ωo|⁻¹`: from the VNDF's square to half vectors (`2π² u_θ sin θm`, floored
/// at 10⁻⁶) and on to reflected directions (`4 wi·m`).
#[inline]
fn jacobian(u_theta: f32, sin_theta_m: f32, wi_dot_m: f32) -> f32 {
    let j = 2.0 * PI * PI * u_theta * sin_theta_m;
    (if j > 1e-6 { j } else { 1e-6 }) * 4.0 * wi_dot_m
}

/// The data's own sampler through the runtime's [`Sampler`](crate::Sampler) interface (φ is
/// ignored: measured data is homogeneous), so renderers and evaluations use it like any
/// learned sampler.
impl<W: Weights> crate::Sampler for MeasuredMaterial<W> {
    type Prepared<'s>
        = MeasuredPrepared<'s, W>
    where
        Self: 's;

    #[inline]
    fn prepare<'s>(
        &'s self,
        _phi: &[f32; crate::FEATURE_DIM],
        wi: Vec3,
    ) -> Option<MeasuredPrepared<'s, W>> {
        MeasuredMaterial::prepare(self, wi)
    }
}

/// The runtime's [`Sample`](crate::Sample) of a measured sample (the weight dropped); its
/// disk density is [`Prepared::pdf_disk`](crate::Prepared::pdf_disk)'s, 0 where `pdf / z`
/// overflows at a grazing `wo`.
pub(crate) fn runtime_sample(s: MeasuredSample) -> crate::Sample {
    crate::Sample {
        wo: s.wo,
        pdf: s.pdf,
        pdf_disk: math::finite_density(s.pdf / s.wo.z),
        mis_pdf: s.pdf,
    }
}

/// The runtime's [`Prepared`](crate::Prepared) interface of a prepared state (the sample's
/// weight is dropped: `Sample` has none).
macro_rules! prepared_trait {
    ($ty:ty, $($bounds:tt)*) => {
        impl<$($bounds)*> crate::Prepared for $ty {
            #[inline]
            fn sample(&self, u: Vec2) -> Option<crate::Sample> {
                let s = Self::sample(self, u)?;
                Some(runtime_sample(s))
            }

            #[inline]
            fn pdf_disk(&self, p: Vec2) -> f32 {
                match crate::warp::from_disk(p) {
                    Some(wo) => math::finite_density(Self::pdf(self, wo) / wo.z),
                    None => 0.0,
                }
            }

            #[inline]
            fn pdf(&self, wo: Vec3) -> f32 {
                Self::pdf(self, wo)
            }
        }
    };
}

prepared_trait!(MeasuredPrepared<'_, W>, W: Weights);
prepared_trait!(MeasuredPreparedCopied<W>, W: Weights + Copy);

#[cfg(test)]
mod tests {
    extern crate std;

    use std::vec::Vec;

    use super::{MeasuredMaterial, MeasuredShape, MeasuredTables};
    use crate::Error;

    /// Node counts whose product passes u32's range are an error, not an overflow.
    #[test]
    fn huge_node_grids_are_refused() {
        let shape = MeasuredShape {
            n_phi: 1 << 16,
            n_theta: 1 << 16,
            ndf: [2, 2],
            sigma: [2, 2],
            vndf: [2, 2],
            rgb: [2, 2],
        };
        let tables = MeasuredTables::from_array(core::array::from_fn(|_| Vec::<f32>::new()));
        assert!(matches!(
            MeasuredMaterial::new(shape, tables, false),
            Err(Error::DimensionMismatch {
                what: "table elements",
                ..
            })
        ));
    }
}
