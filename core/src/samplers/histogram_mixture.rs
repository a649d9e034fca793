//! The paper's histogram mixture (§3.3, Eq. 5–6, `core/ARCHITECTURES.md` §6): an MLP maps
//! the raw condition to per-basis weights, rotations and latent codes; the bases are baked
//! [`Table2D`]s, validated when a blob opens ([`validate_tables`]) and built by
//! [`try_bake_slices`].

use glam::{Vec2, Vec3};

use crate::blob::TensorRole;
use crate::distrib::gaussian;
use crate::distrib::table2d::{cell_of, in_square, Table2D, TableLayout};
use crate::kind::{Interpolation, SamplerKind};
use crate::math::{self, clamp_logit};
use crate::nn::{check_condition, raw_condition, ReluMlp, FEATURE_DIM, RAW_CONDITION_DIM};
use crate::warp;
use crate::weights::{Tensor, Weights};

use super::traits::Held;
use super::{Prepared, Sample, Sampler};

use super::mixture_tables::table_shapes;
#[cfg(feature = "alloc")]
pub use super::mixture_tables::{
    bake_slices, try_bake_compact, try_bake_slices, BakedTables, CompactTables,
};
pub use super::mixture_tables::{
    validate_compact_tables, validate_tables, BASES, CDF_TOLERANCE, INTEGRAL_TOLERANCE, MAX_T,
};
pub use crate::distrib::table2d::MAX_N;

const MIX_HIDDEN: usize = 32;
const MIX_OUTPUTS: usize = 4 * BASES;
type Net = ReluMlp<RAW_CONDITION_DIM, MIX_HIDDEN, MIX_OUTPUTS, 4>;

/// [`BASES`] rounded up to a multiple of 4 (per-basis scratch arrays that vectorise).
const PADDED_BASES: usize = BASES.div_ceil(4) * 4;

/// `|ρ|²` below which a predicted rotation vector counts as zero (identity rotation).
const MIN_ROTATION_NORM2: f32 = 1e-24;

/// The paper's histogram mixture (§3.3, Eq. 5–6): `p(ω⊥) = Σ_k w_k · H_k(Rᵀ_k ω⊥)` over
/// [`BASES`] baked basis histograms (`ARCHITECTURES.md` §6).
///
/// An MLP `10 → 32 → 32 → 32 → 40` (ReLU hidden) maps the raw condition `(φ, wi.x, wi.y)` to
/// `[a_k, ρ_k.x, ρ_k.y, τ_k]` per basis: weight logit, rotation vector and latent-code logit.
/// The bases are the tables `mass` (K × T), `table` (K × T × N × N), `marginal`
/// (K × T × N) and `conditional` (K × T × N × N). Densities are on the **projected disk**.
///
/// The constructor checks sizes only; the contents must have passed [`validate_tables`]
/// (the blob loader does this). Invalid contents cannot cause a panic or a NaN, only a wrong
/// or zero density.
#[derive(Copy, Clone, Debug)]
pub struct HistogramMixtureSampler<W> {
    params: W,
    mass: W,
    table: W,
    marginal: W,
    conditional: W,
    t_levels: u32,
    resolution: u32,
    interpolation: Interpolation,
    /// How the tables are stored (`table` is a copy of `marginal` in the compact layout).
    layout: TableLayout,
}

impl<'a> super::FromBlob<'a> for HistogramMixtureSampler<Tensor<'a>> {
    const KIND: SamplerKind = SamplerKind::HistogramMixture;
    /// The compact layout when the blob has no values tensor, else the full one.
    fn from_blob(src: &impl super::BlobSource<'a>) -> Option<Self> {
        let h = src.header();
        let mass = src.tensor_or_empty(TensorRole::Mass);
        let marginal = src.tensor_or_empty(TensorRole::Marginal);
        let conditional = src.tensor_or_empty(TensorRole::Conditional);
        match src.tensor(TensorRole::Table) {
            None => Self::new_compact(
                src.params(),
                mass,
                marginal,
                conditional,
                h.t_levels,
                h.resolution,
                h.interpolation,
            ),
            Some(table) => Self::new(
                src.params(),
                mass,
                table,
                marginal,
                conditional,
                h.t_levels,
                h.resolution,
                h.interpolation,
            ),
        }
    }
}

impl<W: Weights> HistogramMixtureSampler<W> {
    /// Number of parameters: `dense(10,32) dense(32,32) dense(32,32) dense(32,40)` = 3784.
    pub const PARAM_COUNT: usize = Net::LEN;

    /// A sampler over `params` and the baked tables of `t_levels` = T latent levels at
    /// resolution `resolution` = N. `None` unless `1 ≤ T ≤` [`MAX_T`], `1 ≤ N ≤` [`MAX_N`]
    /// and every array has exactly its required length (see the type docs).
    #[must_use]
    pub fn new(
        params: W,
        mass: W,
        table: W,
        marginal: W,
        conditional: W,
        t_levels: u32,
        resolution: u32,
        interpolation: Interpolation,
    ) -> Option<Self> {
        let fits = Self::fits(
            &params,
            &mass,
            Some(&table),
            &marginal,
            &conditional,
            t_levels,
            resolution,
        );
        // The checked dimensions are within the clamps of `new_unchecked`.
        fits.then(|| {
            Self::new_unchecked(
                params,
                mass,
                table,
                marginal,
                conditional,
                t_levels,
                resolution,
                interpolation,
            )
        })
    }

    /// Whether `params` and the tables have the sizes [`Self::new`] and [`Self::new_compact`]
    /// require (`table` is `None` for compact tables).
    fn fits(
        params: &W,
        mass: &W,
        table: Option<&W>,
        marginal: &W,
        conditional: &W,
        t_levels: u32,
        resolution: u32,
    ) -> bool {
        let k = BASES as u32;
        params.len() as usize == Self::PARAM_COUNT
            && table_shapes(mass, table, marginal, conditional, k, t_levels, resolution).is_ok()
    }

    /// A sampler without the size checks of [`Self::new`], for GPU shaders (`Option<Self>`
    /// with a borrowed `W` cannot be tested by rust-gpu). `t_levels` and `resolution` are
    /// clamped to `1 ..= MAX_T` and `1 ..= MAX_N`. Not `unsafe`: reads past the end of a
    /// short array give 0.0, so wrong densities but never a panic or NaN. Check the sizes on
    /// the host (e.g. with [`Self::new`]).
    #[inline]
    #[must_use]
    pub fn new_unchecked(
        params: W,
        mass: W,
        table: W,
        marginal: W,
        conditional: W,
        t_levels: u32,
        resolution: u32,
        interpolation: Interpolation,
    ) -> Self {
        HistogramMixtureSampler {
            params,
            mass,
            table,
            marginal,
            conditional,
            t_levels: t_levels.clamp(1, MAX_T as u32),
            resolution: resolution.clamp(1, MAX_N as u32),
            interpolation,
            layout: TableLayout::Values,
        }
    }

    /// A sampler over `params` and compact tables ([`TableLayout::Compact`]: `mass` K × T,
    /// `marginal` K × T × N, `conditional` K × T × N × N quantised CDFs, no values). `None`
    /// under the conditions of [`Self::new`].
    #[must_use]
    pub fn new_compact(
        params: W,
        mass: W,
        marginal: W,
        conditional: W,
        t_levels: u32,
        resolution: u32,
        interpolation: Interpolation,
    ) -> Option<Self>
    where
        W: Copy,
    {
        let fits = Self::fits(
            &params,
            &mass,
            None,
            &marginal,
            &conditional,
            t_levels,
            resolution,
        );
        fits.then(|| {
            Self::new_compact_unchecked(
                params,
                mass,
                marginal,
                conditional,
                t_levels,
                resolution,
                interpolation,
            )
        })
    }

    /// [`Self::new_compact`] without the size checks, as [`Self::new_unchecked`].
    #[inline]
    #[must_use]
    pub fn new_compact_unchecked(
        params: W,
        mass: W,
        marginal: W,
        conditional: W,
        t_levels: u32,
        resolution: u32,
        interpolation: Interpolation,
    ) -> Self
    where
        W: Copy,
    {
        let mut s = Self::new_unchecked(
            params,
            mass,
            marginal,
            marginal,
            conditional,
            t_levels,
            resolution,
            interpolation,
        );
        s.layout = TableLayout::Compact;
        s
    }

    /// How the tables are stored.
    #[must_use]
    pub fn layout(&self) -> TableLayout {
        self.layout
    }

    /// The parameter array.
    #[must_use]
    pub fn params(&self) -> &W {
        &self.params
    }

    /// Number of latent-code levels T.
    #[must_use]
    pub fn t_levels(&self) -> u32 {
        self.t_levels
    }

    /// Grid resolution N.
    #[must_use]
    pub fn resolution(&self) -> u32 {
        self.resolution
    }

    /// How the latent axis is read.
    #[must_use]
    pub fn interpolation(&self) -> Interpolation {
        self.interpolation
    }

    /// The same sampler reading its latent axis with `interpolation`.
    #[must_use]
    pub fn with_interpolation(mut self, interpolation: Interpolation) -> Self {
        self.interpolation = interpolation;
        self
    }

    /// Basis table view at `(slice0, slice1, a)` (see [`Table2D::lerp`]).
    #[inline(always)]
    fn basis_table(&self, slices: (u32, u32, f32)) -> Table2D<W>
    where
        W: Copy,
    {
        Table2D::from_parts(
            self.table,
            self.marginal,
            self.conditional,
            self.resolution,
            slices.0,
            slices.1,
            slices.2,
            self.layout,
        )
    }

    /// The raw network outputs `[a_k, ρ_k.x, ρ_k.y, τ_k]` (basis `k` at `4k..4k+4`) for a raw
    /// condition.
    #[inline]
    #[must_use]
    pub fn forward(&self, x: &[f32; RAW_CONDITION_DIM]) -> [f32; MIX_OUTPUTS] {
        Net::forward(&self.params, x)
    }

    /// The prepared mixture from raw network outputs (see [`Self::forward`]):
    ///
    /// * rotation `(cos, sin) = ρ_k/|ρ_k|` (identity when `|ρ_k| < 1e−12` or not finite);
    /// * `s = sigmoid(τ_k)·(T − 1)`, slice `round(s)` ([`Interpolation::Nearest`]) or the
    ///   blend of `⌊s⌋` and `⌊s⌋ + 1` with weight `s − ⌊s⌋` ([`Interpolation::Linear`]);
    /// * `w_k ∝ softmax(a)_k · mass[k, s]` (mass blended like the table), normalised. When
    ///   every blended mass is 0, `w = softmax(a)` over the bases whose table is non-empty.
    ///
    /// `None` only when no basis has a usable table.
    #[inline(always)]
    #[must_use]
    pub fn prepare_outputs(&self, o: &[f32; MIX_OUTPUTS]) -> Option<HistogramMixturePrepared<'_, W>>
    where
        W: Copy,
    {
        Some(self.with_lane(self.lane_from_outputs(o)?))
    }

    /// [`Self::prepare_outputs`] without the weights handle: the lane of the batched API.
    #[inline(always)]
    pub(crate) fn lane_from_outputs(&self, o: &[f32; MIX_OUTPUTS]) -> Option<HistogramMixtureLane>
    where
        W: Copy,
    {
        let mut soft = [0.0f32; BASES];
        let mut k = 0;
        while k < BASES {
            soft[k] = clamp_logit(o[4 * k]);
            k += 1;
        }
        gaussian::softmax(&mut soft);
        self.lane_from_softmax(o, &soft)
    }

    /// The table levels `(l0, l1)` around the level position `s` (`≥ 0`, NaN-free) and the
    /// blend weight of `l1`, by the blob's interpolation.
    #[inline(always)]
    fn levels(&self, s: f32) -> (u32, u32, f32) {
        let t_levels = self.t_levels;
        match self.interpolation {
            // s ≥ 0, so the truncation in clamp_index is the floor.
            Interpolation::Nearest => {
                let l = math::clamp_index(s + 0.5, t_levels);
                (l, l, 0.0)
            }
            Interpolation::Linear => {
                if t_levels >= 2 {
                    let l = math::clamp_index(s, t_levels - 1);
                    (l, l + 1, math::clamp(s - l as f32, 0.0, 1.0))
                } else {
                    (0, 0, 0.0)
                }
            }
        }
    }

    /// [`Self::lane_from_outputs`] with the softmax of the logits `a_k` given (the batched
    /// path computes it across lanes).
    #[inline(always)]
    pub(crate) fn lane_from_softmax(
        &self,
        o: &[f32; MIX_OUTPUTS],
        soft: &[f32; BASES],
    ) -> Option<HistogramMixtureLane>
    where
        W: Copy,
    {
        let t_levels = self.t_levels;
        let mut k;

        // rust-gpu: plain local arrays, assembled into the prepared state at the end: a
        // mutable local struct holding the sampler reference stays a pointer-typed variable
        // on SPIR-V, which spirv-val rejects under logical addressing.
        let mut rotation = [Vec2::X; BASES];
        let mut slice0 = [0u32; BASES];
        let mut slice1 = [0u32; BASES];
        let mut lerp = [0.0f32; BASES];
        let mut mass = [0.0f32; BASES];
        let mut total = [0.0f32; BASES];
        let mut inv_integral = [0.0f32; BASES];
        let code = latent_codes(o);
        let top = (t_levels - 1) as f32;
        k = 0;
        while k < BASES {
            let rho = Vec2::new(o[4 * k + 1], o[4 * k + 2]);
            let len2 = rho.x * rho.x + rho.y * rho.y;
            if len2 >= MIN_ROTATION_NORM2 && math::is_finite(len2) {
                rotation[k] = rho * (1.0 / math::sqrt(len2));
            }
            // NaN τ gives NaN t; the clamp sends it to level 0.
            let s = math::clamp(code[k] * top, 0.0, top);
            let (l0, l1, a) = self.levels(s);
            let base = k as u32 * t_levels;
            slice0[k] = base + l0;
            slice1[k] = base + l1;
            lerp[k] = a;
            let m0 = self.mass.at(base + l0);
            mass[k] = if a > 0.0 {
                (1.0 - a) * m0 + a * self.mass.at(base + l1)
            } else {
                m0
            };
            // The table's normalisation, kept so that `table(k)` need not read and divide
            // again per pdf.
            let (tot, inv) = self.basis_table((slice0[k], slice1[k], a)).normalization();
            total[k] = tot;
            inv_integral[k] = inv;
            k += 1;
        }
        let weights = mixture_weights(soft, &mass, &total)?;
        Some(HistogramMixtureLane {
            weights,
            rotation,
            slice0,
            slice1,
            lerp,
            total,
            inv_integral,
        })
    }
}

/// The latent codes `t_k = sigmoid(τ_k)` of the network outputs `o`, in a loop of their own
/// so that it vectorises: the fast form is exact down to `EXP_IN_RANGE_MIN`, the rest (and
/// NaN) take libm's. Padded to a multiple of 4 (the padding is unused).
#[inline(always)]
fn latent_codes(o: &[f32; MIX_OUTPUTS]) -> [f32; PADDED_BASES] {
    let mut code = [0.0f32; PADDED_BASES];
    let mut k = 0;
    while k < BASES {
        code[k] = o[4 * k + 3];
        k += 1;
    }
    k = 0;
    while k < PADDED_BASES {
        code[k] = math::sigmoid_in_range(code[k]);
        k += 1;
    }
    k = 0;
    while k < BASES {
        if !(o[4 * k + 3] >= math::EXP_IN_RANGE_MIN) {
            code[k] = math::sigmoid(o[4 * k + 3]);
        }
        k += 1;
    }
    code
}

/// The mixture weights from the softmax `soft` and each basis's table mass at its level and
/// table total: `soft·mass` over the usable bases (`total > 0`), normalised; where every
/// basis has zero mass, the softmax weights of the usable bases; `None` when no basis is
/// usable.
#[inline(always)]
fn mixture_weights(
    soft: &[f32; BASES],
    mass: &[f32; BASES],
    total: &[f32; BASES],
) -> Option<[f32; BASES]> {
    let mut weights = [0.0f32; BASES];
    let mut usable = [0u32; BASES]; // rust-gpu: not [bool; _], it cannot memset bools
    let mut k = 0;
    while k < BASES {
        let ok = total[k] > 0.0;
        usable[k] = u32::from(ok);
        let w = soft[k] * mass[k];
        weights[k] = if ok && w > 0.0 && math::is_finite(w) {
            w
        } else {
            0.0
        };
        k += 1;
    }
    let mut sum = 0.0f32;
    k = 0;
    while k < BASES {
        sum += weights[k];
        k += 1;
    }
    if !(sum > 0.0 && math::is_finite(sum)) {
        // Every basis has zero mass here: fall back to the softmax weights.
        sum = 0.0;
        k = 0;
        while k < BASES {
            weights[k] = if usable[k] != 0 { soft[k] } else { 0.0 };
            sum += weights[k];
            k += 1;
        }
        if !(sum > 0.0) {
            return None;
        }
    }
    let inv = 1.0 / sum;
    k = 0;
    while k < BASES {
        weights[k] *= inv;
        k += 1;
    }
    Some(weights)
}

/// The histogram mixture at one shading point without its weights handle (the lane of the
/// batched API): per-basis weight, rotation and table slices.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct HistogramMixtureLane {
    weights: [f32; BASES],
    rotation: [Vec2; BASES],
    slice0: [u32; BASES],
    slice1: [u32; BASES],
    lerp: [f32; BASES],
    /// Each basis table's blended `marginal[N − 1]` ([`Table2D`]'s `total`).
    total: [f32; BASES],
    /// Each basis table's `1 / (total · h²)` ([`Table2D`]'s `inv_integral`).
    inv_integral: [f32; BASES],
}

/// The histogram mixture at one shading point: its [`HistogramMixtureLane`] and a copy of the
/// sampler's weight and table handles.
#[derive(Debug)]
pub struct HistogramMixturePrepared<'s, W> {
    /// A copy of the sampler: weight and table handles (see `Held`).
    sampler: Held<HistogramMixtureSampler<W>>,
    _sampler: core::marker::PhantomData<&'s W>,
    lane: HistogramMixtureLane,
}

impl<W: Copy> Clone for HistogramMixturePrepared<'_, W> {
    fn clone(&self) -> Self {
        HistogramMixturePrepared {
            sampler: self.sampler.clone(),
            _sampler: core::marker::PhantomData,
            lane: self.lane,
        }
    }
}

impl<W: Weights + Copy> HistogramMixtureSampler<W> {
    /// The scalar prepared state of a lane.
    #[inline(always)]
    pub(crate) fn with_lane(&self, lane: HistogramMixtureLane) -> HistogramMixturePrepared<'_, W> {
        HistogramMixturePrepared {
            sampler: Held::new(*self),
            _sampler: core::marker::PhantomData,
            lane,
        }
    }

    /// [`HistogramMixturePrepared::table`] of a lane.
    #[inline(always)]
    pub(crate) fn lane_table(&self, lane: &HistogramMixtureLane, k: usize) -> Table2D<W> {
        let k = if k < BASES { k } else { BASES - 1 };
        Table2D::from_normalized_parts(
            self.table,
            self.marginal,
            self.conditional,
            self.resolution,
            (lane.slice0[k], lane.slice1[k], lane.lerp[k]),
            lane.total[k],
            lane.inv_integral[k],
            self.layout,
        )
    }

    /// [`Prepared::sample`] of a lane: chooses basis `k` by the weights (remapping `u.x`),
    /// samples its table in rotated coordinates and rotates back, `ω⊥ = R_k q`; the density
    /// is the full mixture at the drawn point.
    #[inline(always)]
    pub(crate) fn lane_sample(&self, lane: &HistogramMixtureLane, u: Vec2) -> Option<Sample> {
        let u = math::sanitize_u2(u)?;
        let (k, u0) = gaussian::select_component(&lane.weights, u.x);
        let k = if k < BASES { k } else { BASES - 1 };
        let (q, _) = self.lane_table(lane, k).sample(Vec2::new(u0, u.y))?;
        let p = warp::rotate(q, lane.rotation[k]);
        Sample::from_disk(p, self.lane_pdf_disk(lane, p))
    }

    /// [`Prepared::pdf_disk`] of a lane, Eq. 5: `Σ_k w_k · H_k(Rᵀ_k ω⊥)`.
    #[inline(always)]
    pub(crate) fn lane_pdf_disk(&self, lane: &HistogramMixtureLane, p: Vec2) -> f32 {
        if !(p.x * p.x + p.y * p.y < 1.0) {
            return 0.0;
        }
        // `Σ_k w_k · table(k).pdf(Rᵀ_k p)` in three passes: the cells first, then every
        // basis's table read (independent loads from a table too big for L1 overlap), then
        // the sum in basis order.
        let n = self.resolution;
        let mut row = [0u32; BASES];
        let mut col = [0u32; BASES];
        let mut inside = [0u32; BASES];
        let mut k = 0;
        while k < BASES {
            let q = warp::rotate_inverse(p, lane.rotation[k]);
            inside[k] = u32::from(in_square(q));
            let (r, c) = cell_of(q, n);
            row[k] = r;
            col[k] = c;
            k += 1;
        }
        let mut density = [0.0f32; BASES];
        k = 0;
        while k < BASES {
            density[k] = if inside[k] != 0 {
                self.lane_table(lane, k).density_at_cell(row[k], col[k])
            } else {
                0.0
            };
            k += 1;
        }
        let mut sum = 0.0f32;
        k = 0;
        while k < BASES {
            let w = lane.weights[k];
            if w > 0.0 {
                sum += w * density[k];
            }
            k += 1;
        }
        math::finite_density(sum)
    }

    /// [`HistogramMixturePrepared::invert_basis`] of a lane.
    #[inline(always)]
    pub(crate) fn lane_invert_basis(
        &self,
        lane: &HistogramMixtureLane,
        k: usize,
        wo: Vec3,
    ) -> Option<Vec2> {
        if k >= BASES || !(lane.weights[k] > 0.0) {
            return None;
        }
        let w = warp::upper_hemisphere(wo)?;
        let q = warp::rotate_inverse(warp::to_disk(w), lane.rotation[k]);
        let v = self.lane_table(lane, k).invert(q)?;
        // Start of basis k's interval, summed as gaussian::select_component does.
        let mut lo = 0.0f32;
        let mut i = 0;
        while i < k {
            if lane.weights[i] > 0.0 {
                lo += lane.weights[i];
            }
            i += 1;
        }
        let ux = lo + v.x * lane.weights[k];
        Some(Vec2::new(
            math::clamp(ux, 0.0, math::ONE_MINUS_EPSILON),
            v.y,
        ))
    }

    /// [`Prepared::invert`] of a lane: the basis inverse when exactly one basis has weight.
    #[inline(always)]
    pub(crate) fn lane_invert(&self, lane: &HistogramMixtureLane, wo: Vec3) -> Option<Vec2> {
        let mut only = BASES;
        let mut k = 0;
        while k < BASES {
            if lane.weights[k] > 0.0 {
                if only < BASES {
                    return None;
                }
                only = k;
            }
            k += 1;
        }
        self.lane_invert_basis(lane, only, wo)
    }
}

impl<'s, W: Weights + Copy> HistogramMixturePrepared<'s, W> {
    /// Mixture weights `w_k` (sum 1).
    #[must_use]
    pub fn weights(&self) -> [f32; BASES] {
        self.lane.weights
    }

    /// Rotation `(cos, sin)` of basis `k` (index clamped to `[0, K − 1]`).
    #[must_use]
    pub fn rotation(&self, k: usize) -> Vec2 {
        self.lane.rotation[if k < BASES { k } else { BASES - 1 }]
    }

    /// The prepared state without the weights handle.
    #[must_use]
    pub fn lane(&self) -> HistogramMixtureLane {
        self.lane
    }

    /// The (possibly blended) table `H_k` of basis `k` (index clamped to `[0, K − 1]`), in
    /// the basis's rotated coordinates `q = Rᵀ_k ω⊥`.
    #[inline]
    #[must_use]
    pub fn table(&self, k: usize) -> Table2D<W> {
        self.sampler.get().lane_table(&self.lane, k)
    }

    /// The `u` that [`Prepared::sample`] maps to `wo` *through basis `k`*: the basis's table
    /// inverse, with `u.x` mapped back into basis `k`'s interval of the component choice.
    /// `None` when basis `k` has zero weight or zero density at `wo`, or for invalid `wo`.
    #[must_use]
    pub fn invert_basis(&self, k: usize, wo: Vec3) -> Option<Vec2> {
        self.sampler.get().lane_invert_basis(&self.lane, k, wo)
    }
}

impl<W: Weights + Copy> Sampler for HistogramMixtureSampler<W> {
    type Prepared<'s>
        = HistogramMixturePrepared<'s, W>
    where
        Self: 's;

    #[inline]
    fn prepare<'s>(
        &'s self,
        phi: &[f32; FEATURE_DIM],
        wi: Vec3,
    ) -> Option<HistogramMixturePrepared<'s, W>> {
        let wi = check_condition(phi, wi)?;
        let o = self.forward(&raw_condition(phi, wi));
        self.prepare_outputs(&o)
    }
}

impl<W: Weights + Copy> Prepared for HistogramMixturePrepared<'_, W> {
    /// Chooses basis `k` by the weights (remapping `u.x`), samples its table in rotated
    /// coordinates and rotates back: `ω⊥ = R_k q`. The reported density is the full mixture
    /// (Eq. 5) at the drawn point; `None` when it lands outside the disk.
    #[inline]
    fn sample(&self, u: Vec2) -> Option<Sample> {
        self.sampler.get().lane_sample(&self.lane, u)
    }

    /// Eq. 5: `Σ_k w_k · H_k(Rᵀ_k ω⊥)` with respect to area on the projected disk; 0 outside
    /// the open unit disk.
    #[inline]
    fn pdf_disk(&self, p: Vec2) -> f32 {
        self.sampler.get().lane_pdf_disk(&self.lane, p)
    }

    /// The unique `u` that `sample` maps to `wo` when exactly one basis has positive weight;
    /// `None` otherwise. With several bases the sampling map is not injective (each basis
    /// can produce the same direction), so no single inverse exists; see
    /// [`HistogramMixturePrepared::invert_basis`] for the per-basis inverse.
    #[inline]
    fn invert(&self, wo: Vec3) -> Option<Vec2> {
        self.sampler.get().lane_invert(&self.lane, wo)
    }
}

#[cfg(not(target_arch = "spirv"))]
mod batch;
