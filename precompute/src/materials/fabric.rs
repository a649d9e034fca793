//! `model = "fabric"`: woven cloth with several lobes (paper: Victorian Fabric): per thread
//! float, two anisotropic GGX lobes whose normals are tilted forward and backward along the
//! thread (the float's curvature: off-specular highlights that split and move), a
//! retro-reflective lobe, a Charlie sheen lobe and a diffuse base.
//!
//! ```text
//! f = g · F(wi·h) · Σ_± w_± D(h; n_±) G2 / (4 M_i M_o)          (thread lobes, max-cos frame)
//!   + k_r · D(h_r; α_r) G2 / (4 cos θi cos θo)                   (retro, h_r ∝ wi + M wo)
//!   + σ · c_s · D_charlie(h; α_s) · V_sheen                       (sheen)
//!   + (1 − k_r − σ·max c_s) · ρ/π · (1 − F̄(cos θi))(1 − F̄(cos θo))  (diffuse)
//! ```
//!
//! `M(x, y, z) = (−x, −y, z)` mirrors `wo` about the normal, so the retro lobe peaks at
//! `wo = wi` and stays reciprocal (`h_r(wo, wi) = M h_r(wi, wo)`, and `D` is isotropic).
//! The lobe normals `n_± = (±sin θ_t t, cos θ_t)` tilt along the thread direction `t` by
//! `θ_t = τ_max`, with weights `w_± = (1 ± τ)/2`.
//!
//! # φ layout
//!
//! | index | meaning                                                  | range     |
//! |-------|----------------------------------------------------------|-----------|
//! | 0, 1  | thread direction as doubled angle `(cos 2ψ, sin 2ψ)`     | unit vector |
//! | 2     | position along the float τ (lobe balance `w_± = (1 ± τ)/2`) | `[−1, 1]` |
//! | 3–5   | thread albedo (RGB)                                      | `[0, 1]`  |
//! | 6     | sheen amount σ                                           | `[0, 1]`  |
//! | 7     | gloss `g` (weight of the thread lobes)                   | `[0, 1]`  |

use glam::{Vec2, Vec3};
use serde::Deserialize;

use super::check::params;
use super::format::File;
use super::microfacet::{
    alpha_from_roughness, charlie_d, ggx_d, ggx_dg, ggx_g2, half_angle, normalize_pair, schlick1,
    sheen_visibility, ShadingFrame, LAMBERT,
};
use super::model::{Material, FEATURE_DIM};
use super::noise::{fbm, hash, smoothstep, unit as hunit, wrap_uv};
use super::surface::{lerp, sanitize, signed, unit};

/// Weave pattern.
#[derive(Copy, Clone, Debug, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Weave {
    /// Plain weave (floats of one cell, alternating).
    Plain,
    /// 5-harness satin (floats of four cells).
    Satin,
}

params! {
    /// `[params]` of a `fabric` material.
    pub struct Params {
        /// Noise seed.
        pub seed: u32,
        /// Threads per uv unit (each direction).
        pub threads: u32 => count(4..=1024),
        /// Weave outside the motif.
        pub weave: Weave,
        /// Weave inside the motif (a low-frequency damask pattern).
        pub motif_weave: Weave,
        /// Motif frequency (fBm lattice cells per uv unit).
        pub motif_freq: u32 => count(1..=32),
        /// Warp thread colour (runs along v).
        pub warp_color: [f32; 3] => range_n(0.0..=1.0),
        /// Weft thread colour (runs along u).
        pub weft_color: [f32; 3] => range_n(0.0..=1.0),
        /// Gloss of warp threads.
        pub warp_gloss: f32 => range(0.0..=1.0),
        /// Gloss of weft threads.
        pub weft_gloss: f32 => range(0.0..=1.0),
        /// Thread lobe perceptual roughness along the thread.
        pub roughness_along: f32 => range(0.0..=1.0),
        /// Thread lobe perceptual roughness across the thread.
        pub roughness_across: f32 => range(0.0..=1.0),
        /// Tilt of the lobe normals along the thread, degrees.
        pub tilt_deg: f32 => range(0.0..=60.0),
        /// Thread specular F0.
        pub f0: f32 => range(0.0..=0.2),
        /// Retro-reflective lobe weight.
        pub retro: f32 => range(0.0..=0.3),
        /// Retro lobe perceptual roughness.
        pub retro_roughness: f32 => range(0.0..=1.0),
        /// Sheen colour.
        pub sheen_color: [f32; 3] => range_n(0.0..=1.0),
        /// Sheen α (Charlie).
        pub sheen_alpha: f32 => range(0.05..=1.0),
        /// Sheen amount (fuzz varies over the cloth).
        pub sheen: [f32; 2] => interval(0.0..=1.0),
    }
}

/// A `fabric` material.
#[derive(Clone, Debug)]
pub struct Fabric {
    name: String,
    p: Params,
    tilt_sin: f32,
    tilt_cos: f32,
    ax: f32,
    ay: f32,
    ar: f32,
    sheen_max: f32,
}

impl Fabric {
    /// Validates a parsed file.
    pub fn new(file: File<Params>) -> anyhow::Result<Self> {
        let p = &file.params;
        p.check()?;
        let (tilt_sin, tilt_cos) = p.tilt_deg.to_radians().sin_cos();
        let sheen_max = p.sheen_color.iter().fold(0.0f32, |a, &b| a.max(b));
        Ok(Fabric {
            name: file.name.clone(),
            ax: alpha_from_roughness(p.roughness_along),
            ay: alpha_from_roughness(p.roughness_across),
            ar: alpha_from_roughness(p.retro_roughness),
            p: file.params,
            tilt_sin,
            tilt_cos,
            sheen_max,
        })
    }

    /// Whether the warp is on top at thread cell `(i, j)` and the float's extent along the
    /// top thread `(cells before, float length)`.
    fn weave(w: Weave, i: u32, j: u32) -> (bool, u32, u32) {
        match w {
            Weave::Plain => ((i + j).is_multiple_of(2), 0, 1),
            Weave::Satin => {
                // Weft floats over 4 of every 5 warp threads; the interlacing shifts by 2.
                let k = (i + 5 - (2 * j) % 5) % 5; // position of i in the repeat
                if k == 4 {
                    (true, 0, 1)
                } else {
                    (false, k, 4)
                }
            }
        }
    }
}

impl Material for Fabric {
    fn name(&self) -> &str {
        &self.name
    }

    fn features(&self, uv: Vec2) -> [f32; FEATURE_DIM] {
        let p = &self.p;
        let uv = wrap_uv(uv);
        let q = uv * p.threads as f32;
        let cell = q.floor();
        let l = q - cell;
        let (i, j) = (cell.x as u32 % p.threads, cell.y as u32 % p.threads);
        let motif = fbm(uv, p.motif_freq, 3, 0.5, p.seed) > 0.05;
        let weave = if motif { p.motif_weave } else { p.weave };
        let (warp_on_top, before, len) = Self::weave(weave, i, j);
        // τ runs from −1 to 1 along the float: weft floats along u (cells i), warp along v.
        let (psi_c2, psi_s2, s, color, gloss) = if warp_on_top {
            let s = l.y; // plain/satin warp floats are one cell long
            (-1.0, 0.0, s, p.warp_color, p.warp_gloss)
        } else {
            let s = (before as f32 + l.x) / len as f32;
            (1.0, 0.0, s, p.weft_color, p.weft_gloss)
        };
        let tau = 2.0 * s - 1.0;
        // Yarn twist and slub: small per-thread jitter of direction and colour.
        let th = hash(if warp_on_top { i } else { j + 7919 }, 3, p.seed);
        let jit = 0.12 * (hunit(th) - 0.5);
        let (sj, cj) = (2.0 * jit).sin_cos();
        let (c2, s2) = (psi_c2 * cj - psi_s2 * sj, psi_c2 * sj + psi_s2 * cj);
        let shade = 0.85 + 0.3 * hunit(th.rotate_left(11));
        let color = color.map(|c| (c * shade).clamp(0.0, 1.0));
        let fuzz = smoothstep(
            -0.3,
            0.3,
            fbm(uv, p.motif_freq * 8, 2, 0.5, p.seed ^ 0xf022),
        );
        let sheen = lerp(p.sheen[0], p.sheen[1], fuzz);
        [c2, s2, tau, color[0], color[1], color[2], sheen, gloss]
    }

    fn eval(&self, phi: &[f32; FEATURE_DIM], wi: Vec3, wo: Vec3) -> [f32; 3] {
        let Some((wi, wo)) = normalize_pair(wi, wo) else {
            return [0.0; 3];
        };
        let p = &self.p;
        let (c, s) = half_angle(signed(phi[0]), signed(phi[1]));
        let tau = signed(phi[2]);
        let gloss = unit(phi[7]);
        // Thread lobes: normals tilted ± along the thread.
        let mut spec = 0.0;
        for (sign, w) in [(1.0f32, 0.5 * (1.0 + tau)), (-1.0, 0.5 * (1.0 - tau))] {
            if w <= 0.0 {
                continue;
            }
            let frame =
                ShadingFrame::tilted_along_tangent(c, s, sign * self.tilt_sin, self.tilt_cos);
            if let Some(l) = frame.local(wi, wo) {
                let (dg, cos_d) = ggx_dg(l.wi, l.wo, self.ax, self.ay);
                spec += w * dg * l.inv_4mm * schlick1(p.f0, cos_d);
            }
        }
        let spec = gloss * spec;
        // Retro lobe.
        let inv_4cc = 0.25 / (wi.z * wo.z);
        let hr = Vec3::new(wi.x - wo.x, wi.y - wo.y, wi.z + wo.z).normalize();
        let retro =
            p.retro * ggx_d(hr, self.ar, self.ar) * ggx_g2(wi, wo, self.ar, self.ar) * inv_4cc;
        // Sheen.
        let h = (wi + wo).normalize();
        let sheen_amt = unit(phi[6]);
        let sheen = sheen_amt * charlie_d(h.z, p.sheen_alpha) * sheen_visibility(wi.z, wo.z);
        // Diffuse.
        let kd = (1.0 - p.retro - sheen_amt * self.sheen_max).max(0.0)
            * LAMBERT
            * (1.0 - schlick1(p.f0 * gloss, wi.z))
            * (1.0 - schlick1(p.f0 * gloss, wo.z));
        let mut out = [0.0; 3];
        for k in 0..3 {
            out[k] = spec + retro + sheen * p.sheen_color[k] + kd * unit(phi[3 + k]);
        }
        sanitize(out)
    }
}
