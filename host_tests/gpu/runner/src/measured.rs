//! The measured material's case: `measured` on the device against the same entry point
//! compiled for the host, on a committed RGL file's tables (tolerances: the crate docs in
//! `main.rs`).

use std::path::Path;
use std::time::Instant;

use neusample::{MeasuredShape, Vec3};
use neusample_gpu_shader::kernel::{
    self, Params, IN_STRIDE, MS_OUT_EVAL, MS_OUT_PDF, MS_OUT_PDF_WO2, MS_OUT_WEIGHT, MS_OUT_WO,
    OUT_STRIDE,
};
use neusample_gpu_shader::{UVec3, WORKGROUP_SIZE};

use crate::{
    flags, make_input, push_bytes, rel_diff, vk, Rng, MS_ABS, MS_CORNER_REL, MS_EDGE_Z, MS_GRAZING,
    MS_REL, MS_WO_ABS,
};

/// A measured material as the GPU sees it: its eleven tables as flat f32 buffers (in
/// `MeasuredTables` order), its shape and `jacobian` flag.
pub struct Material {
    pub label: String,
    shape: MeasuredShape,
    jacobian: bool,
    tables: Vec<Vec<f32>>,
}

impl Material {
    /// The RGL file at `path`, read and checked on the host by `neusample-owned`'s reader.
    pub fn open(path: &str) -> Result<Self, String> {
        let owned = neusample_owned::measured::OwnedMeasured::open(Path::new(path))
            .map_err(|e| format!("{path}: {e}"))?;
        let m = owned.material();
        let label = Path::new(path)
            .file_stem()
            .map_or("measured".to_string(), |s| s.to_string_lossy().into_owned());
        Ok(Material {
            label,
            shape: *m.shape(),
            jacobian: m.jacobian(),
            tables: m.tables().as_array().iter().map(|t| t.to_vec()).collect(),
        })
    }

    fn params(&self, n: usize) -> Params {
        let s = &self.shape;
        Params {
            n: n as u32,
            n_phi: s.n_phi,
            n_theta: s.n_theta,
            ndf_w: s.ndf[0],
            ndf_h: s.ndf[1],
            sigma_w: s.sigma[0],
            sigma_h: s.sigma[1],
            vndf_w: s.vndf[0],
            vndf_h: s.vndf[1],
            rgb_w: s.rgb[0],
            rgb_h: s.rgb[1],
            jacobian: u32::from(self.jacobian),
            ..Params::default()
        }
    }

    /// One line: the shape and the tables' total size.
    pub fn describe(&self) {
        let floats: usize = self.tables.iter().map(Vec::len).sum();
        let s = &self.shape;
        println!(
            "{}: {} × {} incident nodes, ndf {:?}, sigma {:?}, vndf {:?}, rgb {:?}, jacobian {}; {floats} floats in 11 buffers",
            self.label, s.n_phi, s.n_theta, s.ndf, s.sigma, s.vndf, s.rgb, self.jacobian
        );
    }
}

/// Input records: [`make_input`]'s (random wi, u and wo2 with its edge cases at fixed
/// positions), with wo2 moved next to the mirror direction of wi on every fourth ordinary
/// record, where the measured lobe is sharp.
fn input(n: usize, seed: u64) -> Vec<f32> {
    let mut v = make_input(n, seed);
    let mut rng = Rng(seed ^ 0x6d69_6e74);
    for i in 0..n {
        let pos = i % 64;
        if pos <= 10 || i % 4 != 0 {
            continue;
        }
        let r = &mut v[i * IN_STRIDE..(i + 1) * IN_STRIDE];
        let wi = &r[kernel::IN_WI..kernel::IN_WI + 3];
        let spread = 0.1 * rng.f32();
        let d = Vec3::new(
            -wi[0] + spread * rng.range(-1.0, 1.0),
            -wi[1] + spread * rng.range(-1.0, 1.0),
            wi[2] + spread * rng.range(-1.0, 1.0),
        );
        if d.z > 0.0 {
            r[kernel::IN_WO2..kernel::IN_WO2 + 3].copy_from_slice(&d.normalize().to_array());
        }
    }
    v
}

/// `|a − b| ≤ MS_REL·max(|a|, |b|) + MS_ABS`.
fn close(a: f32, b: f32) -> bool {
    close_within(a, b, MS_REL)
}

/// `|a − b| ≤ rel·max(|a|, |b|) + MS_ABS`.
fn close_within(a: f32, b: f32, rel: f32) -> bool {
    (a - b).abs() <= rel * a.abs().max(b.abs()) + MS_ABS
}

/// `z` of `d` normalised (0 for a zero or non-finite `d`).
fn cos_theta(d: &[f32]) -> f32 {
    let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    if l > 0.0 && l.is_finite() {
        d[2] / l
    } else {
        0.0
    }
}

#[derive(Default)]
struct Stats {
    prepared: usize,
    sampled: usize,
    max_eval_rel: f32,
    max_pdf2_rel: f32,
    max_wo_abs: f32,
    max_pdf_rel: f32,
    max_weight_rel: f32,
    /// wo2 records where one side's density or value is 0 at a grazing direction.
    grazing: usize,
    /// Records sampled on one side only, with that side's wo at the horizon.
    edge: usize,
    /// Records with u at a corner of the square whose density or weight is beyond `MS_REL`.
    corner: usize,
    /// Largest relative difference of the density or weight at a corner of u.
    max_corner_rel: f32,
    failures: usize,
}

/// Runs the `measured` entry point on `mat`; prints one row. Returns the label when it failed.
pub fn run(
    ctx: &vk::Context,
    mat: &Material,
    n: usize,
    seed: u64,
    verbose: bool,
) -> Option<String> {
    let label = format!("measured:{}", mat.label);
    let input = input(n, seed);
    let params = mat.params(n);
    let push = push_bytes(&params);
    let groups = (n as u32).div_ceil(WORKGROUP_SIZE);
    let out_init = vec![0.0f32; n * OUT_STRIDE];
    let mut bufs: Vec<&[f32]> = vec![&input, &out_init];
    bufs.extend(mat.tables.iter().map(Vec::as_slice));
    let d = match ctx.dispatch("measured", &bufs, 1, n * OUT_STRIDE, &push, groups) {
        Ok(d) => d,
        Err(e) => {
            println!("{label:<24} DISPATCH FAILED: {e}");
            return Some(label);
        }
    };
    // The CPU reference: the same entry point compiled for the host.
    let t = Instant::now();
    let mut cpu = vec![0.0f32; n * OUT_STRIDE];
    let tb = &mat.tables;
    for i in 0..n {
        neusample_gpu_shader::measured(
            UVec3::new(i as u32, 0, 0),
            &params,
            &input,
            &mut cpu,
            &tb[0],
            &tb[1],
            &tb[2],
            &tb[3],
            &tb[4],
            &tb[5],
            &tb[6],
            &tb[7],
            &tb[8],
            &tb[9],
            &tb[10],
        );
    }
    let cpu_ms = t.elapsed().as_secs_f64() * 1e3;

    let mut s = Stats::default();
    let mut shown = 0;
    for i in 0..n {
        let rec = &input[i * IN_STRIDE..(i + 1) * IN_STRIDE];
        let g = &d.output[i * OUT_STRIDE..(i + 1) * OUT_STRIDE];
        let c = &cpu[i * OUT_STRIDE..(i + 1) * OUT_STRIDE];
        let (gf, cf) = (flags(g), flags(c));
        let mut ok = gf & kernel::FLAG_PREPARED == cf & kernel::FLAG_PREPARED;
        let mut class = "";
        if ok && cf & kernel::FLAG_PREPARED != 0 {
            s.prepared += 1;
            // eval(wo2) and pdf(wo2): a zero on one side only is accepted at grazing angles.
            let grazing = cos_theta(&rec[kernel::IN_WI..kernel::IN_WI + 3]) < MS_GRAZING
                || cos_theta(&rec[kernel::IN_WO2..kernel::IN_WO2 + 3]) < MS_GRAZING;
            let mut zero_one_side = false;
            for k in 0..4 {
                let j = if k < 3 {
                    MS_OUT_EVAL + k
                } else {
                    MS_OUT_PDF_WO2
                };
                let (a, b) = (g[j], c[j]);
                if close(a, b) {
                    let r = rel_diff(a, b);
                    if k < 3 {
                        s.max_eval_rel = s.max_eval_rel.max(r);
                    } else {
                        s.max_pdf2_rel = s.max_pdf2_rel.max(r);
                    }
                } else if grazing && (a == 0.0) != (b == 0.0) {
                    zero_one_side = true;
                } else {
                    ok = false;
                }
            }
            if zero_one_side {
                s.grazing += 1;
                class = "grazing";
            }
            // The sample.
            let (gs, cs) = (
                gf & kernel::FLAG_SAMPLED != 0,
                cf & kernel::FLAG_SAMPLED != 0,
            );
            if cs {
                s.sampled += 1;
            }
            if gs && cs {
                for k in 0..3 {
                    let e = (g[MS_OUT_WO + k] - c[MS_OUT_WO + k]).abs();
                    ok &= e <= MS_WO_ABS;
                    s.max_wo_abs = s.max_wo_abs.max(e);
                }
                // The density and the weight; at a corner of the square of u within the
                // corner tolerance.
                let corner = [rec[kernel::IN_U], rec[kernel::IN_U + 1]]
                    .iter()
                    .any(|&v| v == 0.0 || v == 1.0);
                let mut beyond = false;
                for j in [
                    MS_OUT_PDF,
                    MS_OUT_WEIGHT,
                    MS_OUT_WEIGHT + 1,
                    MS_OUT_WEIGHT + 2,
                ] {
                    let (a, b) = (g[j], c[j]);
                    let r = rel_diff(a, b);
                    if corner {
                        s.max_corner_rel = s.max_corner_rel.max(r);
                        beyond |= !close(a, b);
                        ok &= close_within(a, b, MS_CORNER_REL);
                    } else if j == MS_OUT_PDF {
                        s.max_pdf_rel = s.max_pdf_rel.max(r);
                        ok &= close(a, b);
                    } else {
                        s.max_weight_rel = s.max_weight_rel.max(r);
                        ok &= close(a, b);
                    }
                }
                if beyond {
                    s.corner += 1;
                    class = "corner";
                }
            } else if gs != cs {
                // Sampled on one side only: that side's direction must be at the horizon.
                let z = if gs {
                    g[MS_OUT_WO + 2]
                } else {
                    c[MS_OUT_WO + 2]
                };
                if z < MS_EDGE_Z {
                    s.edge += 1;
                    class = "edge";
                } else {
                    ok = false;
                }
            }
        }
        if !ok {
            s.failures += 1;
        }
        if (!ok || (verbose && !class.is_empty())) && shown < 8 {
            shown += 1;
            eprintln!(
                "  {label} record {i}: {}\n    input {rec:?}\n    gpu {g:?}\n    cpu {c:?}",
                if ok { class } else { "MISMATCH" }
            );
        }
    }
    println!(
        "{label:<24} {n:>6} {:>6} {:>6} {:>8.1e} {:>8.1e} {:>8.1e} {:>8.1e} {:>8.1e} {:>8.1e} {:>5} {:>5} {:>5} {:>5} {:>7.1} {:>7.1} {:>7.1} {:>7.1}",
        s.prepared,
        s.sampled,
        s.max_eval_rel,
        s.max_pdf2_rel,
        s.max_wo_abs,
        s.max_pdf_rel,
        s.max_weight_rel,
        s.max_corner_rel,
        s.grazing,
        s.edge,
        s.corner,
        s.failures,
        cpu_ms,
        d.first.as_secs_f64() * 1e3,
        d.second.as_secs_f64() * 1e3,
        d.compile.as_secs_f64() * 1e3,
    );
    if s.failures > 0 || s.sampled == 0 {
        Some(label)
    } else {
        None
    }
}

/// Header of the measured material's table.
pub fn header() {
    println!(
        "{:<24} {:>6} {:>6} {:>6} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>5} {:>5} {:>5} {:>5} {:>7} {:>7} {:>7} {:>7}",
        "material",
        "recs",
        "prep",
        "sampl",
        "f rel",
        "pdf2 rel",
        "wo abs",
        "pdf rel",
        "wt rel",
        "corn rel",
        "graz",
        "edge",
        "corn",
        "bad",
        "cpu ms",
        "gpu1 ms",
        "gpu2 ms",
        "pipe ms"
    );
}
