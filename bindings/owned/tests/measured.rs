//! The measured-material reader and runtime against Mitsuba 3's `measured` BSDF (golden values
//! from `tools/measured_reference.py`), their own invariants (the sampler's pdf integrates to
//! one, sample and pdf agree, the weight is f·cos/pdf), a constructed anisotropic file, and
//! bad files (spectral files: `tests/spectral.rs`).

use std::path::Path;

use neusample::{Vec2, Vec3};
use neusample_owned::measured::{OwnedMeasured, MAGIC};

mod common;

use common::{fixtures, FILES};

fn v3(v: &serde_json::Value) -> Vec3 {
    let a: Vec<f32> = serde_json::from_value(v.clone()).unwrap();
    Vec3::new(a[0], a[1], a[2])
}

fn rel(a: f64, b: f64, floor: f64) -> f64 {
    (a - b).abs() / b.abs().max(floor)
}

/// Eval, pdf and sample against Mitsuba at the golden pairs: relative error ≤ 1e-3 (with an
/// absolute floor of 1e-6 × the file's largest value) on ≥ 99.9 % of the values.
#[test]
fn agrees_with_mitsuba() {
    let text = std::fs::read_to_string(fixtures().join("mitsuba_reference.json")).unwrap();
    let reference: serde_json::Value = serde_json::from_str(&text).unwrap();
    for file in FILES {
        let m = OwnedMeasured::open(&fixtures().join(file)).unwrap();
        let r = &reference["files"][file];
        let n = r["wi"].as_array().unwrap().len();
        let f_max = r["f"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|v| v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()))
            .fold(0.0f64, f64::max);
        let pdf_max = r["pdf"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .fold(0.0f64, f64::max);
        let (mut bad_f, mut bad_pdf, mut bad_sample) = (0, 0, 0);
        let (mut worst_f, mut worst_pdf, mut worst_wo, mut worst_spdf) =
            (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        for i in 0..n {
            let wi = v3(&r["wi"][i]);
            let wo = v3(&r["wo"][i]);
            let p = m.material().prepare(wi).unwrap();
            let f = p.eval(wo);
            for c in 0..3 {
                // Mitsuba keeps the data's slightly negative values; ours read as 0.
                let want = r["f"][i][c].as_f64().unwrap().max(0.0);
                let e = rel(f64::from(f[c]), want, 1e-6 * f_max);
                worst_f = worst_f.max(e);
                bad_f += usize::from(e > 1e-3);
            }
            let e = rel(
                f64::from(p.pdf(wo)),
                r["pdf"][i].as_f64().unwrap(),
                1e-6 * pdf_max,
            );
            worst_pdf = worst_pdf.max(e);
            bad_pdf += usize::from(e > 1e-3);
            if e > 1e-3 {
                eprintln!(
                    "{file} pair {i}: wi {wi:?} wo {wo:?} pdf {} vs Mitsuba {}",
                    p.pdf(wo),
                    r["pdf"][i]
                );
            }

            let u = Vec2::new(
                r["u"][i][0].as_f64().unwrap() as f32,
                r["u"][i][1].as_f64().unwrap() as f32,
            );
            let want_pdf = r["sample_pdf"][i].as_f64().unwrap();
            match p.sample(u) {
                Some(s) if want_pdf > 0.0 => {
                    let d = f64::from((s.wo - v3(&r["sample_wo"][i])).length());
                    let e = rel(f64::from(s.pdf), want_pdf, 1e-6 * pdf_max);
                    worst_wo = worst_wo.max(d);
                    worst_spdf = worst_spdf.max(e);
                    bad_sample += usize::from(d > 1e-3 || e > 1e-3);
                }
                None if want_pdf == 0.0 => {}
                other => {
                    eprintln!("{file} pair {i}: sample {other:?}, Mitsuba pdf {want_pdf}");
                    bad_sample += 1;
                }
            }
        }
        eprintln!(
            "{file}: worst relative f {worst_f:.2e}, pdf {worst_pdf:.2e}; sample |Δwo| {worst_wo:.2e}, pdf {worst_spdf:.2e}; \
             above 1e-3: f {bad_f}/{}, pdf {bad_pdf}/{n}, sample {bad_sample}/{n}",
            3 * n
        );
        // ≥ 99.9 % within 1e-3: with 256 pairs, no value may miss.
        let allowed = |total: usize| total / 1000;
        assert!(
            bad_f <= allowed(3 * n),
            "{file}: {bad_f} RGB values off by > 1e-3"
        );
        assert!(
            bad_pdf <= allowed(n),
            "{file}: {bad_pdf} pdfs off by > 1e-3"
        );
        assert!(
            bad_sample <= allowed(n),
            "{file}: {bad_sample} samples off by > 1e-3"
        );
    }
}

fn open(file: &str) -> OwnedMeasured {
    OwnedMeasured::open(&fixtures().join(file)).unwrap()
}

/// Incident directions from the pole to 80°, at a few azimuths.
fn incident() -> Vec<Vec3> {
    let mut v = Vec::new();
    for (k, theta) in [0.0f32, 0.3, 0.7, 1.0, 1.2, 1.4].into_iter().enumerate() {
        let phi = 0.9 * k as f32 - 1.3;
        v.push(Vec3::new(
            theta.sin() * phi.cos(),
            theta.sin() * phi.sin(),
            theta.cos(),
        ));
    }
    v
}

/// A stratified point of cell `(i, j)` of an `n × n` grid over `[0, 1)²`.
fn strat(i: usize, j: usize, n: usize) -> Vec2 {
    let h = |k: usize, s: u64| {
        let x = (k as u64 * 0x9E37_79B9 + s * 0x85EB_CA6B) % 1000;
        x as f32 / 1000.0
    };
    Vec2::new(
        (i as f32 + h(i * n + j, 1)) / n as f32,
        (j as f32 + h(i * n + j, 2)) / n as f32,
    )
}

/// The sampler's density at its own samples is `pdf` there, and the weight is
/// `f·cos θo / pdf` (relative 1e-3 on ≥ 99.9 % of samples).
#[test]
fn sample_pdf_and_weight_agree() {
    for file in FILES {
        let m = open(file);
        let (mut n, mut bad, mut worst) = (0usize, 0usize, 0.0f64);
        for wi in incident() {
            let p = m.material().prepare(wi).unwrap();
            for i in 0..32 {
                for j in 0..32 {
                    let Some(s) = p.sample(strat(i, j, 32)) else {
                        continue;
                    };
                    assert!(s.wo.z > 0.0 && s.pdf > 0.0 && s.pdf.is_finite());
                    assert!((s.wo.length() - 1.0).abs() < 1e-5);
                    let e = rel(f64::from(p.pdf(s.wo)), f64::from(s.pdf), 0.0);
                    let f = p.eval(s.wo);
                    let mut ew = 0.0f64;
                    for c in 0..3 {
                        let want = f64::from(f[c] * s.wo.z / s.pdf);
                        ew = ew.max((f64::from(s.weight[c]) - want).abs() / want.abs().max(1e-6));
                    }
                    worst = worst.max(e.max(ew));
                    bad += usize::from(e > 1e-3 || ew > 1e-3);
                    n += 1;
                }
            }
        }
        eprintln!(
            "{file}: {n} samples, worst relative pdf/weight mismatch {worst:.2e}, {bad} above 1e-3"
        );
        assert!(n > 3000, "{file}: only {n} valid samples");
        assert!(
            bad * 1000 <= n,
            "{file}: {bad} of {n} samples disagree with pdf or eval"
        );
    }
}

/// ∫ pdf dω over the sphere equals the sampler's mass above the horizon (the fraction of
/// variates whose sample is valid), within 0.2 % absolute. The integral runs over polar
/// coordinates about the mirror direction, `θ = π t²`, dense where the data peaks.
#[test]
fn pdf_integrates_to_the_sampled_mass() {
    let n = 400;
    for file in FILES {
        let m = open(file);
        for wi in incident() {
            let p = m.material().prepare(wi).unwrap();
            let axis = Vec3::new(-wi.x, -wi.y, wi.z).normalize();
            let (t1, t2) = axis.any_orthonormal_pair();
            let (mut integral, mut valid) = (0.0f64, 0usize);
            for i in 0..n {
                for j in 0..n {
                    let u = strat(i, j, n);
                    let theta = std::f32::consts::PI * u.x * u.x;
                    let phi = 2.0 * std::f32::consts::PI * u.y;
                    let wo = axis * theta.cos() + (t1 * phi.cos() + t2 * phi.sin()) * theta.sin();
                    // dω = sin θ dθ dφ, dθ = 2π t dt, dφ = 2π du.
                    let jac = f64::from(theta.sin())
                        * 2.0
                        * std::f64::consts::PI
                        * f64::from(u.x)
                        * 2.0
                        * std::f64::consts::PI;
                    integral += f64::from(p.pdf(wo)) * jac;
                    valid += usize::from(p.sample(strat(j, i, n)).is_some());
                }
            }
            let integral = integral / (n * n) as f64;
            let mass = valid as f64 / (n * n) as f64;
            eprintln!("{file} wi {wi:.3?}: integral {integral:.4}, sampled mass {mass:.4}");
            assert!(
                (integral - mass).abs() < 0.002,
                "{file} wi {wi:?}: integral {integral} vs mass {mass}"
            );
        }
    }
}

/// Directions the runtime refuses: below the horizon, zero, non-finite; never NaN.
#[test]
fn bad_directions_give_zero() {
    let m = open(FILES[2]);
    let mat = m.material();
    for wi in [
        Vec3::ZERO,
        Vec3::new(0.0, 0.0, -1.0),
        Vec3::new(f32::NAN, 0.0, 1.0),
        Vec3::new(0.5, 0.0, 0.0),
    ] {
        assert!(mat.prepare(wi).is_none(), "{wi:?}");
    }
    let p = mat.prepare(Vec3::new(0.2, 0.1, 0.9)).unwrap();
    for wo in [
        Vec3::ZERO,
        Vec3::new(0.3, 0.0, -0.9),
        Vec3::new(f32::INFINITY, 0.0, 1.0),
    ] {
        assert_eq!(p.pdf(wo), 0.0);
        assert_eq!(p.eval(wo), [0.0; 3]);
    }
    for u in [
        Vec2::new(f32::NAN, 0.5),
        Vec2::new(-0.1, 0.5),
        Vec2::new(0.5, 1.5),
    ] {
        assert!(p.sample(u).is_none());
    }
    // The unit square's corners are fine.
    for u in [Vec2::ZERO, Vec2::ONE, Vec2::new(1.0, 0.0)] {
        if let Some(s) = p.sample(u) {
            assert!(s.pdf.is_finite() && s.weight.iter().all(|w| w.is_finite()));
        }
    }
}

/// The header of a tensor file: each field's name position, dtype position, shape
/// positions and data offset.
struct HeaderField {
    name: String,
    name_at: usize,
    shape_at: usize,
    ndim: usize,
    offset: usize,
}

fn header(bytes: &[u8]) -> Vec<HeaderField> {
    let u16_at = |p: usize| u16::from_le_bytes([bytes[p], bytes[p + 1]]) as usize;
    let n = u32::from_le_bytes(bytes[14..18].try_into().unwrap()) as usize;
    let mut p = 18;
    let mut out = Vec::new();
    for _ in 0..n {
        let len = u16_at(p);
        let name = String::from_utf8(bytes[p + 2..p + 2 + len].to_vec()).unwrap();
        let name_at = p + 2;
        p += 2 + len;
        let ndim = u16_at(p);
        let offset = u64::from_le_bytes(bytes[p + 3..p + 11].try_into().unwrap()) as usize;
        let shape_at = p + 11;
        p = shape_at + 8 * ndim;
        out.push(HeaderField {
            name,
            name_at,
            shape_at,
            ndim,
            offset,
        });
    }
    out
}

fn mutated(f: impl FnOnce(&mut Vec<u8>, &[HeaderField])) -> Vec<u8> {
    let mut bytes = std::fs::read(fixtures().join(FILES[0])).unwrap();
    let h = header(&bytes);
    f(&mut bytes, &h);
    bytes
}

fn field<'a>(h: &'a [HeaderField], name: &str) -> &'a HeaderField {
    h.iter().find(|f| f.name == name).unwrap()
}

/// Bad files give an error that names the field, never a panic.
#[test]
fn bad_files_name_the_field() {
    let cases: Vec<(&str, Vec<u8>, Option<&str>, &str)> = vec![
        ("empty", Vec::new(), None, "truncated"),
        (
            "header cut",
            mutated(|b, _| b.truncate(40)),
            None,
            "truncated",
        ),
        (
            "data cut",
            mutated(|b, _| b.truncate(300_000)),
            Some("vndf"),
            "past the end",
        ),
        (
            "magic",
            mutated(|b, _| b[0] = b'T'),
            None,
            "not a tensor file",
        ),
        ("version", mutated(|b, _| b[12] = 2), None, "version"),
        (
            "missing vndf",
            mutated(|b, h| b[field(h, "vndf").name_at] = b'w'),
            Some("vndf"),
            "missing",
        ),
        (
            "NaN in rgb",
            mutated(|b, h| {
                let at = field(h, "rgb").offset + 4 * 17;
                b[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
            }),
            Some("rgb"),
            "element 17 is NaN",
        ),
        (
            "infinite theta_i",
            mutated(|b, h| {
                let at = field(h, "theta_i").offset;
                b[at..at + 4].copy_from_slice(&f32::INFINITY.to_le_bytes());
            }),
            Some("theta_i"),
            "finite",
        ),
        (
            "two channels",
            mutated(|b, h| {
                let at = field(h, "rgb").shape_at + 8 * 2;
                b[at..at + 8].copy_from_slice(&2u64.to_le_bytes());
            }),
            Some("rgb"),
            "expected 3",
        ),
        (
            "vndf slices",
            mutated(|b, h| {
                let at = field(h, "vndf").shape_at + 8;
                b[at..at + 8].copy_from_slice(&7u64.to_le_bytes());
            }),
            Some("vndf"),
            "theta_i",
        ),
        (
            "rank",
            mutated(|b, h| {
                let f = field(h, "ndf");
                assert_eq!(f.ndim, 2);
                b[f.shape_at - 11..f.shape_at - 9].copy_from_slice(&1u16.to_le_bytes());
            }),
            None,
            "",
        ),
        (
            "negative vndf",
            mutated(|b, h| {
                let at = field(h, "vndf").offset + 4 * 5;
                b[at..at + 4].copy_from_slice(&(-1.0f32).to_le_bytes());
            }),
            Some("vndf"),
            "negative",
        ),
        (
            "type",
            mutated(|b, h| b[field(h, "sigma").shape_at - 9] = 11),
            Some("sigma"),
            "",
        ),
        (
            "no colour",
            mutated(|b, h| b[field(h, "rgb").name_at..][..3].copy_from_slice(b"xyz")),
            Some("rgb"),
            "neither an RGB nor a spectral file",
        ),
        (
            "huge shape",
            mutated(|b, h| {
                let at = field(h, "vndf").shape_at;
                b[at..at + 8].copy_from_slice(&u64::MAX.to_le_bytes());
            }),
            Some("vndf"),
            "",
        ),
    ];
    for (what, bytes, want_field, want_text) in cases {
        let e = OwnedMeasured::from_bytes(&bytes).expect_err(what);
        let shown = e.to_string();
        eprintln!("{what}: {shown}");
        if let Some(f) = want_field {
            assert_eq!(e.field.as_deref(), Some(f), "{what}: {shown}");
        }
        assert!(shown.contains(want_text), "{what}: {shown}");
    }
    // A missing file names the path.
    let e = OwnedMeasured::open(Path::new("/nonexistent/x.bsdf")).unwrap_err();
    assert!(e.to_string().starts_with("/nonexistent/x.bsdf: "), "{e}");
    // The magic constant is what the files start with.
    assert!(std::fs::read(fixtures().join(FILES[0]))
        .unwrap()
        .starts_with(MAGIC));
}

/// The batched path is the scalar path bit for bit on every committed file, over random
/// directions and variates with bad lanes mixed in, at batch sizes that leave partial chunks.
#[test]
fn batched_is_scalar_bit_for_bit() {
    use neusample::wavefront::{prefer_isa, Isa, RgbMut, SamplesMut, Vec2s, Vec3s, Vec3sMut};
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    let n = 4099;
    let mut dir = |i: usize| match i % 97 {
        7 => Vec3::new(f32::NAN, 0.0, 1.0),
        8 => Vec3::ZERO,
        9 => Vec3::new(0.2, 0.3, -0.5),
        10 => Vec3::new(0.0, 0.0, 1.0),
        _ => {
            let (a, b) = (next(), next());
            let r = 0.999 * b.sqrt();
            let phi = std::f32::consts::TAU * a;
            Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - r * r).sqrt())
        }
    };
    let wi: Vec<Vec3> = (0..n).map(&mut dir).collect();
    let wo: Vec<Vec3> = (0..n).map(&mut dir).collect();
    let u: Vec<Vec2> = (0..n)
        .map(|i| match i % 89 {
            3 => Vec2::new(1.0, 0.0),
            4 => Vec2::new(f32::NAN, 0.5),
            _ => Vec2::new(next(), next()),
        })
        .collect();
    let col = |v: &[Vec3], k: usize| -> Vec<f32> { v.iter().map(|d| d[k]).collect() };
    let (ix, iy, iz) = (col(&wi, 0), col(&wi, 1), col(&wi, 2));
    let (ox, oy, oz) = (col(&wo, 0), col(&wo, 1), col(&wo, 2));
    let ux: Vec<f32> = u.iter().map(|v| v.x).collect();
    let uy: Vec<f32> = u.iter().map(|v| v.y).collect();
    // Every instruction set this machine has (AVX-512 and AVX2 read the tables with gathers).
    let isas = Isa::ALL.into_iter().filter(|&i| prefer_isa(Some(i)) == i);
    for (isa, file) in isas.flat_map(|i| FILES.iter().map(move |f| (i.name(), f))) {
        let m = open(file);
        let mat = m.material();
        let mut f = vec![vec![0.0f32; n]; 3];
        let mut pdf = vec![0.0f32; n];
        let mut s = vec![vec![0.0f32; n]; 8];
        for batch in [1usize, 13, 64, 1000] {
            for a in (0..n).step_by(batch) {
                let b = (a + batch).min(n);
                let wis = Vec3s {
                    x: &ix[a..b],
                    y: &iy[a..b],
                    z: &iz[a..b],
                };
                let wos = Vec3s {
                    x: &ox[a..b],
                    y: &oy[a..b],
                    z: &oz[a..b],
                };
                let [r, g, bl] = &mut f[..] else {
                    unreachable!()
                };
                let out = RgbMut {
                    r: &mut r[a..b],
                    g: &mut g[a..b],
                    b: &mut bl[a..b],
                };
                mat.eval_batch(wis, wos, out).unwrap();
                mat.pdf_batch(wis, wos, &mut pdf[a..b]).unwrap();
                let [x, y, z, p, q, wr, wg, wb] = &mut s[..] else {
                    unreachable!()
                };
                let samples = SamplesMut {
                    wo: Vec3sMut {
                        x: &mut x[a..b],
                        y: &mut y[a..b],
                        z: &mut z[a..b],
                    },
                    pdf: &mut p[a..b],
                    mis_pdf: &mut q[a..b],
                };
                let weight = RgbMut {
                    r: &mut wr[a..b],
                    g: &mut wg[a..b],
                    b: &mut wb[a..b],
                };
                let us = Vec2s {
                    x: &ux[a..b],
                    y: &uy[a..b],
                };
                mat.sample_batch(wis, us, samples, weight).unwrap();
            }
            for i in 0..n {
                let p = mat.prepare(wi[i]);
                let want_f = p.as_ref().map_or([0.0; 3], |p| p.eval(wo[i]));
                let want_pdf = p.as_ref().map_or(0.0, |p| p.pdf(wo[i]));
                let got_f = [f[0][i], f[1][i], f[2][i]];
                assert_eq!(
                    got_f.map(f32::to_bits),
                    want_f.map(f32::to_bits),
                    "{file} {isa} eval {i}"
                );
                assert_eq!(pdf[i].to_bits(), want_pdf.to_bits(), "{file} {isa} pdf {i}");
                let want = p
                    .as_ref()
                    .and_then(|p| p.sample(u[i]))
                    .map_or([0.0; 8], |s| {
                        // The data's sampler draws from its pdf: its MIS density is `pdf`.
                        [
                            s.wo.x,
                            s.wo.y,
                            s.wo.z,
                            s.pdf,
                            s.pdf,
                            s.weight[0],
                            s.weight[1],
                            s.weight[2],
                        ]
                    });
                let got: [f32; 8] = std::array::from_fn(|k| s[k][i]);
                assert_eq!(
                    got.map(f32::to_bits),
                    want.map(f32::to_bits),
                    "{file} {isa} sample {i}"
                );
            }
        }
    }
    prefer_isa(None);
}
