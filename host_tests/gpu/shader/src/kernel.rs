//! The per-invocation work, shared by the SPIR-V entry points and the host reference.
//!
//! Written in the subset rust-gpu accepts: index loops, fixed-size arrays, no iterators, no
//! sub-slices. Indices are checked by [`in_range`] before [`run`] is called.

use neusample::neural_material::DECODER_OUTPUTS;
use neusample::{
    MeasuredMaterial, MeasuredShape, NeuralMaterial, Prepared, Sampler, Vec2, Vec3, Weights,
    FEATURE_DIM,
};

/// Floats per input record: φ (8), wi (3), u (2), wo2 (3).
pub const IN_STRIDE: usize = 16;
/// Floats per output record: wo (3), pdf, pdf_disk, flags, pdf(wo2), pdf(wo), invert(wo2) (2),
/// pdf_disk(wo2⊥), 0.
pub const OUT_STRIDE: usize = 12;

/// Offset of `wi` in an input record.
pub const IN_WI: usize = FEATURE_DIM;
/// Offset of `u` in an input record.
pub const IN_U: usize = FEATURE_DIM + 3;
/// Offset of `wo2` in an input record.
pub const IN_WO2: usize = FEATURE_DIM + 5;

/// `flags` bit: `prepare` returned `Some`.
pub const FLAG_PREPARED: u32 = 1;
/// `flags` bit: `sample` returned `Some`.
pub const FLAG_SAMPLED: u32 = 2;
/// `flags` bit: `invert(wo2)` returned `Some`.
pub const FLAG_INVERTED: u32 = 4;

/// Push constants shared by every entry point.
#[derive(Copy, Clone, Debug, Default)]
#[repr(C)]
pub struct Params {
    /// Number of records.
    pub n: u32,
    /// Histogram mixture: number of latent levels T.
    pub levels: u32,
    /// Histogram mixture: cells per side N.
    pub cells: u32,
    /// Histogram mixture: 1 = linear interpolation between levels, 0 = nearest level.
    pub interpolate: u32,
    /// Neural material: feature-texture width (texels along u).
    pub width: u32,
    /// Neural material: feature-texture height (texels along v).
    pub height: u32,
    /// Measured material: number of `φi` nodes.
    pub n_phi: u32,
    /// Measured material: number of `θi` nodes.
    pub n_theta: u32,
    /// Measured material: NDF table width.
    pub ndf_w: u32,
    /// Measured material: NDF table height.
    pub ndf_h: u32,
    /// Measured material: projected-area table width.
    pub sigma_w: u32,
    /// Measured material: projected-area table height.
    pub sigma_h: u32,
    /// Measured material: VNDF slice width.
    pub vndf_w: u32,
    /// Measured material: VNDF slice height.
    pub vndf_h: u32,
    /// Measured material: luminance and RGB slice width.
    pub rgb_w: u32,
    /// Measured material: luminance and RGB slice height.
    pub rgb_h: u32,
    /// Measured material: 1 when the RGB values are multiplied by `D/(4σ)`.
    pub jacobian: u32,
}

impl Params {
    /// The measured material's table sizes.
    #[must_use]
    pub fn measured_shape(&self) -> MeasuredShape {
        MeasuredShape {
            n_phi: self.n_phi,
            n_theta: self.n_theta,
            ndf: [self.ndf_w, self.ndf_h],
            sigma: [self.sigma_w, self.sigma_h],
            vndf: [self.vndf_w, self.vndf_h],
            rgb: [self.rgb_w, self.rgb_h],
        }
    }
}

/// `true` when record `i` lies inside both buffers (lengths in floats).
#[inline]
#[must_use]
pub fn in_range(i: u32, input_len: usize, output_len: usize) -> bool {
    let i = i as usize;
    (i + 1) * IN_STRIDE <= input_len && (i + 1) * OUT_STRIDE <= output_len
}

/// The incident direction, the sample's variates and the second direction of the record at
/// `b` of `input`.
fn directions(input: &[f32], b: usize) -> (Vec3, Vec2, Vec3) {
    let wi = Vec3::new(input[b + IN_WI], input[b + IN_WI + 1], input[b + IN_WI + 2]);
    let u = Vec2::new(input[b + IN_U], input[b + IN_U + 1]);
    let wo2 = Vec3::new(
        input[b + IN_WO2],
        input[b + IN_WO2 + 1],
        input[b + IN_WO2 + 2],
    );
    (wi, u, wo2)
}

/// Runs sampler `s` on record `i`: prepare, sample, and the densities; writes the output
/// record. The caller guarantees [`in_range`].
#[inline]
pub fn run<S: Sampler>(s: &S, i: u32, input: &[f32], output: &mut [f32]) {
    let b = i as usize * IN_STRIDE;
    let mut phi = [0.0f32; FEATURE_DIM];
    let mut k = 0;
    while k < FEATURE_DIM {
        phi[k] = input[b + k];
        k += 1;
    }
    let (wi, u, wo2) = directions(input, b);

    let mut rec = [0.0f32; OUT_STRIDE];
    let mut flags = 0u32;
    if let Some(p) = s.prepare(&phi, wi) {
        flags |= FLAG_PREPARED;
        rec[6] = p.pdf(wo2);
        rec[10] = p.pdf_disk(Vec2::new(wo2.x, wo2.y));
        if let Some(v) = p.invert(wo2) {
            flags |= FLAG_INVERTED;
            rec[8] = v.x;
            rec[9] = v.y;
        }
        if let Some(smp) = p.sample(u) {
            flags |= FLAG_SAMPLED;
            rec[0] = smp.wo.x;
            rec[1] = smp.wo.y;
            rec[2] = smp.wo.z;
            rec[3] = smp.pdf;
            rec[4] = smp.pdf_disk;
            rec[7] = p.pdf(smp.wo);
        }
    }
    rec[5] = flags as f32;

    let o = i as usize * OUT_STRIDE;
    let mut k = 0;
    while k < OUT_STRIDE {
        output[o + k] = rec[k];
        k += 1;
    }
}

/// Neural-material input record (same [`IN_STRIDE`]): offset of φ (8 values, the condition
/// of `eval`).
pub const NM_IN_PHI: usize = 0;
/// Neural-material input record: offset of `wi`.
pub const NM_IN_WI: usize = FEATURE_DIM;
/// Neural-material input record: offset of `wo`.
pub const NM_IN_WO: usize = FEATURE_DIM + 3;
/// Neural-material input record: offset of `uv`.
pub const NM_IN_UV: usize = FEATURE_DIM + 6;
/// `neural_eval` output record: offset of `eval(φ, wi, wo)` (RGB).
pub const NM_OUT_EVAL: usize = 0;
/// `neural_eval` output record: offset of `eval(features(uv), wi, wo)` (RGB).
pub const NM_OUT_EVAL_UV: usize = DECODER_OUTPUTS;

/// `NeuralMaterial::features` of record `i`'s `uv`: writes the 8 features to the start of
/// output record `i` (the rest of the record is zero). The caller guarantees [`in_range`].
#[inline]
pub fn run_features<W: Weights>(m: &NeuralMaterial<W>, i: u32, input: &[f32], output: &mut [f32]) {
    let b = i as usize * IN_STRIDE;
    let uv = Vec2::new(input[b + NM_IN_UV], input[b + NM_IN_UV + 1]);
    let phi = m.features(uv);
    let mut rec = [0.0f32; OUT_STRIDE];
    let mut k = 0;
    while k < FEATURE_DIM {
        rec[k] = phi[k];
        k += 1;
    }
    write_record(i, &rec, output);
}

/// `NeuralMaterial::eval(φ, wi, wo)` of record `i` (RGB at [`NM_OUT_EVAL`]) and
/// `eval(features(uv), wi, wo)` (the renderer's path, at [`NM_OUT_EVAL_UV`]). The caller
/// guarantees [`in_range`].
#[inline]
pub fn run_eval<W: Weights>(m: &NeuralMaterial<W>, i: u32, input: &[f32], output: &mut [f32]) {
    let b = i as usize * IN_STRIDE;
    let mut phi = [0.0f32; FEATURE_DIM];
    let mut k = 0;
    while k < FEATURE_DIM {
        phi[k] = input[b + NM_IN_PHI + k];
        k += 1;
    }
    let wi = Vec3::new(
        input[b + NM_IN_WI],
        input[b + NM_IN_WI + 1],
        input[b + NM_IN_WI + 2],
    );
    let wo = Vec3::new(
        input[b + NM_IN_WO],
        input[b + NM_IN_WO + 1],
        input[b + NM_IN_WO + 2],
    );
    let uv = Vec2::new(input[b + NM_IN_UV], input[b + NM_IN_UV + 1]);
    let f = m.eval(&phi, wi, wo);
    let f_uv = m.eval_uv(uv, wi, wo);
    let mut rec = [0.0f32; OUT_STRIDE];
    let mut c = 0;
    while c < DECODER_OUTPUTS {
        rec[NM_OUT_EVAL + c] = f[c];
        rec[NM_OUT_EVAL_UV + c] = f_uv[c];
        c += 1;
    }
    write_record(i, &rec, output);
}

/// Copies `rec` to output record `i`.
#[inline]
fn write_record(i: u32, rec: &[f32; OUT_STRIDE], output: &mut [f32]) {
    let o = i as usize * OUT_STRIDE;
    let mut k = 0;
    while k < OUT_STRIDE {
        output[o + k] = rec[k];
        k += 1;
    }
}

/// `measured` output record: offset of the sampled `wo` (0 when not sampled).
pub const MS_OUT_WO: usize = 0;
/// `measured` output record: the sample's solid-angle density.
pub const MS_OUT_PDF: usize = 3;
/// `measured` output record: the solid-angle density at `wo2`.
pub const MS_OUT_PDF_WO2: usize = 4;
/// `measured` output record: `f(wi, wo2)` (RGB, no cosine).
pub const MS_OUT_EVAL: usize = 6;
/// `measured` output record: the sample's weight `f·cos θo / pdf` (RGB).
pub const MS_OUT_WEIGHT: usize = 9;

/// The measured material on record `i` (input as [`run`]'s, φ unused): prepare at `wi`
/// (`prepare_copied`, as a shader must), `pdf(wo2)` and `eval(wo2)`, and a sample from `u`
/// (direction, density, weight). Output: `wo | pdf | pdf(wo2) | flags | f(wo2) rgb |
/// weight rgb` (flags at 5 as [`run`]'s). The caller guarantees [`in_range`].
#[inline]
pub fn run_measured<W: Weights + Copy>(
    m: &MeasuredMaterial<W>,
    i: u32,
    input: &[f32],
    output: &mut [f32],
) {
    let b = i as usize * IN_STRIDE;
    let (wi, u, wo2) = directions(input, b);
    let mut rec = [0.0f32; OUT_STRIDE];
    let mut flags = 0u32;
    if let Some(p) = m.prepare_copied(wi) {
        flags |= FLAG_PREPARED;
        rec[MS_OUT_PDF_WO2] = p.pdf(wo2);
        let f = p.eval(wo2);
        let mut c = 0;
        while c < 3 {
            rec[MS_OUT_EVAL + c] = f[c];
            c += 1;
        }
        if let Some(s) = p.sample(u) {
            flags |= FLAG_SAMPLED;
            rec[MS_OUT_WO] = s.wo.x;
            rec[MS_OUT_WO + 1] = s.wo.y;
            rec[MS_OUT_WO + 2] = s.wo.z;
            rec[MS_OUT_PDF] = s.pdf;
            let mut c = 0;
            while c < 3 {
                rec[MS_OUT_WEIGHT + c] = s.weight[c];
                c += 1;
            }
        }
    }
    rec[5] = flags as f32;
    write_record(i, &rec, output);
}
