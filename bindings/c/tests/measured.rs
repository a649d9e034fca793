//! The measured material through the C ABI: a measured blob built from a fixture `.bsdf`,
//! opened with `ns_blob_from_bytes` + `ns_measured_new`, and the `.bsdf` file itself opened
//! with `ns_measured_open_bsdf`, give bit for bit the runtime's values (scalar and batched),
//! and bad input — NULL, NaN, refused directions, wrong kinds, corrupted bytes, truncated or
//! foreign files, overlapping outputs — is a status code, never a crash.
#![allow(unsafe_code)]

use std::ffi::{CStr, CString};
use std::path::{Path, PathBuf};
use std::ptr::{null, null_mut};

use neusample::{BlobWriter, Vec2, Vec3};
use neusample_capi::ffi::*;
use neusample_capi::*;
use neusample_owned::measured::OwnedMeasured;

fn fixture_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/measured/chm_mint_rgb.bsdf")
}

fn fixture() -> OwnedMeasured {
    OwnedMeasured::open(&fixture_path()).unwrap()
}

/// `ns_measured_open_bsdf` on `path`: the status, the handle (NULL unless `NS_OK`) and the
/// last error message.
fn open_bsdf(path: &[u8]) -> (NsStatus, *mut NsMeasured, String) {
    let c = CString::new(path).unwrap();
    let mut h = null_mut();
    // SAFETY: a NUL-terminated string, a writable output; the message pointer is read before
    // any other call.
    unsafe {
        let s = ns_measured_open_bsdf(c.as_ptr(), &mut h);
        let msg = CStr::from_ptr(ns_last_error())
            .to_string_lossy()
            .into_owned();
        (s, h, msg)
    }
}

fn blob(bytes: &[u8]) -> Result<*mut NsBlob, NsStatus> {
    let mut b = null_mut();
    // SAFETY: `bytes` is readable for its length; `b` is writable.
    let s = unsafe { ns_blob_from_bytes(bytes.as_ptr(), bytes.len(), &mut b) };
    if s == NsStatus::NS_OK {
        Ok(b)
    } else {
        Err(s)
    }
}

fn v3(v: Vec3) -> NsVec3 {
    NsVec3 {
        x: v.x,
        y: v.y,
        z: v.z,
    }
}

/// A deterministic direction (some below the horizon) and variate.
fn lane(i: usize) -> (Vec3, Vec3, Vec2) {
    let h = |k: usize| {
        ((k as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40) as f32 / (1u64 << 24) as f32
    };
    let dir = |a: f32, b: f32| {
        let z = a * 1.2 - 0.2;
        let s = (1.0 - z * z).max(0.0).sqrt();
        let phi = b * std::f32::consts::TAU;
        Vec3::new(s * phi.cos(), s * phi.sin(), z)
    };
    (
        dir(h(6 * i), h(6 * i + 1)),
        dir(h(6 * i + 2), h(6 * i + 3)),
        Vec2::new(h(6 * i + 4), h(6 * i + 5)),
    )
}

/// Lane `i` through the scalar calls of `h` gives the runtime's values for `m` bit for bit
/// (refused where the runtime refuses).
fn scalar_lane_is_the_runtimes<W: neusample::Weights>(
    h: *const NsMeasured,
    m: &neusample::MeasuredMaterial<W>,
    i: usize,
) {
    let (wi, wo, u) = lane(i);
    let (wi_c, wo_c, u_c) = (v3(wi), v3(wo), NsVec2 { x: u.x, y: u.y });
    let prepared = m.prepare(wi);
    let (mut f, mut pdf, mut smp) = (NsRgb::default(), -1.0f32, NsMeasuredSample::default());
    // SAFETY: live handle, writable outputs.
    let (se, sp, ss) = unsafe {
        (
            ns_measured_eval(h, wi_c, wo_c, &mut f),
            ns_measured_pdf(h, wi_c, wo_c, &mut pdf),
            ns_measured_sample(h, wi_c, u_c, &mut smp),
        )
    };
    assert_eq!(se, NsStatus::NS_OK);
    let want_f = prepared.as_ref().map_or([0.0; 3], |p| p.eval(wo));
    assert_eq!(
        [f.r, f.g, f.b].map(f32::to_bits),
        want_f.map(f32::to_bits),
        "lane {i}"
    );
    match prepared {
        None => {
            assert_eq!((sp, ss), (NsStatus::NS_REFUSED, NsStatus::NS_REFUSED));
            assert_eq!((pdf, smp), (0.0, NsMeasuredSample::default()));
        }
        Some(p) => {
            assert_eq!(sp, NsStatus::NS_OK);
            assert_eq!(pdf.to_bits(), p.pdf(wo).to_bits());
            match p.sample(u) {
                None => assert_eq!(ss, NsStatus::NS_REFUSED),
                Some(want) => {
                    assert_eq!(ss, NsStatus::NS_OK);
                    assert_eq!(smp.pdf.to_bits(), want.pdf.to_bits());
                    assert_eq!(
                        [smp.wo.x, smp.wo.y, smp.wo.z].map(f32::to_bits),
                        want.wo.to_array().map(f32::to_bits)
                    );
                    assert_eq!(
                        [smp.weight.r, smp.weight.g, smp.weight.b].map(f32::to_bits),
                        want.weight.map(f32::to_bits)
                    );
                }
            }
        }
    }
}

#[test]
fn measured_blob_through_the_c_abi() {
    let owned = fixture();
    let m = owned.material();
    let bytes = BlobWriter::measured(m, "name=chm_mint").to_bytes();
    let b = blob(&bytes).unwrap();
    let mut header = std::mem::MaybeUninit::<NsHeader>::uninit();
    // SAFETY: live handle, writable output.
    let status = unsafe { ns_blob_header(b, header.as_mut_ptr()) };
    assert_eq!(status, NsStatus::NS_OK);
    // SAFETY: written by the successful call above.
    let header = unsafe { header.assume_init() };
    assert_eq!(header.kind, NsKind::NS_KIND_MEASURED);

    // Not a sampler, not a neural material.
    let (mut s, mut nm) = (null_mut(), null_mut());
    // SAFETY: live handle, writable outputs.
    unsafe {
        assert_eq!(ns_sampler_new(b, &mut s), NsStatus::NS_ERR_NOT_A_SAMPLER);
        assert_eq!(ns_material_new(b, &mut nm), NsStatus::NS_ERR_WRONG_KIND);
    }
    let mut h = null_mut();
    // SAFETY: live handle, writable output.
    assert_eq!(unsafe { ns_measured_new(b, &mut h) }, NsStatus::NS_OK);
    // The material shares the blob's bytes: the blob handle may go first.
    // SAFETY: a live handle, freed once.
    unsafe { ns_blob_free(b) };

    const N: usize = 1000;
    let mut cols: [Vec<f32>; 7] = std::array::from_fn(|_| Vec::with_capacity(N));
    for i in 0..N {
        let (wi, wo, u) = lane(i);
        for (c, v) in [wi.x, wi.y, wi.z, wo.x, wo.y, wo.z, u.x]
            .into_iter()
            .enumerate()
        {
            cols[c].push(v);
        }
        scalar_lane_is_the_runtimes(h, m, i);
    }
    let uy: Vec<f32> = (0..N).map(|i| lane(i).2.y).collect();

    // Batched: the same lanes through the runtime's batched calls.
    let wi = NsVec3s {
        x: cols[0].as_ptr(),
        y: cols[1].as_ptr(),
        z: cols[2].as_ptr(),
    };
    let wo = NsVec3s {
        x: cols[3].as_ptr(),
        y: cols[4].as_ptr(),
        z: cols[5].as_ptr(),
    };
    let u = NsVec2s {
        x: cols[6].as_ptr(),
        y: uy.as_ptr(),
    };
    let mut out: [Vec<f32>; 12] = std::array::from_fn(|_| vec![0.0; N]);
    let [fr, fg, fb, pdf, sx, sy, sz, sp, sm, wr, wg, wb] = &mut out;
    // SAFETY: every array holds N floats; outputs are distinct vectors.
    unsafe {
        let rgb = NsRgbMut {
            r: fr.as_mut_ptr(),
            g: fg.as_mut_ptr(),
            b: fb.as_mut_ptr(),
        };
        assert_eq!(ns_measured_eval_batch(h, N, wi, wo, rgb), NsStatus::NS_OK);
        assert_eq!(
            ns_measured_pdf_batch(h, N, wi, wo, pdf.as_mut_ptr()),
            NsStatus::NS_OK
        );
        let smp = NsSamplesMut {
            x: sx.as_mut_ptr(),
            y: sy.as_mut_ptr(),
            z: sz.as_mut_ptr(),
            pdf: sp.as_mut_ptr(),
            mis_pdf: sm.as_mut_ptr(),
        };
        let w = NsRgbMut {
            r: wr.as_mut_ptr(),
            g: wg.as_mut_ptr(),
            b: wb.as_mut_ptr(),
        };
        assert_eq!(
            ns_measured_sample_batch(h, N, wi, u, smp, w),
            NsStatus::NS_OK
        );
        // An output overlapping an input is refused, NULL arrays too, n = 0 is a no-op.
        let alias = NsRgbMut {
            r: cols[0].as_ptr().cast_mut(),
            g: fg.as_mut_ptr(),
            b: fb.as_mut_ptr(),
        };
        assert_eq!(
            ns_measured_eval_batch(h, N, wi, wo, alias),
            NsStatus::NS_ERR_INVALID_ARGUMENT
        );
        assert_eq!(
            ns_measured_pdf_batch(h, N, wi, wo, null_mut()),
            NsStatus::NS_ERR_NULL_POINTER
        );
        let none = NsVec3s {
            x: null(),
            y: null(),
            z: null(),
        };
        assert_eq!(
            ns_measured_pdf_batch(h, 0, none, none, null_mut()),
            NsStatus::NS_OK
        );
    }
    // The runtime's batched calls on the same lanes (the ABI adds nothing to them).
    let mut want: [Vec<f32>; 12] = std::array::from_fn(|_| vec![0.0; N]);
    {
        use neusample::wavefront::{RgbMut, SamplesMut, Vec2s, Vec3s, Vec3sMut};
        let wi = Vec3s {
            x: &cols[0],
            y: &cols[1],
            z: &cols[2],
        };
        let wo = Vec3s {
            x: &cols[3],
            y: &cols[4],
            z: &cols[5],
        };
        let [fr, fg, fb, pdf, sx, sy, sz, sp, sm, wr, wg, wb] = &mut want;
        m.eval_batch(
            wi,
            wo,
            RgbMut {
                r: fr,
                g: fg,
                b: fb,
            },
        )
        .unwrap();
        m.pdf_batch(wi, wo, pdf).unwrap();
        let dst = SamplesMut {
            wo: Vec3sMut {
                x: sx,
                y: sy,
                z: sz,
            },
            pdf: sp,
            mis_pdf: sm,
        };
        let u = Vec2s {
            x: &cols[6],
            y: &uy,
        };
        m.sample_batch(
            wi,
            u,
            dst,
            RgbMut {
                r: wr,
                g: wg,
                b: wb,
            },
        )
        .unwrap();
    }
    let bits = |a: &[Vec<f32>; 12]| -> Vec<Vec<u32>> {
        a.iter()
            .map(|v| v.iter().map(|x| x.to_bits()).collect())
            .collect()
    };
    assert!(
        bits(&out) == bits(&want),
        "batched calls differ from the runtime's"
    );
    assert!(out[7].iter().filter(|p| **p > 0.0).count() > N / 2);
    assert!(
        out[7] == out[8],
        "the data's sampler: its MIS density is its density"
    );

    // Bad scalar input.
    let up = NsVec3 {
        x: 0.0,
        y: 0.0,
        z: 1.0,
    };
    let nan = NsVec3 {
        x: f32::NAN,
        y: 0.0,
        z: 1.0,
    };
    let mut f = NsRgb::default();
    let mut pdf = 0.0f32;
    let mut smp = NsMeasuredSample::default();
    // SAFETY: handles live or NULL, outputs writable or NULL: the calls check.
    unsafe {
        assert_eq!(
            ns_measured_eval(null(), up, up, &mut f),
            NsStatus::NS_ERR_NULL_POINTER
        );
        assert_eq!(
            ns_measured_eval(h, up, up, null_mut()),
            NsStatus::NS_ERR_NULL_POINTER
        );
        assert_eq!(
            ns_measured_pdf(h, nan, up, &mut pdf),
            NsStatus::NS_ERR_NOT_FINITE
        );
        let bad_u = NsVec2 {
            x: f32::INFINITY,
            y: 0.5,
        };
        assert_eq!(
            ns_measured_sample(h, up, bad_u, &mut smp),
            NsStatus::NS_ERR_NOT_FINITE
        );
        let out_of_range = NsVec2 { x: 1.5, y: 0.5 };
        assert_eq!(
            ns_measured_sample(h, up, out_of_range, &mut smp),
            NsStatus::NS_REFUSED
        );
        assert_eq!(
            ns_measured_new(null(), null_mut()),
            NsStatus::NS_ERR_NULL_POINTER
        );
        ns_measured_free(h);
        ns_measured_free(null_mut());
    }
}

#[test]
fn bad_measured_blobs_are_status_codes() {
    let owned = fixture();
    let bytes = BlobWriter::measured(owned.material(), "").to_bytes();
    // Corrupted: the checksum.
    let mut bad = bytes.clone();
    let k = bad.len() / 2;
    bad[k] ^= 0x40;
    assert_eq!(blob(&bad).err(), Some(NsStatus::NS_ERR_CHECKSUM_MISMATCH));
    assert_eq!(
        blob(&bytes[..bytes.len() - 9]).err(),
        Some(NsStatus::NS_ERR_TRUNCATED)
    );
    // Another kind: not a measured material.
    let cosine =
        BlobWriter::new(neusample::SamplerKind::Cosine, neusample::DType::F32, "").to_bytes();
    let b = blob(&cosine).unwrap();
    let mut h = null_mut();
    // SAFETY: live handle, writable output; freed once.
    unsafe {
        assert_eq!(ns_measured_new(b, &mut h), NsStatus::NS_ERR_WRONG_KIND);
        assert!(h.is_null());
        ns_blob_free(b);
    }
}

#[test]
fn bsdf_files_open_through_the_c_abi() {
    let owned = fixture();
    let path = fixture_path();
    let (status, h, _) = open_bsdf(path.to_str().unwrap().as_bytes());
    assert_eq!(status, NsStatus::NS_OK);
    for i in 0..500 {
        scalar_lane_is_the_runtimes(h, owned.material(), i);
    }
    // SAFETY: a live handle, freed once.
    unsafe { ns_measured_free(h) };

    // A truncated copy: the file and the field that runs past its end are named.
    let dir = std::env::temp_dir().join(format!("neusample-capi-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let cut = dir.join("truncated.bsdf");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let shown = cut.to_str().unwrap();
    let (status, h, msg) = open_bsdf(shown.as_bytes());
    assert_eq!(status, NsStatus::NS_ERR_MEASURED_FILE, "{msg}");
    assert!(h.is_null());
    assert!(
        msg.starts_with(&format!("{shown}: field `vndf`: ")) && msg.contains("truncated"),
        "{msg}"
    );
    // A blob is not a measured file; a missing file is an I/O error naming it.
    let blob = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures/blobs/cosine.nsb");
    let (status, _, msg) = open_bsdf(blob.to_str().unwrap().as_bytes());
    assert_eq!(status, NsStatus::NS_ERR_MEASURED_FILE, "{msg}");
    assert!(msg.contains("not a tensor file"), "{msg}");
    let missing = dir.join("missing.bsdf");
    let (status, _, msg) = open_bsdf(missing.to_str().unwrap().as_bytes());
    assert_eq!(status, NsStatus::NS_ERR_IO, "{msg}");
    assert!(msg.starts_with(missing.to_str().unwrap()), "{msg}");
    std::fs::remove_dir_all(&dir).unwrap();
    // A path that is not UTF-8, NULL arguments.
    let (status, _, _) = open_bsdf(b"/tmp/\xff.bsdf");
    assert_eq!(status, NsStatus::NS_ERR_INVALID_ARGUMENT);
    let c = CString::new(path.to_str().unwrap()).unwrap();
    let mut h = null_mut();
    // SAFETY: NULL arguments are checked by the call.
    unsafe {
        assert_eq!(
            ns_measured_open_bsdf(null(), &mut h),
            NsStatus::NS_ERR_NULL_POINTER
        );
        assert_eq!(
            ns_measured_open_bsdf(c.as_ptr(), null_mut()),
            NsStatus::NS_ERR_NULL_POINTER
        );
        assert!(h.is_null());
        assert_eq!(
            CStr::from_ptr(ns_status_name(NsStatus::NS_ERR_MEASURED_FILE)).to_str(),
            Ok("NS_ERR_MEASURED_FILE")
        );
    }
}
