//! Small statistics over slices.

/// Mean of f32 values in f64; 0 for an empty slice.
#[must_use]
pub fn mean(v: &[f32]) -> f64 {
    v.iter().map(|&x| f64::from(x)).sum::<f64>() / v.len().max(1) as f64
}

/// `num / den`, or NaN when the quotient is not defined (`den ≤ 0` or either not finite).
#[must_use]
pub fn ratio(num: f64, den: f64) -> f64 {
    if den > 0.0 && num.is_finite() && den.is_finite() {
        num / den
    } else {
        f64::NAN
    }
}

/// Median of means (Lugosi & Mendelson 2019, "Mean estimation and regression under
/// heavy-tailed distributions"): `v` split into `groups` consecutive groups of nearly equal
/// size (at most `v.len()`), the median of the group means (the mean of the two middle ones
/// for an even count). Unlike the plain mean, one huge value moves it by at most one group's
/// share; for light tails it is close to the mean. NaN for an empty slice.
#[must_use]
pub fn median_of_means(v: &[f64], groups: usize) -> f64 {
    let g = groups.clamp(1, v.len().max(1));
    if v.is_empty() {
        return f64::NAN;
    }
    let mut means: Vec<f64> = (0..g)
        .map(|k| {
            let (a, b) = (k * v.len() / g, (k + 1) * v.len() / g);
            v[a..b].iter().sum::<f64>() / (b - a) as f64
        })
        .collect();
    means.sort_by(f64::total_cmp);
    let m = means.len();
    if m % 2 == 1 {
        means[m / 2]
    } else {
        0.5 * (means[m / 2 - 1] + means[m / 2])
    }
}

/// A point estimate with its 95 % interval.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Estimate {
    /// The estimate.
    #[serde(deserialize_with = "crate::util::json::f64_or_nan")]
    pub value: f64,
    /// Lower end of the 95 % interval.
    #[serde(deserialize_with = "crate::util::json::f64_or_nan")]
    pub lo: f64,
    /// Upper end of the 95 % interval.
    #[serde(deserialize_with = "crate::util::json::f64_or_nan")]
    pub hi: f64,
}

impl Estimate {
    /// Every field NaN (nothing to estimate from).
    pub const NAN: Estimate = Estimate {
        value: f64::NAN,
        lo: f64::NAN,
        hi: f64::NAN,
    };

    /// The estimate and its interval multiplied by `k ≥ 0`.
    #[must_use]
    pub fn scaled(self, k: f64) -> Estimate {
        Estimate {
            value: self.value * k,
            lo: self.lo * k,
            hi: self.hi * k,
        }
    }
}

/// Resamples of [`bootstrap`].
pub const BOOTSTRAP_RESAMPLES: usize = 2000;

/// `stat` of `sets` with a 95 % percentile-bootstrap interval (Efron & Tibshirani 1993): each
/// set is resampled with replacement, independently of the others, [`BOOTSTRAP_RESAMPLES`]
/// times from a stream seeded by `seed`, and the interval is the 2.5th to 97.5th percentile
/// of `stat` over the resamples (non-finite values dropped); a set of one value stays as it
/// is. The interval is NaN when no set has two values (nothing to resample), everything when
/// a set is empty.
pub fn bootstrap<const K: usize>(
    sets: [&[f64]; K],
    seed: u64,
    stat: impl Fn([&[f64]; K]) -> f64,
) -> Estimate {
    use rand::{RngExt, SeedableRng};
    if sets.iter().any(|s| s.is_empty()) {
        return Estimate::NAN;
    }
    let value = stat(sets);
    if sets.iter().all(|s| s.len() < 2) {
        return Estimate {
            value,
            lo: f64::NAN,
            hi: f64::NAN,
        };
    }
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
    let mut bufs: [Vec<f64>; K] = std::array::from_fn(|k| vec![0.0; sets[k].len()]);
    let mut draws = Vec::with_capacity(BOOTSTRAP_RESAMPLES);
    for _ in 0..BOOTSTRAP_RESAMPLES {
        for (buf, set) in bufs.iter_mut().zip(sets) {
            for x in buf.iter_mut() {
                *x = set[rng.random_range(0..set.len())];
            }
        }
        let v = stat(std::array::from_fn(|k| bufs[k].as_slice()));
        if v.is_finite() {
            draws.push(v);
        }
    }
    if draws.is_empty() {
        return Estimate {
            value,
            lo: f64::NAN,
            hi: f64::NAN,
        };
    }
    draws.sort_by(f64::total_cmp);
    let at = |q: f64| draws[((q * draws.len() as f64) as usize).min(draws.len() - 1)];
    Estimate {
        value,
        lo: at(0.025),
        hi: at(0.975),
    }
}

#[cfg(test)]
mod tests {
    use rand::{RngExt, SeedableRng};

    use super::*;

    #[test]
    fn median_of_means_of_known_values() {
        assert_eq!(median_of_means(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0], 3), 3.5);
        assert_eq!(median_of_means(&[1.0, 3.0, 100.0, 2.0], 4), 2.5);
        assert_eq!(median_of_means(&[5.0], 8), 5.0);
        assert!(median_of_means(&[], 4).is_nan());
        // One huge value moves it by one group's share at most.
        let mut v = vec![1.0; 16];
        v[3] = 1e9;
        assert_eq!(median_of_means(&v, 4), 1.0);
    }

    /// Coverage on a heavy-tailed case with a known mean: Pareto(α = 3, x_m = 1), mean 1.5,
    /// in 16 blocks of 400 draws (as the evaluation's 16 blocks of pixels × samples). The
    /// 95 % interval of the median of means must cover the mean in most replications.
    #[test]
    fn bootstrap_interval_of_median_of_means_covers_a_heavy_tailed_mean() {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(42);
        let (reps, mut covered) = (200, 0);
        for rep in 0..reps {
            let blocks: Vec<f64> = (0..16)
                .map(|_| {
                    (0..400)
                        .map(|_| (1.0 - rng.random::<f64>()).powf(-1.0 / 3.0))
                        .sum::<f64>()
                        / 400.0
                })
                .collect();
            let e = bootstrap([&blocks], rep, |[b]| median_of_means(b, 4));
            assert!(e.lo <= e.value && e.value <= e.hi, "{e:?}");
            if e.lo <= 1.5 && 1.5 <= e.hi {
                covered += 1;
            }
        }
        // Nominal 95 %; percentile intervals from 16 blocks run a little short.
        assert!(covered >= 170, "covered {covered} of {reps}");
    }
}
