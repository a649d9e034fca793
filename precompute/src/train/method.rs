//! The trainable methods, named by the runtime's [`SamplerKind`], and their trainers: the
//! one list of trainer modules ([`TRAINERS`]). A method's trainer lives in its module
//! (`lobes`, `flow`, `direct_histogram`, `histogram_mixture`, `reparam`), which lists it in
//! its `TRAINERS`; the trainer gives its kind and default settings. Adding a method to a
//! module is that module alone; a new module is one line here.

use neusample::SamplerKind;

use super::config::TrainConfig;
use super::config::{ByKind, Common, HistogramMixture, MaxLikelihood, Reparam, Schedule};
use super::trainer::Trainer;
use super::{direct_histogram, flow, histogram_mixture, lobes, reparam};

/// The trainers of each trainer module, one per trainable kind ([`Trainer::kind`]).
const TRAINERS: [&[&dyn Trainer]; 5] = [
    lobes::TRAINERS,
    flow::TRAINERS,
    direct_histogram::TRAINERS,
    histogram_mixture::TRAINERS,
    reparam::TRAINERS,
];

/// Every trainer.
fn trainers() -> impl Iterator<Item = &'static dyn Trainer> {
    TRAINERS.into_iter().flatten().copied()
}

/// The trainer of `kind`; `None` for cosine sampling, which has nothing to train.
pub(crate) fn trainer(kind: SamplerKind) -> Option<&'static dyn Trainer> {
    trainers().find(|t| t.kind() == kind)
}

/// Every trainable method: every sampler kind but cosine, in the runtime's order (the paper's
/// methods, the disk flow beside the flow, then the reparameterization sampler, which needs
/// an integrand: [`needs_integrand`]).
pub const METHODS: [SamplerKind; SamplerKind::ALL.len() - 1] = {
    let mut out = [SamplerKind::Cosine; SamplerKind::ALL.len() - 1];
    let (mut i, mut j) = (0, 0);
    while i < SamplerKind::ALL.len() {
        if !matches!(SamplerKind::ALL[i], SamplerKind::Cosine) {
            out[j] = SamplerKind::ALL[i];
            j += 1;
        }
        i += 1;
    }
    out
};

/// The trainable method named `name`; the error lists the names.
pub fn parse_method(name: &str) -> anyhow::Result<SamplerKind> {
    SamplerKind::from_name(name)
        .filter(|k| METHODS.contains(k))
        .ok_or_else(|| {
            let names: Vec<_> = METHODS.iter().map(|m| m.name()).collect();
            anyhow::anyhow!(
                "unknown method `{name}`; expected one of {}",
                names.join(", ")
            )
        })
}

/// Whether `method` trains on the integrand itself (a neural material or the synthetic
/// target) rather than on samples of p*: only the reparameterization sampler.
#[must_use]
pub fn needs_integrand(method: SamplerKind) -> bool {
    trainer(method).is_some_and(|t| t.needs_integrand())
}

/// The blob check's tolerance within 1e-2 of a pole of the disk for `method`, where its f32
/// runtime loses precision that its f64 mirror keeps (the disk flow); `None` for the others.
#[must_use]
pub fn pole_tolerance(method: SamplerKind) -> Option<f64> {
    trainer(method).and_then(|t| t.pole_tolerance())
}

impl Default for TrainConfig {
    /// The default run of every method: about a minute per method on two cores.
    fn default() -> Self {
        TrainConfig {
            common: Common::default(),
            max_likelihood: ByKind::from_fn(&METHODS, |k| trainer(k)?.max_likelihood(false)),
            histogram_mixture: HistogramMixture::default(),
            reparam: Reparam::default(),
        }
    }
}

/// The per-method settings of a [`TrainConfig`], reached through the methods' trainers.
impl TrainConfig {
    /// A short run for tests and CI (a few seconds per method).
    #[must_use]
    pub fn quick() -> Self {
        TrainConfig {
            common: Common::quick(),
            max_likelihood: ByKind::from_fn(&METHODS, |k| trainer(k)?.max_likelihood(true)),
            histogram_mixture: HistogramMixture::quick(),
            reparam: Reparam::quick(),
        }
    }

    /// The settings of the methods with a χ² fine-tuning phase after maximum likelihood
    /// (the spline flows), which the command line's χ² options change together.
    pub fn fine_tuned_mut(&mut self) -> impl Iterator<Item = &mut MaxLikelihood> {
        self.max_likelihood
            .iter_mut()
            .filter(|(k, _)| trainer(*k).is_some_and(|t| t.fine_tunes_chi2()))
            .map(|(_, m)| m)
    }

    /// The schedule of `method`; `None` for the kinds that are not trained (cosine, the
    /// neural material).
    #[must_use]
    pub fn schedule(&self, method: SamplerKind) -> Option<Schedule> {
        self.clone().schedule_mut(method).copied()
    }

    /// The schedule of `method`, to change it; `None` for the kinds that are not trained.
    pub fn schedule_mut(&mut self, method: SamplerKind) -> Option<&mut Schedule> {
        Some(super::method::trainer(method)?.schedule_mut(self))
    }

    /// Sets the steps of `method`'s main phase (its schedule; for the reparameterization
    /// sampler the warp's, with or without a warm start); nothing for the kinds that are not
    /// trained.
    pub fn set_steps(&mut self, method: SamplerKind, steps: usize) {
        if let Some(t) = super::method::trainer(method) {
            t.set_steps(self, steps);
        }
    }

    /// Every method's step count multiplied by `factor` (rounded, at least 1).
    #[must_use]
    pub fn with_steps_scaled(mut self, factor: f64) -> Self {
        for kind in METHODS {
            self.scale_steps(kind, factor);
        }
        self
    }

    /// `method`'s step counts multiplied by `factor` (rounded, at least 1): its schedule and,
    /// for the reparameterization sampler, the pdf network's too.
    pub fn scale_steps(&mut self, method: SamplerKind, factor: f64) {
        let scale =
            |s: &mut Schedule| s.steps = ((s.steps as f64 * factor).round() as usize).max(1);
        if let Some(t) = super::method::trainer(method) {
            t.scale_steps(self, &scale);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_by_kind() {
        // Every kind is trained by maximum likelihood but the untrained cosine and the two
        // methods with settings of their own.
        let own = [
            SamplerKind::Cosine,
            SamplerKind::HistogramMixture,
            SamplerKind::Reparam,
        ];
        let ml: Vec<SamplerKind> = SamplerKind::ALL
            .into_iter()
            .filter(|k| !own.contains(k))
            .collect();
        for (cfg, quick) in [
            (TrainConfig::default(), false),
            (TrainConfig::quick(), true),
        ] {
            for k in SamplerKind::ALL {
                let m = cfg.max_likelihood.get(k);
                assert_eq!(m.is_some(), ml.contains(&k), "{k:?}");
                if let Some(m) = m {
                    assert_eq!(Some(m.schedule), cfg.schedule(k), "{k:?}");
                }
            }
            assert_eq!(cfg.schedule(SamplerKind::Cosine), None);
            let hm = cfg.schedule(SamplerKind::HistogramMixture);
            assert_eq!(hm, Some(cfg.histogram_mixture.schedule));
            assert_eq!(
                cfg.schedule(SamplerKind::Reparam),
                Some(cfg.reparam.schedule)
            );
            let flow = cfg.max_likelihood[SamplerKind::SplineFlow].schedule;
            if quick {
                assert_eq!(flow, Schedule::quick());
            } else {
                // The flows' shorter default run.
                assert_eq!((flow.steps, flow.lr), (2000, 5e-3));
            }
        }
    }

    #[test]
    fn every_method_has_one_trainer_and_cosine_none() {
        for k in METHODS {
            let n = trainers().filter(|t| t.kind() == k).count();
            assert_eq!(n, 1, "{k:?}");
        }
        assert!(trainer(SamplerKind::Cosine).is_none());
        assert_eq!(METHODS.len(), SamplerKind::ALL.len() - 1);
    }
}
