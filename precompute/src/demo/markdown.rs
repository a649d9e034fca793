//! `report.md`: the report as Markdown tables (Table 2 speed-ups, fit and cost per material,
//! rendering results) with the figures embedded.

use std::fmt::Write;

use neusample_render::Estimator;

use super::report::{
    FigureReport, MaterialReport, NeuralReport, ReferenceReport, RenderSetup, Report,
};
use crate::util::stats::Estimate;

pub(super) fn fmt_x(v: Option<f64>) -> String {
    match v {
        Some(x) if x.is_finite() => {
            if x >= 10.0 {
                format!("{x:.1}×")
            } else {
                format!("{x:.2}×")
            }
        }
        _ => "—".to_string(),
    }
}

/// `2.49× [1.90–3.10]`: a ratio with its 95 % interval (the interval left out when unknown).
pub(super) fn fmt_x_interval(e: &Estimate) -> String {
    let v = fmt_x(Some(e.value));
    if e.lo.is_finite() && e.hi.is_finite() {
        format!("{v} [{:.2}–{:.2}]", e.lo, e.hi)
    } else {
        v
    }
}

/// `1.2e-3 [0.9e-3–1.6e-3]`: an MSE with its 95 % interval.
pub(super) fn fmt_e_interval(e: &Estimate) -> String {
    if e.lo.is_finite() && e.hi.is_finite() {
        format!("{:.2e} [{:.2e}–{:.2e}]", e.value, e.lo, e.hi)
    } else {
        format!("{:.2e}", e.value)
    }
}

/// The first line of a smoke-test report (`--smoke`), also printed at the end of the run.
pub const SMOKE_LINE: &str = "**Smoke test (`--smoke`): CI-sized run — its numbers check that the \
pipeline works and are not results; drop `--smoke` for the evaluation.**";

/// The Markdown report.
#[must_use]
pub fn markdown(r: &Report) -> String {
    let mut s = String::new();
    intro(&mut s, r);
    if let Some(rs) = &r.render {
        render_intro(&mut s, rs);
        speedup_table(&mut s, r);
    }
    for m in &r.materials {
        let _ = writeln!(s, "## {}\n", m.material);
        if let Some(n) = &m.neural {
            neural_section(&mut s, n);
        }
        fit_table(&mut s, m);
        sampled_notes(&mut s, m);
        if let (Some(rf), Some(fg)) = (&m.reference, &m.figures) {
            rendering_section(&mut s, m, rf, fg);
        }
    }
    s
}

/// The run's first lines: what ran, with which samplers, how fit and cost are measured.
fn intro(s: &mut String, r: &Report) {
    if r.quick {
        let _ = writeln!(s, "{SMOKE_LINE}\n");
    }
    let _ = writeln!(s, "# neusample report\n");
    let _ = writeln!(
        s,
        "{} run, {}, seed {}, {:.0} s. Fit: mean over {} random conditions (φ, wi), ground truth on a {}² grid. \
         Cost: single thread, ns per shading point through the batched API ({} lanes per call), median of passes.\n",
        if r.quick { "Smoke-test" } else { "Full" },
        match (r.fixtures, r.steps_scale) {
            (true, _) => r.blobs.as_ref().map_or_else(
                || "committed pretrained samplers (fixtures/blobs)".to_string(),
                |b| format!("pretrained samplers from {b}"),
            ),
            (false, Some(f)) => format!("freshly trained samplers ({f}× the default training steps)"),
            (false, None) => "freshly trained samplers (quick training)".to_string(),
        },
        r.seed,
        r.seconds,
        r.eval_conditions,
        r.eval_res,
        crate::eval::COST_BATCH
    );
}

/// How the images are rendered and compared.
fn render_intro(s: &mut String, rs: &RenderSetup) {
    let st = &rs.settings;
    let _ = writeln!(
        s,
        "Rendering: a {}×{} image of a textured patch and a sphere under {} (sun radiance {}, \
         radius {}°), direct lighting by {}. Reference: the tabulated oracle ({}² cells) with MIS at {} spp; \
         MSE over the pixels that hit an object, minus the reference's own noise. \
         Time per sample: single-thread wall time of the whole render loop per pixel sample \
         (oracle: per-pixel table build excluded — it is a limit, not a method). \
         Runtime samplers render on the wavefront (batched) path, the oracle on the scalar one (the two integrators give the same image). \
         Speed-up (Table 2): (V·time of the improved baseline) / (V·time of the method), i.e. the relative time the \
         baseline needs for the same quality, with V the per-sample variance from independent sample blocks of the \
         N = {} spp renders (median of means) and time the median of interleaved single-thread passes; 95 % bootstrap \
         intervals over blocks and passes (the speed-up from the whole image's MSE against the reference is shown \
         beside it). Equal time: every method gets the baseline's time for {} spp.\n",
        rs.width,
        rs.height,
        match (&rs.env_map, rs.uniform_light) {
            (Some(e), _) => format!("the map {e}"),
            (None, true) => "uniform white light".to_string(),
            (None, false) => "a procedural sky".to_string(),
        },
        rs.sun_radiance,
        rs.sun_radius_deg,
        match st.estimator {
            Estimator::Bsdf => "BSDF sampling (the paper's main mode)",
            Estimator::Mis => "MIS of BSDF and environment sampling (power heuristic)",
        },
        st.ref_res,
        st.ref_spp,
        st.max_spp,
        st.max_spp,
    );
}

/// Table 2: every material's speed-up over the improved baseline, with the verdict.
fn speedup_table(s: &mut String, r: &Report) {
    // Table 2.
    let methods: Vec<String> = r
        .materials
        .first()
        .map(|m| m.methods.iter().map(|x| x.method.clone()).collect())
        .unwrap_or_default();
    let _ = writeln!(s, "## Speed-up over the improved baseline (Table 2)\n");
    let _ = writeln!(
        s,
        "Paper: best method per material 1.28×–6.78×, mean 2.58×; flow 1.17–6.78×, histogram mixture 1.07–6.12×, cosine 0.05–0.88×. \
         In brackets the 95 % interval (bootstrap over {} independent sample blocks per render, median of means; \
         docs/report_schema.md, \"Statistics\"). The best practical method (oracle excluded) is in bold when its interval clears every other \
         method's; otherwise the verdict column names the tie.\n",
        r.render.as_ref().map_or(0, |rs| rs.settings.blocks)
    );
    let _ = writeln!(s, "| material | {} | verdict |", methods.join(" | "));
    let _ = writeln!(s, "|---|{}---|", "---:|".repeat(methods.len()));
    for m in &r.materials {
        let cells: Vec<String> = m
            .methods
            .iter()
            .map(|x| {
                let t = x
                    .render
                    .as_ref()
                    .map_or_else(|| fmt_x(None), |rr| fmt_x_interval(&rr.speedup));
                match &m.verdict {
                    Some(v) if v.clear && v.best == x.method => format!("**{t}**"),
                    _ => t,
                }
            })
            .collect();
        let verdict = match &m.verdict {
            Some(v) if v.clear => format!("{} (clear)", v.best),
            Some(v) => format!("tie: {}, {}", v.best, v.tied_with.join(", ")),
            None => "—".to_string(),
        };
        let _ = writeln!(s, "| {} | {} | {verdict} |", m.material, cells.join(" | "));
    }
    let _ = writeln!(s);
}

/// A neural material's fit to its source and its cost.
fn neural_section(s: &mut String, n: &NeuralReport) {
    let _ = writeln!(
        s,
        "Neural material (feature texture + decoder, NEURAL.md) fitted to `{}`: relative RGB error {:.1} % \
         (wo on the disk), {:.1} % (around the mirror direction), albedo error {:.1} %, \
         KL(p*_source ‖ p*_neural) = {:.4} nats (cosine sampling: {:.4}). Evaluation cost: {:.0} ns \
         per lane batched ({} lanes per call), {:.0} ns one at a time (source {:.0} ns); feature lookup \
         {:.0} ns batched, {:.0} ns one at a time (source {:.0} ns). The samplers are trained on the \
         neural material (φ = learned features, p* from the decoder); `KL(p*_src‖p)` measures them \
         against the source material.\n",
        n.source,
        100.0 * n.fit.relative_rgb_error,
        100.0 * n.fit.relative_rgb_error_lobe,
        100.0 * n.fit.albedo_relative_error,
        n.fit.kl_pstar,
        n.fit.kl_pstar_vs_cosine,
        n.cost.eval_batch_ns,
        crate::eval::COST_BATCH,
        n.cost.eval_ns,
        n.source_cost.eval_ns,
        n.cost.features_batch_ns,
        n.cost.features_ns,
        n.source_cost.features_ns,
    );
}

/// A material's table of fit and cost per method.
fn fit_table(s: &mut String, m: &MaterialReport) {
    let _ = writeln!(
        s,
        "### pdf fit and cost (Table 1 ratio: sampling cost / material evaluation)\n\n\
         Costs are single-thread ns per shading point through the batched API ({} lanes per \
         call, the path the renderer uses), the material's evaluation likewise; the scalar \
         column is prepare + sample + pdf one shading point at a time. The oracle has no \
         batched path (its figures are scalar).\n",
        crate::eval::COST_BATCH
    );
    let _ = writeln!(
        s,
        "| method | KL(p*‖p) | χ²(p*‖p) mean | χ² worst | KL(p*_src‖p) | pdf MSE | mass in disk | prepare ns | sample ns | pdf ns | prepare+sample+pdf ns | scalar ns | material eval ns | ×material eval | train s | blob bytes |"
    );
    let _ = writeln!(
        s,
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
    );
    for x in &m.methods {
        let _ = writeln!(
            s,
            "| {} | {:.4} | {} | {} | {} | {:.3e} | {:.4} | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} | {:.2} | {:.1} | {} |",
            x.method,
            x.fit.kl_divergence,
            fmt_chi2(x.fit.chi2),
            fmt_chi2(x.fit.chi2_worst),
            x.kl_vs_source
                .map_or_else(|| "—".to_string(), |k| format!("{k:.4}")),
            x.fit.pdf_mse,
            x.fit.mass_in_disk,
            x.cost.prepare_ns,
            x.cost.sample_ns,
            x.cost.pdf_ns,
            x.cost.total_ns,
            x.cost.scalar_total_ns,
            x.cost.material_eval_ns,
            x.cost_vs_material_eval(),
            x.train_seconds,
            x.blob_bytes
        );
    }
    let _ = writeln!(s);
}

/// What a method that draws with another density than its pdf measured on its own samples.
fn sampled_notes(s: &mut String, m: &MaterialReport) {
    for x in &m.methods {
        if let Some(sf) = &x.fit.sampled {
            let _ = writeln!(
                s,
                "`{}` draws with the density of its warp and reports its pdf network for MIS \
                 (the fit columns above are the pdf network's). On its own samples ({} per \
                 condition): weight mean E[f·cos/pdf]/albedo {:.4} (worst condition {:.4}; 1 is \
                 unbiased), χ²(p*‖q) of the sampling density {}, pdf network against it: \
                 KL(q‖p̂) {:.4}, χ²(q‖p̂) {}.\n",
                x.method,
                crate::eval::FIT_SAMPLES,
                sf.weight_mean,
                sf.weight_mean_worst,
                fmt_chi2(sf.chi2),
                sf.mis_kl,
                fmt_chi2(sf.mis_chi2),
            );
        }
    }
}

/// A material's rendering table, reference and figures.
fn rendering_section(s: &mut String, m: &MaterialReport, rf: &ReferenceReport, fg: &FigureReport) {
    let _ = writeln!(s, "### Rendering\n");
    let _ = writeln!(
        s,
        "| method | render ns/sample | ×cosine time | MSE @ N spp (image) | MSE @ N spp (blocks) | MSE ratio vs baseline (N spp) | equal-time spp | MSE @ equal time | speed-up vs baseline | speed-up (image MSE) |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for x in &m.methods {
        if let Some(rr) = &x.render {
            let _ = writeln!(
                s,
                "| {} | {:.0} | {:.2} | {:.3e} | {} | {} | {} | {} | {} | {} |",
                x.method,
                rr.ns_per_sample,
                rr.time_vs_cosine,
                rr.mse_equal_spp,
                fmt_e_interval(&rr.mse_equal_spp_interval),
                fmt_x_interval(&rr.mse_ratio),
                rr.equal_time_spp,
                fmt_e_interval(&rr.mse_equal_time_interval),
                fmt_x_interval(&rr.speedup),
                fmt_x(Some(rr.speedup_measured_mse)),
            );
        }
    }
    let _ = writeln!(
        s,
        "\nReference: {} spp, oracle {}², {} pixels on objects, its noise {:.2e} (subtracted). \
         Equal-time budget: {:.0} ms single-thread per image. Linear EXRs beside the PNGs.\n",
        rf.spp,
        rf.res,
        rf.pixels,
        rf.noise,
        m.equal_time_budget_seconds.unwrap_or(f64::NAN) * 1e3
    );
    let _ = writeln!(s, "![equal time]({})\n", fg.equal_time);
    let _ = writeln!(s, "![convergence]({})\n", fg.convergence);
    let _ = writeln!(s, "![pdfs]({})\n", fg.pdfs);
    if !fg.weights.is_empty() {
        let _ = writeln!(
            s,
            "Sample weights p*/p of each learned sampler at its two worst-χ² fit \
             conditions (where the render's variance comes from):\n\n![weights]({})\n",
            fg.weights
        );
    }
    let _ = writeln!(s, "![equal spp]({})\n", fg.equal_spp);
}

/// A χ² divergence for the tables: 3 significant digits, `—` when not measured.
pub(crate) fn fmt_chi2(x: f64) -> String {
    if x.is_nan() {
        "—".to_string()
    } else if x.abs() >= 1000.0 {
        format!("{x:.2e}")
    } else {
        format!("{x:.3}")
    }
}
