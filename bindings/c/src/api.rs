//! The safe bodies of the entry points: references and slices in, `Result` out. `ffi` checks
//! the pointers and calls these.

use std::path::Path;

use neusample::wavefront::{
    BatchSampler, BlobLane, Features, FeaturesMut, LaneState, RgbMut, SamplesMut, Vec2s, Vec3s,
    Vec3sMut,
};
use neusample::{BlobWriter, Prepared, Sampler, Vec2, Vec3, FEATURE_DIM};
use neusample_owned::measured::OwnedMeasured;
use neusample_owned::{measured_label, OwnedMeasuredBlob};

use crate::error::CallError;
use crate::types::{
    NsMeasured, NsMeasuredSample, NsPhi, NsPrepared, NsRgb, NsSample, NsSampler, NsVec2, NsVec3,
};

pub(crate) fn vec3(v: NsVec3, what: &'static str) -> Result<Vec3, CallError> {
    let w = Vec3::new(v.x, v.y, v.z);
    if w.is_finite() {
        Ok(w)
    } else {
        Err(CallError::NotFinite(what))
    }
}

pub(crate) fn vec2(v: NsVec2, what: &'static str) -> Result<Vec2, CallError> {
    let w = Vec2::new(v.x, v.y);
    if w.is_finite() {
        Ok(w)
    } else {
        Err(CallError::NotFinite(what))
    }
}

pub(crate) fn phi(p: &NsPhi) -> Result<[f32; FEATURE_DIM], CallError> {
    if p.v.iter().all(|x| x.is_finite()) {
        Ok(p.v)
    } else {
        Err(CallError::NotFinite("phi"))
    }
}

fn ns_vec3(v: Vec3) -> NsVec3 {
    NsVec3 {
        x: v.x,
        y: v.y,
        z: v.z,
    }
}

/// Prepare + sample in one call (the scalar API).
pub(crate) fn sample(
    s: &NsSampler,
    phi: &[f32; FEATURE_DIM],
    wi: Vec3,
    u: Vec2,
    out: &mut NsSample,
) -> Result<(), CallError> {
    *out = NsSample::default();
    let p = s.0.get().prepare(phi, wi).ok_or(CallError::Refused)?;
    let smp = p.sample(u).ok_or(CallError::Refused)?;
    *out = NsSample {
        wo: ns_vec3(smp.wo),
        pdf: smp.pdf,
        mis_pdf: smp.mis_pdf,
    };
    Ok(())
}

/// Prepare + pdf in one call (the scalar API).
pub(crate) fn pdf(
    s: &NsSampler,
    phi: &[f32; FEATURE_DIM],
    wi: Vec3,
    wo: Vec3,
    out: &mut f32,
) -> Result<(), CallError> {
    *out = 0.0;
    let p = s.0.get().prepare(phi, wi).ok_or(CallError::Refused)?;
    *out = p.pdf(wo);
    Ok(())
}

/// One-lane views of a scalar condition, for the lane-based prepared state.
fn one<const N: usize>(v: &[f32; N]) -> [&[f32]; N] {
    core::array::from_fn(|i| core::slice::from_ref(&v[i]))
}

fn sampler_id(s: &NsSampler) -> usize {
    s as *const NsSampler as usize
}

fn check_owner(s: &NsSampler, p: &NsPrepared) -> Result<(), CallError> {
    if p.owner == sampler_id(s) {
        Ok(())
    } else {
        Err(CallError::Invalid(
            "this NsPrepared was not prepared by this sampler (call ns_prepare first)".into(),
        ))
    }
}

pub(crate) fn prepare(
    s: &NsSampler,
    phi: &[f32; FEATURE_DIM],
    wi: Vec3,
    p: &mut NsPrepared,
) -> Result<(), CallError> {
    let channels = one(phi);
    let w = [wi.x, wi.y, wi.z];
    let [x, y, z] = one(&w);
    let mut lane = [BlobLane::default()];
    s.0.get()
        .prepare_batch(Features { channels }, Vec3s { x, y, z }, &mut lane)?;
    p.lane = lane[0];
    p.owner = sampler_id(s);
    if p.lane.is_prepared() {
        Ok(())
    } else {
        Err(CallError::Refused)
    }
}

pub(crate) fn prepared_sample(
    s: &NsSampler,
    p: &NsPrepared,
    u: Vec2,
    out: &mut NsSample,
) -> Result<(), CallError> {
    check_owner(s, p)?;
    *out = NsSample::default();
    let (ux, uy) = ([u.x], [u.y]);
    let [mut x, mut y, mut z, mut pdf, mut mis] = [[0.0f32]; 5];
    let dst = SamplesMut {
        wo: Vec3sMut {
            x: &mut x,
            y: &mut y,
            z: &mut z,
        },
        pdf: &mut pdf,
        mis_pdf: &mut mis,
    };
    s.0.get().sample_batch(
        core::slice::from_ref(&p.lane),
        Vec2s { x: &ux, y: &uy },
        dst,
    )?;
    if !(pdf[0] > 0.0) {
        return Err(CallError::Refused);
    }
    *out = NsSample {
        wo: NsVec3 {
            x: x[0],
            y: y[0],
            z: z[0],
        },
        pdf: pdf[0],
        mis_pdf: mis[0],
    };
    Ok(())
}

pub(crate) fn prepared_pdf(
    s: &NsSampler,
    p: &NsPrepared,
    wo: Vec3,
    out: &mut f32,
) -> Result<(), CallError> {
    check_owner(s, p)?;
    let w = [wo.x, wo.y, wo.z];
    let [x, y, z] = one(&w);
    let mut pdf = [0.0f32];
    s.0.get()
        .pdf_batch(core::slice::from_ref(&p.lane), Vec3s { x, y, z }, &mut pdf)?;
    *out = pdf[0];
    Ok(())
}

pub(crate) fn sample_batch(
    s: &NsSampler,
    phi: Features<'_>,
    wi: Vec3s<'_>,
    u: Vec2s<'_>,
    out: SamplesMut<'_>,
) -> Result<(), CallError> {
    Ok(s.0.get().sample_fused(phi, wi, u, out)?)
}

pub(crate) fn pdf_batch(
    s: &NsSampler,
    phi: Features<'_>,
    wi: Vec3s<'_>,
    wo: Vec3s<'_>,
    pdf: &mut [f32],
) -> Result<(), CallError> {
    Ok(s.0.get().pdf_fused(phi, wi, wo, pdf)?)
}

pub(crate) fn features(m: &crate::types::NsMaterial, uv: Vec2) -> [f32; FEATURE_DIM] {
    m.0.get().features(uv)
}

pub(crate) fn eval(
    m: &crate::types::NsMaterial,
    phi: &[f32; FEATURE_DIM],
    wi: Vec3,
    wo: Vec3,
) -> NsRgb {
    let [r, g, b] = m.0.get().eval(phi, wi, wo);
    NsRgb { r, g, b }
}

pub(crate) fn features_batch(
    m: &crate::types::NsMaterial,
    uv: Vec2s<'_>,
    phi: FeaturesMut<'_>,
) -> Result<(), CallError> {
    Ok(m.0.get().features_batch(uv, phi)?)
}

pub(crate) fn eval_batch(
    m: &crate::types::NsMaterial,
    phi: Features<'_>,
    wi: Vec3s<'_>,
    wo: Vec3s<'_>,
    out: RgbMut<'_>,
) -> Result<(), CallError> {
    Ok(m.0.get().eval_batch(phi, wi, wo, out)?)
}

/// The measured material of the `.bsdf` file at `path`, held as the blob `neusample
/// measured-blob` writes from it (labelled with the file's stem and name), so that both
/// constructors give one handle type with the same values.
pub(crate) fn measured_open_bsdf(path: &str) -> Result<NsMeasured, CallError> {
    let bytes = std::fs::read(path).map_err(|e| CallError::Io(format!("{path}: {e}")))?;
    let data = OwnedMeasured::from_bytes(&bytes).map_err(|mut e| {
        e.file = Some(path.to_string());
        CallError::MeasuredFile(e)
    })?;
    let file = Path::new(path);
    let text = |s: Option<&std::ffi::OsStr>| {
        s.map_or_else(String::new, |s| s.to_string_lossy().into_owned())
    };
    let label = measured_label(
        &text(file.file_stem()),
        &text(file.file_name()),
        data.description(),
    );
    let blob = BlobWriter::measured(data.material(), &label).to_bytes();
    Ok(NsMeasured(OwnedMeasuredBlob::from_bytes(&blob)?))
}

/// The measured BRDF without the cosine; 0 where `wi` or `wo` is at or below the horizon.
pub(crate) fn measured_eval(m: &NsMeasured, wi: Vec3, wo: Vec3) -> NsRgb {
    let [r, g, b] = m.0.get().prepare(wi).map_or([0.0; 3], |p| p.eval(wo));
    NsRgb { r, g, b }
}

/// The measured sampler's solid-angle density of `wo` at `wi` (refused: `wi` at or below the
/// horizon).
pub(crate) fn measured_pdf(
    m: &NsMeasured,
    wi: Vec3,
    wo: Vec3,
    out: &mut f32,
) -> Result<(), CallError> {
    *out = 0.0;
    let p = m.0.get().prepare(wi).ok_or(CallError::Refused)?;
    *out = p.pdf(wo);
    Ok(())
}

/// One direction from the measured material's own sampler.
pub(crate) fn measured_sample(
    m: &NsMeasured,
    wi: Vec3,
    u: Vec2,
    out: &mut NsMeasuredSample,
) -> Result<(), CallError> {
    *out = NsMeasuredSample::default();
    let p = m.0.get().prepare(wi).ok_or(CallError::Refused)?;
    let s = p.sample(u).ok_or(CallError::Refused)?;
    let [r, g, b] = s.weight;
    *out = NsMeasuredSample {
        wo: ns_vec3(s.wo),
        pdf: s.pdf,
        weight: NsRgb { r, g, b },
    };
    Ok(())
}

pub(crate) fn measured_eval_batch(
    m: &NsMeasured,
    wi: Vec3s<'_>,
    wo: Vec3s<'_>,
    out: RgbMut<'_>,
) -> Result<(), CallError> {
    Ok(m.0.get().eval_batch(wi, wo, out)?)
}

pub(crate) fn measured_pdf_batch(
    m: &NsMeasured,
    wi: Vec3s<'_>,
    wo: Vec3s<'_>,
    pdf: &mut [f32],
) -> Result<(), CallError> {
    Ok(m.0.get().pdf_batch(wi, wo, pdf)?)
}

pub(crate) fn measured_sample_batch(
    m: &NsMeasured,
    wi: Vec3s<'_>,
    u: Vec2s<'_>,
    out: SamplesMut<'_>,
    weight: RgbMut<'_>,
) -> Result<(), CallError> {
    Ok(m.0.get().sample_batch(wi, u, out, weight)?)
}
