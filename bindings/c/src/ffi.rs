//! The `extern "C"` entry points: the only module with `unsafe`. Each function checks its
//! pointers (NULL, alignment, length, outputs overlapping anything else), turns them into
//! references and slices, and calls the safe body in `api` under `guard` (no panic
//! unwinds into C).
//!
//! # Safety (for every function taking pointers)
//!
//! Non-NULL pointers must point to memory valid for the documented number of elements for
//! the duration of the call (`n` floats for each array of a batched call); handles must come
//! from this library and not have been freed. Inputs are not modified. What this module
//! checks itself, and reports as a status rather than undefined behaviour: NULL, float
//! pointers not 4-byte aligned, `n` too large for the address space, and output arrays that
//! overlap another output or an input.

use std::ffi::{c_char, CStr};
use std::path::Path;

use neusample::wavefront::BlobLane;
use neusample::wavefront::{Features, FeaturesMut, RgbMut, SamplesMut, Vec2s, Vec3s, Vec3sMut};
use neusample::FEATURE_DIM;
use neusample_owned::{OwnedBlob, OwnedMaterial, OwnedMeasuredBlob, OwnedSampler};

use crate::api;
use crate::error::{guard, guard_void, open_error, status_name, with_last_error, CallError};
use crate::types::*;

/// The version of this library (`"0.1.0"`), NUL-terminated, static.
#[no_mangle]
pub extern "C" fn ns_version() -> *const c_char {
    concat!(env!("CARGO_PKG_VERSION"), "\0").as_ptr().cast()
}

/// The message of the last call on this thread that failed (empty if none). The pointer
/// stays valid until the next call into this library on this thread.
#[no_mangle]
pub extern "C" fn ns_last_error() -> *const c_char {
    with_last_error(|p| p)
}

/// The name of a status (`"NS_OK"`, `"NS_ERR_IO"`, …), NUL-terminated, static.
#[no_mangle]
pub extern "C" fn ns_status_name(status: NsStatus) -> *const c_char {
    status_name(status).as_ptr().cast()
}

// ---------------------------------------------------------------------------------------
// Pointer checks.

/// The byte range `[start, end)` of `n` floats at `p`, after checking `p`; `(0, 0)` when
/// `n == 0` (any pointer, NULL included, is then fine).
fn float_range(p: *const f32, n: usize, what: &'static str) -> Result<(usize, usize), CallError> {
    if n == 0 {
        return Ok((0, 0));
    }
    if p.is_null() {
        return Err(CallError::Null(what));
    }
    let start = p as usize;
    if !start.is_multiple_of(core::mem::align_of::<f32>()) {
        return Err(CallError::Invalid(format!(
            "`{what}` is not aligned to 4 bytes"
        )));
    }
    let end = n
        .checked_mul(core::mem::size_of::<f32>())
        .filter(|b| *b <= isize::MAX as usize)
        .and_then(|b| start.checked_add(b))
        .ok_or_else(|| CallError::Invalid(format!("n = {n} is too large")))?;
    Ok((start, end))
}

/// The arrays of one batched call: every one checked, and no output overlapping another
/// array (inputs may overlap each other: they are only read).
struct Arrays {
    n: usize,
    inputs: Vec<(usize, usize, &'static str)>,
    outputs: Vec<(usize, usize, &'static str)>,
}

impl Arrays {
    fn new(n: usize) -> Self {
        Arrays {
            n,
            inputs: Vec::with_capacity(16),
            outputs: Vec::with_capacity(8),
        }
    }
    fn input(&mut self, p: *const f32, what: &'static str) -> Result<(), CallError> {
        let (a, b) = float_range(p, self.n, what)?;
        self.inputs.push((a, b, what));
        Ok(())
    }
    fn output(&mut self, p: *mut f32, what: &'static str) -> Result<(), CallError> {
        let (a, b) = float_range(p, self.n, what)?;
        self.outputs.push((a, b, what));
        Ok(())
    }
    fn check_overlap(&self) -> Result<(), CallError> {
        for (i, o) in self.outputs.iter().enumerate() {
            let others = self.inputs.iter().chain(self.outputs[i + 1..].iter());
            for x in others {
                if o.0 < x.1 && x.0 < o.1 {
                    return Err(CallError::Invalid(format!(
                        "output `{}` overlaps `{}`",
                        o.2, x.2
                    )));
                }
            }
        }
        Ok(())
    }
}

/// `n` floats at `p` as a slice.
///
/// # Safety
/// `p` was checked by [`float_range`] with the same `n`, and the caller's contract (module
/// docs) holds: `n` readable floats, not written during the call.
unsafe fn slice<'a>(p: *const f32, n: usize) -> &'a [f32] {
    if n == 0 {
        return &[];
    }
    // SAFETY: non-NULL, aligned and not too long (checked); valid for `n` reads by the
    // caller's contract.
    unsafe { core::slice::from_raw_parts(p, n) }
}

/// `n` floats at `p` as a mutable slice.
///
/// # Safety
/// As [`slice`], for writes, and `p`'s range overlaps no other array of the call
/// ([`Arrays::check_overlap`]).
unsafe fn slice_mut<'a>(p: *mut f32, n: usize) -> &'a mut [f32] {
    if n == 0 {
        return &mut [];
    }
    // SAFETY: non-NULL, aligned, not too long and overlapping nothing else of this call
    // (checked); valid for `n` writes by the caller's contract.
    unsafe { core::slice::from_raw_parts_mut(p, n) }
}

/// A shared reference from a pointer, or [`CallError::Null`].
///
/// # Safety
/// A non-NULL `p` points to a live, properly aligned `T` (a handle from this library, or a
/// caller's struct) that is not written during the call.
unsafe fn get<'a, T>(p: *const T, what: &'static str) -> Result<&'a T, CallError> {
    // SAFETY: the caller's contract for non-NULL pointers; `as_ref` handles NULL.
    unsafe { p.as_ref() }.ok_or(CallError::Null(what))
}

/// A mutable reference from a pointer, or [`CallError::Null`].
///
/// # Safety
/// A non-NULL `p` points to a live, properly aligned `T` that nothing else accesses during
/// the call.
unsafe fn get_mut<'a, T>(p: *mut T, what: &'static str) -> Result<&'a mut T, CallError> {
    // SAFETY: the caller's contract for non-NULL pointers; `as_mut` handles NULL.
    unsafe { p.as_mut() }.ok_or(CallError::Null(what))
}

/// A path argument as UTF-8 text: [`CallError::Null`] for NULL, `NS_ERR_INVALID_ARGUMENT`
/// for bytes that are not UTF-8.
///
/// # Safety
/// `path` is NULL or a NUL-terminated string, not written during the call.
unsafe fn path_arg<'a>(path: *const c_char) -> Result<&'a str, CallError> {
    if path.is_null() {
        return Err(CallError::Null("path"));
    }
    // SAFETY: non-NULL and NUL-terminated (caller's contract).
    unsafe { CStr::from_ptr(path) }
        .to_str()
        .map_err(|_| CallError::Invalid("`path` is not UTF-8".into()))
}

/// Moves `value` to the heap and stores the pointer in `*out`.
fn put<T>(out: &mut *mut T, value: T) {
    *out = Box::into_raw(Box::new(value));
}

/// Frees a handle made by [`put`].
///
/// # Safety
/// `p` is NULL or came from [`put`] and was not freed.
unsafe fn free<T>(p: *mut T) {
    if !p.is_null() {
        // SAFETY: `p` came from `Box::into_raw` and is freed once (caller's contract).
        drop(unsafe { Box::from_raw(p) });
    }
}

// ---------------------------------------------------------------------------------------
// Blobs.

/// Reads and validates the blob file at `path` (UTF-8, NUL-terminated) and stores a new
/// handle in `*out` (free it with `ns_blob_free`). Errors: `NS_ERR_IO` (missing or
/// unreadable file), the blob errors (`NS_ERR_CHECKSUM_MISMATCH` for a corrupted file, …).
///
/// # Safety
/// `path` is NULL or a NUL-terminated string; `out` is NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn ns_blob_open(path: *const c_char, out: *mut *mut NsBlob) -> NsStatus {
    guard(|| {
        // SAFETY: `out` is NULL or writable (contract).
        let out = unsafe { get_mut(out, "out") }?;
        // SAFETY: NULL or NUL-terminated (contract).
        let path = unsafe { path_arg(path) }?;
        let blob = OwnedBlob::open(Path::new(path)).map_err(|e| open_error(path, e))?;
        put(out, NsBlob(blob));
        Ok(())
    })
}

/// Validates `len` bytes at `bytes` (copied; the caller may free them afterwards) and stores
/// a new handle in `*out`.
///
/// # Safety
/// `bytes` is NULL (only with `len == 0`) or readable for `len` bytes; `out` is NULL or
/// writable.
#[no_mangle]
pub unsafe extern "C" fn ns_blob_from_bytes(
    bytes: *const u8,
    len: usize,
    out: *mut *mut NsBlob,
) -> NsStatus {
    guard(|| {
        // SAFETY: `out` is NULL or writable (contract).
        let out = unsafe { get_mut(out, "out") }?;
        let data: &[u8] = if len == 0 {
            &[]
        } else if bytes.is_null() {
            return Err(CallError::Null("bytes"));
        } else if len > isize::MAX as usize {
            return Err(CallError::Invalid(format!("len = {len} is too large")));
        } else {
            // SAFETY: non-NULL, `len` readable bytes (contract); u8 needs no alignment.
            unsafe { core::slice::from_raw_parts(bytes, len) }
        };
        put(out, NsBlob(OwnedBlob::from_bytes(data)?));
        Ok(())
    })
}

/// Frees a blob handle (NULL is ignored). Samplers and materials built from it stay valid:
/// they share its bytes.
///
/// # Safety
/// `blob` is NULL or a handle from `ns_blob_open`/`ns_blob_from_bytes`, freed once.
#[no_mangle]
pub unsafe extern "C" fn ns_blob_free(blob: *mut NsBlob) {
    // SAFETY: caller's contract.
    guard_void(|| unsafe { free(blob) })
}

/// Writes the blob's header to `*out`.
///
/// # Safety
/// `blob` is NULL or a live handle; `out` is NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn ns_blob_header(blob: *const NsBlob, out: *mut NsHeader) -> NsStatus {
    guard(|| {
        // SAFETY: live handle or NULL (contract).
        let blob = unsafe { get(blob, "blob") }?;
        // SAFETY: writable or NULL (contract).
        let out = unsafe { get_mut(out, "out") }?;
        *out = NsHeader::of(&blob.0);
        Ok(())
    })
}

/// Copies the blob's label (free text: material, method, settings) into `buf` as a
/// NUL-terminated string, truncated to `cap - 1` bytes, and stores the label's full length
/// (without the NUL) in `*len` when `len` is not NULL. `buf` may be NULL when `cap == 0`.
///
/// # Safety
/// `blob` is NULL or a live handle; `buf` is writable for `cap` bytes; `len` is NULL or
/// writable.
#[no_mangle]
pub unsafe extern "C" fn ns_blob_label(
    blob: *const NsBlob,
    buf: *mut c_char,
    cap: usize,
    len: *mut usize,
) -> NsStatus {
    guard(|| {
        // SAFETY: live handle or NULL (contract).
        let blob = unsafe { get(blob, "blob") }?;
        let label = blob.0.blob().header().label.as_bytes();
        if cap > 0 {
            if buf.is_null() {
                return Err(CallError::Null("buf"));
            }
            let k = label.len().min(cap - 1);
            // SAFETY: `buf` is writable for `cap > k` bytes (contract) and cannot overlap the
            // label, which lives in memory this library owns.
            let dst = unsafe { core::slice::from_raw_parts_mut(buf.cast::<u8>(), k + 1) };
            dst[..k].copy_from_slice(&label[..k]);
            dst[k] = 0;
        }
        if !len.is_null() {
            // SAFETY: non-NULL and writable (contract).
            unsafe { *len = label.len() };
        }
        Ok(())
    })
}

// ---------------------------------------------------------------------------------------
// Samplers and materials.

/// Builds the sampler a blob holds (any kind) and stores a new handle in `*out` (free it with
/// `ns_sampler_free`). `NS_ERR_NOT_A_SAMPLER` for a neural-material blob.
///
/// # Safety
/// `blob` is NULL or a live handle; `out` is NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn ns_sampler_new(blob: *const NsBlob, out: *mut *mut NsSampler) -> NsStatus {
    guard(|| {
        // SAFETY: live handle or NULL (contract).
        let blob = unsafe { get(blob, "blob") }?;
        // SAFETY: writable or NULL (contract).
        let out = unsafe { get_mut(out, "out") }?;
        put(out, NsSampler(OwnedSampler::new(&blob.0)?));
        Ok(())
    })
}

/// The cosine-hemisphere sampler (needs no blob), as a new handle in `*out`.
///
/// # Safety
/// `out` is NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn ns_sampler_cosine(out: *mut *mut NsSampler) -> NsStatus {
    guard(|| {
        // SAFETY: writable or NULL (contract).
        let out = unsafe { get_mut(out, "out") }?;
        put(out, NsSampler(OwnedSampler::cosine()));
        Ok(())
    })
}

/// Frees a sampler handle (NULL is ignored).
///
/// # Safety
/// `sampler` is NULL or a handle from `ns_sampler_new`/`ns_sampler_cosine`, freed once.
#[no_mangle]
pub unsafe extern "C" fn ns_sampler_free(sampler: *mut NsSampler) {
    // SAFETY: caller's contract.
    guard_void(|| unsafe { free(sampler) })
}

/// The sampler's kind.
///
/// # Safety
/// `sampler` is NULL or a live handle; `out` is NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn ns_sampler_kind(sampler: *const NsSampler, out: *mut NsKind) -> NsStatus {
    guard(|| {
        // SAFETY: live handle or NULL (contract).
        let s = unsafe { get(sampler, "sampler") }?;
        // SAFETY: writable or NULL (contract).
        let out = unsafe { get_mut(out, "out") }?;
        *out = s.0.kind().into();
        Ok(())
    })
}

/// Builds the neural material of a neural-material blob and stores a new handle in `*out`
/// (free it with `ns_material_free`). `NS_ERR_WRONG_KIND` for a sampler blob.
///
/// # Safety
/// `blob` is NULL or a live handle; `out` is NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn ns_material_new(
    blob: *const NsBlob,
    out: *mut *mut NsMaterial,
) -> NsStatus {
    guard(|| {
        // SAFETY: live handle or NULL (contract).
        let blob = unsafe { get(blob, "blob") }?;
        // SAFETY: writable or NULL (contract).
        let out = unsafe { get_mut(out, "out") }?;
        put(out, NsMaterial(OwnedMaterial::new(&blob.0)?));
        Ok(())
    })
}

/// Frees a material handle (NULL is ignored).
///
/// # Safety
/// `material` is NULL or a handle from `ns_material_new`, freed once.
#[no_mangle]
pub unsafe extern "C" fn ns_material_free(material: *mut NsMaterial) {
    // SAFETY: caller's contract.
    guard_void(|| unsafe { free(material) })
}

/// φ(uv): the bilinearly interpolated feature vector at texture coordinate `uv` (the texture
/// wraps; non-finite coordinates read as 0).
///
/// # Safety
/// `material` is NULL or a live handle; `out` is NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn ns_material_features(
    material: *const NsMaterial,
    uv: NsVec2,
    out: *mut NsPhi,
) -> NsStatus {
    guard(|| {
        // SAFETY: live handle or NULL (contract).
        let m = unsafe { get(material, "material") }?;
        // SAFETY: writable or NULL (contract).
        let out = unsafe { get_mut(out, "out") }?;
        out.v = api::features(m, api::vec2(uv, "uv")?);
        Ok(())
    })
}

/// The BRDF `f(φ, wi, wo)` in linear RGB, **without** the cosine (0 below the horizon).
///
/// # Safety
/// `material` is NULL or a live handle; `phi` NULL or readable; `out` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn ns_material_eval(
    material: *const NsMaterial,
    phi: *const NsPhi,
    wi: NsVec3,
    wo: NsVec3,
    out: *mut NsRgb,
) -> NsStatus {
    guard(|| {
        // SAFETY: live handle or NULL (contract).
        let m = unsafe { get(material, "material") }?;
        // SAFETY: readable or NULL (contract).
        let phi = api::phi(unsafe { get(phi, "phi") }?)?;
        // SAFETY: writable or NULL (contract).
        let out = unsafe { get_mut(out, "out") }?;
        let (wi, wo) = (api::vec3(wi, "wi")?, api::vec3(wo, "wo")?);
        *out = api::eval(m, &phi, wi, wo);
        Ok(())
    })
}

// ---------------------------------------------------------------------------------------
// Scalar sampling.

/// Prepares the sampler for `(φ, wi)` and draws one direction from `u ∈ [0,1)²` into `*out`
/// (solid-angle pdf). `NS_REFUSED` (with `*out` zeroed) when `wi` is at or below the horizon
/// or the sample falls outside the support; `NS_ERR_NOT_FINITE` for NaN/∞ inputs.
///
/// # Safety
/// `sampler` is NULL or a live handle; `phi` NULL or readable; `out` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn ns_sample(
    sampler: *const NsSampler,
    phi: *const NsPhi,
    wi: NsVec3,
    u: NsVec2,
    out: *mut NsSample,
) -> NsStatus {
    guard(|| {
        // SAFETY: live handle or NULL (contract).
        let s = unsafe { get(sampler, "sampler") }?;
        // SAFETY: writable or NULL (contract).
        let out = unsafe { get_mut(out, "out") }?;
        *out = NsSample::default();
        // SAFETY: readable or NULL (contract).
        let phi = api::phi(unsafe { get(phi, "phi") }?)?;
        api::sample(s, &phi, api::vec3(wi, "wi")?, api::vec2(u, "u")?, out)
    })
}

/// The solid-angle density with which `ns_sample` draws `wo` at `(φ, wi)`: 0 below the
/// horizon. `NS_REFUSED` (with `*pdf = 0`) when `wi` is refused.
///
/// # Safety
/// `sampler` is NULL or a live handle; `phi` NULL or readable; `pdf` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn ns_pdf(
    sampler: *const NsSampler,
    phi: *const NsPhi,
    wi: NsVec3,
    wo: NsVec3,
    pdf: *mut f32,
) -> NsStatus {
    guard(|| {
        // SAFETY: live handle or NULL (contract).
        let s = unsafe { get(sampler, "sampler") }?;
        // SAFETY: writable or NULL (contract).
        let pdf = unsafe { get_mut(pdf, "pdf") }?;
        *pdf = 0.0;
        // SAFETY: readable or NULL (contract).
        let phi = api::phi(unsafe { get(phi, "phi") }?)?;
        api::pdf(s, &phi, api::vec3(wi, "wi")?, api::vec3(wo, "wo")?, pdf)
    })
}

/// A new, empty prepared state in `*out` (free it with `ns_prepared_free`). One per thread;
/// reuse it for every shading point.
///
/// # Safety
/// `out` is NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn ns_prepared_new(out: *mut *mut NsPrepared) -> NsStatus {
    guard(|| {
        // SAFETY: writable or NULL (contract).
        let out = unsafe { get_mut(out, "out") }?;
        put(
            out,
            NsPrepared {
                lane: BlobLane::default(),
                owner: 0,
            },
        );
        Ok(())
    })
}

/// Frees a prepared state (NULL is ignored).
///
/// # Safety
/// `prepared` is NULL or from `ns_prepared_new`, freed once.
#[no_mangle]
pub unsafe extern "C" fn ns_prepared_free(prepared: *mut NsPrepared) {
    // SAFETY: caller's contract.
    guard_void(|| unsafe { free(prepared) })
}

/// Runs the sampler's networks for `(φ, wi)` once and keeps the result in `*prepared` for
/// `ns_prepared_sample` / `ns_prepared_pdf` (pbrt: build the BxDF at the intersection).
/// `NS_REFUSED` when `wi` is at or below the horizon (the state then samples nothing).
///
/// # Safety
/// `sampler` is NULL or a live handle; `phi` NULL or readable; `prepared` NULL or a live
/// state not used by another thread during the call.
#[no_mangle]
pub unsafe extern "C" fn ns_prepare(
    sampler: *const NsSampler,
    phi: *const NsPhi,
    wi: NsVec3,
    prepared: *mut NsPrepared,
) -> NsStatus {
    guard(|| {
        // SAFETY: live handle or NULL (contract).
        let s = unsafe { get(sampler, "sampler") }?;
        // SAFETY: exclusive or NULL (contract).
        let p = unsafe { get_mut(prepared, "prepared") }?;
        p.lane = BlobLane::default();
        p.owner = 0;
        // SAFETY: readable or NULL (contract).
        let phi = api::phi(unsafe { get(phi, "phi") }?)?;
        api::prepare(s, &phi, api::vec3(wi, "wi")?, p)
    })
}

/// Draws one direction from a prepared state (as `ns_sample`, within the batched runtime's
/// tolerances: the prepared state is a one-lane wavefront; its pdf is `ns_prepared_pdf` at
/// the sampled direction bit for bit).
///
/// # Safety
/// `sampler` is NULL or a live handle; `prepared` NULL or a live state; `out` NULL or
/// writable.
#[no_mangle]
pub unsafe extern "C" fn ns_prepared_sample(
    sampler: *const NsSampler,
    prepared: *const NsPrepared,
    u: NsVec2,
    out: *mut NsSample,
) -> NsStatus {
    guard(|| {
        // SAFETY: live handle or NULL (contract).
        let s = unsafe { get(sampler, "sampler") }?;
        // SAFETY: live state or NULL (contract).
        let p = unsafe { get(prepared, "prepared") }?;
        // SAFETY: writable or NULL (contract).
        let out = unsafe { get_mut(out, "out") }?;
        *out = NsSample::default();
        api::prepared_sample(s, p, api::vec2(u, "u")?, out)
    })
}

/// The solid-angle density of `wo` under a prepared state (as `ns_pdf`, within the batched
/// runtime's tolerances).
///
/// # Safety
/// `sampler` is NULL or a live handle; `prepared` NULL or a live state; `pdf` NULL or
/// writable.
#[no_mangle]
pub unsafe extern "C" fn ns_prepared_pdf(
    sampler: *const NsSampler,
    prepared: *const NsPrepared,
    wo: NsVec3,
    pdf: *mut f32,
) -> NsStatus {
    guard(|| {
        // SAFETY: live handle or NULL (contract).
        let s = unsafe { get(sampler, "sampler") }?;
        // SAFETY: live state or NULL (contract).
        let p = unsafe { get(prepared, "prepared") }?;
        // SAFETY: writable or NULL (contract).
        let pdf = unsafe { get_mut(pdf, "pdf") }?;
        *pdf = 0.0;
        api::prepared_pdf(s, p, api::vec3(wo, "wo")?, pdf)
    })
}

// ---------------------------------------------------------------------------------------
// Batched (wavefront) calls. Per lane the scalar rules hold, but a refused or non-finite
// lane is not an error: it gives zeros in that lane only, and the call returns NS_OK.

fn features<'a>(arr: &mut Arrays, phi: &NsFeatures) -> Result<Features<'a>, CallError> {
    for c in phi.c.iter() {
        arr.input(*c, "phi")?;
    }
    let n = arr.n;
    // SAFETY: each channel was checked by `Arrays::input` for `n` floats.
    let channels: [&[f32]; FEATURE_DIM] = core::array::from_fn(|k| unsafe { slice(phi.c[k], n) });
    Ok(Features { channels })
}

fn vec3s<'a>(arr: &mut Arrays, v: &NsVec3s, what: &'static str) -> Result<Vec3s<'a>, CallError> {
    arr.input(v.x, what)?;
    arr.input(v.y, what)?;
    arr.input(v.z, what)?;
    let n = arr.n;
    // SAFETY: the three arrays were checked by `Arrays::input` for `n` floats.
    let (x, y, z) = unsafe { (slice(v.x, n), slice(v.y, n), slice(v.z, n)) };
    Ok(Vec3s { x, y, z })
}

fn vec2s<'a>(arr: &mut Arrays, v: &NsVec2s, what: &'static str) -> Result<Vec2s<'a>, CallError> {
    arr.input(v.x, what)?;
    arr.input(v.y, what)?;
    let n = arr.n;
    // SAFETY: both arrays were checked by `Arrays::input` for `n` floats.
    let (x, y) = unsafe { (slice(v.x, n), slice(v.y, n)) };
    Ok(Vec2s { x, y })
}

/// `out`'s five arrays as `n`-float outputs of `arr`.
fn samples_output(arr: &mut Arrays, out: &NsSamplesMut) -> Result<(), CallError> {
    arr.output(out.x, "out.x")?;
    arr.output(out.y, "out.y")?;
    arr.output(out.z, "out.z")?;
    arr.output(out.pdf, "out.pdf")?;
    arr.output(out.mis_pdf, "out.mis_pdf")
}

/// `out`'s arrays as slices of `n` floats.
///
/// # Safety
/// `samples_output` accepted `out` for `n` floats in an `Arrays` whose overlap check passed.
unsafe fn samples_mut<'a>(out: &NsSamplesMut, n: usize) -> SamplesMut<'a> {
    // SAFETY: checked for `n` floats each and overlapping nothing else (contract).
    unsafe {
        SamplesMut {
            wo: Vec3sMut {
                x: slice_mut(out.x, n),
                y: slice_mut(out.y, n),
                z: slice_mut(out.z, n),
            },
            pdf: slice_mut(out.pdf, n),
            mis_pdf: slice_mut(out.mis_pdf, n),
        }
    }
}

/// Prepare + sample for `n` lanes (structure of arrays; fused: no lane state to keep).
/// Lane `i` draws from `u[i]` at `(phi[i], wi[i])` and writes `out.{x,y,z,pdf,mis_pdf}[i]`.
/// `n == 0` is a no-op (any pointers).
///
/// # Safety
/// `sampler` is NULL or a live handle; every array holds `n` floats; outputs overlap
/// nothing (checked: `NS_ERR_INVALID_ARGUMENT`).
#[no_mangle]
pub unsafe extern "C" fn ns_sample_batch(
    sampler: *const NsSampler,
    n: usize,
    phi: NsFeatures,
    wi: NsVec3s,
    u: NsVec2s,
    out: NsSamplesMut,
) -> NsStatus {
    guard(|| {
        // SAFETY: live handle or NULL (contract).
        let s = unsafe { get(sampler, "sampler") }?;
        let mut arr = Arrays::new(n);
        let phi = features(&mut arr, &phi)?;
        let wi = vec3s(&mut arr, &wi, "wi")?;
        let u = vec2s(&mut arr, &u, "u")?;
        samples_output(&mut arr, &out)?;
        arr.check_overlap()?;
        // SAFETY: checked for `n` floats each and overlapping nothing else.
        let dst = unsafe { samples_mut(&out, n) };
        api::sample_batch(s, phi, wi, u, dst)
    })
}

/// Prepare + pdf for `n` lanes: `pdf[i]` is the solid-angle density of `wo[i]` at
/// `(phi[i], wi[i])`.
///
/// # Safety
/// As `ns_sample_batch`.
#[no_mangle]
pub unsafe extern "C" fn ns_pdf_batch(
    sampler: *const NsSampler,
    n: usize,
    phi: NsFeatures,
    wi: NsVec3s,
    wo: NsVec3s,
    pdf: *mut f32,
) -> NsStatus {
    guard(|| {
        // SAFETY: live handle or NULL (contract).
        let s = unsafe { get(sampler, "sampler") }?;
        let mut arr = Arrays::new(n);
        let phi = features(&mut arr, &phi)?;
        let wi = vec3s(&mut arr, &wi, "wi")?;
        let wo = vec3s(&mut arr, &wo, "wo")?;
        arr.output(pdf, "pdf")?;
        arr.check_overlap()?;
        // SAFETY: checked for `n` floats and overlapping nothing else.
        let pdf = unsafe { slice_mut(pdf, n) };
        api::pdf_batch(s, phi, wi, wo, pdf)
    })
}

/// φ at `n` texture coordinates.
///
/// # Safety
/// As `ns_sample_batch`.
#[no_mangle]
pub unsafe extern "C" fn ns_material_features_batch(
    material: *const NsMaterial,
    n: usize,
    uv: NsVec2s,
    phi: NsFeaturesMut,
) -> NsStatus {
    guard(|| {
        // SAFETY: live handle or NULL (contract).
        let m = unsafe { get(material, "material") }?;
        let mut arr = Arrays::new(n);
        let uv = vec2s(&mut arr, &uv, "uv")?;
        for c in phi.c.iter() {
            arr.output(*c, "phi")?;
        }
        arr.check_overlap()?;
        // SAFETY: each channel checked for `n` floats and overlapping nothing else.
        let channels: [&mut [f32]; FEATURE_DIM] =
            core::array::from_fn(|k| unsafe { slice_mut(phi.c[k], n) });
        api::features_batch(m, uv, FeaturesMut { channels })
    })
}

/// The BRDF (RGB, no cosine) of `n` direction pairs.
///
/// # Safety
/// As `ns_sample_batch`.
#[no_mangle]
pub unsafe extern "C" fn ns_material_eval_batch(
    material: *const NsMaterial,
    n: usize,
    phi: NsFeatures,
    wi: NsVec3s,
    wo: NsVec3s,
    out: NsRgbMut,
) -> NsStatus {
    guard(|| {
        // SAFETY: live handle or NULL (contract).
        let m = unsafe { get(material, "material") }?;
        let mut arr = Arrays::new(n);
        let phi = features(&mut arr, &phi)?;
        let wi = vec3s(&mut arr, &wi, "wi")?;
        let wo = vec3s(&mut arr, &wo, "wo")?;
        arr.output(out.r, "out.r")?;
        arr.output(out.g, "out.g")?;
        arr.output(out.b, "out.b")?;
        arr.check_overlap()?;
        // SAFETY: checked for `n` floats each and overlapping nothing else.
        let dst = unsafe {
            RgbMut {
                r: slice_mut(out.r, n),
                g: slice_mut(out.g, n),
                b: slice_mut(out.b, n),
            }
        };
        api::eval_batch(m, phi, wi, wo, dst)
    })
}

// ---------------------------------------------------------------------------------------
// Measured materials (RGL data in a measured blob or a `.bsdf` file): eval, the data's own
// sampler and its density, each with respect to solid angle.

/// Builds the measured material of a measured blob (kind `NS_KIND_MEASURED`, written by
/// `neusample measured-blob`) and stores a new handle in `*out` (free it with
/// `ns_measured_free`). `NS_ERR_WRONG_KIND` for any other blob.
///
/// # Safety
/// `blob` is NULL or a live handle; `out` is NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn ns_measured_new(
    blob: *const NsBlob,
    out: *mut *mut NsMeasured,
) -> NsStatus {
    guard(|| {
        // SAFETY: live handle or NULL (contract).
        let blob = unsafe { get(blob, "blob") }?;
        // SAFETY: writable or NULL (contract).
        let out = unsafe { get_mut(out, "out") }?;
        put(out, NsMeasured(OwnedMeasuredBlob::new(&blob.0)?));
        Ok(())
    })
}

/// Reads the RGL measured-material file at `path` (UTF-8, NUL-terminated; an RGB or spectral
/// `.bsdf` file in Mitsuba's `measured` format, spectra read in linear sRGB) and stores a new
/// handle in `*out` (free it with `ns_measured_free`): the same material, bit for bit, as
/// `ns_measured_new` on the blob `neusample measured-blob` writes from the file. Errors:
/// `NS_ERR_IO` (missing or unreadable file), `NS_ERR_MEASURED_FILE` (not a measured file, or
/// a field missing or wrong: `ns_last_error` names the file and the field).
///
/// # Safety
/// `path` is NULL or a NUL-terminated string; `out` is NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn ns_measured_open_bsdf(
    path: *const c_char,
    out: *mut *mut NsMeasured,
) -> NsStatus {
    guard(|| {
        // SAFETY: writable or NULL (contract).
        let out = unsafe { get_mut(out, "out") }?;
        // SAFETY: NULL or NUL-terminated (contract).
        let path = unsafe { path_arg(path) }?;
        put(out, api::measured_open_bsdf(path)?);
        Ok(())
    })
}

/// Frees a measured-material handle (NULL is ignored).
///
/// # Safety
/// `measured` is NULL or a handle from `ns_measured_new` or `ns_measured_open_bsdf`, freed
/// once.
#[no_mangle]
pub unsafe extern "C" fn ns_measured_free(measured: *mut NsMeasured) {
    // SAFETY: caller's contract.
    guard_void(|| unsafe { free(measured) })
}

/// The measured BRDF `f(wi, wo)` in linear RGB, **without** the cosine (0 where either
/// direction is at or below the horizon). `NS_ERR_NOT_FINITE` for NaN/∞ inputs.
///
/// # Safety
/// `measured` is NULL or a live handle; `out` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn ns_measured_eval(
    measured: *const NsMeasured,
    wi: NsVec3,
    wo: NsVec3,
    out: *mut NsRgb,
) -> NsStatus {
    guard(|| {
        // SAFETY: live handle or NULL (contract).
        let m = unsafe { get(measured, "measured") }?;
        // SAFETY: writable or NULL (contract).
        let out = unsafe { get_mut(out, "out") }?;
        let (wi, wo) = (api::vec3(wi, "wi")?, api::vec3(wo, "wo")?);
        *out = api::measured_eval(m, wi, wo);
        Ok(())
    })
}

/// The density with which `ns_measured_sample` draws `wo` at `wi`, with respect to solid
/// angle, in `*out` (0 for `wo` at or below the horizon). `NS_REFUSED` (with `*out = 0`)
/// when `wi` is at or below the horizon; `NS_ERR_NOT_FINITE` for NaN/∞ inputs.
///
/// # Safety
/// `measured` is NULL or a live handle; `out` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn ns_measured_pdf(
    measured: *const NsMeasured,
    wi: NsVec3,
    wo: NsVec3,
    out: *mut f32,
) -> NsStatus {
    guard(|| {
        // SAFETY: live handle or NULL (contract).
        let m = unsafe { get(measured, "measured") }?;
        // SAFETY: writable or NULL (contract).
        let out = unsafe { get_mut(out, "out") }?;
        let (wi, wo) = (api::vec3(wi, "wi")?, api::vec3(wo, "wo")?);
        api::measured_pdf(m, wi, wo, out)
    })
}

/// Draws one direction at `wi` from `u ∈ [0,1)²` with the data's own sampler (Mitsuba's
/// `measured` sampler: the same direction for the same `u`) into `*out`: the direction, its
/// solid-angle pdf and the RGB weight `f · cos θo / pdf`. `NS_REFUSED` (with `*out` zeroed)
/// when `wi` is at or below the horizon, `u` is outside [0, 1] or the sample has no density;
/// `NS_ERR_NOT_FINITE` for NaN/∞ inputs.
///
/// # Safety
/// `measured` is NULL or a live handle; `out` NULL or writable.
#[no_mangle]
pub unsafe extern "C" fn ns_measured_sample(
    measured: *const NsMeasured,
    wi: NsVec3,
    u: NsVec2,
    out: *mut NsMeasuredSample,
) -> NsStatus {
    guard(|| {
        // SAFETY: live handle or NULL (contract).
        let m = unsafe { get(measured, "measured") }?;
        // SAFETY: writable or NULL (contract).
        let out = unsafe { get_mut(out, "out") }?;
        let (wi, u) = (api::vec3(wi, "wi")?, api::vec2(u, "u")?);
        api::measured_sample(m, wi, u, out)
    })
}

/// `ns_measured_eval` of `n` direction pairs (RGB, no cosine; a refused or non-finite lane
/// gives 0).
///
/// # Safety
/// As `ns_sample_batch`.
#[no_mangle]
pub unsafe extern "C" fn ns_measured_eval_batch(
    measured: *const NsMeasured,
    n: usize,
    wi: NsVec3s,
    wo: NsVec3s,
    out: NsRgbMut,
) -> NsStatus {
    guard(|| {
        // SAFETY: live handle or NULL (contract).
        let m = unsafe { get(measured, "measured") }?;
        let mut arr = Arrays::new(n);
        let wi = vec3s(&mut arr, &wi, "wi")?;
        let wo = vec3s(&mut arr, &wo, "wo")?;
        arr.output(out.r, "out.r")?;
        arr.output(out.g, "out.g")?;
        arr.output(out.b, "out.b")?;
        arr.check_overlap()?;
        // SAFETY: checked for `n` floats each and overlapping nothing else.
        let dst = unsafe {
            RgbMut {
                r: slice_mut(out.r, n),
                g: slice_mut(out.g, n),
                b: slice_mut(out.b, n),
            }
        };
        api::measured_eval_batch(m, wi, wo, dst)
    })
}

/// `ns_measured_pdf` of `n` lanes: `pdf[i]` is the solid-angle density of `wo[i]` at
/// `wi[i]` (0 for a refused or non-finite lane).
///
/// # Safety
/// As `ns_sample_batch`.
#[no_mangle]
pub unsafe extern "C" fn ns_measured_pdf_batch(
    measured: *const NsMeasured,
    n: usize,
    wi: NsVec3s,
    wo: NsVec3s,
    pdf: *mut f32,
) -> NsStatus {
    guard(|| {
        // SAFETY: live handle or NULL (contract).
        let m = unsafe { get(measured, "measured") }?;
        let mut arr = Arrays::new(n);
        let wi = vec3s(&mut arr, &wi, "wi")?;
        let wo = vec3s(&mut arr, &wo, "wo")?;
        arr.output(pdf, "pdf")?;
        arr.check_overlap()?;
        // SAFETY: checked for `n` floats and overlapping nothing else.
        let pdf = unsafe { slice_mut(pdf, n) };
        api::measured_pdf_batch(m, wi, wo, pdf)
    })
}

/// `ns_measured_sample` of `n` lanes: lane `i` draws from `u[i]` at `wi[i]` and writes
/// `out.{x,y,z,pdf}[i]` (solid-angle pdf) and `weight.{r,g,b}[i]` (`f · cos θo / pdf`); a
/// refused lane gets `wo = 0`, `pdf = 0` and a zero weight.
///
/// # Safety
/// As `ns_sample_batch`.
#[no_mangle]
pub unsafe extern "C" fn ns_measured_sample_batch(
    measured: *const NsMeasured,
    n: usize,
    wi: NsVec3s,
    u: NsVec2s,
    out: NsSamplesMut,
    weight: NsRgbMut,
) -> NsStatus {
    guard(|| {
        // SAFETY: live handle or NULL (contract).
        let m = unsafe { get(measured, "measured") }?;
        let mut arr = Arrays::new(n);
        let wi = vec3s(&mut arr, &wi, "wi")?;
        let u = vec2s(&mut arr, &u, "u")?;
        samples_output(&mut arr, &out)?;
        arr.output(weight.r, "weight.r")?;
        arr.output(weight.g, "weight.g")?;
        arr.output(weight.b, "weight.b")?;
        arr.check_overlap()?;
        // SAFETY: checked for `n` floats each and overlapping nothing else.
        let (dst, w) = unsafe {
            (
                samples_mut(&out, n),
                RgbMut {
                    r: slice_mut(weight.r, n),
                    g: slice_mut(weight.g, n),
                    b: slice_mut(weight.b, n),
                },
            )
        };
        api::measured_sample_batch(m, wi, u, dst, w)
    })
}
