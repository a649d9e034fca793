//! Single-thread cost, nanoseconds per shading point, by the timing harness of
//! [`crate::util::timing`] (medians of repeated passes): a sampler's hot path through the
//! batched API (a wavefront of [`COST_BATCH`] lanes per call, as the renderer calls it) and
//! through the scalar API, and a material's own evaluation (the denominator of the paper's
//! Table 1 ratio). `neusample bench` measures with the same functions at more batch sizes.

use std::hint::black_box;

use glam::{Vec2, Vec3};
use neusample::wavefront::{
    BatchSampler, Features, FeaturesMut, RgbMut, SamplesMut, Scratch, Vec2s, Vec3s, Vec3sMut,
};
use neusample::{Prepared, Sampler, FEATURE_DIM};
use rand::SeedableRng;
use serde::{Deserialize, Serialize};

use crate::groundtruth;
use crate::materials::Material;
use crate::util::json::f64_or_nan;
use crate::util::timing::{median_of_passes, ns_per_call};
use neusample::wavefront::SamplerVisitor;

/// Lanes per batched call of [`cost()`] and [`eval_cost`] (the size the wavefront renderer's
/// batches are at least, per surface and depth, on the evaluation scenes).
pub const COST_BATCH: usize = 64;

/// Per-shading-point costs of one call sequence, in ns.
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct Split {
    /// `prepare` (or `prepare_batch` per lane).
    pub prepare_ns: f64,
    /// `sample`.
    pub sample_ns: f64,
    /// `pdf` of another direction (the MIS query).
    pub pdf_ns: f64,
    /// The sum: one shading point's prepare + sample + pdf.
    pub total_ns: f64,
}

/// Single-thread cost of a sampler's hot path, ns per shading point.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Cost {
    /// Lanes per call of the figures below: [`COST_BATCH`] for the batched API, 1 for a
    /// sampler measured through the scalar API only (the tabulated oracle).
    #[serde(default = "one")]
    pub batch: usize,
    /// `prepare(φ, wi)`.
    #[serde(deserialize_with = "f64_or_nan")]
    pub prepare_ns: f64,
    /// `sample(u)` on a prepared state.
    #[serde(deserialize_with = "f64_or_nan")]
    pub sample_ns: f64,
    /// `pdf(wo)` on a prepared state.
    #[serde(deserialize_with = "f64_or_nan")]
    pub pdf_ns: f64,
    /// One shading point: prepare + sample + pdf.
    #[serde(deserialize_with = "f64_or_nan")]
    pub total_ns: f64,
    /// `material.eval`, same batch size (the material's own cost, for the Table 1 ratio).
    #[serde(deserialize_with = "f64_or_nan")]
    pub material_eval_ns: f64,
    /// prepare + sample + pdf through the scalar API, one shading point at a time.
    #[serde(default, deserialize_with = "f64_or_nan")]
    pub scalar_total_ns: f64,
    /// `material.eval` one call at a time.
    #[serde(default, deserialize_with = "f64_or_nan")]
    pub scalar_material_eval_ns: f64,
}

fn one() -> usize {
    1
}

/// Single-thread cost of a material, ns per call.
#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
pub struct EvalCost {
    /// `features(uv)` (texture lookup).
    #[serde(deserialize_with = "f64_or_nan")]
    pub features_ns: f64,
    /// `eval(φ, wi, wo)` (the decoder, or the analytic BRDF).
    #[serde(deserialize_with = "f64_or_nan")]
    pub eval_ns: f64,
    /// `features_batch` per lane at [`COST_BATCH`] lanes per call.
    #[serde(default, deserialize_with = "f64_or_nan")]
    pub features_batch_ns: f64,
    /// `eval_batch` per lane at [`COST_BATCH`] lanes per call.
    #[serde(default, deserialize_with = "f64_or_nan")]
    pub eval_batch_ns: f64,
}

/// The median over `passes` of `f`'s ns per `per` calls, after one warm-up pass.
pub fn time_per(passes: usize, per: usize, mut f: impl FnMut()) -> f64 {
    f();
    median_of_passes(passes, || [ns_per_call(per, &mut f)])[0]
}

/// The inputs every measurement cycles through: conditions, and per lane a `u`, a second
/// direction (the MIS query) and a texture coordinate.
pub struct Inputs {
    /// `(φ, wi)` per lane.
    pub conds: Vec<([f32; FEATURE_DIM], Vec3)>,
    /// `u` per lane.
    pub us: Vec<Vec2>,
    /// A direction per lane (inside the hemisphere).
    pub wos: Vec<Vec3>,
    /// A texture coordinate per lane.
    pub uvs: Vec<Vec2>,
}

impl Inputs {
    /// `n` lanes cycling through `base` (not empty), with a fixed low-discrepancy sequence of
    /// `u`, directions and uv: reproducible without a random stream.
    #[must_use]
    pub fn cycling(base: &[([f32; FEATURE_DIM], Vec3)], n: usize) -> Inputs {
        let frac = |x: f64| (x - x.floor()) as f32;
        let (g1, g2) = (0.754_877_666_246_692_8, 0.569_840_290_998_053_2);
        let us: Vec<Vec2> = (0..n)
            .map(|i| Vec2::new(frac(0.5 + g1 * i as f64), frac(0.5 + g2 * i as f64)))
            .collect();
        let wos = us
            .iter()
            .map(|u| {
                let (r, a) = (0.98 * u.y.sqrt(), std::f32::consts::TAU * u.x);
                Vec3::new(r * a.cos(), r * a.sin(), (1.0 - r * r).sqrt())
            })
            .collect();
        let uvs = us.iter().map(|u| Vec2::new(u.y * 3.0, u.x * 2.0)).collect();
        Inputs {
            conds: (0..n).map(|i| base[i % base.len().max(1)]).collect(),
            us,
            wos,
            uvs,
        }
    }

    /// `n` random conditions of `m` (seeded), as [`Inputs::cycling`].
    #[must_use]
    pub fn random(m: &dyn Material, n: usize, seed: u64) -> Inputs {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
        let base: Vec<_> = (0..n.max(1))
            .map(|_| {
                let c = groundtruth::random_condition(m, &mut rng);
                (c.phi, c.wi)
            })
            .collect();
        Inputs::cycling(&base, n.max(1))
    }

    /// Number of lanes.
    #[must_use]
    pub fn len(&self) -> usize {
        self.conds.len()
    }

    /// `true` without lanes.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.conds.is_empty()
    }
}

/// Structure-of-arrays rows of [`Inputs`], for the batched calls: `rows.wi.at(a, b)` is
/// the view of lanes `a .. b` that a batched call takes.
pub struct Rows {
    /// φ per lane.
    pub phi: Columns<FEATURE_DIM>,
    /// `wi` per lane.
    pub wi: Columns<3>,
    /// `u` per lane.
    pub u: Columns<2>,
    /// The second direction per lane.
    pub wo: Columns<3>,
    /// The texture coordinate per lane.
    pub uv: Columns<2>,
}

impl Rows {
    /// The rows of `inp`.
    #[must_use]
    pub fn new(inp: &Inputs) -> Rows {
        Rows {
            phi: Columns::gather(&inp.conds, |x, c| x.0[c]),
            wi: Columns::gather(&inp.conds, |x, k| x.1[k]),
            u: Columns::gather(&inp.us, |x, k| x[k]),
            wo: Columns::gather(&inp.wos, |x, k| x[k]),
            uv: Columns::gather(&inp.uvs, |x, k| x[k]),
        }
    }

    /// Number of lanes.
    #[must_use]
    pub fn len(&self) -> usize {
        self.wi.0[0].len()
    }

    /// `true` without lanes.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The lanes `(a, b)` of each call over all of the rows at `n` lanes per call (at least
    /// 1).
    pub fn calls(&self, n: usize) -> impl Iterator<Item = (usize, usize)> + Clone {
        let (total, n) = (self.len(), n.max(1));
        (0..total).step_by(n).map(move |a| (a, (a + n).min(total)))
    }
}

/// `K` columns of values, one per component, for [`Rows`].
pub struct Columns<const K: usize>([Vec<f32>; K]);

impl<const K: usize> Columns<K> {
    /// Component `k` of every lane is `get(&lane, k)`.
    fn gather<T>(lanes: &[T], get: impl Fn(&T, usize) -> f32) -> Self {
        Columns(std::array::from_fn(|k| {
            lanes.iter().map(|x| get(x, k)).collect()
        }))
    }
}

impl Columns<FEATURE_DIM> {
    /// φ of lanes `a .. b`.
    #[must_use]
    pub fn at(&self, a: usize, b: usize) -> Features<'_> {
        Features {
            channels: std::array::from_fn(|c| &self.0[c][a..b]),
        }
    }
}

impl Columns<3> {
    /// The directions of lanes `a .. b`.
    #[must_use]
    pub fn at(&self, a: usize, b: usize) -> Vec3s<'_> {
        let [x, y, z] = &self.0;
        Vec3s {
            x: &x[a..b],
            y: &y[a..b],
            z: &z[a..b],
        }
    }
}

impl Columns<2> {
    /// The 2-D values of lanes `a .. b`.
    #[must_use]
    pub fn at(&self, a: usize, b: usize) -> Vec2s<'_> {
        let [x, y] = &self.0;
        Vec2s {
            x: &x[a..b],
            y: &y[a..b],
        }
    }
}

/// The scalar API's split: each call cycles through the lanes.
pub fn scalar_split<S: Sampler>(s: &S, inp: &Inputs, passes: usize) -> Split {
    let n = inp.len();
    let prepare_ns = time_per(passes, n, || {
        for (phi, wi) in &inp.conds {
            black_box(s.prepare(black_box(phi), *wi).is_some());
        }
    });
    let prepared: Vec<_> = inp.conds.iter().map(|(p, w)| s.prepare(p, *w)).collect();
    let sample_ns = time_per(passes, n, || {
        for (p, u) in prepared.iter().zip(&inp.us) {
            if let Some(p) = p {
                black_box(p.sample(*u));
            }
        }
    });
    let pdf_ns = time_per(passes, n, || {
        for (p, wo) in prepared.iter().zip(&inp.wos) {
            if let Some(p) = p {
                black_box(p.pdf(*wo));
            }
        }
    });
    Split {
        prepare_ns,
        sample_ns,
        pdf_ns,
        total_ns: prepare_ns + sample_ns + pdf_ns,
    }
}

/// The batched API's split at `n` lanes per call over all of `rows`.
pub fn batched_split<S: BatchSampler>(s: &S, rows: &Rows, n: usize, passes: usize) -> Split {
    let total = rows.len();
    let mut lanes = vec![S::Lane::default(); total];
    let mut wo = [0, 1, 2].map(|_| vec![0.0f32; total]);
    let mut pdf = vec![0.0f32; total];
    let mut mis = vec![0.0f32; total];
    let mut pdf2 = vec![0.0f32; total];
    // Kept across calls, as a renderer keeps it.
    let mut scratch = Box::new(<S::Scratch as Scratch>::NEW);
    let prepare_ns = time_per(passes, total, || {
        for (a, b) in rows.calls(n) {
            s.prepare_batch(rows.phi.at(a, b), rows.wi.at(a, b), &mut lanes[a..b])
                .expect("lengths agree");
        }
    });
    let sample_ns = time_per(passes, total, || {
        let [x, y, z] = &mut wo;
        for (a, b) in rows.calls(n) {
            let out = SamplesMut {
                wo: Vec3sMut {
                    x: &mut x[a..b],
                    y: &mut y[a..b],
                    z: &mut z[a..b],
                },
                pdf: &mut pdf[a..b],
                mis_pdf: &mut mis[a..b],
            };
            s.sample_batch_in(&lanes[a..b], rows.u.at(a, b), out, &mut scratch)
                .expect("lengths agree");
        }
    });
    let pdf_ns = time_per(passes, total, || {
        for (a, b) in rows.calls(n) {
            s.pdf_batch_in(
                &lanes[a..b],
                rows.wo.at(a, b),
                &mut pdf2[a..b],
                &mut scratch,
            )
            .expect("lengths agree");
        }
    });
    black_box((&pdf, &pdf2));
    Split {
        prepare_ns,
        sample_ns,
        pdf_ns,
        total_ns: prepare_ns + sample_ns + pdf_ns,
    }
}

/// A batched `eval` (`eval(phi, wi, wo, out)`) in ns per lane at `n` lanes per call over all
/// of `rows` (the second directions as `wo`).
pub fn eval_batch_ns(
    eval: impl Fn(Features<'_>, Vec3s<'_>, Vec3s<'_>, RgbMut<'_>),
    rows: &Rows,
    n: usize,
    passes: usize,
) -> f64 {
    let total = rows.len();
    let mut rgb = vec![0.0f32; 3 * total];
    time_per(passes, total, || {
        let (r, gb) = rgb.split_at_mut(total);
        let (g, bl) = gb.split_at_mut(total);
        for (a, b) in rows.calls(n) {
            let out = RgbMut {
                r: &mut r[a..b],
                g: &mut g[a..b],
                b: &mut bl[a..b],
            };
            eval(rows.phi.at(a, b), rows.wi.at(a, b), rows.wo.at(a, b), out);
        }
    })
}

/// A batched `features` (`features(uv, phi)`) in ns per lane at `n` lanes per call.
pub fn features_batch_ns(
    features: impl Fn(Vec2s<'_>, FeaturesMut<'_>),
    rows: &Rows,
    n: usize,
    passes: usize,
) -> f64 {
    let total = rows.len();
    let n = n.max(1);
    let mut phi = vec![0.0f32; FEATURE_DIM * n];
    time_per(passes, total, || {
        for (a, b) in rows.calls(n) {
            let out =
                FeaturesMut::from_rows(&mut phi[..FEATURE_DIM * (b - a)], b - a).expect("sized");
            features(rows.uv.at(a, b), out);
        }
    })
}

/// The scalar `eval` of `material` in ns per call over `inp`.
fn scalar_eval_ns(material: &dyn Material, inp: &Inputs, passes: usize) -> f64 {
    time_per(passes, inp.len(), || {
        for ((phi, wi), wo) in inp.conds.iter().zip(&inp.wos) {
            black_box(material.eval(black_box(phi), black_box(*wi), black_box(*wo)));
        }
    })
}

/// Seed of the conditions of [`cost()`] and [`eval_cost`].
const COST_SEED: u64 = 0xC057;

/// Measures [`Cost`] on `n` random conditions of `material`, `passes` times: the batched API
/// at [`COST_BATCH`] lanes per call (the concrete sampler's own lanes for a blob's
/// [`neusample::BlobSampler`]; see [`cost_any`]) and the scalar API.
pub fn cost<S: Sampler + BatchSampler>(
    sampler: &S,
    material: &dyn Material,
    n: usize,
    passes: usize,
) -> Cost {
    let inp = Inputs::random(material, n, COST_SEED);
    let rows = Rows::new(&inp);
    let batched = batched_split(sampler, &rows, COST_BATCH, passes);
    let scalar = scalar_split(sampler, &inp, passes);
    Cost {
        batch: COST_BATCH,
        prepare_ns: batched.prepare_ns,
        sample_ns: batched.sample_ns,
        pdf_ns: batched.pdf_ns,
        total_ns: batched.total_ns,
        material_eval_ns: eval_batch_ns(
            |phi, wi, wo, out| material.eval_batch(phi, wi, wo, out),
            &rows,
            COST_BATCH,
            passes,
        ),
        scalar_total_ns: scalar.total_ns,
        scalar_material_eval_ns: scalar_eval_ns(material, &inp, passes),
    }
}

/// [`cost()`] of a blob's sampler through its concrete type.
pub fn cost_any(
    sampler: &neusample::BlobSampler<'_>,
    material: &dyn Material,
    n: usize,
    passes: usize,
) -> Cost {
    struct Measure<'m> {
        material: &'m dyn Material,
        n: usize,
        passes: usize,
    }
    impl SamplerVisitor for Measure<'_> {
        type Output = Cost;
        fn visit<S: Sampler + BatchSampler + Copy + Sync>(self, s: S) -> Cost
        where
            S::Lane: Send,
        {
            cost(&s, self.material, self.n, self.passes)
        }
    }
    sampler.visit(Measure {
        material,
        n,
        passes,
    })
}

/// [`Cost`] through the scalar API only (a sampler without a batched path: the tabulated
/// oracle); `batch` is 1 and the batched fields repeat the scalar ones.
pub fn cost_scalar<S: Sampler>(
    sampler: &S,
    material: &dyn Material,
    n: usize,
    passes: usize,
) -> Cost {
    let inp = Inputs::random(material, n, COST_SEED);
    let scalar = scalar_split(sampler, &inp, passes);
    let eval = scalar_eval_ns(material, &inp, passes);
    Cost {
        batch: 1,
        prepare_ns: scalar.prepare_ns,
        sample_ns: scalar.sample_ns,
        pdf_ns: scalar.pdf_ns,
        total_ns: scalar.total_ns,
        material_eval_ns: eval,
        scalar_total_ns: scalar.total_ns,
        scalar_material_eval_ns: eval,
    }
}

/// Measures [`EvalCost`] of `material` on `n` random `(uv, wi, wo)`, `passes` times, on the
/// calling thread.
pub fn eval_cost(material: &dyn Material, n: usize, passes: usize) -> EvalCost {
    let inp = Inputs::random(material, n, COST_SEED ^ 0xE7A1);
    let rows = Rows::new(&inp);
    let features_ns = time_per(passes, inp.len(), || {
        for uv in &inp.uvs {
            black_box(material.features(black_box(*uv)));
        }
    });
    EvalCost {
        features_ns,
        eval_ns: scalar_eval_ns(material, &inp, passes),
        features_batch_ns: features_batch_ns(
            |uv, phi| material.features_batch(uv, phi),
            &rows,
            COST_BATCH,
            passes,
        ),
        eval_batch_ns: eval_batch_ns(
            |phi, wi, wo, out| material.eval_batch(phi, wi, wo, out),
            &rows,
            COST_BATCH,
            passes,
        ),
    }
}
