//! [`BatchSampler`], the batched sampler interface, and what its implementations share:
//! chunks of lanes, structure-of-arrays blocks, the condition encodings over lanes, the
//! calls' argument checks.

use super::lanes;
use super::views::{check_len, Features, SamplesMut, Vec2s, Vec2sMut, Vec3s};
use crate::error::Result;

/// The chunks `[a, b)` of `0..n`, `c` lanes each (the last one shorter; `c = 0` counts as
/// 1). A plain iterator without closures, so that a loop over it inside a dispatched kernel
/// compiles for the kernel's instruction set.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Chunks {
    a: usize,
    n: usize,
    c: usize,
}

impl Iterator for Chunks {
    type Item = (usize, usize);
    #[inline(always)]
    fn next(&mut self) -> Option<(usize, usize)> {
        if self.a >= self.n {
            return None;
        }
        let a = self.a;
        self.a = if self.n - a > self.c {
            a + self.c
        } else {
            self.n
        };
        Some((a, self.a))
    }
}

/// [`Chunks`] of `0..n`, `c` lanes each.
#[inline(always)]
pub(crate) fn chunks(n: usize, c: usize) -> Chunks {
    Chunks {
        a: 0,
        n,
        c: if c > 0 { c } else { 1 },
    }
}

/// Lanes per chunk of the fused calls ([`BatchSampler::sample_fused`],
/// [`BatchSampler::pdf_fused`]): their prepared states live on the stack.
pub const FUSED_CHUNK: usize = 32;

/// Working memory of a sampler's batched sample, pdf and invert calls (`()` for a sampler
/// that needs none): [`BatchSampler::sample_batch`] and [`BatchSampler::pdf_batch`] make one
/// per call; a caller that keeps one ([`BatchSampler::sample_batch_in`],
/// [`BatchSampler::pdf_batch_in`]), one per thread, saves making it at every call. Its
/// contents carry nothing from one call to the next: results never depend on them.
pub trait Scratch {
    /// Fresh working memory (a constant, so that a call writes it in place).
    const NEW: Self;
}

impl Scratch for () {
    const NEW: () = ();
}

/// A sampler evaluated over wavefronts (see the [`crate::wavefront`] docs for the contract).
pub trait BatchSampler {
    /// The prepared state of one shading point, without the sampler's weights handle
    /// (`Option<…>`: `None`, the default, is a refused lane).
    type Lane: LaneState;

    /// The working memory of its sample, pdf and invert calls.
    type Scratch: Scratch;

    /// Runs the networks for the `N = lanes.len()` conditions `(phi[i], wi[i])` and writes
    /// each lane's state (refused conditions: `Lane::default()`).
    fn prepare_batch(
        &self,
        phi: Features<'_>,
        wi: Vec3s<'_>,
        lanes: &mut [Self::Lane],
    ) -> Result<()>;

    /// Draws one direction per lane from `u[i]` (as [`Prepared::sample`](crate::Prepared::sample)),
    /// with its density and its MIS density ([`crate::Sample`]).
    fn sample_batch(&self, lanes: &[Self::Lane], u: Vec2s<'_>, out: SamplesMut<'_>) -> Result<()> {
        let mut scratch = <Self::Scratch as Scratch>::NEW;
        self.sample_batch_in(lanes, u, out, &mut scratch)
    }

    /// [`BatchSampler::sample_batch`] in the caller's working memory (the same results).
    fn sample_batch_in(
        &self,
        lanes: &[Self::Lane],
        u: Vec2s<'_>,
        out: SamplesMut<'_>,
        scratch: &mut Self::Scratch,
    ) -> Result<()>;

    /// The solid-angle density of `wo[i]` at lane `i` (as [`Prepared::pdf`](crate::Prepared::pdf)).
    fn pdf_batch(&self, lanes: &[Self::Lane], wo: Vec3s<'_>, pdf: &mut [f32]) -> Result<()> {
        let mut scratch = <Self::Scratch as Scratch>::NEW;
        self.pdf_batch_in(lanes, wo, pdf, &mut scratch)
    }

    /// [`BatchSampler::pdf_batch`] in the caller's working memory (the same results).
    fn pdf_batch_in(
        &self,
        lanes: &[Self::Lane],
        wo: Vec3s<'_>,
        pdf: &mut [f32],
        scratch: &mut Self::Scratch,
    ) -> Result<()>;

    /// The `u` that [`BatchSampler::sample_batch`] maps to `wo[i]`, where the method has a
    /// unique inverse (as [`Prepared::invert`](crate::Prepared::invert)); `ok[i]` says whether lane `i` has one (its
    /// `u` is then written, else left as it was).
    fn invert_batch(
        &self,
        lanes: &[Self::Lane],
        wo: Vec3s<'_>,
        u: Vec2sMut<'_>,
        ok: &mut [bool],
    ) -> Result<()>;

    /// [`BatchSampler::prepare_batch`] then [`BatchSampler::sample_batch`], in chunks of
    /// [`FUSED_CHUNK`] lanes whose states stay on the stack.
    fn sample_fused(
        &self,
        phi: Features<'_>,
        wi: Vec3s<'_>,
        u: Vec2s<'_>,
        out: SamplesMut<'_>,
    ) -> Result<()> {
        sample_fused_chunks(self, phi, wi, u, out)
    }

    /// [`BatchSampler::prepare_batch`] then [`BatchSampler::pdf_batch`], in chunks of
    /// [`FUSED_CHUNK`] lanes whose states stay on the stack.
    fn pdf_fused(
        &self,
        phi: Features<'_>,
        wi: Vec3s<'_>,
        wo: Vec3s<'_>,
        pdf: &mut [f32],
    ) -> Result<()> {
        pdf_fused_chunks(self, phi, wi, wo, pdf)
    }
}

/// [`BatchSampler::sample_fused`]'s default: prepare and sample in chunks of [`FUSED_CHUNK`]
/// lanes on the stack, in one working memory.
pub(crate) fn sample_fused_chunks<S: BatchSampler + ?Sized>(
    s: &S,
    phi: Features<'_>,
    wi: Vec3s<'_>,
    u: Vec2s<'_>,
    mut out: SamplesMut<'_>,
) -> Result<()> {
    let n = wi.len();
    phi.check(n)?;
    wi.check(n)?;
    u.check(n)?;
    out.check(n)?;
    let mut lanes = [S::Lane::default(); FUSED_CHUNK];
    let mut scratch = <S::Scratch as Scratch>::NEW;
    for (a, b) in chunks(n, FUSED_CHUNK) {
        let chunk = &mut lanes[..b - a];
        s.prepare_batch(phi.range(a, b), wi.range(a, b), chunk)?;
        s.sample_batch_in(chunk, u.range(a, b), out.range(a, b), &mut scratch)?;
    }
    Ok(())
}

/// [`BatchSampler::pdf_fused`]'s default: prepare and evaluate in chunks of [`FUSED_CHUNK`]
/// lanes on the stack, in one working memory.
pub(crate) fn pdf_fused_chunks<S: BatchSampler + ?Sized>(
    s: &S,
    phi: Features<'_>,
    wi: Vec3s<'_>,
    wo: Vec3s<'_>,
    pdf: &mut [f32],
) -> Result<()> {
    let n = wi.len();
    phi.check(n)?;
    wi.check(n)?;
    wo.check(n)?;
    check_len("pdf", pdf.len(), n)?;
    let mut lanes = [S::Lane::default(); FUSED_CHUNK];
    let mut scratch = <S::Scratch as Scratch>::NEW;
    for (a, b) in chunks(n, FUSED_CHUNK) {
        let chunk = &mut lanes[..b - a];
        s.prepare_batch(phi.range(a, b), wi.range(a, b), chunk)?;
        s.pdf_batch_in(chunk, wo.range(a, b), &mut pdf[a..b], &mut scratch)?;
    }
    Ok(())
}

/// A lane's prepared state: `Default` is the refused lane, and [`LaneState::is_prepared`]
/// tells a renderer whether `prepare` accepted the condition (a scalar `prepare` that
/// returned `Some`), which the densities alone cannot (a prepared lane may give a zero pdf).
pub trait LaneState: Copy + Default {
    /// Whether the lane holds a prepared state.
    fn is_prepared(&self) -> bool;
}

impl<T: Copy> LaneState for Option<T> {
    #[inline(always)]
    fn is_prepared(&self) -> bool {
        self.is_some()
    }
}

/// Activations of a chunk of `B` lanes: `[feature][lane]`.
pub(crate) type Soa<const N: usize, const B: usize> = [[f32; B]; N];

/// Lane `l` of a chunk's activations.
#[inline(always)]
pub(crate) fn column<const N: usize, const B: usize>(soa: &Soa<N, B>, l: usize) -> [f32; N] {
    let mut c = [0.0f32; N];
    for (k, v) in c.iter_mut().enumerate() {
        *v = soa[k][l];
    }
    c
}

/// Sets lane `l` of a chunk's activations to `v`, or to zeros for `None` (a refused lane).
#[inline(always)]
pub(crate) fn set_column<const N: usize, const B: usize>(
    soa: &mut Soa<N, B>,
    l: usize,
    v: Option<&[f32; N]>,
) {
    for (k, row) in soa.iter_mut().enumerate() {
        row[l] = v.map_or(0.0, |v| v[k]);
    }
}

/// A lane state built from a network's `N` outputs per lane (the samplers of
/// [`mlp_lane_sampler`](super::chunked::mlp_lane_sampler)).
pub(crate) trait FromOutputs<const N: usize>: Sized {
    /// Whether [`Self::lanes`] works across whole rows, so that a small chunk is given rows of
    /// [`lanes::NARROW`] lanes (a lane-by-lane constructor gains nothing from them).
    const ROWS: bool = false;

    /// The lanes of a chunk from its output rows (`None` where not `valid`).
    fn lanes<const B: usize>(o: &Soa<N, B>, valid: &[bool; B], lanes: &mut [Option<Self>]);
}

/// The first `lanes.len()` lanes of a chunk from its network outputs `o`: `f` of the lane's
/// column where its condition is valid, refused (`None`) elsewhere.
#[inline(always)]
pub(crate) fn lanes_from_outputs<P, const N: usize, const B: usize>(
    o: &Soa<N, B>,
    valid: &[bool; B],
    lanes: &mut [Option<P>],
    f: impl Fn(&[f32; N]) -> P,
) {
    for (l, lane) in lanes.iter_mut().enumerate().take(B) {
        *lane = if valid[l] {
            Some(f(&column(o, l)))
        } else {
            None
        };
    }
}

/// `[0, 1, 2, …]`: every lane of a chunk, as an index list.
#[inline(always)]
pub(crate) fn identity_index<const B: usize>() -> [usize; B] {
    let mut idx = [0usize; B];
    for (i, x) in idx.iter_mut().enumerate() {
        *x = i;
    }
    idx
}

/// `encode` (a condition encoding) of every lane of a chunk, and which lanes are usable
/// ([`crate::nn::check_condition`]); refused lanes are zeros.
#[inline(always)]
fn conditions<const N: usize, const B: usize>(
    phi: &Features<'_>,
    wi: &Vec3s<'_>,
    encode: impl Fn(&[f32; crate::nn::FEATURE_DIM], glam::Vec3) -> [f32; N],
) -> (Soa<N, B>, [bool; B]) {
    let mut c = [[0.0f32; B]; N];
    let mut valid = [false; B];
    for l in 0..wi.len() {
        let p = phi.at(l);
        if let Some(w) = crate::nn::check_condition(&p, wi.at(l)) {
            let enc = encode(&p, w);
            for (k, v) in enc.iter().enumerate() {
                c[k][l] = *v;
            }
            valid[l] = true;
        }
    }
    (c, valid)
}

/// The encoded conditions ([`crate::nn::encode_condition`], the sinusoids by the batched
/// path's fast `sin`/`cos` over all lanes at once) of a chunk's lanes and which lanes are
/// usable; refused lanes hold the encoding of `φ = 0, wi = (0, 0)`. A chunk of at most
/// [`lanes::NARROW`] lanes is encoded that wide (the same bits; the columns past it are 0).
#[inline(always)]
pub(crate) fn encoded_conditions<const B: usize>(
    phi: &Features<'_>,
    wi: &Vec3s<'_>,
) -> (Soa<{ crate::nn::CONDITION_DIM }, B>, [bool; B]) {
    if B > lanes::NARROW && wi.len() <= lanes::NARROW {
        let (c, valid) = encode_chunk::<{ lanes::NARROW }>(phi, wi);
        let [valid] = lanes::head(&[valid]);
        (lanes::head(&c), valid)
    } else {
        encode_chunk::<B>(phi, wi)
    }
}

/// [`encoded_conditions`] over all `B` lanes.
#[inline(always)]
fn encode_chunk<const B: usize>(
    phi: &Features<'_>,
    wi: &Vec3s<'_>,
) -> (Soa<{ crate::nn::CONDITION_DIM }, B>, [bool; B]) {
    use crate::nn::{encoding_len, CONDITION_BANDS, CONDITION_DIM, FEATURE_DIM};
    let (raw, valid) = raw_conditions::<B>(phi, wi);
    let mut c = [[0.0f32; B]; CONDITION_DIM];
    c[..FEATURE_DIM].copy_from_slice(&raw[..FEATURE_DIM]);
    let at = FEATURE_DIM + encoding_len(CONDITION_BANDS);
    lanes::encode_rows::<CONDITION_BANDS, CONDITION_DIM, B>(&raw[FEATURE_DIM], &mut c, FEATURE_DIM);
    lanes::encode_rows::<CONDITION_BANDS, CONDITION_DIM, B>(&raw[FEATURE_DIM + 1], &mut c, at);
    (c, valid)
}

/// The raw conditions ([`crate::nn::raw_condition`]) of a chunk's lanes and which lanes are
/// usable; refused lanes are zeros.
#[inline(always)]
pub(crate) fn raw_conditions<const B: usize>(
    phi: &Features<'_>,
    wi: &Vec3s<'_>,
) -> (Soa<{ crate::nn::RAW_CONDITION_DIM }, B>, [bool; B]) {
    conditions(phi, wi, crate::nn::raw_condition)
}

/// The length checks every [`BatchSampler::sample_batch`] does.
pub(crate) fn check_sample_args<L>(
    lanes: &[L],
    u: &Vec2s<'_>,
    out: &SamplesMut<'_>,
) -> Result<usize> {
    let n = lanes.len();
    u.check(n)?;
    out.check(n)?;
    Ok(n)
}

/// The length checks every [`BatchSampler::pdf_batch`] does.
pub(crate) fn check_pdf_args<L>(lanes: &[L], wo: &Vec3s<'_>, pdf: &[f32]) -> Result<usize> {
    let n = lanes.len();
    wo.check(n)?;
    check_len("pdf", pdf.len(), n)?;
    Ok(n)
}

/// The length checks every [`BatchSampler::prepare_batch`] does.
pub(crate) fn check_prepare_args<L>(
    phi: &Features<'_>,
    wi: &Vec3s<'_>,
    lanes: &[L],
) -> Result<usize> {
    let n = lanes.len();
    phi.check(n)?;
    wi.check(n)?;
    Ok(n)
}

/// The length checks every [`BatchSampler::invert_batch`] does.
pub(crate) fn check_invert_args<L>(
    lanes: &[L],
    wo: &Vec3s<'_>,
    u: &Vec2sMut<'_>,
    ok: &[bool],
) -> Result<usize> {
    let n = lanes.len();
    wo.check(n)?;
    u.check(n)?;
    check_len("ok", ok.len(), n)?;
    Ok(n)
}
