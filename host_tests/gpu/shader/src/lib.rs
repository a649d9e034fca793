//! Compute-shader entry points around `neusample`'s samplers (rust-gpu → SPIR-V).
//!
//! Every entry point is a thin wrapper: it reads one condition (φ, wi), one random pair `u`
//! and one extra direction `wo2` from the input buffer, runs core's
//! `prepare → sample → pdf`, and writes the results to the output buffer. The same
//! wrapper ([`kernel::run`]) is compiled for the host and used by the runner as the CPU
//! reference, so the comparison exercises core's code on both sides.
//!
//! Buffer layouts (all flat `f32`, one record per invocation):
//!
//! ```text
//! input  [IN_STRIDE = 16]:  φ0..φ7 | wi.x wi.y wi.z | u0 u1 | wo2.x wo2.y wo2.z
//! output [OUT_STRIDE = 12]: wo.x wo.y wo.z | pdf | pdf_disk | flags | pdf(wo2) | pdf(wo)
//!                           | invert(wo2).x invert(wo2).y | pdf_disk(wo2⊥) | 0
//! ```
//!
//! `flags` = 1 (prepared) + 2 (sampled) + 4 (`invert(wo2)` is `Some`), stored as an exact
//! small float. `pdf`/`pdf_disk` are the sample's solid-angle / projected-disk densities;
//! `pdf(wo)` re-evaluates `Prepared::pdf` at the sampled direction (equal to `pdf` but for
//! the reparameterization sampler, whose pdf is its pdf network's);
//! `pdf(wo2)` is the density of an unrelated direction, as MIS needs.
//!
//! The measured material's entry point (`measured`) reads [`kernel::run`]'s input records
//! (φ unused) and writes its own output record:
//!
//! ```text
//! output [12]: wo.x wo.y wo.z | pdf | pdf(wo2) | flags | f(wo2) rgb | weight rgb
//! ```
//!
//! The neural material's entry points (`neural_features`, `neural_eval`) use the same
//! strides with their own record layout:
//!
//! ```text
//! input  [16]: φ0..φ7 | wi.x wi.y wi.z | wo.x wo.y wo.z | u v
//! neural_features output [12]: φ(uv)0..7 | 0 0 0 0
//! neural_eval     output [12]: eval(φ, wi, wo) rgb | eval(φ(uv), wi, wo) rgb | 0 … 0
//! ```
#![cfg_attr(target_arch = "spirv", no_std)]
#![deny(missing_docs)]

pub mod kernel;

use kernel::{Params, IN_STRIDE, OUT_STRIDE};
pub use spirv_std::glam::UVec3;
use spirv_std::spirv;

/// Invocations per workgroup of every entry point (the host dispatches `⌈n / 64⌉` groups).
pub const WORKGROUP_SIZE: u32 = 64;

/// Cosine-hemisphere sampling (no weights).
#[spirv(compute(threads(64)))]
pub fn cosine(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(push_constant)] params: &Params,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] input: &[f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] output: &mut [f32],
) {
    let i = id.x;
    if i < params.n && kernel::in_range(i, input.len(), output.len()) {
        kernel::run(&neusample::samplers::CosineSampler, i, input, output);
    }
}

/// An entry point for a sampler built from one flat weight buffer at binding 2.
macro_rules! weighted_entry {
    ($(#[$doc:meta])* $name:ident, $sampler:ident) => {
        $(#[$doc])*
        #[spirv(compute(threads(64)))]
        pub fn $name(
            #[spirv(global_invocation_id)] id: UVec3,
            #[spirv(push_constant)] params: &Params,
            #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] input: &[f32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] output: &mut [f32],
            #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] weights: &[f32],
        ) {
            let i = id.x;
            if i < params.n && kernel::in_range(i, input.len(), output.len()) {
                let s = neusample::samplers::$sampler::new_unchecked(weights);
                kernel::run(&s, i, input, output);
            }
        }
    };
}

weighted_entry!(
    /// Improved baseline: Lambert + isotropic Gaussian (paper Eq. 1).
    baseline,
    ImprovedBaselineSampler
);
weighted_entry!(
    /// Analytic mixture: Lambert + two anisotropic Gaussians (paper Eq. 2).
    analytic,
    AnalyticMixtureSampler
);
weighted_entry!(
    /// Direct 16 × 16 histogram baseline (Zhu et al. 2021).
    direct_histogram,
    DirectHistogramSampler
);
weighted_entry!(
    /// Conditional rational-quadratic spline flow (paper Eq. 3–4).
    flow,
    SplineFlowSampler
);
weighted_entry!(
    /// Affine-coupling flow baseline (Xie et al. 2019).
    affine_flow,
    AffineFlowSampler
);

weighted_entry!(
    /// Reparameterization sampler: warp MLP with its Jacobian weight, pdf network for MIS.
    reparam,
    ReparamSampler
);

weighted_entry!(
    /// Disk flow: the flow's two spline couplings on chords of the disk over a uniform base.
    disk_flow,
    DiskFlowSampler
);

/// The defensive weight of [`defensive_flow`] (a blob's α on a host; a constant here).
pub const DEFENSIVE_ALPHA: f32 = 0.25;

/// The spline flow mixed with cosine sampling at weight [`DEFENSIVE_ALPHA`]
/// (`neusample::Defensive`: one uniform picks the part, both parts give the density).
#[spirv(compute(threads(64)))]
pub fn defensive_flow(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(push_constant)] params: &Params,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] input: &[f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] output: &mut [f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] weights: &[f32],
) {
    let i = id.x;
    if i < params.n && kernel::in_range(i, input.len(), output.len()) {
        let s = neusample::Defensive::new_unchecked(
            neusample::samplers::SplineFlowSampler::new_unchecked(weights),
            DEFENSIVE_ALPHA,
        );
        kernel::run(&s, i, input, output);
    }
}

/// The reparameterization sampler mixed with cosine sampling at weight [`DEFENSIVE_ALPHA`]
/// (one-sample MIS over its pdf network: `neusample::Defensive`).
#[spirv(compute(threads(64)))]
pub fn defensive_reparam(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(push_constant)] params: &Params,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] input: &[f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] output: &mut [f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] weights: &[f32],
) {
    let i = id.x;
    if i < params.n && kernel::in_range(i, input.len(), output.len()) {
        let s = neusample::Defensive::new_unchecked(
            neusample::samplers::ReparamSampler::new_unchecked(weights),
            DEFENSIVE_ALPHA,
        );
        kernel::run(&s, i, input, output);
    }
}

/// Histogram mixture (paper Eq. 5–6): network weights at binding 2, baked tables `mass`,
/// `table`, `marginal`, `conditional` at 3–6; T, N and the interpolation in the push
/// constants.
#[spirv(compute(threads(64)))]
#[allow(clippy::too_many_arguments)] // one argument per binding
pub fn histogram_mixture(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(push_constant)] params: &Params,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] input: &[f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] output: &mut [f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] weights: &[f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] mass: &[f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] table: &[f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] marginal: &[f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] conditional: &[f32],
) {
    let i = id.x;
    if i < params.n && kernel::in_range(i, input.len(), output.len()) {
        let interpolation = if params.interpolate != 0 {
            neusample::Interpolation::Linear
        } else {
            neusample::Interpolation::Nearest
        };
        let s = neusample::samplers::HistogramMixtureSampler::new_unchecked(
            weights,
            mass,
            table,
            marginal,
            conditional,
            params.levels,
            params.cells,
            interpolation,
        );
        kernel::run(&s, i, input, output);
    }
}

/// Neural material (NeuMIP-style BRDF, `ARCHITECTURES.md` §7): `features(uv)` of every
/// record. Feature texture at binding 2, decoder parameters at 3 (unused here, bound for a
/// common layout); texture size in the push constants.
#[spirv(compute(threads(64)))]
pub fn neural_features(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(push_constant)] params: &Params,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] input: &[f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] output: &mut [f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] texture: &[f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] decoder: &[f32],
) {
    let i = id.x;
    if i < params.n && kernel::in_range(i, input.len(), output.len()) {
        let m =
            neusample::NeuralMaterial::new_unchecked(texture, decoder, params.width, params.height);
        kernel::run_features(&m, i, input, output);
    }
}

/// Neural material: `eval(φ, wi, wo)` and `eval(features(uv), wi, wo)` of every record.
/// Bindings and push constants as [`neural_features`].
#[spirv(compute(threads(64)))]
pub fn neural_eval(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(push_constant)] params: &Params,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] input: &[f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] output: &mut [f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] texture: &[f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] decoder: &[f32],
) {
    let i = id.x;
    if i < params.n && kernel::in_range(i, input.len(), output.len()) {
        let m =
            neusample::NeuralMaterial::new_unchecked(texture, decoder, params.width, params.height);
        kernel::run_eval(&m, i, input, output);
    }
}

/// Measured material (RGL data, Mitsuba 3's `measured`): `eval(wo2)`, `pdf(wo2)` and the data's
/// own sampler of every record (`kernel::run_measured`). The eleven tables at bindings 2–12
/// in `MeasuredTables` order (`phi_i`, `theta_i`, `ndf`, `sigma`, `vndf`, `vndf_marginal`,
/// `vndf_conditional`, `luminance`, `luminance_marginal`, `luminance_conditional`, `rgb`);
/// their shape and the `jacobian` flag in the push constants.
#[spirv(compute(threads(64)))]
#[allow(clippy::too_many_arguments)] // one argument per binding
pub fn measured(
    #[spirv(global_invocation_id)] id: UVec3,
    #[spirv(push_constant)] params: &Params,
    #[spirv(storage_buffer, descriptor_set = 0, binding = 0)] input: &[f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 1)] output: &mut [f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 2)] phi_i: &[f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 3)] theta_i: &[f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 4)] ndf: &[f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 5)] sigma: &[f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 6)] vndf: &[f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 7)] vndf_marginal: &[f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 8)] vndf_conditional: &[f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 9)] luminance: &[f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 10)] luminance_marginal: &[f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 11)] luminance_conditional: &[f32],
    #[spirv(storage_buffer, descriptor_set = 0, binding = 12)] rgb: &[f32],
) {
    let i = id.x;
    if i < params.n && kernel::in_range(i, input.len(), output.len()) {
        let tables = neusample::MeasuredTables {
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
        };
        let m = neusample::MeasuredMaterial::new_unchecked(
            params.measured_shape(),
            tables,
            params.jacobian != 0,
        );
        kernel::run_measured(&m, i, input, output);
    }
}

// Keep the strides referenced on every target (they document the layout above).
const _: () = assert!(IN_STRIDE == 16 && OUT_STRIDE == 12);
