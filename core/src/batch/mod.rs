//! The batched runtime's building blocks: structure-of-arrays views, the [`BatchSampler`]
//! trait, chunked kernels and their run-time instruction-set dispatch, dense layers over
//! lanes. Samplers and the neural material implement their batched calls with these; users
//! reach them through [`crate::wavefront`], which also names the samplers' lane types.

use glam::{Vec2, Vec3};

pub(crate) mod dense;
pub(crate) mod lanes;
pub(crate) mod simd;

pub use simd::{current as current_isa, detected as detected_isa, prefer as prefer_isa, Isa};

use crate::error::{Error, Result};
use crate::nn::FEATURE_DIM;
use crate::samplers::Sample;

/// Lanes per chunk of the fused calls ([`BatchSampler::sample_fused`],
/// [`BatchSampler::pdf_fused`]): their prepared states live on the stack.
pub const FUSED_CHUNK: usize = 32;

/// `N` two-dimensional values in structure-of-arrays form (e.g. the random numbers `u`).
#[derive(Copy, Clone, Debug)]
pub struct Vec2s<'a> {
    /// First components.
    pub x: &'a [f32],
    /// Second components.
    pub y: &'a [f32],
}

/// `N` directions in structure-of-arrays form (local shading frame).
#[derive(Copy, Clone, Debug)]
pub struct Vec3s<'a> {
    /// x components.
    pub x: &'a [f32],
    /// y components.
    pub y: &'a [f32],
    /// z components (the normal's axis).
    pub z: &'a [f32],
}

/// Writable [`Vec2s`].
#[derive(Debug)]
pub struct Vec2sMut<'a> {
    /// First components.
    pub x: &'a mut [f32],
    /// Second components.
    pub y: &'a mut [f32],
}

/// Writable [`Vec3s`].
#[derive(Debug)]
pub struct Vec3sMut<'a> {
    /// x components.
    pub x: &'a mut [f32],
    /// y components.
    pub y: &'a mut [f32],
    /// z components.
    pub z: &'a mut [f32],
}

/// The feature vectors φ of `N` shading points, one slice per channel (`channels[c][i]` is
/// channel `c` of point `i`).
#[derive(Copy, Clone, Debug)]
pub struct Features<'a> {
    /// The [`FEATURE_DIM`] channels.
    pub channels: [&'a [f32]; FEATURE_DIM],
}

/// Writable [`Features`].
#[derive(Debug)]
pub struct FeaturesMut<'a> {
    /// The [`FEATURE_DIM`] channels.
    pub channels: [&'a mut [f32]; FEATURE_DIM],
}

/// Where [`BatchSampler::sample_batch`] writes: the sampled directions and their
/// solid-angle densities (`pdf = 0` and `wo = 0` for a refused sample).
#[derive(Debug)]
pub struct SamplesMut<'a> {
    /// Sampled directions (local shading frame, unit length).
    pub wo: Vec3sMut<'a>,
    /// Their densities with respect to solid angle ([`Sample::pdf`]).
    pub pdf: &'a mut [f32],
}

/// Where [`NeuralMaterial::eval_batch`](crate::NeuralMaterial::eval_batch) writes: the BRDF (no cosine) per RGB channel.
#[derive(Debug)]
pub struct RgbMut<'a> {
    /// Red.
    pub r: &'a mut [f32],
    /// Green.
    pub g: &'a mut [f32],
    /// Blue.
    pub b: &'a mut [f32],
}

impl<'a> RgbMut<'a> {
    /// The `(3, n)` row-major array `rows` (r, g, b) as three slices; `None` unless
    /// `rows.len() == 3n`.
    #[must_use]
    pub fn from_rows(rows: &'a mut [f32], n: usize) -> Option<Self> {
        if rows.len() != 3 * n {
            return None;
        }
        let (r, gb) = rows.split_at_mut(n);
        let (g, b) = gb.split_at_mut(n);
        Some(RgbMut { r, g, b })
    }
}

impl<'a> Vec2s<'a> {
    /// The `(2, n)` row-major array `rows` (x then y) as two slices; `None` unless
    /// `rows.len() == 2n`.
    #[must_use]
    pub fn from_rows(rows: &'a [f32], n: usize) -> Option<Self> {
        if rows.len() != 2 * n {
            return None;
        }
        let (x, y) = rows.split_at(n);
        Some(Vec2s { x, y })
    }

    /// Number of values (the length of `x`).
    #[must_use]
    pub fn len(&self) -> usize {
        self.x.len()
    }

    /// `true` when there are no values.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    #[inline(always)]
    pub(crate) fn at(&self, i: usize) -> Vec2 {
        Vec2::new(self.x[i], self.y[i])
    }

    pub(crate) fn check(&self, n: usize) -> Result<()> {
        check_len("x", self.x.len(), n)?;
        check_len("y", self.y.len(), n)
    }

    pub(crate) fn range(&self, a: usize, b: usize) -> Vec2s<'a> {
        Vec2s {
            x: &self.x[a..b],
            y: &self.y[a..b],
        }
    }
}

impl<'a> Vec3s<'a> {
    /// The `(3, n)` row-major array `rows` (x, y, z) as three slices; `None` unless
    /// `rows.len() == 3n`.
    #[must_use]
    pub fn from_rows(rows: &'a [f32], n: usize) -> Option<Self> {
        if rows.len() != 3 * n {
            return None;
        }
        let (x, yz) = rows.split_at(n);
        let (y, z) = yz.split_at(n);
        Some(Vec3s { x, y, z })
    }

    /// Number of directions (the length of `x`).
    #[must_use]
    pub fn len(&self) -> usize {
        self.x.len()
    }

    /// `true` when there are no directions.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    #[inline(always)]
    pub(crate) fn at(&self, i: usize) -> Vec3 {
        Vec3::new(self.x[i], self.y[i], self.z[i])
    }

    pub(crate) fn check(&self, n: usize) -> Result<()> {
        check_len("x", self.x.len(), n)?;
        check_len("y", self.y.len(), n)?;
        check_len("z", self.z.len(), n)
    }

    pub(crate) fn range(&self, a: usize, b: usize) -> Vec3s<'a> {
        Vec3s {
            x: &self.x[a..b],
            y: &self.y[a..b],
            z: &self.z[a..b],
        }
    }
}

impl<'a> Vec2sMut<'a> {
    /// The `(2, n)` row-major array `rows` as two slices; `None` unless `rows.len() == 2n`.
    #[must_use]
    pub fn from_rows(rows: &'a mut [f32], n: usize) -> Option<Self> {
        if rows.len() != 2 * n {
            return None;
        }
        let (x, y) = rows.split_at_mut(n);
        Some(Vec2sMut { x, y })
    }

    pub(crate) fn check(&self, n: usize) -> Result<()> {
        check_len("x", self.x.len(), n)?;
        check_len("y", self.y.len(), n)
    }

    #[inline(always)]
    pub(crate) fn set(&mut self, i: usize, v: Vec2) {
        self.x[i] = v.x;
        self.y[i] = v.y;
    }

    pub(crate) fn range(&mut self, a: usize, b: usize) -> Vec2sMut<'_> {
        Vec2sMut {
            x: &mut self.x[a..b],
            y: &mut self.y[a..b],
        }
    }
}

impl<'a> Vec3sMut<'a> {
    /// The `(3, n)` row-major array `rows` as three slices; `None` unless `rows.len() == 3n`.
    #[must_use]
    pub fn from_rows(rows: &'a mut [f32], n: usize) -> Option<Self> {
        if rows.len() != 3 * n {
            return None;
        }
        let (x, yz) = rows.split_at_mut(n);
        let (y, z) = yz.split_at_mut(n);
        Some(Vec3sMut { x, y, z })
    }

    pub(crate) fn check(&self, n: usize) -> Result<()> {
        check_len("x", self.x.len(), n)?;
        check_len("y", self.y.len(), n)?;
        check_len("z", self.z.len(), n)
    }

    #[inline(always)]
    pub(crate) fn set(&mut self, i: usize, v: Vec3) {
        self.x[i] = v.x;
        self.y[i] = v.y;
        self.z[i] = v.z;
    }

    pub(crate) fn range(&mut self, a: usize, b: usize) -> Vec3sMut<'_> {
        Vec3sMut {
            x: &mut self.x[a..b],
            y: &mut self.y[a..b],
            z: &mut self.z[a..b],
        }
    }
}

impl<'a> Features<'a> {
    /// The `(FEATURE_DIM, n)` row-major array `rows` (channel-major) as one slice per
    /// channel; `None` unless `rows.len() == FEATURE_DIM · n`.
    #[must_use]
    pub fn from_rows(rows: &'a [f32], n: usize) -> Option<Self> {
        if rows.len() != FEATURE_DIM * n {
            return None;
        }
        let mut channels: [&'a [f32]; FEATURE_DIM] = [&[]; FEATURE_DIM];
        let mut rest = rows;
        for c in channels.iter_mut() {
            let (head, tail) = rest.split_at(n);
            *c = head;
            rest = tail;
        }
        Some(Features { channels })
    }

    /// Number of points (the length of channel 0).
    #[must_use]
    pub fn len(&self) -> usize {
        self.channels[0].len()
    }

    /// `true` when there are no points.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.channels[0].is_empty()
    }

    /// φ of point `i`.
    #[inline(always)]
    #[must_use]
    pub fn at(&self, i: usize) -> [f32; FEATURE_DIM] {
        let mut phi = [0.0f32; FEATURE_DIM];
        for (p, c) in phi.iter_mut().zip(self.channels.iter()) {
            *p = c[i];
        }
        phi
    }

    pub(crate) fn check(&self, n: usize) -> Result<()> {
        for c in self.channels.iter() {
            check_len("phi", c.len(), n)?;
        }
        Ok(())
    }

    pub(crate) fn range(&self, a: usize, b: usize) -> Features<'a> {
        let mut channels: [&'a [f32]; FEATURE_DIM] = [&[]; FEATURE_DIM];
        for (dst, src) in channels.iter_mut().zip(self.channels.iter()) {
            *dst = &src[a..b];
        }
        Features { channels }
    }
}

impl<'a> FeaturesMut<'a> {
    /// The `(FEATURE_DIM, n)` row-major array `rows` as one slice per channel; `None` unless
    /// `rows.len() == FEATURE_DIM · n`.
    #[must_use]
    pub fn from_rows(rows: &'a mut [f32], n: usize) -> Option<Self> {
        if rows.len() != FEATURE_DIM * n {
            return None;
        }
        let mut it = rows.chunks_exact_mut(n.max(1));
        let channels: [&'a mut [f32]; FEATURE_DIM] = core::array::from_fn(|_| match it.next() {
            Some(c) if n > 0 => c,
            _ => &mut [],
        });
        Some(FeaturesMut { channels })
    }

    /// Read-only view.
    #[must_use]
    pub fn as_features(&self) -> Features<'_> {
        let mut channels: [&[f32]; FEATURE_DIM] = [&[]; FEATURE_DIM];
        for (dst, src) in channels.iter_mut().zip(self.channels.iter()) {
            *dst = src;
        }
        Features { channels }
    }

    pub(crate) fn check(&self, n: usize) -> Result<()> {
        for c in self.channels.iter() {
            check_len("phi", c.len(), n)?;
        }
        Ok(())
    }

    #[inline(always)]
    pub(crate) fn set(&mut self, i: usize, phi: &[f32; FEATURE_DIM]) {
        for (c, v) in self.channels.iter_mut().zip(phi.iter()) {
            c[i] = *v;
        }
    }
}

impl<'a> SamplesMut<'a> {
    /// Writes lane `i`: the sample, or a refusal (`wo = 0`, `pdf = 0`).
    #[inline(always)]
    pub(crate) fn set(&mut self, i: usize, s: Option<Sample>) {
        match s {
            Some(s) => {
                self.wo.set(i, s.wo);
                self.pdf[i] = s.pdf;
            }
            None => {
                self.wo.set(i, Vec3::ZERO);
                self.pdf[i] = 0.0;
            }
        }
    }

    pub(crate) fn check(&self, n: usize) -> Result<()> {
        self.wo.check(n)?;
        check_len("pdf", self.pdf.len(), n)
    }

    pub(crate) fn range(&mut self, a: usize, b: usize) -> SamplesMut<'_> {
        SamplesMut {
            wo: self.wo.range(a, b),
            pdf: &mut self.pdf[a..b],
        }
    }
}

/// [`Error::BatchLength`] unless `found == expected`.
#[inline]
pub(crate) fn check_len(what: &'static str, found: usize, expected: usize) -> Result<()> {
    if found == expected {
        Ok(())
    } else {
        Err(Error::BatchLength {
            what,
            expected: clamp_u32(expected),
            found: clamp_u32(found),
        })
    }
}

fn clamp_u32(x: usize) -> u32 {
    u32::try_from(x).unwrap_or(u32::MAX)
}

/// A sampler evaluated over wavefronts (see the [`crate::wavefront`] docs for the contract).
pub trait BatchSampler {
    /// The prepared state of one shading point, without the sampler's weights handle
    /// (`Option<…>`: `None`, the default, is a refused lane).
    type Lane: Copy + Default;

    /// Runs the networks for the `N = lanes.len()` conditions `(phi[i], wi[i])` and writes
    /// each lane's state (refused conditions: `Lane::default()`).
    fn prepare_batch(
        &self,
        phi: Features<'_>,
        wi: Vec3s<'_>,
        lanes: &mut [Self::Lane],
    ) -> Result<()>;

    /// Draws one direction per lane from `u[i]` (as [`Prepared::sample`](crate::Prepared::sample)).
    fn sample_batch(&self, lanes: &[Self::Lane], u: Vec2s<'_>, out: SamplesMut<'_>) -> Result<()>;

    /// The solid-angle density of `wo[i]` at lane `i` (as [`Prepared::pdf`](crate::Prepared::pdf)).
    fn pdf_batch(&self, lanes: &[Self::Lane], wo: Vec3s<'_>, pdf: &mut [f32]) -> Result<()>;

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
        mut out: SamplesMut<'_>,
    ) -> Result<()> {
        let n = wi.len();
        phi.check(n)?;
        wi.check(n)?;
        u.check(n)?;
        out.check(n)?;
        let mut lanes = [Self::Lane::default(); FUSED_CHUNK];
        let mut a = 0;
        while a < n {
            let b = if n - a > FUSED_CHUNK {
                a + FUSED_CHUNK
            } else {
                n
            };
            let chunk = &mut lanes[..b - a];
            self.prepare_batch(phi.range(a, b), wi.range(a, b), chunk)?;
            self.sample_batch(chunk, u.range(a, b), out.range(a, b))?;
            a = b;
        }
        Ok(())
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
        let n = wi.len();
        phi.check(n)?;
        wi.check(n)?;
        wo.check(n)?;
        check_len("pdf", pdf.len(), n)?;
        let mut lanes = [Self::Lane::default(); FUSED_CHUNK];
        let mut a = 0;
        while a < n {
            let b = if n - a > FUSED_CHUNK {
                a + FUSED_CHUNK
            } else {
                n
            };
            let chunk = &mut lanes[..b - a];
            self.prepare_batch(phi.range(a, b), wi.range(a, b), chunk)?;
            self.pdf_batch(chunk, wo.range(a, b), &mut pdf[a..b])?;
            a = b;
        }
        Ok(())
    }
}

pub(crate) use chunked::ChunkedSampler;

mod chunked {
    //! [`ChunkedSampler`]: what a sampler writes to be batched; [`BatchSampler`] follows
    //! (argument checks, chunking, instruction-set dispatch).

    use super::simd::{dispatch, Kernel};
    use super::{
        check_invert_args, check_pdf_args, check_prepare_args, check_sample_args, BatchSampler,
        Features, SamplesMut, Vec2s, Vec2sMut, Vec3s,
    };
    use crate::error::Result;

    /// How a sampler computes one chunk of at most `CHUNK` lanes (arguments already checked).
    /// Every method must be `#[inline(always)]`, so that [`dispatch`] compiles it for the
    /// chosen instruction set. Public only to name it in [`BatchSampler`]'s blanket impl; the
    /// module is private.
    pub trait ChunkedSampler {
        /// See [`BatchSampler::Lane`].
        type Lane: Copy + Default;
        /// Lanes per chunk.
        const CHUNK: usize;
        /// [`BatchSampler::prepare_batch`] of one chunk.
        fn prepare_chunk(&self, phi: Features<'_>, wi: Vec3s<'_>, lanes: &mut [Self::Lane]);
        /// [`BatchSampler::sample_batch`] of one chunk.
        fn sample_chunk(&self, lanes: &[Self::Lane], u: Vec2s<'_>, out: SamplesMut<'_>);
        /// [`BatchSampler::pdf_batch`] of one chunk.
        fn pdf_chunk(&self, lanes: &[Self::Lane], wo: Vec3s<'_>, pdf: &mut [f32]);
        /// [`BatchSampler::invert_batch`] of one chunk.
        fn invert_chunk(
            &self,
            lanes: &[Self::Lane],
            wo: Vec3s<'_>,
            u: Vec2sMut<'_>,
            ok: &mut [bool],
        );
    }

    /// The chunks `[a, b)` of `0..n`, `c` lanes each.
    #[inline(always)]
    fn next_chunk(a: usize, n: usize, c: usize) -> usize {
        if n - a > c {
            a + c
        } else {
            n
        }
    }

    struct Prepare<'a, 's, S: ChunkedSampler> {
        s: &'s S,
        phi: Features<'a>,
        wi: Vec3s<'a>,
        lanes: &'a mut [S::Lane],
    }

    impl<S: ChunkedSampler> Kernel for Prepare<'_, '_, S> {
        type Output = ();
        #[inline(always)]
        fn run(self) {
            let n = self.lanes.len();
            let mut a = 0;
            while a < n {
                let b = next_chunk(a, n, S::CHUNK);
                let (phi, wi) = (self.phi.range(a, b), self.wi.range(a, b));
                self.s.prepare_chunk(phi, wi, &mut self.lanes[a..b]);
                a = b;
            }
        }
    }

    struct Sample<'a, 's, S: ChunkedSampler> {
        s: &'s S,
        lanes: &'a [S::Lane],
        u: Vec2s<'a>,
        out: SamplesMut<'a>,
    }

    impl<S: ChunkedSampler> Kernel for Sample<'_, '_, S> {
        type Output = ();
        #[inline(always)]
        fn run(mut self) {
            let n = self.lanes.len();
            let mut a = 0;
            while a < n {
                let b = next_chunk(a, n, S::CHUNK);
                let u = self.u.range(a, b);
                self.s
                    .sample_chunk(&self.lanes[a..b], u, self.out.range(a, b));
                a = b;
            }
        }
    }

    struct Pdf<'a, 's, S: ChunkedSampler> {
        s: &'s S,
        lanes: &'a [S::Lane],
        wo: Vec3s<'a>,
        pdf: &'a mut [f32],
    }

    impl<S: ChunkedSampler> Kernel for Pdf<'_, '_, S> {
        type Output = ();
        #[inline(always)]
        fn run(self) {
            let n = self.lanes.len();
            let mut a = 0;
            while a < n {
                let b = next_chunk(a, n, S::CHUNK);
                let wo = self.wo.range(a, b);
                self.s.pdf_chunk(&self.lanes[a..b], wo, &mut self.pdf[a..b]);
                a = b;
            }
        }
    }

    struct Invert<'a, 's, S: ChunkedSampler> {
        s: &'s S,
        lanes: &'a [S::Lane],
        wo: Vec3s<'a>,
        u: Vec2sMut<'a>,
        ok: &'a mut [bool],
    }

    impl<S: ChunkedSampler> Kernel for Invert<'_, '_, S> {
        type Output = ();
        #[inline(always)]
        fn run(mut self) {
            let n = self.lanes.len();
            let mut a = 0;
            while a < n {
                let b = next_chunk(a, n, S::CHUNK);
                let wo = self.wo.range(a, b);
                let lanes = &self.lanes[a..b];
                self.s
                    .invert_chunk(lanes, wo, self.u.range(a, b), &mut self.ok[a..b]);
                a = b;
            }
        }
    }

    impl<S: ChunkedSampler> BatchSampler for S {
        type Lane = S::Lane;

        fn prepare_batch(
            &self,
            phi: Features<'_>,
            wi: Vec3s<'_>,
            lanes: &mut [S::Lane],
        ) -> Result<()> {
            check_prepare_args(&phi, &wi, lanes)?;
            dispatch(Prepare {
                s: self,
                phi,
                wi,
                lanes,
            });
            Ok(())
        }

        fn sample_batch(&self, lanes: &[S::Lane], u: Vec2s<'_>, out: SamplesMut<'_>) -> Result<()> {
            check_sample_args(lanes, &u, &out)?;
            dispatch(Sample {
                s: self,
                lanes,
                u,
                out,
            });
            Ok(())
        }

        fn pdf_batch(&self, lanes: &[S::Lane], wo: Vec3s<'_>, pdf: &mut [f32]) -> Result<()> {
            check_pdf_args(lanes, &wo, pdf)?;
            dispatch(Pdf {
                s: self,
                lanes,
                wo,
                pdf,
            });
            Ok(())
        }

        fn invert_batch(
            &self,
            lanes: &[S::Lane],
            wo: Vec3s<'_>,
            u: Vec2sMut<'_>,
            ok: &mut [bool],
        ) -> Result<()> {
            check_invert_args(lanes, &wo, &u, ok)?;
            dispatch(Invert {
                s: self,
                lanes,
                wo,
                u,
                ok,
            });
            Ok(())
        }
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

/// `[0, 1, 2, …]`: every lane of a chunk, as an index list.
#[inline(always)]
pub(crate) fn identity_index<const B: usize>() -> [usize; B] {
    let mut idx = [0usize; B];
    for (i, x) in idx.iter_mut().enumerate() {
        *x = i;
    }
    idx
}

/// The encoded conditions ([`crate::nn::encode_condition`]) of a chunk's lanes and which
/// lanes are usable ([`crate::nn::check_condition`]); refused lanes are zeros.
#[inline(always)]
pub(crate) fn encoded_conditions<const B: usize>(
    phi: &Features<'_>,
    wi: &Vec3s<'_>,
) -> (Soa<{ crate::nn::CONDITION_DIM }, B>, [bool; B]) {
    let mut c = [[0.0f32; B]; crate::nn::CONDITION_DIM];
    let mut valid = [false; B];
    for l in 0..wi.len() {
        let p = phi.at(l);
        if let Some(w) = crate::nn::check_condition(&p, wi.at(l)) {
            let enc = crate::nn::encode_condition(&p, w);
            for (k, v) in enc.iter().enumerate() {
                c[k][l] = *v;
            }
            valid[l] = true;
        }
    }
    (c, valid)
}

/// The raw conditions ([`crate::nn::raw_condition`]) of a chunk's lanes and which lanes are
/// usable; refused lanes are zeros.
#[inline(always)]
pub(crate) fn raw_conditions<const B: usize>(
    phi: &Features<'_>,
    wi: &Vec3s<'_>,
) -> (Soa<{ crate::nn::RAW_CONDITION_DIM }, B>, [bool; B]) {
    let mut c = [[0.0f32; B]; crate::nn::RAW_CONDITION_DIM];
    let mut valid = [false; B];
    for l in 0..wi.len() {
        let p = phi.at(l);
        if let Some(w) = crate::nn::check_condition(&p, wi.at(l)) {
            let enc = crate::nn::raw_condition(&p, w);
            for (k, v) in enc.iter().enumerate() {
                c[k][l] = *v;
            }
            valid[l] = true;
        }
    }
    (c, valid)
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

/// [`ChunkedSampler`]'s `sample_chunk`, `pdf_chunk` and `invert_chunk` for lanes that are
/// `Option<P>` of a scalar [`Prepared`] state `P` that needs no weights: the scalar code
/// lane by lane.
macro_rules! per_lane_chunks {
    ($p:ty) => {
        #[inline(always)]
        fn sample_chunk(
            &self,
            lanes: &[Option<$p>],
            u: $crate::batch::Vec2s<'_>,
            mut out: $crate::batch::SamplesMut<'_>,
        ) {
            for (i, l) in lanes.iter().enumerate() {
                out.set(i, l.as_ref().and_then(|p| p.sample(u.at(i))));
            }
        }

        #[inline(always)]
        fn pdf_chunk(&self, lanes: &[Option<$p>], wo: $crate::batch::Vec3s<'_>, pdf: &mut [f32]) {
            for (i, l) in lanes.iter().enumerate() {
                pdf[i] = l.as_ref().map_or(0.0, |p| p.pdf(wo.at(i)));
            }
        }

        #[inline(always)]
        fn invert_chunk(
            &self,
            lanes: &[Option<$p>],
            wo: $crate::batch::Vec3s<'_>,
            mut u: $crate::batch::Vec2sMut<'_>,
            ok: &mut [bool],
        ) {
            for (i, l) in lanes.iter().enumerate() {
                match l.as_ref().and_then(|p| p.invert(wo.at(i))) {
                    Some(v) => {
                        u.set(i, v);
                        ok[i] = true;
                    }
                    None => ok[i] = false,
                }
            }
        }
    };
}
pub(crate) use per_lane_chunks;
