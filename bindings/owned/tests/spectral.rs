//! Spectral RGL files (`spectra` over `wavelengths` instead of `rgb`) read in linear sRGB:
//! the conversion's weights against a brute-force integration of the CIE tables, files built
//! here from the mint's tables and from a small anisotropic material whose spectra are known
//! combinations of three basis spectra (each reads as the RGB file of its brute-force
//! conversion: same tables, same eval, the same pdf and samples bit for bit), a flat spectrum
//! reading as grey, and bad spectral files naming their field. Mitsuba's own spectral
//! evaluation is compared in `bindings/python/tests/test_spectral.py`.

use neusample::{MeasuredMaterial, Vec2, Vec3};
use neusample_owned::measured::{cie, spectral, OwnedMeasured, TensorFile};
use rand::{RngExt, SeedableRng};

mod common;

use common::{fixtures, tensor_file, Values};

type Rng = rand_pcg::Pcg64Mcg;

/// A measured file's fields other than the colour: name, shape, values.
type Fields = Vec<(&'static str, Vec<u64>, Values)>;

/// A file's fields other than the colour, the shape of its `rgb` and its values.
struct Material {
    fields: Fields,
    rgb_shape: Vec<u64>,
    rgb: Vec<f32>,
}

impl Material {
    /// The bytes of the file with `colour` (`rgb`, or `wavelengths` and `spectra`) added.
    fn file(&self, colour: Fields) -> Vec<u8> {
        let fields: Vec<_> = self
            .fields
            .iter()
            .map(|(n, s, v)| {
                let v = match v {
                    Values::U8(b) => Values::U8(b.clone()),
                    Values::F32(f) => Values::F32(f.clone()),
                };
                (*n, s.clone(), v)
            })
            .chain(colour)
            .collect();
        tensor_file(&fields)
    }

    /// `(slices, pixels)`: the rgb table is `slices × 3` planes of `pixels` values.
    fn planes(&self) -> (usize, usize) {
        let s = &self.rgb_shape;
        ((s[0] * s[1]) as usize, (s[3] * s[4]) as usize)
    }
}

/// The committed mint's tables.
fn mint() -> Material {
    let bytes = std::fs::read(fixtures().join("chm_mint_rgb.bsdf")).unwrap();
    let tf = TensorFile::parse(&bytes).unwrap();
    let mut fields: Fields = Vec::new();
    for name in ["description", "jacobian"] {
        let b = tf.bytes(name).unwrap();
        fields.push((name, vec![b.len() as u64], Values::U8(b.to_vec())));
    }
    for name in ["phi_i", "theta_i", "ndf", "sigma", "vndf", "luminance"] {
        let rank = tf.field(name).unwrap().shape.len();
        let (shape, v) = tf.f32s(name, rank).unwrap();
        fields.push((name, shape, Values::F32(v)));
    }
    let (rgb_shape, rgb) = tf.f32s("rgb", 5).unwrap();
    Material {
        fields,
        rgb_shape,
        rgb,
    }
}

/// A small anisotropic material (three φi nodes over a quarter turn: fourfold symmetry) with
/// smooth positive tables.
fn anisotropic() -> Material {
    let wave = |n: u64, k: f32| -> Values {
        Values::F32((0..n).map(|i| 0.2 + (i as f32 * k).sin().abs()).collect())
    };
    let (n_phi, n_theta, n) = (3u64, 3u64, 5u64);
    let half_pi = std::f32::consts::FRAC_PI_2;
    let s = n_phi * n_theta;
    let fields: Fields = vec![
        ("description", vec![5], Values::U8(b"aniso".to_vec())),
        ("jacobian", vec![1], Values::U8(vec![1])),
        (
            "phi_i",
            vec![n_phi],
            Values::F32(vec![0.0, half_pi / 2.0, half_pi]),
        ),
        ("theta_i", vec![n_theta], Values::F32(vec![0.0, 0.6, 1.3])),
        ("ndf", vec![4, 5], wave(20, 0.3)),
        ("sigma", vec![3, 4], wave(12, 0.5)),
        ("vndf", vec![n_phi, n_theta, 5, 6], wave(s * 30, 0.37)),
        ("luminance", vec![n_phi, n_theta, n, n], wave(s * 25, 0.71)),
    ];
    let Values::F32(rgb) = wave(s * 75, 0.13) else {
        unreachable!()
    };
    Material {
        fields,
        rgb_shape: vec![n_phi, n_theta, 3, n, n],
        rgb,
    }
}

/// Irregular wavelengths from 390 to about 715 nm: Mitsuba clamps the spectrum outside them,
/// where the observer still sees light.
fn wavelengths(r: &mut Rng) -> Vec<f32> {
    (0..33)
        .map(|k| 390.0 + 10.0 * k as f32 + if k == 0 { 0.0 } else { 3.0 * r.random::<f32>() })
        .collect()
}

/// Three smooth basis spectra (reddish, greenish, bluish bumps over a floor) at `wl`.
fn basis(wl: &[f32]) -> [Vec<f32>; 3] {
    [(610.0f32, 40.0f32), (540.0, 35.0), (450.0, 30.0)].map(|(mu, sigma)| {
        wl.iter()
            .map(|&l| 0.05 + (-((l - mu) / sigma).powi(2)).exp())
            .collect()
    })
}

/// The linear sRGB of the spectrum `values` at `wl` (linear between, clamped outside), by
/// a midpoint rule at 1/256 nm over the tables' range, the tables read linearly.
fn brute_rgb(wl: &[f32], values: &[f32]) -> [f64; 3] {
    let steps_per_nm = 256usize;
    let last = cie::NODES - 1;
    let range = cie::WAVELENGTH_STEP * last as f64;
    let n = (range as usize) * steps_per_nm;
    let h = 1.0 / steps_per_nm as f64;
    let spectrum = |l: f64| -> f64 {
        let i = wl.partition_point(|&x| f64::from(x) <= l);
        if i == 0 {
            f64::from(values[0])
        } else if i == wl.len() {
            f64::from(values[wl.len() - 1])
        } else {
            let (a, b) = (f64::from(wl[i - 1]), f64::from(wl[i]));
            let t = (l - a) / (b - a);
            f64::from(values[i - 1]) * (1.0 - t) + f64::from(values[i]) * t
        }
    };
    let (mut xyz, mut y_white) = ([0.0f64; 3], 0.0f64);
    for j in 0..n {
        let l = cie::WAVELENGTH_MIN + (j as f64 + 0.5) * h;
        let x = (l - cie::WAVELENGTH_MIN) / cie::WAVELENGTH_STEP;
        let i = (x.floor() as usize).min(last - 1);
        let t = x - i as f64;
        let lerp = |a: f32, b: f32| f64::from(a) * (1.0 - t) + f64::from(b) * t;
        let d65 = lerp(cie::D65[i], cie::D65[i + 1]);
        let cmf = [0, 1, 2].map(|c| lerp(cie::CIE1931_XYZ[i][c], cie::CIE1931_XYZ[i + 1][c]));
        let s = spectrum(l);
        for c in 0..3 {
            xyz[c] += s * cmf[c] * d65 * h;
        }
        y_white += cmf[1] * d65 * h;
    }
    cie::XYZ_TO_SRGB.map(|row| (0..3).map(|c| row[c] * xyz[c]).sum::<f64>() / y_white)
}

/// The tables are the standard ones: ȳ peaks at 1 at 555 nm and integrates to 106.857 nm
/// (the 5 nm table), D65 is 100 at 560 nm, and its white (through x̄, ȳ, z̄) has the
/// chromaticity (0.3127, 0.3290) that sRGB calls white.
#[test]
fn cie_tables_are_the_standard_ones() {
    let y: Vec<f64> = cie::CIE1931_XYZ.iter().map(|v| f64::from(v[1])).collect();
    let peak = (0..cie::NODES)
        .max_by(|&a, &b| y[a].total_cmp(&y[b]))
        .unwrap();
    assert_eq!(
        cie::WAVELENGTH_MIN + cie::WAVELENGTH_STEP * peak as f64,
        555.0
    );
    assert_eq!(y[peak], 1.0);
    let integral = y.iter().sum::<f64>() * cie::WAVELENGTH_STEP;
    assert!((integral - 106.857).abs() < 1e-3, "∫ȳ = {integral}");
    assert_eq!(cie::D65[40], 100.0);
    let white: [f64; 3] = [0, 1, 2].map(|c| {
        cie::CIE1931_XYZ
            .iter()
            .zip(cie::D65)
            .map(|(v, d)| f64::from(v[c]) * f64::from(d))
            .sum()
    });
    let sum: f64 = white.iter().sum();
    let (x, y) = (white[0] / sum, white[1] / sum);
    assert!(
        (x - 0.3127).abs() < 2e-4 && (y - 0.3290).abs() < 2e-4,
        "({x}, {y})"
    );
}

/// The weights are the exact integrals: a brute-force integration of each hat function (a
/// midpoint rule, whose own error is far below the bound) agrees within 1e-6 of the largest
/// weight for irregular, single, out-of-range and dense node sets; the weights of any node
/// set sum to white, (1, 1, 1) within 2e-4.
#[test]
fn weights_are_the_integrals_of_the_hat_functions() {
    let mut r = Rng::seed_from_u64(0x5EC7);
    let mut sets: Vec<Vec<f32>> = vec![
        vec![555.0],
        vec![300.0],
        vec![900.0],
        vec![300.0, 340.0],
        vec![850.0, 1000.0],
        vec![300.0, 362.5, 400.0, 827.5, 1000.0],
        (360..=830).step_by(1).map(|l| l as f32).collect(),
        wavelengths(&mut r),
    ];
    for _ in 0..3 {
        let mut v: Vec<f32> = (0..12).map(|_| 340.0 + 520.0 * r.random::<f32>()).collect();
        v.sort_by(f32::total_cmp);
        sets.push(v);
    }
    for wl in &sets {
        let w = spectral::rgb_weights(wl);
        assert_eq!(w.len(), wl.len());
        let scale = w
            .iter()
            .flat_map(|v| v.iter())
            .fold(0.0f64, |m, v| m.max(v.abs()));
        let mut worst = 0.0f64;
        for k in 0..wl.len() {
            let mut hat = vec![0.0f32; wl.len()];
            hat[k] = 1.0;
            let want = brute_rgb(wl, &hat);
            for c in 0..3 {
                worst = worst.max((w[k][c] - want[c]).abs() / scale);
            }
        }
        assert!(worst < 1e-6, "{} nodes: worst {worst:.2e}", wl.len());
        let white = [0, 1, 2].map(|c| w.iter().map(|v| v[c]).sum::<f64>());
        assert!(white.iter().all(|v| (v - 1.0).abs() < 2e-4), "{white:?}");
    }
    assert!(spectral::rgb_weights(&[]).is_empty());
}

/// Scalar and sample results of two materials at seeded random directions: the largest
/// relative eval difference (floor: 1e-5 × the largest value); pdfs and samples must be
/// identical.
fn compare<A, B>(a: &MeasuredMaterial<A>, b: &MeasuredMaterial<B>) -> f64
where
    A: neusample::Weights,
    B: neusample::Weights,
{
    let mut r = Rng::seed_from_u64(0xC0105);
    let mut dir = || {
        let z: f32 = r.random::<f32>() * 0.98 + 0.01;
        let phi: f32 = r.random::<f32>() * std::f32::consts::TAU;
        let s = (1.0 - z * z).sqrt();
        Vec3::new(s * phi.cos(), s * phi.sin(), z)
    };
    let pairs: Vec<(Vec3, Vec3)> = (0..2000).map(|_| (dir(), dir())).collect();
    let mut r = Rng::seed_from_u64(0x5A3);
    let mut f = Vec::new();
    for (wi, wo) in &pairs {
        let (pa, pb) = (a.prepare(*wi).unwrap(), b.prepare(*wi).unwrap());
        f.push((pa.eval(*wo), pb.eval(*wo)));
        assert_eq!(pa.pdf(*wo).to_bits(), pb.pdf(*wo).to_bits());
        let u = Vec2::new(r.random::<f32>(), r.random::<f32>());
        let (sa, sb) = (pa.sample(u), pb.sample(u));
        assert_eq!(sa.map(|s| (s.wo, s.pdf)), sb.map(|s| (s.wo, s.pdf)));
    }
    let fmax = f
        .iter()
        .flat_map(|(_, b)| b.iter())
        .fold(0.0f32, |m, &v| m.max(v));
    assert!(fmax > 0.0);
    let floor = 1e-5 * f64::from(fmax);
    f.iter()
        .flat_map(|(a, b)| (0..3).map(move |c| (f64::from(a[c]), f64::from(b[c]))))
        .map(|(a, b)| (a - b).abs() / b.abs().max(floor))
        .fold(0.0, f64::max)
}

/// A spectral file whose texels are `rgb · (basis spectra)` reads as the RGB file of its
/// brute-force conversion: its table within 1e-6 of the largest value, its eval within 1e-5,
/// the same pdfs and samples (the distributions are the same fields).
#[test]
fn a_spectral_file_reads_as_its_rgb_conversion() {
    let mut r = Rng::seed_from_u64(0xF11E);
    for (name, m) in [("mint", mint()), ("anisotropic", anisotropic())] {
        let wl = wavelengths(&mut r);
        let basis = basis(&wl);
        let basis_rgb = basis.each_ref().map(|b| brute_rgb(&wl, b));
        let (slices, pixels) = m.planes();
        let n = wl.len();
        let mut spectra = vec![0.0f32; slices * n * pixels];
        let mut expected = vec![0.0f32; slices * 3 * pixels];
        for s in 0..slices {
            for p in 0..pixels {
                let rgb = [0, 1, 2].map(|c| m.rgb[(s * 3 + c) * pixels + p]);
                for k in 0..n {
                    spectra[(s * n + k) * pixels + p] = (0..3).map(|c| rgb[c] * basis[c][k]).sum();
                }
                for c in 0..3 {
                    expected[(s * 3 + c) * pixels + p] = (0..3)
                        .map(|j| f64::from(rgb[j]) * basis_rgb[j][c])
                        .sum::<f64>()
                        as f32;
                }
            }
        }
        let mut spectra_shape = m.rgb_shape.clone();
        spectra_shape[2] = n as u64;
        let spectral = m.file(vec![
            ("wavelengths", vec![n as u64], Values::F32(wl.clone())),
            ("spectra", spectra_shape, Values::F32(spectra)),
        ]);
        let rgb_file = m.file(vec![(
            "rgb",
            m.rgb_shape.clone(),
            Values::F32(expected.clone()),
        )]);
        let a = OwnedMeasured::from_bytes(&spectral).unwrap();
        let b = OwnedMeasured::from_bytes(&rgb_file).unwrap();
        assert_eq!(a.wavelengths(), Some(&wl[..]));
        assert_eq!(b.wavelengths(), None);
        assert_eq!(a.material().isotropic(), name == "mint");
        let scale = expected.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        let table = a
            .material()
            .tables()
            .rgb
            .iter()
            .zip(&expected)
            .map(|(x, y)| (x - y).abs() / scale)
            .fold(0.0f32, f32::max);
        let eval = compare(a.material(), b.material());
        eprintln!("{name}: table {table:.2e} of the largest value, eval {eval:.2e}");
        assert!(table < 1e-6, "{name}: table off by {table:.2e}");
        assert!(eval < 1e-5, "{name}: eval off by {eval:.2e}");
    }
}

/// A flat spectrum reads as grey: each channel is the flat value within 2e-4 (relative) on
/// every texel, the same file with one wavelength too.
#[test]
fn a_flat_spectrum_reads_as_grey() {
    let mut r = Rng::seed_from_u64(0x6EE1);
    for m in [mint(), anisotropic()] {
        let (slices, pixels) = m.planes();
        for wl in [wavelengths(&mut r), vec![560.0]] {
            let n = wl.len();
            // The flat value of a texel: its green channel.
            let mut spectra = vec![0.0f32; slices * n * pixels];
            for s in 0..slices {
                for k in 0..n {
                    spectra[(s * n + k) * pixels..][..pixels]
                        .copy_from_slice(&m.rgb[(s * 3 + 1) * pixels..][..pixels]);
                }
            }
            let mut shape = m.rgb_shape.clone();
            shape[2] = n as u64;
            let file = m.file(vec![
                ("wavelengths", vec![n as u64], Values::F32(wl)),
                ("spectra", shape, Values::F32(spectra)),
            ]);
            let read = OwnedMeasured::from_bytes(&file).unwrap();
            let rgb = &read.material().tables().rgb;
            let mut worst = 0.0f32;
            for s in 0..slices {
                for p in 0..pixels {
                    let g = m.rgb[(s * 3 + 1) * pixels + p];
                    for c in 0..3 {
                        let v = rgb[(s * 3 + c) * pixels + p];
                        worst = worst.max((v - g).abs() / g.abs().max(f32::MIN_POSITIVE));
                    }
                }
            }
            assert!(worst < 2e-4, "{n} wavelengths: worst {worst:.2e}");
        }
    }
}

/// Bad spectral files give an error naming the field, never a panic.
#[test]
fn bad_spectral_files_name_the_field() {
    let m = anisotropic();
    let (slices, pixels) = m.planes();
    let wl: Vec<f32> = vec![400.0, 500.0, 600.0, 700.0];
    let n = wl.len() as u64;
    let shape = |k: u64| {
        let mut s = m.rgb_shape.clone();
        s[2] = k;
        s
    };
    let spectra = |k: usize| Values::F32(vec![0.5; slices * k * pixels]);
    let wavelengths = |v: &[f32]| ("wavelengths", vec![v.len() as u64], Values::F32(v.to_vec()));
    let mut nan_spectra = vec![0.5; slices * 4 * pixels];
    nan_spectra[17] = f32::NAN;
    let mut tall = shape(n);
    tall[3] += 1;
    let cases: Vec<(&str, Fields, &str, &str)> = vec![
        (
            "no wavelengths",
            vec![("spectra", shape(n), spectra(4))],
            "wavelengths",
            "missing",
        ),
        ("no spectra", vec![wavelengths(&wl)], "spectra", "missing"),
        ("neither", vec![], "rgb", "missing"),
        (
            "NaN wavelength",
            vec![
                wavelengths(&[400.0, f32::NAN, 600.0, 700.0]),
                ("spectra", shape(n), spectra(4)),
            ],
            "wavelengths",
            "finite",
        ),
        (
            "infinite wavelength",
            vec![
                wavelengths(&[400.0, 500.0, 600.0, f32::INFINITY]),
                ("spectra", shape(n), spectra(4)),
            ],
            "wavelengths",
            "finite",
        ),
        (
            "unsorted",
            vec![
                wavelengths(&[400.0, 600.0, 500.0, 700.0]),
                ("spectra", shape(n), spectra(4)),
            ],
            "wavelengths",
            "ascend",
        ),
        (
            "repeated",
            vec![
                wavelengths(&[400.0, 500.0, 500.0, 700.0]),
                ("spectra", shape(n), spectra(4)),
            ],
            "wavelengths",
            "ascend",
        ),
        (
            "empty",
            vec![wavelengths(&[]), ("spectra", shape(0), spectra(0))],
            "wavelengths",
            "empty",
        ),
        (
            "u8 wavelengths",
            vec![
                ("wavelengths", vec![4], Values::U8(vec![1, 2, 3, 4])),
                ("spectra", shape(n), spectra(4)),
            ],
            "wavelengths",
            "expected f32",
        ),
        (
            "wavelength count",
            vec![wavelengths(&wl), ("spectra", shape(5), spectra(5))],
            "spectra",
            "the length of wavelengths",
        ),
        (
            "slice height",
            vec![
                wavelengths(&wl),
                ("spectra", tall, Values::F32(vec![0.5; slices * 4 * 6 * 5])),
            ],
            "spectra",
            "the luminance's height",
        ),
        (
            "rank",
            vec![
                wavelengths(&wl),
                (
                    "spectra",
                    shape(n)[1..].to_vec(),
                    Values::F32(vec![0.5; 3 * 4 * pixels]),
                ),
            ],
            "spectra",
            "dimensions",
        ),
        (
            "φ count",
            vec![
                wavelengths(&wl),
                (
                    "spectra",
                    [vec![2], shape(n)[1..].to_vec()].concat(),
                    Values::F32(vec![0.5; 2 * 3 * 4 * pixels]),
                ),
            ],
            "spectra",
            "phi_i",
        ),
        (
            "NaN in spectra",
            vec![
                wavelengths(&wl),
                ("spectra", shape(n), Values::F32(nan_spectra)),
            ],
            "spectra",
            "element 17 is NaN",
        ),
    ];
    for (what, colour, field, text) in cases {
        let e = OwnedMeasured::from_bytes(&m.file(colour)).expect_err(what);
        let shown = e.to_string();
        eprintln!("{what}: {shown}");
        assert_eq!(e.field.as_deref(), Some(field), "{what}: {shown}");
        assert!(shown.contains(text), "{what}: {shown}");
    }
    // The well-formed file of these cases reads.
    let good = m.file(vec![wavelengths(&wl), ("spectra", shape(n), spectra(4))]);
    OwnedMeasured::from_bytes(&good).unwrap();
}
