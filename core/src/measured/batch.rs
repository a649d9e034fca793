//! The measured material over `N` lanes at once ([`crate::wavefront`]'s conventions:
//! structure-of-arrays views, every buffer the caller's, a bad lane never disturbs another).
//!
//! Lanes run in chunks of [`CHUNK`] through the scalar path's arithmetic, operation for
//! operation, written as loops over the chunk so that they vectorise: the transcendental
//! functions are `math`'s branch-free ones (libm's numbers), table reads are gathers (one
//! instruction per chunk with AVX-512, two with AVX2, [`Gather`]; a load per lane on the
//! portable path of aarch64 and wasm), and the two binary searches of sampling take a fixed
//! number of steps with the scalar search's probes. The results are therefore the scalar
//! path's **bit for bit**. Tables that are not plain f32 slices (f16 or unaligned blob
//! tensors) take the scalar path lane by lane, and so does an x86 CPU without AVX2 (the
//! chunks are compiled for AVX2 and AVX-512 only there).

use glam::{Vec2, Vec3};

use crate::distrib::marginal2d::{invert_segment, lerp, patch, sample_segment, SliceBlend};
use crate::error::Result;
use crate::math;
use crate::wavefront::check_len;
use crate::wavefront::simd::{dispatch_gathers, Gather, GatherKernel};
use crate::wavefront::{chunks, RgbMut, SamplesMut, Vec2s, Vec3s};
use crate::weights::Weights;

use super::{
    azimuth, elevation, fold_sign, jacobian, normalize_lane, phi2u, theta2u, u2phi, u2theta,
    wrap_unit, MeasuredMaterial, MeasuredShape,
};

/// Lanes per chunk: one AVX-512 register (two AVX2 ones), so that a table read is one
/// gather instruction, or two ([`Gather`]).
const CHUNK: usize = 16;

/// Node grids with up to this many nodes are searched by counting (which vectorises); longer
/// ones by the scalar binary search per lane.
const COUNTED_NODES: usize = 64;

impl<W: Weights> MeasuredMaterial<W> {
    /// [`MeasuredPrepared::eval`](super::MeasuredPrepared::eval) of every `(wi[i], wo[i])`:
    /// the RGB BRDF without the cosine, `[0, 0, 0]` for refused lanes. The scalar path's
    /// values bit for bit.
    ///
    /// # Errors
    /// [`Error::BatchLength`](crate::Error::BatchLength) when the slices' lengths differ
    /// (nothing is written).
    pub fn eval_batch(&self, wi: Vec3s<'_>, wo: Vec3s<'_>, out: RgbMut<'_>) -> Result<()> {
        let n = wi.len();
        wi.check(n)?;
        wo.check(n)?;
        out.check(n)?;
        self.run(Op::Eval { wi, wo, out });
        Ok(())
    }

    /// [`MeasuredPrepared::pdf`](super::MeasuredPrepared::pdf) of every `(wi[i], wo[i])`:
    /// the data sampler's density with respect to solid angle, 0 for refused lanes. The
    /// scalar path's values bit for bit.
    ///
    /// # Errors
    /// [`Error::BatchLength`](crate::Error::BatchLength) when the slices' lengths differ.
    pub fn pdf_batch(&self, wi: Vec3s<'_>, wo: Vec3s<'_>, pdf: &mut [f32]) -> Result<()> {
        let n = wi.len();
        wi.check(n)?;
        wo.check(n)?;
        check_len("pdf", pdf.len(), n)?;
        self.run(Op::Pdf { wi, wo, pdf });
        Ok(())
    }

    /// [`MeasuredPrepared::sample`](super::MeasuredPrepared::sample) of every `(wi[i], u[i])`:
    /// directions and solid-angle densities in `out`, `f · cos θo / pdf` per channel in
    /// `weight`; a refused lane gets `wo = 0`, `pdf = 0` and a zero weight. The scalar path's
    /// values bit for bit.
    ///
    /// # Errors
    /// [`Error::BatchLength`](crate::Error::BatchLength) when the slices' lengths differ.
    pub fn sample_batch(
        &self,
        wi: Vec3s<'_>,
        u: Vec2s<'_>,
        out: SamplesMut<'_>,
        weight: RgbMut<'_>,
    ) -> Result<()> {
        self.sample_op(wi, u, out, Some(weight))
    }

    /// [`Self::sample_batch`] without the weights: the directions and densities only, for a
    /// renderer that evaluates the material itself (the RGB tables are not read). The same
    /// directions and densities bit for bit.
    ///
    /// # Errors
    /// [`Error::BatchLength`](crate::Error::BatchLength) when the slices' lengths differ.
    pub fn sample_directions_batch(
        &self,
        wi: Vec3s<'_>,
        u: Vec2s<'_>,
        out: SamplesMut<'_>,
    ) -> Result<()> {
        self.sample_op(wi, u, out, None)
    }

    /// [`Self::sample_batch`] with or without the weights, after the length checks.
    fn sample_op(
        &self,
        wi: Vec3s<'_>,
        u: Vec2s<'_>,
        out: SamplesMut<'_>,
        weight: Option<RgbMut<'_>>,
    ) -> Result<()> {
        let n = wi.len();
        wi.check(n)?;
        u.check(n)?;
        out.check(n)?;
        if let Some(w) = &weight {
            w.check(n)?;
        }
        self.run(Op::Sample { wi, u, out, weight });
        Ok(())
    }

    /// Runs `op` (its lengths checked) on the chunked path, or lane by lane when a table is
    /// not a plain f32 slice.
    fn run(&self, op: Op<'_>) {
        let t = &self.tables;
        let flat = (|| {
            Some(Flat {
                phi_i: t.phi_i.as_f32_slice()?,
                theta_i: t.theta_i.as_f32_slice()?,
                ndf: t.ndf.as_f32_slice()?,
                sigma: t.sigma.as_f32_slice()?,
                vndf: t.vndf.as_f32_slice()?,
                vndf_marg: t.vndf_marginal.as_f32_slice()?,
                vndf_cond: t.vndf_conditional.as_f32_slice()?,
                lum: t.luminance.as_f32_slice()?,
                lum_marg: t.luminance_marginal.as_f32_slice()?,
                lum_cond: t.luminance_conditional.as_f32_slice()?,
                rgb: t.rgb.as_f32_slice()?,
            })
        })();
        // Validated tables are never empty; the chunks' loads rely on it.
        let Some(f) = flat.filter(|f| {
            [
                f.phi_i,
                f.theta_i,
                f.ndf,
                f.sigma,
                f.vndf,
                f.vndf_marg,
                f.vndf_cond,
                f.lum,
                f.lum_marg,
                f.lum_cond,
                f.rgb,
            ]
            .iter()
            .all(|t| !t.is_empty())
        }) else {
            return self.per_lane(op);
        };
        let counted = f.phi_i.len() <= COUNTED_NODES && f.theta_i.len() <= COUNTED_NODES;
        let s = self.shape;
        let ctx = Ctx {
            f,
            s,
            jacobian: self.jacobian,
            reduction: self.reduction,
            isotropic: self.isotropic(),
            counted,
            stride: [
                if s.n_phi > 1 { s.n_theta } else { 0 },
                if s.n_theta > 1 { 1 } else { 0 },
            ],
            g: (),
        };
        if let Some(op) = run_chunks(ctx, op) {
            self.per_lane(op);
        }
    }

    /// The scalar path, one lane at a time.
    fn per_lane(&self, op: Op<'_>) {
        match op {
            Op::Eval { wi, wo, mut out } => {
                for i in 0..wi.len() {
                    let v = self
                        .prepare(wi.at(i))
                        .map_or([0.0; 3], |p| p.eval(wo.at(i)));
                    out.set(i, v);
                }
            }
            Op::Pdf { wi, wo, pdf } => {
                for (i, p) in pdf.iter_mut().enumerate() {
                    *p = self
                        .prepare(wi.at(i))
                        .map_or(0.0, |prep| prep.pdf(wo.at(i)));
                }
            }
            Op::Sample {
                wi,
                u,
                mut out,
                mut weight,
            } => {
                for i in 0..wi.len() {
                    let s = self.prepare(wi.at(i)).and_then(|p| p.sample(u.at(i)));
                    if let Some(weight) = &mut weight {
                        weight.set(i, s.map_or([0.0; 3], |s| s.weight));
                    }
                    out.set(i, s.map(super::runtime_sample));
                }
            }
        }
    }
}

/// The chunked path, or `op` back (not run) on an x86 CPU without AVX2 (or with
/// [`Isa::Portable`](crate::wavefront::Isa::Portable) chosen), where the scalar path gives
/// the same bits: the chunks are not compiled for SSE2. Not generic and never inlined, so
/// that it is compiled once, in this crate, whatever table type the material holds,
/// instead of in every crate that calls a batched method.
#[inline(never)]
fn run_chunks<'a>(c: Ctx<'a, ()>, op: Op<'a>) -> Option<Op<'a>> {
    // Slices blend along φi only with more than one φi node.
    if c.s.n_phi > 1 {
        dispatch_gathers(Job::<true> { c, op }).err().map(|j| j.op)
    } else {
        dispatch_gathers(Job::<false> { c, op }).err().map(|j| j.op)
    }
}

/// A batched call, its lengths checked.
enum Op<'a> {
    Eval {
        wi: Vec3s<'a>,
        wo: Vec3s<'a>,
        out: RgbMut<'a>,
    },
    Pdf {
        wi: Vec3s<'a>,
        wo: Vec3s<'a>,
        pdf: &'a mut [f32],
    },
    Sample {
        wi: Vec3s<'a>,
        u: Vec2s<'a>,
        out: SamplesMut<'a>,
        /// `None`: directions and densities only.
        weight: Option<RgbMut<'a>>,
    },
}

/// Every table as an f32 slice.
#[derive(Copy, Clone)]
struct Flat<'a> {
    phi_i: &'a [f32],
    theta_i: &'a [f32],
    ndf: &'a [f32],
    sigma: &'a [f32],
    vndf: &'a [f32],
    vndf_marg: &'a [f32],
    vndf_cond: &'a [f32],
    lum: &'a [f32],
    lum_marg: &'a [f32],
    lum_cond: &'a [f32],
    rgb: &'a [f32],
}

/// What the chunks read: the tables and the material's constants, and how (`G`: a
/// [`Gather`] in the chunks, `()` before the instruction set is chosen).
#[derive(Copy, Clone)]
struct Ctx<'a, G> {
    f: Flat<'a>,
    s: MeasuredShape,
    jacobian: bool,
    reduction: u32,
    isotropic: bool,
    /// Whether both node grids are searched by counting.
    counted: bool,
    /// The slice strides of [`SliceBlend`].
    stride: [u32; 2],
    /// The table reads.
    g: G,
}

impl<'a> Ctx<'a, ()> {
    /// These constants with the table reads `g`.
    #[inline(always)]
    fn with<G: Gather>(self, g: G) -> Ctx<'a, G> {
        Ctx {
            f: self.f,
            s: self.s,
            jacobian: self.jacobian,
            reduction: self.reduction,
            isotropic: self.isotropic,
            counted: self.counted,
            stride: self.stride,
            g,
        }
    }
}

/// One value per lane of a chunk.
type Lanes = [f32; CHUNK];
/// One table index per lane.
type Idx = [u32; CHUNK];
/// Each lane's slice-blend weights, `[axis][node]` ([`SliceBlend`]'s `weight`).
type BlendWeights = [[Lanes; 2]; 2];

/// `[e(0), e(1), …]` over a chunk's lanes, as a plain loop (so that it vectorises; a
/// closure would be a function of its own, compiled without `dispatch`'s instruction set).
macro_rules! per_lane {
    ($zero:expr, |$l:ident| $e:expr) => {{
        let mut o = [$zero; CHUNK];
        for $l in 0..CHUNK {
            o[$l] = $e;
        }
        o
    }};
}

/// `i + k` on every lane.
#[inline(always)]
fn plus(i: &Idx, k: u32) -> Idx {
    per_lane!(0, |l| i[l] + k)
}

/// `i + j` lane by lane.
#[inline(always)]
fn add(i: &Idx, j: &Idx) -> Idx {
    per_lane!(0, |l| i[l] + j[l])
}

/// `i − 1` where `i > 0`, else 0, on every lane (the cell before `i`, read at 0 where there
/// is none and then unused).
#[inline(always)]
fn before(i: &Idx) -> Idx {
    per_lane!(0, |l| if i[l] > 0 { i[l] - 1 } else { 0 })
}

/// `patch` on every lane: each lane's cell `(column, row)` and its position in it.
#[inline(always)]
fn patches(w: u32, h: u32, pos: &[Lanes; 2]) -> (Idx, Idx, [Lanes; 2]) {
    let (mut c, mut r, mut t) = ([0; CHUNK], [0; CHUNK], [[0.0; CHUNK]; 2]);
    for l in 0..CHUNK {
        let (cl, rl, tl) = patch(w, h, Vec2::new(pos[0][l], pos[1][l]));
        (c[l], r[l], t[0][l], t[1][l]) = (cl, rl, tl.x, tl.y);
    }
    (c, r, t)
}

/// `x0·w[0] + x1·w[1]` on every lane (one axis of [`SliceBlend`]).
#[inline(always)]
fn blend(x0: &Lanes, x1: &Lanes, w: &[Lanes; 2]) -> Lanes {
    per_lane!(0.0, |l| x0[l] * w[0][l] + x1[l] * w[1][l])
}

/// The bilinear interpolation of a cell's corners at `t` on every lane.
#[inline(always)]
fn bilerp(v: &[Lanes; 4], t: &[Lanes; 2]) -> Lanes {
    let [v00, v10, v01, v11] = v;
    per_lane!(0.0, |l| lerp(
        lerp(v00[l], v10[l], t[0][l]),
        lerp(v01[l], v11[l], t[0][l]),
        t[1][l]
    ))
}

/// A table of slices of `w × h` values and its running integrals (a `Marginal2D`).
#[derive(Copy, Clone)]
struct Dist<'a> {
    data: &'a [f32],
    marg: &'a [f32],
    cond: &'a [f32],
    w: u32,
    h: u32,
}

/// Every step below is `Marginal2D`'s on each lane of a chunk: the same operations in the
/// same order, written as loops over the lanes (table reads are gathers).
impl<G: Gather> Ctx<'_, G> {
    /// Element `i` of `t` on every lane, the last one for an index past the end
    /// ([`Gather::read`]).
    #[inline(always)]
    fn gather(&self, t: &[f32], i: &Idx) -> Lanes {
        self.g.read(t, i)
    }

    /// Elements `i` and `i + 1` of `t` on every lane: adjacent elements, read together
    /// ([`Gather::read_pair`]; the gathers clamp `i` to the table's length − 2, no change
    /// for the in-range indices of validated tables).
    #[inline(always)]
    fn gather_pair(&self, t: &[f32], i: &Idx) -> (Lanes, Lanes) {
        self.g.read_pair(t, i)
    }

    /// `SliceBlend::lookup`: the blended value of `t` at element `i` of each lane's first
    /// slice (slices of `n`). Without `φi` blending its weights are `(1, 0)`, so the first
    /// axis reads one element (`a·1 + a·0 = a` for the finite values the tables hold).
    #[inline(always)]
    fn lookup<const A: bool>(&self, t: &[f32], n: u32, i: &Idx, w: &BlendWeights) -> Lanes {
        let i1 = plus(i, self.stride[1] * n);
        let (a0, a1) = if A {
            let j = self.stride[0] * n;
            let (x0, x1) = (self.gather(t, i), self.gather(t, &plus(i, j)));
            let (y0, y1) = (self.gather(t, &i1), self.gather(t, &plus(&i1, j)));
            (blend(&x0, &x1, &w[0]), blend(&y0, &y1, &w[0]))
        } else {
            (self.gather(t, i), self.gather(t, &i1))
        };
        blend(&a0, &a1, &w[1])
    }

    /// [`Self::lookup`] at `i` and at `i + 1` (a cell's two columns), each slice's two
    /// elements read together.
    #[inline(always)]
    fn lookup_pair<const A: bool>(
        &self,
        t: &[f32],
        n: u32,
        i: &Idx,
        w: &BlendWeights,
    ) -> (Lanes, Lanes) {
        let i1 = plus(i, self.stride[1] * n);
        let ((a0, b0), (a1, b1)) = if A {
            let j = self.stride[0] * n;
            let (x0, x1) = (self.gather_pair(t, i), self.gather_pair(t, &plus(i, j)));
            let (y0, y1) = (self.gather_pair(t, &i1), self.gather_pair(t, &plus(&i1, j)));
            (
                (blend(&x0.0, &x1.0, &w[0]), blend(&x0.1, &x1.1, &w[0])),
                (blend(&y0.0, &y1.0, &w[0]), blend(&y0.1, &y1.1, &w[0])),
            )
        } else {
            (self.gather_pair(t, i), self.gather_pair(t, &i1))
        };
        (blend(&a0, &a1, &w[1]), blend(&b0, &b1, &w[1]))
    }

    /// `Marginal2D::corners` of cell `(c, r)` of each lane's blended slice.
    #[inline(always)]
    fn corners<const A: bool>(
        &self,
        d: &Dist<'_>,
        slice: &Idx,
        w: &BlendWeights,
        c: &Idx,
        r: &Idx,
    ) -> [Lanes; 4] {
        let n = d.w * d.h;
        let i = per_lane!(0, |l| slice[l] * n + r[l] * d.w + c[l]);
        let (v00, v10) = self.lookup_pair::<A>(d.data, n, &i, w);
        let (v01, v11) = self.lookup_pair::<A>(d.data, n, &plus(&i, d.w), w);
        [v00, v10, v01, v11]
    }

    /// `Marginal2D::eval` of each lane's blended slice.
    #[inline(always)]
    fn eval<const A: bool>(
        &self,
        d: &Dist<'_>,
        slice: &Idx,
        w: &BlendWeights,
        pos: &[Lanes; 2],
    ) -> Lanes {
        let (c, r, t) = patches(d.w, d.h, pos);
        bilerp(&self.corners::<A>(d, slice, w, &c, &r), &t)
    }

    /// `Marginal2D::eval` of a single-slice table (`SliceBlend::single(0)`: one read per
    /// corner).
    #[inline(always)]
    fn eval_single(&self, t: &[f32], w: u32, h: u32, pos: &[Lanes; 2]) -> Lanes {
        let (c, r, tt) = patches(w, h, pos);
        let i = per_lane!(0, |l| r[l] * w + c[l]);
        let (v00, v10) = self.gather_pair(t, &i);
        let (v01, v11) = self.gather_pair(t, &plus(&i, w));
        bilerp(&[v00, v10, v01, v11], &tt)
    }

    /// `Marginal2D::invert` of each lane's blended slice: the sample-space positions and
    /// the densities.
    #[inline(always)]
    fn invert<const A: bool>(
        &self,
        d: &Dist<'_>,
        slice: &Idx,
        w: &BlendWeights,
        pos: &[Lanes; 2],
    ) -> ([Lanes; 2], Lanes) {
        let (n_marg, n_cond) = (d.h - 1, d.h * (d.w - 1));
        let (c, r, t) = patches(d.w, d.h, pos);
        let [v00, v10, v01, v11] = self.corners::<A>(d, slice, w, &c, &r);
        let c0 = per_lane!(0.0, |l| lerp(v00[l], v01[l], t[1][l]));
        let c1 = per_lane!(0.0, |l| lerp(v10[l], v11[l], t[1][l]));
        let pdf = per_lane!(0.0, |l| lerp(c0[l], c1[l], t[0][l]));
        let inv_w = 1.0 / (d.w - 1) as f32;
        let mut ux = per_lane!(0.0, |l| invert_segment(t[0][l], inv_w, c0[l], c1[l]));
        let off = per_lane!(0, |l| slice[l] * n_cond + r[l] * (d.w - 1));
        let cm = add(&off, &before(&c));
        let v0 = self.lookup::<A>(d.cond, n_cond, &cm, w);
        let v1 = self.lookup::<A>(d.cond, n_cond, &plus(&cm, d.w - 1), w);
        for l in 0..CHUNK {
            let plus = ux[l] + lerp(v0[l], v1[l], t[1][l]);
            ux[l] = if c[l] > 0 { plus } else { ux[l] };
        }
        let r0 = self.lookup::<A>(d.cond, n_cond, &plus(&off, (d.w - 1) - 1), w);
        let r1 = self.lookup::<A>(d.cond, n_cond, &plus(&off, 2 * (d.w - 1) - 1), w);
        let inv_h = 1.0 / (d.h - 1) as f32;
        let mut uy = [0.0; CHUNK];
        for l in 0..CHUNK {
            ux[l] /= lerp(r0[l], r1[l], t[1][l]);
            uy[l] = invert_segment(t[1][l], inv_h, r0[l], r1[l]);
        }
        let im = add(&per_lane!(0, |l| slice[l] * n_marg), &before(&r));
        let mv = self.lookup::<A>(d.marg, n_marg, &im, w);
        for l in 0..CHUNK {
            let plus = uy[l] + mv[l];
            uy[l] = if r[l] > 0 { plus } else { uy[l] };
        }
        ([ux, uy], pdf)
    }

    /// The blended conditional integral of `d` at element `i` (row offset + column) of each
    /// lane's row pair, interpolated at `uy` between the rows.
    #[inline(always)]
    fn cond<const A: bool>(&self, d: &Dist<'_>, w: &BlendWeights, i: &Idx, uy: &Lanes) -> Lanes {
        let n_cond = d.h * (d.w - 1);
        let v0 = self.lookup::<A>(d.cond, n_cond, i, w);
        let v1 = self.lookup::<A>(d.cond, n_cond, &plus(i, d.w - 1), w);
        per_lane!(0.0, |l| lerp(v0[l], v1[l], uy[l]))
    }

    #[inline(always)]
    fn vndf(&self) -> Dist<'_> {
        Dist {
            data: self.f.vndf,
            marg: self.f.vndf_marg,
            cond: self.f.vndf_cond,
            w: self.s.vndf[0].max(2),
            h: self.s.vndf[1].max(2),
        }
    }

    #[inline(always)]
    fn luminance(&self) -> Dist<'_> {
        Dist {
            data: self.f.lum,
            marg: self.f.lum_marg,
            cond: self.f.lum_cond,
            w: self.s.rgb[0].max(2),
            h: self.s.rgb[1].max(2),
        }
    }
}

/// One chunk's prepared lanes (`MeasuredPrepared` in structure-of-arrays form).
struct Prepared {
    ok: [bool; CHUNK],
    /// `wi`, folded into the stored azimuths.
    wi: [Lanes; 3],
    /// The signs that fold directions into the stored azimuths.
    flip: [Lanes; 2],
    phi_i: Lanes,
    slice: Idx,
    w: BlendWeights,
    inv_4sigma: Lanes,
}

/// Lanes `a .. a + m` of `v` in structure-of-arrays form (the rest of the chunk `+z`).
#[inline(always)]
fn load3(v: &Vec3s<'_>, a: usize, m: usize) -> [Lanes; 3] {
    let mut out = [[0.0; CHUNK], [0.0; CHUNK], [1.0; CHUNK]];
    for (o, x) in out.iter_mut().zip([v.x, v.y, v.z]) {
        // A full chunk copies a constant length (inline moves, not a `memcpy` call).
        if m == CHUNK {
            o.copy_from_slice(&x[a..a + CHUNK]);
        } else {
            o[..m].copy_from_slice(&x[a..a + m]);
        }
    }
    out
}

/// `SliceBlend::new`'s `locate` on each lane: the interval of `nodes` holding `p` and the
/// weights across it, counting the interior nodes below `p` (ascending nodes: the binary
/// search's answer).
#[inline(always)]
fn locate<G: Gather>(c: &Ctx<'_, G>, nodes: &[f32], p: &Lanes, idx: &mut Idx, w: &mut [Lanes; 2]) {
    let n = nodes.len();
    if n < 2 {
        *idx = [0; CHUNK];
        *w = [[1.0; CHUNK], [0.0; CHUNK]];
        return;
    }
    // Counted and weighted in locals, written out once.
    let mut i: Idx = [0; CHUNK];
    for &node in &nodes[1..n - 1] {
        for l in 0..CHUNK {
            i[l] += u32::from(node < p[l]);
        }
    }
    let (p0, p1) = c.gather_pair(nodes, &i);
    let t = per_lane!(0.0, |l| math::clamp(
        (p[l] - p0[l]) / (p1[l] - p0[l]),
        0.0,
        1.0
    ));
    *w = [per_lane!(0.0, |l| 1.0 - t[l]), t];
    *idx = i;
}

/// `search` (the first index in `0 ..= last` where `below` is false) on every lane: the
/// scalar binary search's steps, each lane idle once it has its answer; `below` gives every
/// lane's outcome at the lanes' probes `i`. A macro rather than a function of a closure, so
/// that the predicate is compiled for `dispatch`'s instruction set.
macro_rules! search {
    ($last:expr, |$i:ident| $below:expr) => {{
        let last: u32 = $last;
        let mut lo = [0u32; CHUNK];
        let mut hi = [last; CHUNK];
        // The scalar search halves 0 ..= last each step: ⌈log₂(last + 1)⌉ steps.
        for _ in 0..(u32::BITS - last.leading_zeros()) {
            let $i: Idx = per_lane!(0, |l| (lo[l] + hi[l]) / 2);
            let below: [bool; CHUNK] = $below;
            for l in 0..CHUNK {
                let active = lo[l] < hi[l];
                lo[l] = if active & below[l] { $i[l] + 1 } else { lo[l] };
                hi[l] = if active & !below[l] { $i[l] } else { hi[l] };
            }
        }
        lo
    }};
}

/// A dispatched batched call.
struct Job<'a, const A: bool> {
    c: Ctx<'a, ()>,
    op: Op<'a>,
}

impl<const A: bool> GatherKernel for Job<'_, A> {
    type Output = ();

    #[inline(always)]
    fn run<G: Gather>(self, g: G) {
        // No closures here: a closure is a function of its own, compiled without the
        // instruction set `dispatch_gathers` chose unless it is inlined.
        let c = &self.c.with(g);
        match self.op {
            Op::Eval { wi, wo, mut out } => {
                for (a, b) in chunks(wi.len(), CHUNK) {
                    c.eval_chunk::<A>(&wi, &wo, &mut out, a, b - a);
                }
            }
            Op::Pdf { wi, wo, pdf } => {
                for (a, b) in chunks(wi.len(), CHUNK) {
                    c.pdf_chunk::<A>(&wi, &wo, &mut pdf[a..b], a);
                }
            }
            Op::Sample {
                wi,
                u,
                mut out,
                mut weight,
            } => {
                for (a, b) in chunks(wi.len(), CHUNK) {
                    c.sample_chunk::<A>(&wi, &u, &mut out, weight.as_mut(), a, b - a);
                }
            }
        }
    }
}

impl<G: Gather> Ctx<'_, G> {
    /// `eval_batch` of lanes `a .. a + m`.
    #[inline(always)]
    fn eval_chunk<const A: bool>(
        &self,
        wi: &Vec3s<'_>,
        wo: &Vec3s<'_>,
        out: &mut RgbMut<'_>,
        a: usize,
        m: usize,
    ) {
        let mut p = self.empty();
        self.prepare::<A>(wi, a, m, true, &mut p);
        let wo = load3(wo, a, m);
        // `eval` normalises wo, then `half` normalises it again.
        let mut won = [[0.0; CHUNK]; 3];
        let mut inv_cos = [0.0; CHUNK];
        let mut ok = [false; CHUNK];
        for l in 0..CHUNK {
            let (w, ok_w) = normalize_lane(Vec3::new(wo[0][l], wo[1][l], wo[2][l]));
            inv_cos[l] = 1.0 / w.z;
            ok[l] = ok_w & (w.z > 0.0);
            [won[0][l], won[1][l], won[2][l]] = [w.x, w.y, w.z];
        }
        let h = self.half(&p, &won);
        let (sample, _) = self.invert::<A>(&self.vndf(), &p.slice, &p.w, &h.u_m);
        let f = self.rgb::<A>(&p, &sample, &h.u_m);
        for l in 0..m {
            let keep = p.ok[l] & ok[l] & h.ok[l];
            let mut v = [0.0; 3];
            for c in 0..3 {
                v[c] = if keep {
                    math::finite_density(f[c][l] * inv_cos[l])
                } else {
                    0.0
                };
            }
            out.set(a + l, v);
        }
    }

    /// `pdf_batch` of lanes `a .. a + pdf.len()`.
    #[inline(always)]
    fn pdf_chunk<const A: bool>(&self, wi: &Vec3s<'_>, wo: &Vec3s<'_>, pdf: &mut [f32], a: usize) {
        let m = pdf.len();
        let mut p = self.empty();
        self.prepare::<A>(wi, a, m, false, &mut p);
        let h = self.half(&p, &load3(wo, a, m));
        let (sample, vndf_pdf) = self.invert::<A>(&self.vndf(), &p.slice, &p.w, &h.u_m);
        let lum_pdf = self.eval::<A>(&self.luminance(), &p.slice, &p.w, &sample);
        let mut d = [0.0; CHUNK];
        for l in 0..CHUNK {
            let [mx, my, mz] = [h.m[0][l], h.m[1][l], h.m[2][l]];
            let sin_theta_m = math::sqrt(mx * mx + my * my);
            let wi = Vec3::new(p.wi[0][l], p.wi[1][l], p.wi[2][l]);
            let jac = jacobian(h.u_m[0][l], sin_theta_m, wi.dot(Vec3::new(mx, my, mz)));
            let v = math::finite_density(vndf_pdf[l] * lum_pdf[l] / jac);
            d[l] = if p.ok[l] & h.ok[l] { v } else { 0.0 };
        }
        if m == CHUNK {
            pdf.copy_from_slice(&d);
        } else {
            pdf.copy_from_slice(&d[..m]);
        }
    }

    /// `sample_batch` of lanes `a .. a + m`; the weights (and the `sigma` table they need)
    /// only with `weight`. A run-time choice, not a const parameter: one copy of the
    /// sampling code serves both (the branch is taken once per chunk).
    #[inline(always)]
    fn sample_chunk<const A: bool>(
        &self,
        wi: &Vec3s<'_>,
        u: &Vec2s<'_>,
        out: &mut SamplesMut<'_>,
        weight: Option<&mut RgbMut<'_>>,
        a: usize,
        m: usize,
    ) {
        let mut p = self.empty();
        self.prepare::<A>(wi, a, m, weight.is_some(), &mut p);
        let mut uu = [[0.0; CHUNK]; 2];
        for l in 0..m {
            let v = u.at(a + l);
            (uu[0][l], uu[1][l]) = (v.x, v.y);
        }
        self.sample_lanes::<A>(&p, &uu, out, weight, a, m);
    }

    /// A chunk's prepared lanes, before [`Ctx::prepare`] fills them.
    #[inline(always)]
    fn empty(&self) -> Prepared {
        Prepared {
            ok: [false; CHUNK],
            wi: [[0.0; CHUNK]; 3],
            flip: [[1.0; CHUNK]; 2],
            phi_i: [0.0; CHUNK],
            slice: [0; CHUNK],
            w: [[[0.0; CHUNK]; 2]; 2],
            inv_4sigma: [0.0; CHUNK],
        }
    }

    /// `MeasuredMaterial::prepare` of lanes `a .. a + m` of `wi`, into `p`; the `sigma`
    /// table (the scale of `f`) is read only when `sigma` (the density does not need it).
    #[inline(always)]
    fn prepare<const A: bool>(
        &self,
        wi: &Vec3s<'_>,
        a: usize,
        m: usize,
        sigma: bool,
        p: &mut Prepared,
    ) {
        let wi = load3(wi, a, m);
        let mut theta_i = [0.0; CHUNK];
        for l in 0..CHUNK {
            let (w, ok) = normalize_lane(Vec3::new(wi[0][l], wi[1][l], wi[2][l]));
            p.ok[l] = ok & (w.z > 0.0) & (l < m);
            let (mut fx, mut fy) = (1.0, 1.0);
            if self.reduction >= 2 {
                fy = fold_sign(w.y);
                fx = if self.reduction == 4 {
                    fold_sign(w.x)
                } else {
                    fy
                };
            }
            let w = Vec3::new(w.x * fx, w.y * fy, w.z);
            [p.wi[0][l], p.wi[1][l], p.wi[2][l]] = [w.x, w.y, w.z];
            [p.flip[0][l], p.flip[1][l]] = [fx, fy];
            theta_i[l] = elevation(w);
            p.phi_i[l] = azimuth(w);
        }
        let t = &self.f;
        if self.counted {
            let mut i0 = [0; CHUNK];
            let mut i1 = [0; CHUNK];
            locate(self, t.phi_i, &p.phi_i, &mut i0, &mut p.w[0]);
            locate(self, t.theta_i, &theta_i, &mut i1, &mut p.w[1]);
            let n1 = t.theta_i.len() as u32;
            for l in 0..CHUNK {
                p.slice[l] = i0[l] * n1 + i1[l];
            }
        } else {
            for l in 0..CHUNK {
                let b = SliceBlend::new(
                    t.phi_i,
                    self.s.n_phi,
                    t.theta_i,
                    self.s.n_theta,
                    [p.phi_i[l], theta_i[l]],
                );
                p.slice[l] = b.slice;
                [[p.w[0][0][l], p.w[0][1][l]], [p.w[1][0][l], p.w[1][1][l]]] = b.weight;
            }
        }
        if !sigma {
            return;
        }
        let u_wi = [
            per_lane!(0.0, |l| theta2u(theta_i[l])),
            per_lane!(0.0, |l| phi2u(p.phi_i[l])),
        ];
        let [sw, sh] = [self.s.sigma[0].max(2), self.s.sigma[1].max(2)];
        let sigma = self.eval_single(t.sigma, sw, sh, &u_wi);
        for l in 0..CHUNK {
            p.inv_4sigma[l] = if sigma[l] > 0.0 { 0.25 / sigma[l] } else { 0.0 };
        }
    }

    /// `MeasuredPrepared::half` of every lane: the half vectors, their table coordinates,
    /// and whether they exist.
    #[inline(always)]
    fn half(&self, p: &Prepared, wo: &[Lanes; 3]) -> Half {
        let mut h = Half {
            m: [[0.0; CHUNK]; 3],
            u_m: [[0.0; CHUNK]; 2],
            ok: [false; CHUNK],
        };
        for l in 0..CHUNK {
            let (w, ok) = normalize_lane(Vec3::new(wo[0][l], wo[1][l], wo[2][l]));
            let ok = ok & (w.z > 0.0);
            let w = Vec3::new(w.x * p.flip[0][l], w.y * p.flip[1][l], w.z);
            let wi = Vec3::new(p.wi[0][l], p.wi[1][l], p.wi[2][l]);
            let (m, ok_m) = normalize_lane(wi + w);
            let theta_m = elevation(m);
            let phi_m = azimuth(m);
            let rel = if self.isotropic {
                phi_m - p.phi_i[l]
            } else {
                phi_m
            };
            let uy = wrap_unit(phi2u(rel));
            [h.m[0][l], h.m[1][l], h.m[2][l]] = [m.x, m.y, m.z];
            [h.u_m[0][l], h.u_m[1][l]] = [theta2u(theta_m), uy];
            h.ok[l] = ok & ok_m;
        }
        h
    }

    /// `MeasuredPrepared::rgb` of every lane: `f · cos θo` at `sample` of the VNDF's sample
    /// space, per channel.
    #[inline(always)]
    fn rgb<const A: bool>(
        &self,
        p: &Prepared,
        sample: &[Lanes; 2],
        u_m: &[Lanes; 2],
    ) -> [Lanes; 3] {
        let [w, h] = [self.s.rgb[0].max(2), self.s.rgb[1].max(2)];
        let scale = if self.jacobian {
            let [nw, nh] = [self.s.ndf[0].max(2), self.s.ndf[1].max(2)];
            let d = self.eval_single(self.f.ndf, nw, nh, u_m);
            per_lane!(0.0, |l| d[l] * p.inv_4sigma[l])
        } else {
            [1.0; CHUNK]
        };
        // The channel is the innermost slice index: the blend's slices and strides times 3.
        let c3 = Ctx {
            stride: [self.stride[0] * 3, self.stride[1] * 3],
            ..*self
        };
        let d = Dist {
            data: self.f.rgb,
            marg: self.f.rgb,
            cond: self.f.rgb,
            w,
            h,
        };
        let (col, row, t) = patches(w, h, sample);
        let mut out = [[0.0; CHUNK]; 3];
        for (c, o) in out.iter_mut().enumerate() {
            let slice = per_lane!(0, |l| p.slice[l] * 3 + c as u32);
            let v = bilerp(&c3.corners::<A>(&d, &slice, &p.w, &col, &row), &t);
            *o = per_lane!(0.0, |l| math::finite_density(v[l] * scale[l]));
        }
        out
    }

    /// `Marginal2D::sample` of the blended slices on every lane.
    #[inline(always)]
    fn sample_dist<const A: bool>(
        &self,
        d: &Dist<'_>,
        p: &Prepared,
        u: &[Lanes; 2],
    ) -> ([Lanes; 2], Lanes) {
        let (w, h) = (d.w, d.h);
        let (n_marg, n_cond) = (h - 1, h * (w - 1));
        let eps = f32::EPSILON / 2.0;
        let mut ux = per_lane!(0.0, |l| math::clamp(u[0][l], eps, math::ONE_MINUS_EPSILON));
        let mut uy = per_lane!(0.0, |l| math::clamp(u[1][l], eps, math::ONE_MINUS_EPSILON));
        let marg = per_lane!(0, |l| p.slice[l] * n_marg);
        let row = search!(h - 2, |i| {
            let v = self.lookup::<A>(d.marg, n_marg, &add(&marg, &i), &p.w);
            per_lane!(false, |l| v[l] < uy[l])
        });
        let mv = self.lookup::<A>(d.marg, n_marg, &add(&marg, &before(&row)), &p.w);
        for l in 0..CHUNK {
            let minus = uy[l] - mv[l];
            uy[l] = if row[l] > 0 { minus } else { uy[l] };
        }
        let off = per_lane!(0, |l| p.slice[l] * n_cond + row[l] * (w - 1));
        let r0 = self.lookup::<A>(d.cond, n_cond, &plus(&off, (w - 1) - 1), &p.w);
        let r1 = self.lookup::<A>(d.cond, n_cond, &plus(&off, 2 * (w - 1) - 1), &p.w);
        for l in 0..CHUNK {
            uy[l] = sample_segment(uy[l], (h - 1) as f32, r0[l], r1[l]);
            ux[l] *= lerp(r0[l], r1[l], uy[l]);
        }
        let col = search!(w - 2, |i| {
            let v = self.cond::<A>(d, &p.w, &add(&off, &i), &uy);
            per_lane!(false, |l| v[l] < ux[l])
        });
        let cv = self.cond::<A>(d, &p.w, &add(&off, &before(&col)), &uy);
        for l in 0..CHUNK {
            let minus = ux[l] - cv[l];
            ux[l] = if col[l] > 0 { minus } else { ux[l] };
        }
        let [v00, v10, v01, v11] = self.corners::<A>(d, &p.slice, &p.w, &col, &row);
        let mut pos = [[0.0; CHUNK]; 2];
        let mut pdf = [0.0; CHUNK];
        for l in 0..CHUNK {
            let c0 = lerp(v00[l], v01[l], uy[l]);
            let c1 = lerp(v10[l], v11[l], uy[l]);
            let x = sample_segment(ux[l], (w - 1) as f32, c0, c1);
            pos[0][l] = (col[l] as f32 + x) * (1.0 / (w - 1) as f32);
            pos[1][l] = (row[l] as f32 + uy[l]) * (1.0 / (h - 1) as f32);
            pdf[l] = lerp(c0, c1, x);
        }
        (pos, pdf)
    }

    /// `MeasuredPrepared::sample` on every lane, written for lanes `a .. a + m` (zero where
    /// refused); the weights are read from the RGB tables and written only with `weight`.
    #[inline(always)]
    fn sample_lanes<const A: bool>(
        &self,
        p: &Prepared,
        u: &[Lanes; 2],
        out: &mut SamplesMut<'_>,
        mut weight: Option<&mut RgbMut<'_>>,
        a: usize,
        m: usize,
    ) {
        // As the scalar path: u's components swapped, refused outside [0, 1].
        let mut ok = [false; CHUNK];
        let mut us = [[0.0; CHUNK]; 2];
        for l in 0..CHUNK {
            let (x, y) = (u[1][l], u[0][l]);
            ok[l] = p.ok[l] & (x >= 0.0) & (x <= 1.0) & (y >= 0.0) & (y <= 1.0);
            us[0][l] = if x < math::ONE_MINUS_EPSILON {
                x
            } else {
                math::ONE_MINUS_EPSILON
            };
            us[1][l] = if y < math::ONE_MINUS_EPSILON {
                y
            } else {
                math::ONE_MINUS_EPSILON
            };
        }
        let (sample, lum_pdf) = self.sample_dist::<A>(&self.luminance(), p, &us);
        let (u_m, vndf_pdf) = self.sample_dist::<A>(&self.vndf(), p, &sample);
        let mut phi_m = [0.0; CHUNK];
        let mut theta_m = [0.0; CHUNK];
        let add = if self.isotropic {
            p.phi_i
        } else {
            [0.0; CHUNK]
        };
        for l in 0..CHUNK {
            // u2phi is never −0, so adding +0 where the data is anisotropic changes nothing.
            phi_m[l] = u2phi(u_m[1][l]) + add[l];
            theta_m[l] = u2theta(u_m[0][l]);
        }
        let mut sc = [[0.0; CHUNK]; 2];
        let mut st = [[0.0; CHUNK]; 2];
        for l in 0..CHUNK {
            (sc[0][l], sc[1][l]) = math::sin_cos_fast(phi_m[l]);
            (st[0][l], st[1][l]) = math::sin_cos_fast(theta_m[l]);
        }
        for l in 0..CHUNK {
            if !math::sin_cos_fast_covers(phi_m[l]) {
                (sc[0][l], sc[1][l]) = math::sin_cos(phi_m[l]);
            }
            if !math::sin_cos_fast_covers(theta_m[l]) {
                (st[0][l], st[1][l]) = math::sin_cos(theta_m[l]);
            }
        }
        let mut wo = [[0.0; CHUNK]; 3];
        let mut pdf = [0.0; CHUNK];
        for l in 0..CHUNK {
            let (sin_phi, cos_phi) = (sc[0][l], sc[1][l]);
            let (sin_theta, cos_theta) = (st[0][l], st[1][l]);
            let mv = Vec3::new(cos_phi * sin_theta, sin_phi * sin_theta, cos_theta);
            let wi = Vec3::new(p.wi[0][l], p.wi[1][l], p.wi[2][l]);
            let dot = mv.dot(wi);
            pdf[l] = vndf_pdf[l] * lum_pdf[l] / jacobian(u_m[0][l], sin_theta, dot);
            let w = mv * (2.0 * dot) - wi;
            [wo[0][l], wo[1][l], wo[2][l]] = [w.x * p.flip[0][l], w.y * p.flip[1][l], w.z];
            ok[l] &= (wo[2][l] > 0.0) & (pdf[l] > 0.0) & math::is_finite(pdf[l]);
        }
        if let Some(weight) = &mut weight {
            let rgb = self.rgb::<A>(p, &sample, &u_m);
            for l in 0..m {
                let inv_pdf = 1.0 / pdf[l];
                let f = if ok[l] {
                    [
                        math::finite_density(rgb[0][l] * inv_pdf),
                        math::finite_density(rgb[1][l] * inv_pdf),
                        math::finite_density(rgb[2][l] * inv_pdf),
                    ]
                } else {
                    [0.0; 3]
                };
                weight.set(a + l, f);
            }
        }
        for l in 0..m {
            let (w, d) = if ok[l] {
                (Vec3::new(wo[0][l], wo[1][l], wo[2][l]), pdf[l])
            } else {
                (Vec3::ZERO, 0.0)
            };
            out.wo.set(a + l, w);
            out.pdf[a + l] = d;
            out.mis_pdf[a + l] = d;
        }
    }
}

/// The half vectors of a chunk ([`Ctx::half`]).
struct Half {
    m: [Lanes; 3],
    /// Their table coordinates `(u(θm), u(φm))`.
    u_m: [Lanes; 2],
    ok: [bool; CHUNK],
}

#[cfg(test)]
mod tests {
    //! The batched path against the scalar one, bit for bit, on random isotropic and
    //! anisotropic materials with adversarial lanes (the committed RGL files are checked the
    //! same way in `bindings/owned/tests/measured.rs`).

    extern crate std;

    use std::vec::Vec;

    use glam::{Vec2, Vec3};

    use super::super::{MeasuredMaterial, MeasuredShape, MeasuredTables};
    use crate::distrib::marginal2d::build;
    use crate::wavefront::{RgbMut, SamplesMut, Vec2s, Vec3s, Vec3sMut};

    /// A small deterministic generator (xorshift).
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> f32 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 40) as f32 / (1u64 << 24) as f32
        }

        fn values(&mut self, n: usize) -> Vec<f32> {
            (0..n).map(|_| self.next() * self.next() + 0.01).collect()
        }
    }

    /// A random material with `phi` nodes spanning `[0, span]` (`span` = 2π/reduction).
    fn material(n_phi: u32, span: f32, seed: u64) -> MeasuredMaterial<Vec<f32>> {
        let mut r = Rng(seed);
        let n_theta = 5;
        let shape = MeasuredShape {
            n_phi,
            n_theta,
            ndf: [17, 9],
            sigma: [13, 7],
            vndf: [19, 11],
            rgb: [9, 12],
        };
        let s = (n_phi * n_theta) as usize;
        let phi_i = (0..n_phi)
            .map(|i| {
                if n_phi == 1 {
                    0.0
                } else {
                    span * i as f32 / (n_phi - 1) as f32
                }
            })
            .collect();
        let theta_i = (0..n_theta)
            .map(|i| 1.5 * (i as f32 / (n_theta - 1) as f32).powi(2))
            .collect();
        // (values, marginal, conditional) each.
        let vndf = build(&r.values(s * 19 * 11), 19, 11, true);
        let luminance = build(&r.values(s * 9 * 12), 9, 12, true);
        let tables = MeasuredTables::from_array([
            phi_i,
            theta_i,
            r.values(17 * 9),
            r.values(13 * 7),
            vndf.0,
            vndf.1,
            vndf.2,
            luminance.0,
            luminance.1,
            luminance.2,
            r.values(s * 3 * 9 * 12).iter().map(|v| v - 0.02).collect(),
        ]);
        MeasuredMaterial::new(shape, tables, true).unwrap()
    }

    /// Random directions over the sphere (a third below the horizon) with bad ones mixed in.
    fn directions(r: &mut Rng, n: usize) -> Vec<Vec3> {
        let bad = [
            Vec3::ZERO,
            Vec3::new(f32::NAN, 0.0, 1.0),
            Vec3::new(0.0, f32::INFINITY, 1.0),
            Vec3::new(0.3, 0.2, 0.0),
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(-0.0, -0.0, 3.0),
            Vec3::new(1e-30, 0.0, 1e-30),
            Vec3::new(1e30, 1e30, 1e30),
        ];
        (0..n)
            .map(|i| {
                if i % 11 == 5 {
                    return bad[(i / 11) % bad.len()];
                }
                let z = 1.5 * r.next() - 0.5;
                let phi = core::f32::consts::TAU * r.next();
                let s = (1.0 - z * z).max(0.0).sqrt();
                Vec3::new(s * phi.cos(), s * phi.sin(), z) * (0.5 + r.next())
            })
            .collect()
    }

    fn soa(v: &[Vec3]) -> [Vec<f32>; 3] {
        [
            v.iter().map(|d| d.x).collect(),
            v.iter().map(|d| d.y).collect(),
            v.iter().map(|d| d.z).collect(),
        ]
    }

    fn same(a: f32, b: f32) -> bool {
        a.to_bits() == b.to_bits()
    }

    /// `sample_batch`'s directions, densities and weights, and `sample_directions_batch`'s
    /// directions and densities, for the lanes `wi`, `u` (buffers filled with 9 first).
    #[allow(clippy::type_complexity)]
    fn samples(
        m: &MeasuredMaterial<Vec<f32>>,
        wis: Vec3s<'_>,
        u: Vec2s<'_>,
    ) -> ([Vec<f32>; 5], [Vec<f32>; 3], [Vec<f32>; 5]) {
        let n = wis.x.len();
        let mut s = [(); 5].map(|_| vec![9.0; n]);
        let mut w = [vec![9.0; n], vec![9.0; n], vec![9.0; n]];
        {
            let [sx, sy, sz, sp, sm] = &mut s;
            let [wr, wg, wb] = &mut w;
            m.sample_batch(
                wis,
                u,
                SamplesMut {
                    wo: Vec3sMut {
                        x: sx,
                        y: sy,
                        z: sz,
                    },
                    pdf: sp,
                    mis_pdf: sm,
                },
                RgbMut {
                    r: wr,
                    g: wg,
                    b: wb,
                },
            )
            .unwrap();
        }
        // Without the weights: the same directions and densities.
        let mut d = [(); 5].map(|_| vec![9.0; n]);
        {
            let [dx, dy, dz, dp, dm] = &mut d;
            m.sample_directions_batch(
                wis,
                u,
                SamplesMut {
                    wo: Vec3sMut {
                        x: dx,
                        y: dy,
                        z: dz,
                    },
                    pdf: dp,
                    mis_pdf: dm,
                },
            )
            .unwrap();
        }
        (s, w, d)
    }

    fn check(m: &MeasuredMaterial<Vec<f32>>, seed: u64) {
        let mut r = Rng(seed);
        let n = 1000;
        let wi = directions(&mut r, n);
        let wo = directions(&mut r, n);
        let u: Vec<Vec2> = (0..n)
            .map(|i| match i % 13 {
                3 => Vec2::new(f32::NAN, 0.5),
                4 => Vec2::new(1.0, 1.0),
                5 => Vec2::new(0.0, 0.0),
                6 => Vec2::new(-0.5, 0.5),
                _ => Vec2::new(r.next(), r.next()),
            })
            .collect();
        let [ix, iy, iz] = soa(&wi);
        let [ox, oy, oz] = soa(&wo);
        let ux: Vec<f32> = u.iter().map(|v| v.x).collect();
        let uy: Vec<f32> = u.iter().map(|v| v.y).collect();
        let wis = Vec3s {
            x: &ix,
            y: &iy,
            z: &iz,
        };
        let wos = Vec3s {
            x: &ox,
            y: &oy,
            z: &oz,
        };
        let mut rgb = [vec![9.0; n], vec![9.0; n], vec![9.0; n]];
        let [r0, g0, b0] = &mut rgb;
        m.eval_batch(
            wis,
            wos,
            RgbMut {
                r: r0,
                g: g0,
                b: b0,
            },
        )
        .unwrap();
        let mut pdf = vec![9.0; n];
        m.pdf_batch(wis, wos, &mut pdf).unwrap();
        let (s, w, d) = samples(m, wis, Vec2s { x: &ux, y: &uy });
        for (k, (a, b)) in d.iter().zip(&s).enumerate() {
            for i in 0..n {
                assert!(
                    same(a[i], b[i]),
                    "lane {i} directions {k}: {} vs {}",
                    a[i],
                    b[i]
                );
            }
        }
        let mut sampled = 0;
        for i in 0..n {
            let p = m.prepare(wi[i]);
            let f = p.as_ref().map_or([0.0; 3], |p| p.eval(wo[i]));
            let d = p.as_ref().map_or(0.0, |p| p.pdf(wo[i]));
            let smp = p.as_ref().and_then(|p| p.sample(u[i]));
            for c in 0..3 {
                assert!(
                    same(rgb[c][i], f[c]),
                    "lane {i} eval {c}: {} vs {}",
                    rgb[c][i],
                    f[c]
                );
            }
            assert!(same(pdf[i], d), "lane {i} pdf: {} vs {d}", pdf[i]);
            let (wo_s, pdf_s, w_s) = smp.map_or((Vec3::ZERO, 0.0, [0.0; 3]), |s| {
                sampled += 1;
                (s.wo, s.pdf, s.weight)
            });
            let got = [
                s[0][i], s[1][i], s[2][i], s[3][i], s[4][i], w[0][i], w[1][i], w[2][i],
            ];
            // The data's sampler draws from its pdf: its MIS density is its density.
            let want = [wo_s.x, wo_s.y, wo_s.z, pdf_s, pdf_s, w_s[0], w_s[1], w_s[2]];
            for k in 0..8 {
                assert!(
                    same(got[k], want[k]),
                    "lane {i} sample {k}: {got:?} vs {want:?}"
                );
            }
        }
        assert!(sampled > n / 4, "only {sampled} samples");
    }

    /// `prepare_copied` over `&[f32]` views of tables padded with junk (as GPU buffers are)
    /// and built by `new_unchecked` gives `prepare`'s numbers bit for bit: the counts come
    /// from the shape.
    fn check_copied(m: &MeasuredMaterial<Vec<f32>>, seed: u64) {
        use crate::Prepared;
        let padded: Vec<Vec<f32>> = m
            .tables()
            .as_array()
            .iter()
            .map(|t| {
                let mut v = t.to_vec();
                v.extend([7.0, -3.0, f32::NAN, 1e30]);
                v
            })
            .collect();
        let views: [&[f32]; 11] = core::array::from_fn(|i| padded[i].as_slice());
        let g = MeasuredMaterial::new_unchecked(
            *m.shape(),
            MeasuredTables::from_array(views),
            m.jacobian(),
        );
        let mut r = Rng(seed);
        let n = 1000;
        let wi = directions(&mut r, n);
        let wo = directions(&mut r, n);
        let mut sampled = 0;
        for i in 0..n {
            let (a, b) = (m.prepare(wi[i]), g.prepare_copied(wi[i]));
            assert_eq!(a.is_some(), b.is_some(), "lane {i}");
            let (Some(a), Some(b)) = (a, b) else {
                continue;
            };
            let u = Vec2::new(r.next(), r.next());
            let bits = |v: [f32; 3]| v.map(f32::to_bits);
            assert_eq!(bits(a.eval(wo[i])), bits(b.eval(wo[i])), "lane {i}");
            assert_eq!(bits(a.eval_cos(wo[i])), bits(b.eval_cos(wo[i])), "lane {i}");
            assert_eq!(a.pdf(wo[i]).to_bits(), b.pdf(wo[i]).to_bits(), "lane {i}");
            let p = Vec2::new(wo[i].x, wo[i].y) * 0.7;
            assert_eq!(a.pdf_disk(p).to_bits(), b.pdf_disk(p).to_bits(), "lane {i}");
            let (sa, sb) = (a.sample(u), b.sample(u));
            assert_eq!(sa, sb, "lane {i}");
            sampled += usize::from(sa.is_some());
        }
        assert!(sampled > n / 4, "only {sampled} samples");
    }

    #[test]
    fn copied_handles_on_padded_tables_are_borrowed_bit_for_bit() {
        let pi = core::f32::consts::PI;
        check_copied(&material(1, 0.0, 7), 5);
        check_copied(&material(2, pi, 8), 6);
        check_copied(&material(3, pi, 9), 7);
        check_copied(&material(4, pi / 2.0, 10), 8);
    }

    #[test]
    fn batched_is_scalar_bit_for_bit() {
        let pi = core::f32::consts::PI;
        check(&material(1, 0.0, 7), 1);
        // Two φi nodes: isotropic data blending two slices.
        check(&material(2, pi, 8), 2);
        // Anisotropic halves and quarters (folded azimuths).
        check(&material(3, pi, 9), 3);
        check(&material(4, pi / 2.0, 10), 4);
    }
}
