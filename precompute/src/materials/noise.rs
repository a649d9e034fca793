//! Seeded, tileable procedural noise on the unit square (uv wraps with period 1).
//!
//! * [`gradient`]: Perlin-style gradient noise on an integer lattice of `freq × freq` cells,
//!   periodic with period 1 in u and v; values in about `[−0.7, 0.7]`.
//! * [`fbm`]: sum of `octaves` gradient-noise layers, frequency ×2 and amplitude × `gain` per
//!   octave, divided by the total amplitude (so values stay in about `[−0.7, 0.7]`).
//! * [`worley`]: cellular noise with one jittered feature point per cell of a `freq × freq`
//!   grid: distances to the nearest and second-nearest points and the nearest cell's id.
//!
//! Everything is a pure function of `(uv, parameters, seed)`.

use glam::Vec2;

/// A 32-bit integer hash of a lattice point and a seed (PCG-style output permutation of a
/// linear combination; good enough for textures, not for statistics).
#[inline]
#[must_use]
pub fn hash(x: u32, y: u32, seed: u32) -> u32 {
    let mut h = x
        .wrapping_mul(0x8da6_b343)
        .wrapping_add(y.wrapping_mul(0xd816_3841))
        .wrapping_add(seed.wrapping_mul(0xcb1a_b31f))
        .wrapping_add(0x9e37_79b9);
    h ^= h >> 16;
    h = h.wrapping_mul(0x7feb_352d);
    h ^= h >> 15;
    h = h.wrapping_mul(0x846c_a68b);
    h ^= h >> 16;
    h
}

/// A uniform value in `[0, 1)` from a hash.
#[inline]
#[must_use]
pub fn unit(h: u32) -> f32 {
    (h >> 8) as f32 * (1.0 / 16_777_216.0)
}

#[inline]
fn wrap(i: i64, period: u32) -> u32 {
    i.rem_euclid(i64::from(period.max(1))) as u32
}

#[inline]
fn fade(t: f32) -> f32 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

#[inline]
fn grad(x: u32, y: u32, seed: u32, d: Vec2) -> f32 {
    // 16 evenly spaced gradient directions.
    let a = (hash(x, y, seed) >> 28) as f32 * (std::f32::consts::TAU / 16.0);
    let (s, c) = a.sin_cos();
    c * d.x + s * d.y
}

/// Periodic gradient noise at `uv` with `freq` lattice cells per unit.
#[must_use]
pub fn gradient(uv: Vec2, freq: u32, seed: u32) -> f32 {
    let f = freq.max(1);
    let p = uv * f as f32;
    let (fx, fy) = (p.x.floor(), p.y.floor());
    let (tx, ty) = (p.x - fx, p.y - fy);
    let (ix, iy) = (fx as i64, fy as i64);
    let x0 = wrap(ix, f);
    let x1 = wrap(ix + 1, f);
    let y0 = wrap(iy, f);
    let y1 = wrap(iy + 1, f);
    let n00 = grad(x0, y0, seed, Vec2::new(tx, ty));
    let n10 = grad(x1, y0, seed, Vec2::new(tx - 1.0, ty));
    let n01 = grad(x0, y1, seed, Vec2::new(tx, ty - 1.0));
    let n11 = grad(x1, y1, seed, Vec2::new(tx - 1.0, ty - 1.0));
    let (sx, sy) = (fade(tx), fade(ty));
    let a = n00 + (n10 - n00) * sx;
    let b = n01 + (n11 - n01) * sx;
    a + (b - a) * sy
}

/// Sums `octaves` octaves of [`gradient`] noise, each passed through
/// `shape`, doubling the frequency and scaling the amplitude by `gain`
/// per octave; normalised by the total amplitude.
fn octave_sum(
    uv: Vec2,
    freq: u32,
    octaves: u32,
    gain: f32,
    seed: u32,
    shape: impl Fn(f32) -> f32,
) -> f32 {
    let mut sum = 0.0;
    let mut amp = 1.0;
    let mut norm = 0.0;
    let mut f = freq.max(1);
    for o in 0..octaves.max(1) {
        let n = gradient(uv, f, seed.wrapping_add(o.wrapping_mul(0x51ed_270b)));
        sum += amp * shape(n);
        norm += amp;
        amp *= gain;
        f = f.saturating_mul(2);
    }
    sum / norm
}

/// Fractal sum of [`gradient`] octaves, normalised by the total amplitude.
#[must_use]
pub fn fbm(uv: Vec2, freq: u32, octaves: u32, gain: f32, seed: u32) -> f32 {
    octave_sum(uv, freq, octaves, gain, seed, |n| n)
}

/// `|fbm|`-style turbulence (sum of absolute octaves), in about `[0, 0.7]`.
#[must_use]
pub fn turbulence(uv: Vec2, freq: u32, octaves: u32, gain: f32, seed: u32) -> f32 {
    octave_sum(uv, freq, octaves, gain, seed, f32::abs)
}

/// Gradient `(∂/∂u, ∂/∂v)` of a scalar texture by central differences with step `h`
/// (uv units).
#[must_use]
pub fn gradient_of(f: impl Fn(Vec2) -> f32, uv: Vec2, h: f32) -> Vec2 {
    let dx = f(uv + Vec2::new(h, 0.0)) - f(uv - Vec2::new(h, 0.0));
    let dy = f(uv + Vec2::new(0.0, h)) - f(uv - Vec2::new(0.0, h));
    Vec2::new(dx, dy) / (2.0 * h)
}

/// Result of [`worley`].
#[derive(Copy, Clone, Debug)]
pub struct Worley {
    /// Distance to the nearest feature point (in cell units).
    pub f1: f32,
    /// Distance to the second-nearest feature point (in cell units).
    pub f2: f32,
    /// Hash of the nearest point's cell (stable per cell, for per-cell attributes).
    pub id: u32,
}

/// Periodic cellular noise with `freq × freq` cells, one feature point per cell jittered by
/// `jitter ∈ [0, 1]`.
#[must_use]
pub fn worley(uv: Vec2, freq: u32, jitter: f32, seed: u32) -> Worley {
    let f = freq.max(1);
    let p = uv * f as f32;
    let (fx, fy) = (p.x.floor(), p.y.floor());
    let (ix, iy) = (fx as i64, fy as i64);
    let mut f1 = f32::MAX;
    let mut f2 = f32::MAX;
    let mut id = 0;
    for dy in -1..=1i64 {
        for dx in -1..=1i64 {
            let cx = wrap(ix + dx, f);
            let cy = wrap(iy + dy, f);
            let h = hash(cx, cy, seed);
            let jx = 0.5 + jitter * (unit(h) - 0.5);
            let jy = 0.5 + jitter * (unit(hash(h, 0x2545_f491, seed)) - 0.5);
            let q = Vec2::new((ix + dx) as f32 + jx, (iy + dy) as f32 + jy);
            let d = (q - p).length();
            if d < f1 {
                f2 = f1;
                f1 = d;
                id = h;
            } else if d < f2 {
                f2 = d;
            }
        }
    }
    Worley { f1, f2, id }
}

/// Smoothstep `3t² − 2t³` of `(x − a)/(b − a)` clamped to `[0, 1]`.
#[inline]
#[must_use]
pub fn smoothstep(a: f32, b: f32, x: f32) -> f32 {
    let t = ((x - a) / (b - a)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Wraps uv into `[0, 1)²`.
#[inline]
#[must_use]
pub fn wrap_uv(uv: Vec2) -> Vec2 {
    let w = uv - uv.floor();
    // `x − floor(x)` can round to 1.0 for tiny negative x.
    Vec2::new(
        if w.x >= 1.0 { 0.0 } else { w.x },
        if w.y >= 1.0 { 0.0 } else { w.y },
    )
}
