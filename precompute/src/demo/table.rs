//! The evaluation over every built-in material (`neusample table`): the demo pipeline on the
//! neural version of each built-in with the committed samplers (and on material files, whose
//! samplers come from the fixtures or are trained once into the output folder), under two
//! lightings, and one Markdown file with the paper's Table 2 (speed-up over the improved
//! baseline, with intervals) and Table 1 (time per sample: tracing and shading, material
//! evaluation, sampling) for both.
//!
//! Two lightings, because they measure different things: under **uniform white light** the
//! render's variance comes from the BSDF sampler alone (the paper's uniformly lit scenes);
//! under the **sky with a small bright sun** BSDF sampling must also find the light, which
//! for broad lobes no sampler can do well (the paper's environment-lit scenes). The table
//! keeps them apart instead of averaging them.

use std::fmt::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use neusample::SamplerKind;

use super::config::{neural_fixture, DemoConfig, BASELINE, COSINE, ORACLE};
use super::fixtures::{fixture_path, fixtures_dir, neural_fixtures};
use super::markdown::{fmt_x, fmt_x_interval};
use super::pipeline;
use super::report::{MaterialReport, Report};
use crate::materials::{self, Material};
use crate::train::{has_integrand, needs_integrand};
use crate::util::io::{self, slug};
use crate::util::stats::Estimate;

/// Random conditions of each material's fit measures in the table (more than the demo's).
pub const TABLE_EVAL_CONDITIONS: usize = 128;

/// Interleaved timing passes per method in the table (more than the demo's).
pub const TABLE_TIMING_PASSES: usize = 15;

/// A lighting of the table.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Lighting {
    /// Uniform white light: the variance measures the sampler.
    Uniform,
    /// The procedural sky with a small bright sun (the demo's default).
    SkySun,
}

impl Lighting {
    /// Both, in the order of the table.
    pub const ALL: [Lighting; 2] = [Lighting::Uniform, Lighting::SkySun];

    /// Folder name and label.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Lighting::Uniform => "uniform",
            Lighting::SkySun => "sky-sun",
        }
    }

    const fn title(self) -> &'static str {
        match self {
            Lighting::Uniform => "uniform white light",
            Lighting::SkySun => "sky with a small bright sun",
        }
    }
}

/// What `neusample table` runs.
#[derive(Clone, Debug, PartialEq)]
pub struct TableConfig {
    /// Output folder: `<out>/<lighting>/` holds each lighting's demo report, `<out>/table.md`
    /// the combined tables.
    pub out: PathBuf,
    /// Materials, mixed as they come: built-in names (their neural versions are evaluated,
    /// with the committed samplers) and material files (`.toml`, `.json`, `.bsdf`, `.nsb`;
    /// their samplers are read from `fixtures/blobs/<name>/` when it holds every method
    /// evaluated, else trained once, as `demo --train` trains them, into
    /// `<out>/blobs/<name>/`, where a later run finds them); default: every built-in.
    pub materials: Vec<String>,
    /// Seed of the evaluation.
    pub seed: u64,
    /// Image width (height = 3/4 of it).
    pub width: usize,
    /// Equal-spp sample count N.
    pub spp: u32,
    /// Only rewrite `table.md` from the reports already in `out`.
    pub markdown_only: bool,
    /// The demo's CI-sized smoke test for each lighting (its numbers are not results).
    pub smoke: bool,
    /// The trained methods evaluated (`DemoConfig::methods`; empty: all).
    pub methods: Vec<SamplerKind>,
    /// The lightings run (empty: both). `table.md` also shows a lighting not run whose
    /// report is already in `out`, marked as from an earlier run.
    pub lightings: Vec<Lighting>,
}

impl TableConfig {
    /// The defaults of the command line, writing to `out`.
    #[must_use]
    pub fn new(out: impl Into<PathBuf>) -> Self {
        TableConfig {
            out: out.into(),
            materials: Vec::new(),
            seed: 1,
            width: 128,
            spp: 32,
            markdown_only: false,
            smoke: false,
            methods: Vec::new(),
            lightings: Vec::new(),
        }
    }

    /// The lightings run, in the table's order.
    fn lightings_run(&self) -> Vec<Lighting> {
        Lighting::ALL
            .into_iter()
            .filter(|l| self.lightings.is_empty() || self.lightings.contains(l))
            .collect()
    }

    /// The materials asked for (every built-in by default), each a built-in name or a file.
    fn entries(&self) -> Result<Vec<Entry>> {
        if self.materials.is_empty() {
            return Ok(materials::builtin_names()
                .iter()
                .map(|n| Entry::Builtin(n.to_string()))
                .collect());
        }
        self.materials
            .iter()
            .map(|spec| {
                if materials::builtin_names().contains(&spec.as_str()) {
                    return Ok(Entry::Builtin(spec.clone()));
                }
                let material = materials::resolve(spec).with_context(|| {
                    format!("`{spec}` is neither a built-in material nor a material file")
                })?;
                Ok(Entry::File {
                    spec: spec.clone(),
                    material,
                })
            })
            .collect()
    }

    /// The demo run of one lighting over `entries`, reading the samplers of the materials in
    /// `material_blobs` from their folders.
    fn demo(
        &self,
        lighting: Lighting,
        entries: &[Entry],
        material_blobs: &[(String, PathBuf)],
    ) -> DemoConfig {
        let mut d = DemoConfig::new(self.out.join(lighting.name()));
        d.use_fixtures = true;
        d.quick = self.smoke;
        d.seed = self.seed;
        if !self.smoke {
            d.width = Some(self.width);
            d.spp = Some(self.spp);
            d.eval_conditions = Some(TABLE_EVAL_CONDITIONS);
            d.timing_passes = Some(TABLE_TIMING_PASSES);
        }
        d.uniform_light = lighting == Lighting::Uniform;
        d.methods = self.methods.clone();
        d.materials = entries
            .iter()
            .map(|e| match e {
                Entry::Builtin(n) => neural_fixture(n).to_string_lossy().into_owned(),
                Entry::File { spec, .. } => spec.clone(),
            })
            .collect();
        d.material_blobs = material_blobs.to_vec();
        d
    }
}

/// A material of the table.
enum Entry {
    /// A built-in: its neural version with the committed samplers.
    Builtin(String),
    /// A material file, as given, and its material.
    File {
        spec: String,
        material: Box<dyn Material>,
    },
}

/// `neusample table`: regenerates the neural fixtures that are not committed (training, slow),
/// runs the demo pipeline for both lightings and writes `<out>/table.md`.
pub fn run(cfg: &TableConfig) -> Result<()> {
    let entries = cfg.entries()?;
    let mut seconds = Vec::new();
    if !cfg.markdown_only {
        let methods = cfg.demo(Lighting::Uniform, &[], &[]).method_list();
        let missing: Vec<&str> = entries
            .iter()
            .filter_map(|e| match e {
                Entry::Builtin(n) if !fixtures_complete(n, &methods) => Some(n.as_str()),
                _ => None,
            })
            .collect();
        if !missing.is_empty() {
            eprintln!(
                "neusample table: training the neural fixtures not committed: {}",
                missing.join(", ")
            );
            neural_fixtures(&fixtures_dir(), &neural_dir(), &missing, &[], false)?;
        }
        let mut material_blobs = Vec::new();
        for e in &entries {
            if let Entry::File { material, .. } = e {
                if let Some(dir) = file_samplers(cfg, material.as_ref())? {
                    material_blobs.push((material.name().to_string(), dir));
                }
            }
        }
        for lighting in cfg.lightings_run() {
            let t = Instant::now();
            pipeline::run(&cfg.demo(lighting, &entries, &material_blobs))
                .with_context(|| format!("the {} run", lighting.name()))?;
            seconds.push((lighting, t.elapsed().as_secs_f64()));
        }
    }
    let run_now = cfg.lightings_run();
    let mut reports = Vec::new();
    let mut earlier = Vec::new();
    for lighting in Lighting::ALL {
        let path = cfg.out.join(lighting.name()).join("report.json");
        let wanted = run_now.contains(&lighting);
        if !wanted && !path.exists() {
            continue;
        }
        if !wanted {
            earlier.push(lighting);
        }
        let text = std::fs::read_to_string(&path)
            .with_context(|| format!("cannot read {}", path.display()))?;
        let r: Report = serde_json::from_str(&text)
            .with_context(|| format!("{} is not a demo report", path.display()))?;
        reports.push((lighting, r));
    }
    let md = table_markdown(&reports, &earlier, cfg);
    io::atomic_write(&cfg.out.join("table.md"), md.as_bytes())?;
    if !seconds.is_empty() {
        let parts: Vec<String> = seconds
            .iter()
            .map(|(l, t)| format!("{t:.0} s {}", l.name()))
            .collect();
        eprintln!(
            "neusample table: {} materials, {:.0} s ({}); {}",
            entries.len(),
            seconds.iter().map(|x| x.1).sum::<f64>(),
            parts.join(", "),
            cfg.out.join("table.md").display()
        );
    }
    Ok(())
}

fn neural_dir() -> PathBuf {
    neural_fixture("x")
        .parent()
        .map_or_else(PathBuf::new, Path::to_path_buf)
}

/// The samplers of the material file `m`: `None` when `fixtures/blobs/<name>/` holds every
/// method evaluated (the demo reads them there); else the folder `<out>/blobs`, after training
/// the methods not yet in `<out>/blobs/<name>/` as `demo --train` trains them. A blob already
/// there is kept when its label says it was trained with this run's settings (a run of one
/// lighting, then of the other, evaluates the same samplers), and trained again otherwise
/// (e.g. a `--smoke` blob met by a full run).
fn file_samplers(cfg: &TableConfig, m: &dyn Material) -> Result<Option<PathBuf>> {
    let demo = cfg.demo(Lighting::Uniform, &[], &[]);
    let name = slug(m.name());
    let methods: Vec<SamplerKind> = demo
        .method_list()
        .into_iter()
        .filter(|&k| !needs_integrand(k) || has_integrand(m))
        .collect();
    let holds_all = |dir: &Path| {
        methods
            .iter()
            .all(|k| fixture_path(dir, &name, k.name()).exists())
    };
    if holds_all(&fixtures_dir()) {
        return Ok(None);
    }
    let dir = cfg.out.join("blobs");
    let settings = pipeline::demo_train_config(&demo);
    for &k in &methods {
        let path = fixture_path(&dir, &name, k.name());
        let want = pipeline::demo_blob_label(m.name(), k, &settings);
        match trained_label(&path) {
            Some(label) if label == want => continue,
            Some(_) => eprintln!(
                "neusample table: {} was not trained with this run's settings; retraining",
                path.display()
            ),
            None => {}
        }
        eprintln!(
            "neusample table: training {} on {} into {}",
            k.name(),
            m.name(),
            path.display()
        );
        let trained = pipeline::train_blob(m, k, &demo)?;
        io::atomic_write(&path, &trained.bytes)?;
    }
    Ok(Some(dir))
}

/// The label of the blob at `path`; `None` when there is no file or it is not a blob.
fn trained_label(path: &Path) -> Option<String> {
    let bytes = std::fs::read(path).ok()?;
    let blob = neusample::Blob::open(&bytes).ok()?;
    Some(blob.header().label.to_string())
}

/// Whether the neural version of `name` and its samplers of `methods` are committed.
fn fixtures_complete(name: &str, methods: &[SamplerKind]) -> bool {
    let dir = fixtures_dir();
    let neural = format!("{}{}", slug(name), super::config::NEURAL_SUFFIX);
    neural_fixture(name).exists()
        && methods
            .iter()
            .all(|m| fixture_path(&dir, &neural, m.name()).exists())
}

/// The best practical method of a material (largest speed-up, oracle excluded) and its
/// speed-up.
fn best_practical(m: &MaterialReport) -> Option<(&str, f64)> {
    m.methods
        .iter()
        .filter(|x| x.method != ORACLE)
        .filter_map(|x| Some((x.method.as_str(), x.render.as_ref()?.speedup.value)))
        .filter(|(_, v)| v.is_finite())
        .max_by(|a, b| a.1.total_cmp(&b.1))
}

fn speedup(m: &MaterialReport, method: &str) -> Option<Estimate> {
    m.methods
        .iter()
        .find(|x| x.method == method)
        .and_then(|x| x.render.as_ref())
        .map(|r| r.speedup)
}

/// The combined Markdown: Table 2 per lighting, a summary of which methods win, the equal-spp
/// error ratios, Table 1 and links to the convergence plots. The lightings of `earlier` were
/// not run by this invocation (their reports were already in the folder).
#[must_use]
pub fn table_markdown(
    reports: &[(Lighting, Report)],
    earlier: &[Lighting],
    cfg: &TableConfig,
) -> String {
    let mut s = String::new();
    if cfg.smoke {
        let _ = writeln!(s, "{}\n", super::markdown::SMOKE_LINE);
    }
    let (title, what) = if cfg.materials.is_empty() {
        (
            "every built-in material",
            "the neural version of each built-in material with its committed samplers \
             (`fixtures/`)",
        )
    } else {
        (
            "the materials asked for",
            "the neural version of each built-in material named with its committed samplers \
             (`fixtures/`), and each material file with the samplers of `fixtures/blobs/<name>/` \
             when it holds them all, else with samplers trained once into \
             `<out>/blobs/<name>/` as `neusample demo --train` trains them",
        )
    };
    let _ = writeln!(
        s,
        "# neusample over {title} (Table 2 and Table 1)\n\n\
         `neusample table --out {}` (seed {}, {}×{} pixels, N = {} spp): {what}, rendered \
         through the batched path on one patch and sphere, **direct lighting by BSDF \
         sampling** under two lightings. Each lighting's full report (fits, costs, images, convergence plots, \
         `report.json`) is in its folder. Speed-up = `(V·t)_baseline / (V·t)_method`: V the \
         per-sample variance (median of means over independent sample blocks), t the \
         single-thread time per sample including the neural material's evaluation; in brackets \
         the 95 % bootstrap interval. **Bold**: best with confidence (its interval clears every \
         other practical method's); otherwise the verdict names the tie. The oracle (a \
         per-shading-point table of p*) is a limit, not a method.\n",
        cfg.out.display(),
        cfg.seed,
        cfg.width,
        cfg.width * 3 / 4,
        cfg.spp
    );
    for (lighting, r) in reports {
        let _ = writeln!(
            s,
            "Run time, {}: {:.0} s on this machine{}.",
            lighting.title(),
            r.seconds,
            if earlier.contains(lighting) {
                " (an earlier run, kept from the folder: its fixtures and methods may differ \
                 from the other lighting's)"
            } else {
                ""
            }
        );
    }
    let _ = writeln!(s);
    for (lighting, r) in reports {
        table2(&mut s, *lighting, r);
    }
    let _ = writeln!(
        s,
        "## Error at equal sample count (MSE ratio, baseline = 1)\n"
    );
    let _ = writeln!(
        s,
        "How much of the baseline's variance each method removes at equal spp, time left out: \
         the fit's side of Table 2 (point values; intervals in the reports).\n"
    );
    for (lighting, r) in reports {
        mse_ratios(&mut s, *lighting, r);
    }
    if let Some((_, r)) = reports.first() {
        table1(&mut s, r);
    }
    let _ = writeln!(s, "## Convergence plots (Fig. 8 style)\n");
    let _ = writeln!(
        s,
        "MSE against time per method, one plot per material and lighting:\n"
    );
    let _ = writeln!(s, "| material | {} |", {
        let v: Vec<&str> = reports.iter().map(|(l, _)| l.title()).collect();
        v.join(" | ")
    });
    let _ = writeln!(s, "|---|{}", "---|".repeat(reports.len()));
    if let Some((_, first)) = reports.first() {
        for (i, m) in first.materials.iter().enumerate() {
            let cells: Vec<String> = reports
                .iter()
                .map(|(l, r)| {
                    r.materials
                        .get(i)
                        .and_then(|m| m.figures.as_ref())
                        .map_or_else(
                            || "—".to_string(),
                            |f| format!("[plot]({}/{})", l.name(), f.convergence),
                        )
                })
                .collect();
            let _ = writeln!(s, "| {} | {} |", m.material, cells.join(" | "));
        }
    }
    let _ = writeln!(s);
    s
}

fn method_names(r: &Report) -> Vec<String> {
    r.materials
        .first()
        .map(|m| m.methods.iter().map(|x| x.method.clone()).collect())
        .unwrap_or_default()
}

fn table2(s: &mut String, lighting: Lighting, r: &Report) {
    let methods = method_names(r);
    let _ = writeln!(s, "## Table 2, {}\n", lighting.title());
    let _ = writeln!(s, "| material | {} | verdict |", methods.join(" | "));
    let _ = writeln!(s, "|---|{}---|", "---:|".repeat(methods.len()));
    let mut best_sum = 0.0;
    let mut best_n = 0usize;
    let mut wins: Vec<(String, usize, usize)> = methods
        .iter()
        .filter(|m| m.as_str() != ORACLE)
        .map(|m| (m.clone(), 0, 0))
        .collect();
    for m in &r.materials {
        let cells: Vec<String> = methods
            .iter()
            .map(|name| {
                let t = speedup(m, name).map_or_else(|| "—".to_string(), |e| fmt_x_interval(&e));
                match &m.verdict {
                    Some(v) if v.clear && &v.best == name => format!("**{t}**"),
                    _ => t,
                }
            })
            .collect();
        let verdict = match &m.verdict {
            Some(v) if v.clear => {
                if let Some(w) = wins.iter_mut().find(|w| w.0 == v.best) {
                    w.1 += 1;
                }
                format!("{} (clear)", v.best)
            }
            Some(v) => {
                for name in std::iter::once(&v.best).chain(&v.tied_with) {
                    if let Some(w) = wins.iter_mut().find(|w| &w.0 == name) {
                        w.2 += 1;
                    }
                }
                format!("tie: {}, {}", v.best, v.tied_with.join(", "))
            }
            None => "—".to_string(),
        };
        if let Some((_, v)) = best_practical(m) {
            best_sum += v;
            best_n += 1;
        }
        let _ = writeln!(s, "| {} | {} | {verdict} |", m.material, cells.join(" | "));
    }
    let _ = writeln!(
        s,
        "\nMean over materials of the best practical method's speed-up (point values): **{}** \
         (paper: 2.58× over its twelve materials). Best with confidence / among the tied best, \
         per method: {}.\n",
        fmt_x((best_n > 0).then(|| best_sum / best_n as f64)),
        wins.iter()
            .map(|(n, c, t)| format!("{n} {c} / {t}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
}

fn mse_ratios(s: &mut String, lighting: Lighting, r: &Report) {
    let methods = method_names(r);
    let _ = writeln!(s, "**{}**\n", lighting.title());
    let _ = writeln!(s, "| material | {} |", methods.join(" | "));
    let _ = writeln!(s, "|---|{}", "---:|".repeat(methods.len()));
    for m in &r.materials {
        let cells: Vec<String> = methods
            .iter()
            .map(|name| {
                m.methods
                    .iter()
                    .find(|x| &x.method == name)
                    .and_then(|x| x.render.as_ref())
                    .map_or_else(|| "—".to_string(), |rr| fmt_x(Some(rr.mse_ratio.value)))
            })
            .collect();
        let _ = writeln!(s, "| {} | {} |", m.material, cells.join(" | "));
    }
    let _ = writeln!(s);
}

/// Table 1: the time per sample of each method split into tracing and shading, the neural
/// material's evaluation and sampling, as medians over the materials. Sampling inside the
/// render is the method's render time minus cosine sampling's render time (plus cosine's own
/// sampling cost): everything else in the loop is the same for every method.
fn table1(s: &mut String, r: &Report) {
    let methods: Vec<String> = method_names(r)
        .into_iter()
        .filter(|m| m != ORACLE)
        .collect();
    let _ = writeln!(
        s,
        "## Table 1: where the time per sample goes
"
    );
    let _ = writeln!(
        s,
        "Single thread, ns per pixel sample, median over the {} materials of the first lighting's \
         run (ranges in brackets). *Render*: the measured time per sample of the whole render \
         loop (wavefront path, tiles of 256 pixels). *Material eval*: the neural material's \
         batched evaluation per call, measured apart. *Tracing and the rest*: cosine sampling's \
         render time minus its sampling cost and the material's evaluation — rays, frames, the \
         light, the integrator, the same for every method. *Sampling in the render*: a method's \
         render time minus cosine's, plus cosine's sampling cost. *Sampling apart*: prepare + \
         sample + pdf through the batched API at {} lanes, measured apart (`report.json` \
         `cost`); it is larger than the share inside the render because BSDF sampling needs no \
         separate `pdf` call and the render's batches are larger. The paper's Table 1 (GPU): \
         sampling 0.1–6.5 ms of 41–55 ms per spp, the material 25 ms.\n",
        r.materials.len(),
        crate::eval::COST_BATCH
    );
    let _ = writeln!(
        s,
        "| method | render | material eval | tracing and the rest | sampling in the render | sampling apart | sampling in the render ÷ eval |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|---:|");
    for name in &methods {
        let mut cols: [Vec<f64>; 6] = Default::default();
        for m in &r.materials {
            let find = |n: &str| m.methods.iter().find(|x| x.method == n);
            let (Some(x), Some(c)) = (find(name), find(COSINE)) else {
                continue;
            };
            let (Some(rr), Some(rc)) = (&x.render, &c.render) else {
                continue;
            };
            let e = m
                .neural
                .as_ref()
                .map_or(x.cost.material_eval_ns, |n| n.cost.eval_batch_ns);
            let in_render = rr.ns_per_sample - rc.ns_per_sample + c.cost.total_ns;
            cols[0].push(rr.ns_per_sample);
            cols[1].push(e);
            cols[2].push(rc.ns_per_sample - c.cost.total_ns - e);
            cols[3].push(in_render);
            cols[4].push(x.cost.total_ns);
            cols[5].push(in_render / e.max(1e-9));
        }
        let cells: Vec<String> = cols
            .iter_mut()
            .enumerate()
            .map(|(i, v)| med_range(v, if i == 5 { 2 } else { 0 }))
            .collect();
        let _ = writeln!(s, "| {name} | {} |", cells.join(" | "));
    }
    let _ = writeln!(
        s,
        "\n{BASELINE} is the reference of every speed-up; its row shows what the cheapest \
         learned sampler costs.\n"
    );
}

fn med_range(v: &mut Vec<f64>, digits: usize) -> String {
    v.retain(|x| x.is_finite());
    if v.is_empty() {
        return "—".to_string();
    }
    v.sort_by(f64::total_cmp);
    let med = v[v.len() / 2];
    format!(
        "{med:.digits$} ({:.digits$}–{:.digits$})",
        v[0],
        v[v.len() - 1]
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A blob in `<out>/blobs` is reused only when its label names this run's training
    /// settings: another schedule, step scale or seed gives another label (the lighting
    /// does not: both lightings evaluate one set of samplers), and a missing or broken file
    /// has no label.
    #[test]
    fn blobs_trained_with_other_settings_are_not_reused() {
        let dir = tempfile::tempdir().unwrap();
        let mut t = TableConfig::new(dir.path());
        let k = SamplerKind::ImprovedBaseline;
        let label =
            |d: &DemoConfig| pipeline::demo_blob_label("mint", k, &pipeline::demo_train_config(d));
        t.smoke = true;
        let quick = t.demo(Lighting::Uniform, &[], &[]);
        t.smoke = false;
        let full = t.demo(Lighting::Uniform, &[], &[]);
        assert_eq!(label(&full), label(&t.demo(Lighting::SkySun, &[], &[])));
        assert_eq!(label(&quick), label(&quick.clone()));
        assert_ne!(label(&quick), label(&full));
        let mut reseeded = full.clone();
        reseeded.seed += 1;
        assert_ne!(label(&full), label(&reseeded));
        let mut longer = full.clone();
        longer.steps_scale *= 2.0;
        assert_ne!(label(&full), label(&longer));
        let head = format!("demo material=mint method={} steps=", k.name());
        assert!(label(&full).starts_with(&head), "{}", label(&full));

        let path = dir.path().join("baseline.nsb");
        assert_eq!(trained_label(&path), None);
        std::fs::write(&path, b"not a blob").unwrap();
        assert_eq!(trained_label(&path), None);
        let committed = fixture_path(&fixtures_dir(), "goat_leather_neural", "flow");
        let l = trained_label(&committed).expect("a committed blob has a label");
        assert!(l.contains("method=flow"), "{l}");
    }
}
