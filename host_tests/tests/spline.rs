//! Rational-quadratic spline (`neusample::distrib::spline`): agreement with an independent f64
//! transcription of nflows' `unconstrained_rational_quadratic_spline`, bijectivity,
//! monotonicity, log-determinants, and totality on hostile input.

use neusample::distrib::spline::{Knots, MIN_BIN_HEIGHT, MIN_BIN_WIDTH, MIN_DERIVATIVE, RAW_LIMIT};
use neusample_host_tests::TestRng;
use proptest::prelude::*;
use proptest::test_runner::RngSeed;
use rand::RngExt;

const K: usize = 20;
const RAW: usize = 3 * K - 1;
type Spline = Knots<K>;

// ---------------------------------------------------------------------------------------
// Independent f64 reference (nflows, tails = "linear", tail_bound = B).
// ---------------------------------------------------------------------------------------

struct RefSpline {
    cw: Vec<f64>, // K + 1 x-knots
    ch: Vec<f64>, // K + 1 y-knots
    d: Vec<f64>,  // K + 1 derivatives
    b: f64,
}

fn softmax(v: &[f64]) -> Vec<f64> {
    let m = v.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    let e: Vec<f64> = v.iter().map(|x| (x - m).exp()).collect();
    let s: f64 = e.iter().sum();
    e.iter().map(|x| x / s).collect()
}

fn softplus(x: f64) -> f64 {
    if x > 30.0 {
        x
    } else {
        x.exp().ln_1p()
    }
}

fn ref_knots(raw: &[f32], b: f64) -> RefSpline {
    let raw: Vec<f64> = raw.iter().map(|&v| f64::from(v)).collect();
    let cum = |r: &[f64], min: f64| {
        let w = softmax(r);
        let mut c = vec![0.0];
        let mut acc = 0.0;
        for wi in &w {
            acc += min + (1.0 - min * K as f64) * wi;
            c.push(acc);
        }
        let mut c: Vec<f64> = c.iter().map(|v| 2.0 * b * v - b).collect();
        c[0] = -b;
        c[K] = b;
        c
    };
    let cw = cum(&raw[..K], f64::from(MIN_BIN_WIDTH));
    let ch = cum(&raw[K..2 * K], f64::from(MIN_BIN_HEIGHT));
    let mut d = vec![1.0; K + 1];
    for k in 1..K {
        d[k] = f64::from(MIN_DERIVATIVE) + softplus(raw[2 * K + k - 1]);
    }
    RefSpline { cw, ch, d, b }
}

impl RefSpline {
    /// The reference evaluation over the f32 knots of `s` (isolates evaluation error from
    /// the constraint step).
    fn from_knots(s: &Spline) -> RefSpline {
        let b = f64::from(s.bound);
        let mut cw: Vec<f64> = s.x.iter().map(|&v| f64::from(v)).collect();
        let mut ch: Vec<f64> = s.y.iter().map(|&v| f64::from(v)).collect();
        let d: Vec<f64> = (0..=K).map(|k| f64::from(s.derivative(k))).collect();
        cw.push(b);
        ch.push(b);
        RefSpline { cw, ch, d, b }
    }

    fn forward(&self, x: f64) -> (f64, f64) {
        if x < -self.b || x > self.b {
            return (x, 0.0);
        }
        let k = (1..K).filter(|&k| x >= self.cw[k]).count();
        let (x0, w) = (self.cw[k], self.cw[k + 1] - self.cw[k]);
        let (y0, h) = (self.ch[k], self.ch[k + 1] - self.ch[k]);
        let (d0, d1) = (self.d[k], self.d[k + 1]);
        let s = h / w;
        let xi = (x - x0) / w;
        let t = xi * (1.0 - xi);
        let den = s + (d1 + d0 - 2.0 * s) * t;
        let y = y0 + h * (s * xi * xi + d0 * t) / den;
        let dn = s * s * (d1 * xi * xi + 2.0 * s * t + d0 * (1.0 - xi) * (1.0 - xi));
        (y, dn.ln() - 2.0 * den.ln())
    }
}

fn random_raw(rng: &mut TestRng, scale: f32) -> [f32; RAW] {
    let mut r = [0.0f32; RAW];
    for v in &mut r {
        *v = scale * (2.0 * rng.random::<f32>() - 1.0);
    }
    r
}

fn assert_valid_knots(s: &Spline) {
    assert_eq!(s.x[0], -s.bound);
    assert_eq!(s.y[0], -s.bound);
    assert_eq!(s.derivative(0), 1.0);
    assert_eq!(s.derivative(K), 1.0);
    for k in 0..K {
        let d = s.derivative(k);
        assert!(
            s.x[k].is_finite() && s.y[k].is_finite() && d.is_finite(),
            "{s:?}"
        );
        assert!(d >= MIN_DERIVATIVE, "{s:?}");
        let (xr, yr) = if k + 1 < K {
            (s.x[k + 1], s.y[k + 1])
        } else {
            (s.bound, s.bound)
        };
        assert!(
            xr > s.x[k] && yr > s.y[k],
            "knots not increasing at {k}: {s:?}"
        );
    }
}

// ---------------------------------------------------------------------------------------
// Seeded tests
// ---------------------------------------------------------------------------------------

#[test]
fn matches_f64_reference() {
    let mut rng = neusample_host_tests::rng(1);
    let (mut max_y, mut max_ld, mut max_knot) = (0.0f64, 0.0f64, 0.0f64);
    for trial in 0..200 {
        let scale = [0.5, 2.0, 5.0][trial % 3];
        let raw = random_raw(&mut rng, scale);
        let s = Spline::from_raw(&raw, 1.0);
        assert_valid_knots(&s);
        let r = ref_knots(&raw, 1.0);
        for k in 0..K {
            max_knot = max_knot.max((f64::from(s.x[k]) - r.cw[k]).abs());
            max_knot = max_knot.max((f64::from(s.y[k]) - r.ch[k]).abs());
            let d = f64::from(s.derivative(k));
            max_knot = max_knot.max((d - r.d[k]).abs() / r.d[k].max(1.0));
        }
        let r = RefSpline::from_knots(&s);
        for i in 0..=400 {
            let x = -1.2 + 2.4 * i as f32 / 400.0;
            let (y, ld) = s.forward(x);
            let (yr, ldr) = r.forward(f64::from(x));
            max_y = max_y.max((f64::from(y) - yr).abs());
            max_ld = max_ld.max((f64::from(ld) - ldr).abs());
        }
    }
    eprintln!(
        "spline vs f64 reference: knots max error {max_knot:.2e}; on the same knots max |Δy| = \
         {max_y:.2e}, max |Δ log-det| = {max_ld:.2e}"
    );
    assert!(max_knot < 1e-6, "{max_knot}");
    assert!(max_y < 1e-6, "{max_y}");
    assert!(max_ld < 1e-4, "{max_ld}");
}

/// Error bound of the round trip `x → y → x` in f32: the resolution of `y` divided by the
/// slope (a flat stretch of a steep spline cannot be inverted better), plus 1e-6.
fn x_tolerance(log_slope: f32) -> f32 {
    1e-6 + 4.0 * f32::EPSILON / log_slope.exp()
}

/// Error bound of the round trip `y → x → y` in f32: the resolution of `x` times the slope.
fn y_tolerance(log_slope: f32) -> f32 {
    1e-6 + 4.0 * f32::EPSILON * log_slope.exp()
}

/// `x = inv(y)` is as good as f32 allows: `y` lies between the forward images of
/// `x ∓ 1e-6` (up to 1e-6), whatever the conditioning.
fn assert_inverse_brackets(s: &Spline, y: f32, x: f32) {
    let lo = s.forward(x - 1e-6).0 - 1e-6;
    let hi = s.forward(x + 1e-6).0 + 1e-6;
    assert!(
        lo <= y && y <= hi,
        "inverse({y}) = {x}: forward brackets [{lo}, {hi}]"
    );
}

/// `ln |dx/dy| = ldi` reported by `inv(y) = x` is the negated forward log-det at a point
/// within one ulp of `x`, up to 1e-3: in a steep, narrow bin `x` itself is only known to an
/// ulp, and the log-det can change by more than 1e-3 across it.
fn log_dets_agree(s: &Spline, x: f32, ldi: f32) -> bool {
    let lds = [x.next_down(), x, x.next_up()].map(|v| s.forward(v).1);
    let lo = lds.iter().copied().fold(f32::INFINITY, f32::min);
    let hi = lds.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    lo - 1e-3 <= -ldi && -ldi <= hi + 1e-3
}

/// Round trips at raw-output scale `scale`: (max |Δx|, max |Δy|, max |ld_f + ld_i|, max of
/// the errors relative to the conditioned tolerances).
fn round_trips(rng: &mut TestRng, scale: f32, splines: usize) -> (f32, f32, f32, f32) {
    let (mut dx, mut dy, mut ld, mut ratio) = (0.0f32, 0.0f32, 0.0f32, 0.0f32);
    for _ in 0..splines {
        let s = Spline::from_raw(&random_raw(rng, scale), 1.0);
        for _ in 0..200 {
            let x = 2.4 * rng.random::<f32>() - 1.2;
            let (y, ldf) = s.forward(x);
            let e = (s.inverse(y).0 - x).abs();
            dx = dx.max(e);
            ratio = ratio.max(e / x_tolerance(ldf));
            // y → x → y: both log-dets at the same ξ.
            let y = 2.4 * rng.random::<f32>() - 1.2;
            let (x, ldi) = s.inverse(y);
            assert_inverse_brackets(&s, y, x);
            let (y2, ldf) = s.forward(x);
            dy = dy.max((y2 - y).abs());
            ratio = ratio.max((y2 - y).abs() / y_tolerance(ldf));
            ld = ld.max((ldf + ldi).abs());
        }
    }
    (dx, dy, ld, ratio)
}

/// A bin of near-minimal width and slope ~400 (a case proptest once drew): the log-det
/// changes by ~0.01 per ulp of `x` there, so the round trip's log-dets differ by more than
/// 1e-3, yet the inverse's is the forward's within an ulp of `x`.
#[test]
fn steep_narrow_bin_log_dets() {
    // Widths, heights and the first derivatives; the rest stay 0.
    #[rustfmt::skip]
    let head: [f32; 40] = [
        0.0, 0.0, 3.0524864, 0.0, 0.0, 0.0, 0.0, 0.0,
        0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 2.1274137, 0.0,
        0.0, 0.0, -4.461288, 0.0, -3.2076871, 2.9105496, -0.4915614, -5.7487106,
        3.4772983, 4.0314574, 2.5300918, -3.3845882, 1.1643997, 2.12361, -2.0954177, 0.9299914,
        0.5552089, 2.6171186, -0.38142702, -4.846855, -2.9174314, 2.271703, 5.4478717, 3.7453835,
    ];
    let mut raw = [0.0f32; RAW];
    raw[..head.len()].copy_from_slice(&head);
    let s = Spline::from_raw(&raw, 1.0);
    let y = 0.807_265_7;
    let (x, ldi) = s.inverse(y);
    let (y2, ldf) = s.forward(x);
    assert!((y2 - y).abs() <= 1e-4, "{y} → {x} → {y2}");
    assert!(
        (ldf + ldi).abs() > 1e-3,
        "no longer a steep case: {ldf} {ldi}"
    );
    assert!(log_dets_agree(&s, x, ldi), "{ldf} {ldi}");
}

#[test]
fn round_trip_and_log_dets() {
    let mut rng = neusample_host_tests::rng(2);
    for (scale, flat_x) in [(0.5, true), (1.5, true), (3.0, false), (10.0, false)] {
        let (dx, dy, ld, ratio) = round_trips(&mut rng, scale, 300);
        let ld_limit = if scale <= 3.0 { 1e-3 } else { 1e-2 };
        eprintln!(
            "spline round trips, |raw| ≤ {scale}: max |x − inv(fwd(x))| = {dx:.2e}, \
             max |y − fwd(inv(y))| = {dy:.2e}, max |ld_f + ld_i| = {ld:.2e}, \
             max error / conditioned tolerance = {ratio:.2}"
        );
        // Trained networks' raw outputs are O(1): there x round-trips to 1e-4 flat. Wilder
        // splines have flat stretches where only the conditioned bound holds.
        if flat_x {
            assert!(dx <= 1e-4, "{dx}");
        }
        assert!(dy <= 1e-4, "{dy}");
        assert!(ld <= ld_limit, "{ld}");
        assert!(ratio <= 1.0, "{ratio}");
    }
}

#[test]
fn log_det_matches_finite_differences() {
    let mut rng = neusample_host_tests::rng(3);
    let mut max_rel = 0.0f64;
    for _ in 0..100 {
        let raw = random_raw(&mut rng, 2.0);
        let s = Spline::from_raw(&raw, 1.0);
        let r = RefSpline::from_knots(&s);
        for _ in 0..100 {
            let x = 1.9 * rng.random::<f32>() - 0.95;
            let h = 1e-6;
            let xd = f64::from(x);
            let fd = (r.forward(xd + h).0 - r.forward(xd - h).0) / (2.0 * h);
            let ld = f64::from(s.forward(x).1);
            max_rel = max_rel.max((ld.exp() - fd).abs() / fd);
        }
    }
    eprintln!("spline log-det vs finite differences: max relative error {max_rel:.2e}");
    assert!(max_rel < 1e-3, "{max_rel}");
}

#[test]
fn monotone_and_onto() {
    let mut rng = neusample_host_tests::rng(4);
    for trial in 0..100 {
        let scale = [0.5, 3.0, 8.0][trial % 3];
        let s = Spline::from_raw(&random_raw(&mut rng, scale), 1.0);
        let mut prev = f32::NEG_INFINITY;
        for i in 0..=4000 {
            let x = -1.0 + 2.0 * i as f32 / 4000.0;
            let (y, _) = s.forward(x);
            assert!(y >= prev, "not monotone at x = {x}: {y} < {prev}");
            prev = y;
        }
        assert_eq!(s.forward(-1.0).0, -1.0);
        assert_eq!(s.forward(1.0).0, 1.0);
        assert_eq!(s.inverse(-1.0).0, -1.0);
        assert_eq!(s.inverse(1.0).0, 1.0);
    }
}

#[test]
fn identity_tails_and_hostile_inputs() {
    let mut rng = neusample_host_tests::rng(5);
    let s = Spline::from_raw(&random_raw(&mut rng, 3.0), 1.0);
    for &x in &[-1e30f32, -7.0, -1.000_001, 1.000_001, 2.5, 1e30] {
        assert_eq!(s.forward(x), (x, 0.0));
        assert_eq!(s.inverse(x), (x, 0.0));
    }
    // Documented sentinel: ±∞ → ±f32::MAX, NaN → −f32::MAX, log-det 0.
    for f in [Spline::forward, Spline::inverse] {
        assert_eq!(f(&s, f32::INFINITY), (f32::MAX, 0.0));
        assert_eq!(f(&s, f32::NEG_INFINITY), (-f32::MAX, 0.0));
        assert_eq!(f(&s, f32::NAN), (-f32::MAX, 0.0));
        for &x in &[
            -1.0f32,
            1.0,
            -0.0,
            0.0,
            f32::MIN_POSITIVE,
            1.0 - f32::EPSILON,
            -1.0 + 1e-7,
        ] {
            let (y, ld) = f(&s, x);
            assert!(y.is_finite() && ld.is_finite(), "{x} → {y} {ld}");
            assert!((-1.0..=1.0).contains(&y));
        }
    }
}

#[test]
fn other_bounds() {
    let mut rng = neusample_host_tests::rng(6);
    for &b in &[0.5f32, 3.0, 100.0] {
        let raw = random_raw(&mut rng, 2.0);
        let s = Spline::from_raw(&raw, b);
        assert_eq!(s.bound, b);
        assert_valid_knots(&s);
        let r = ref_knots(&raw, f64::from(b));
        for i in 0..=100 {
            let x = b * (-1.1 + 2.2 * i as f32 / 100.0);
            let (y, ld) = s.forward(x);
            let (yr, ldr) = r.forward(f64::from(x));
            assert!((f64::from(y) - yr).abs() < 1e-5 * f64::from(b), "{b} {x}");
            assert!((f64::from(ld) - ldr).abs() < 2e-3);
            assert!((s.inverse(y).0 - x).abs() < 1e-4 * b);
        }
    }
    // Unusable bounds are clamped into [MIN_TAIL_BOUND, MAX_TAIL_BOUND].
    for &b in &[0.0f32, -1.0, f32::NAN, f32::INFINITY, 1e-30] {
        let s = Spline::from_raw(&[0.0; RAW], b);
        assert_valid_knots(&s);
        assert!(s.bound.is_finite() && s.bound > 0.0);
    }
}

#[test]
fn adversarial_raw_parameters() {
    let specials = [
        f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::MAX,
        -f32::MAX,
        1e30,
        -1e30,
        RAW_LIMIT,
        1e4,
        -1e4,
        0.0,
    ];
    let mut rng = neusample_host_tests::rng(7);
    let mut max_dy = 0.0f32;
    for trial in 0..2000 {
        let mut raw = random_raw(&mut rng, 1.0);
        // A mix of special values, sometimes all of one kind.
        if trial < specials.len() {
            raw = [specials[trial]; RAW];
        } else {
            for v in &mut raw {
                if rng.random::<f32>() < 0.3 {
                    *v = specials[rng.random_range(0..specials.len())];
                }
            }
        }
        let s = Spline::from_raw(&raw, 1.0);
        assert_valid_knots(&s);
        let mut prev = f32::NEG_INFINITY;
        for i in 0..=200 {
            let v = -1.1 + 2.2 * i as f32 / 200.0;
            let (y, ldf) = s.forward(v);
            // Monotone up to rounding at the scale of the knots (B = 1), where the bin's two
            // formulas meet.
            assert!(y >= prev - 2.0 * f32::EPSILON, "not monotone: {prev} {y}");
            prev = y;
            let (x2, ldi) = s.inverse(y);
            assert!(y.is_finite() && ldf.is_finite() && x2.is_finite() && ldi.is_finite());
            assert!((-1.1..=1.1).contains(&y) && (-1.1..=1.1).contains(&x2));
            let (x, ldx) = s.inverse(v);
            assert!(x.is_finite() && ldx.is_finite());
            assert_inverse_brackets(&s, v, x);
            max_dy = max_dy.max((s.forward(x).0 - v).abs());
        }
    }
    // Derivatives up to ~10⁶ make parts of the spline nearly vertical: there fwd(inv(y))
    // can differ from y by far more than 1e-4, yet inv(y) is the best f32 answer (bracketed).
    eprintln!(
        "adversarial raw parameters: max |y − fwd(inv(y))| = {max_dy:.2e} (inverse bracketed)"
    );
}

// ---------------------------------------------------------------------------------------
// Property tests
// ---------------------------------------------------------------------------------------

fn raw_strategy() -> impl Strategy<Value = [f32; RAW]> {
    proptest::collection::vec(-6.0f32..6.0, RAW).prop_map(|v| {
        let mut a = [0.0f32; RAW];
        a.copy_from_slice(&v);
        a
    })
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 512,
        rng_seed: RngSeed::Fixed(0x5b1e),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn prop_inverse_of_forward(raw in raw_strategy(), x in -1.5f32..1.5) {
        let s = Spline::from_raw(&raw, 1.0);
        let (y, ldf) = s.forward(x);
        let (x2, _) = s.inverse(y);
        prop_assert!((x2 - x).abs() <= x_tolerance(ldf), "x {} → y {} → {}", x, y, x2);
    }

    #[test]
    fn prop_forward_of_inverse(raw in raw_strategy(), y in -1.5f32..1.5) {
        let s = Spline::from_raw(&raw, 1.0);
        let (x, ldi) = s.inverse(y);
        let (y2, ldf) = s.forward(x);
        prop_assert!((y2 - y).abs() <= 1e-4);
        prop_assert!(log_dets_agree(&s, x, ldi), "{} {}", ldf, ldi);
    }

    #[test]
    fn prop_monotone(raw in raw_strategy(), a in -1.2f32..1.2, b in -1.2f32..1.2) {
        let s = Spline::from_raw(&raw, 1.0);
        let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
        prop_assert!(s.forward(lo).0 <= s.forward(hi).0);
        prop_assert!(s.inverse(lo).0 <= s.inverse(hi).0);
    }

    #[test]
    fn prop_total(raw in proptest::collection::vec(any::<f32>(), RAW), x in any::<f32>()) {
        let mut a = [0.0f32; RAW];
        a.copy_from_slice(&raw);
        let s = Spline::from_raw(&a, 1.0);
        for (v, ld) in [s.forward(x), s.inverse(x)] {
            prop_assert!(v.is_finite() && ld.is_finite(), "{} → {} {}", x, v, ld);
        }
    }
}
