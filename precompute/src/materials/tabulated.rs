//! `model = "tabulated"`: an isotropic BRDF given as a table of values (measured or
//! precomputed data), interpolated.
//!
//! # Table file (`.nstab`, little-endian)
//!
//! ```text
//! offset  size  field
//! 0       8     magic  b"NSTAB\x01\0\0"
//! 8       4     n_theta   u32, ≥ 2       number of incident elevations
//! 12      4     n         u32, ≥ 2       wo⊥ grid resolution (n × n cells over [−1, 1]²)
//! 16      4     channels  u32, 1 or 3    luminance or linear RGB
//! 20      4     reserved  u32, 0
//! 24      …     f32 values[n_theta][n][n][channels]   (row-major, rows = y)
//! ```
//!
//! Entry `[k][r][c]` is `f(wi_k, wo)` (no cosine) with
//! `θ_k = k/(n_theta − 1) · π/2`, `wi_k = (sin θ_k, 0, cos θ_k)` (incident azimuth 0), and
//! `wo⊥ = (−1 + (c + ½)·2/n, −1 + (r + ½)·2/n)` the cell centre; entries whose centre is
//! outside the unit disk are ignored (treated as 0). Values must be finite and ≥ 0.
//!
//! Lookup for any `(wi, wo)`: rotate `wo⊥` by `−φi` (the table is isotropic: only the relative
//! azimuth matters), interpolate linearly in θi between the two nearest elevations and
//! bilinearly between cell centres in `wo⊥` (clamped at the grid edge); 0 below the horizon.
//! Tables need not be reciprocal, so [`Material::reciprocal`] is false.
//!
//! # φ layout
//!
//! | index | meaning                                              | range      |
//! |-------|------------------------------------------------------|------------|
//! | 0     | gain (scales f; a procedural stain texture)          | `[0, 1]`   |
//! | 1–7   | unused, 0                                            | `0`        |
//!
//! So the target pdf does not depend on uv; samplers must learn the (θi, wo) dependence only.

use anyhow::{bail, Context};
use glam::{Vec2, Vec3};

use super::check::params;
use super::format::{File, SideFiles};
use super::microfacet::normalize_pair;
use super::model::{luminance, Material, FEATURE_DIM};
use super::noise::{fbm, wrap_uv};
use super::surface::{lerp, sanitize, unit};

/// Magic bytes of a `.nstab` file.
pub const MAGIC: [u8; 8] = *b"NSTAB\x01\0\0";

params! {
    /// `[params]` of a `tabulated` material.
    pub struct Params {
        /// Table file, relative to the material file.
        pub table: String,
        /// Noise seed of the gain texture.
        #[serde(default)]
        pub seed: u32,
        /// Gain range (a stain texture); `[1, 1]` for none.
        pub gain: [f32; 2] => interval(0.0..=1.0),
    }
}

/// An isotropic BRDF table (see the module docs for the layout).
#[derive(Clone, Debug, PartialEq)]
pub struct Table {
    /// Number of incident elevations.
    pub n_theta: usize,
    /// Grid resolution of wo⊥.
    pub n: usize,
    /// 1 (luminance) or 3 (RGB).
    pub channels: usize,
    /// `n_theta · n · n · channels` values.
    pub values: Vec<f32>,
}

impl Table {
    /// Tabulates `f(wi, wo)` (e.g. an analytic BRDF) at the grid points of the module docs.
    pub fn from_fn(
        n_theta: usize,
        n: usize,
        channels: usize,
        f: impl Fn(Vec3, Vec3) -> [f32; 3],
    ) -> Table {
        let mut values = Vec::with_capacity(n_theta * n * n * channels);
        for k in 0..n_theta {
            let theta = k as f32 / (n_theta - 1) as f32 * std::f32::consts::FRAC_PI_2;
            let wi = Vec3::new(theta.sin(), 0.0, theta.cos().max(1e-4)).normalize();
            for r in 0..n {
                for c in 0..n {
                    let p = cell_center(n, r, c);
                    let r2 = p.length_squared();
                    let v = if r2 < 1.0 {
                        f(wi, Vec3::new(p.x, p.y, (1.0 - r2).sqrt()))
                    } else {
                        [0.0; 3]
                    };
                    if channels == 1 {
                        values.push(luminance(v));
                    } else {
                        values.extend_from_slice(&v);
                    }
                }
            }
        }
        Table {
            n_theta,
            n,
            channels,
            values,
        }
    }

    /// Serialises to the `.nstab` format.
    #[must_use]
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(24 + 4 * self.values.len());
        out.extend_from_slice(&MAGIC);
        for v in [self.n_theta, self.n, self.channels, 0] {
            out.extend_from_slice(&(v as u32).to_le_bytes());
        }
        for v in &self.values {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out
    }

    /// Parses and validates the `.nstab` format.
    pub fn from_bytes(b: &[u8]) -> anyhow::Result<Table> {
        if b.len() < 24 || b[..8] != MAGIC {
            bail!("not a neusample BRDF table (bad magic or shorter than its 24-byte header)");
        }
        let u = |o: usize| u32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]]) as usize;
        let (n_theta, n, channels) = (u(8), u(12), u(16));
        if !(2..=1024).contains(&n_theta) {
            bail!("table header: n_theta must be in 2..=1024, got {n_theta}");
        }
        if !(2..=4096).contains(&n) {
            bail!("table header: n must be in 2..=4096, got {n}");
        }
        if channels != 1 && channels != 3 {
            bail!("table header: channels must be 1 or 3, got {channels}");
        }
        let count = n_theta * n * n * channels;
        if b.len() != 24 + 4 * count {
            bail!(
                "table size: expected {} bytes for {n_theta}×{n}×{n}×{channels} values, got {}",
                24 + 4 * count,
                b.len()
            );
        }
        let values: Vec<f32> = b[24..]
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        if let Some(i) = values.iter().position(|v| !(v.is_finite() && *v >= 0.0)) {
            bail!("table value #{i} is {} (must be finite and ≥ 0)", values[i]);
        }
        Ok(Table {
            n_theta,
            n,
            channels,
            values,
        })
    }

    #[inline]
    fn at(&self, k: usize, r: usize, c: usize) -> [f32; 3] {
        let i = ((k * self.n + r) * self.n + c) * self.channels;
        if self.channels == 1 {
            [self.values[i]; 3]
        } else {
            [self.values[i], self.values[i + 1], self.values[i + 2]]
        }
    }

    /// Interpolated `f(wi, wo)` for unit directions above the horizon (module docs).
    #[must_use]
    pub fn lookup(&self, wi: Vec3, wo: Vec3) -> [f32; 3] {
        // Rotate wo⊥ by −φi.
        let s = (wi.x * wi.x + wi.y * wi.y).sqrt();
        let (c, sn) = if s > 1e-7 {
            (wi.x / s, wi.y / s)
        } else {
            (1.0, 0.0)
        };
        let p = Vec2::new(c * wo.x + sn * wo.y, -sn * wo.x + c * wo.y);
        let theta = s.atan2(wi.z).clamp(0.0, std::f32::consts::FRAC_PI_2);
        let tk = theta / std::f32::consts::FRAC_PI_2 * (self.n_theta - 1) as f32;
        let k0 = (tk.floor() as usize).min(self.n_theta - 2);
        let wk = (tk - k0 as f32).clamp(0.0, 1.0);
        let n = self.n as f32;
        let gx = ((p.x + 1.0) * 0.5 * n - 0.5).clamp(0.0, n - 1.0);
        let gy = ((p.y + 1.0) * 0.5 * n - 0.5).clamp(0.0, n - 1.0);
        let c0 = (gx.floor() as usize).min(self.n - 2);
        let r0 = (gy.floor() as usize).min(self.n - 2);
        let (wx, wy) = (gx - c0 as f32, gy - r0 as f32);
        let mut out = [0.0f32; 3];
        for (k, a) in [(k0, 1.0 - wk), (k0 + 1, wk)] {
            for (r, b) in [(r0, 1.0 - wy), (r0 + 1, wy)] {
                for (cc, d) in [(c0, 1.0 - wx), (c0 + 1, wx)] {
                    let w = a * b * d;
                    if w > 0.0 {
                        let v = self.at(k, r, cc);
                        out[0] += w * v[0];
                        out[1] += w * v[1];
                        out[2] += w * v[2];
                    }
                }
            }
        }
        out
    }
}

/// Centre of cell `(r, c)` of an `n × n` grid over `[−1, 1]²`.
#[inline]
#[must_use]
pub fn cell_center(n: usize, r: usize, c: usize) -> Vec2 {
    let h = 2.0 / n as f32;
    Vec2::new(-1.0 + (c as f32 + 0.5) * h, -1.0 + (r as f32 + 0.5) * h)
}

/// A `tabulated` material.
#[derive(Clone, Debug)]
pub struct Tabulated {
    name: String,
    p: Params,
    table: Table,
}

impl Tabulated {
    /// Validates a parsed file and loads its table through `side`.
    pub fn new(file: File<Params>, side: SideFiles<'_>) -> anyhow::Result<Self> {
        file.params.check()?;
        let bytes = side(&file.params.table).with_context(|| "field `params.table`".to_string())?;
        let table = Table::from_bytes(&bytes)
            .with_context(|| format!("field `params.table`: table `{}`", file.params.table))?;
        Ok(Tabulated {
            name: file.name,
            p: file.params,
            table,
        })
    }

    /// A tabulated material from an in-memory table.
    #[must_use]
    pub fn from_table(name: &str, table: Table) -> Self {
        Tabulated {
            name: name.to_string(),
            p: Params {
                table: String::new(),
                seed: 0,
                gain: [1.0, 1.0],
            },
            table,
        }
    }

    /// The table.
    #[must_use]
    pub fn table(&self) -> &Table {
        &self.table
    }
}

impl Material for Tabulated {
    fn name(&self) -> &str {
        &self.name
    }

    fn features(&self, uv: Vec2) -> [f32; FEATURE_DIM] {
        let [g0, g1] = self.p.gain;
        let g = if g1 > g0 {
            let uv = wrap_uv(uv);
            let t = (0.5 + 1.5 * fbm(uv, 4, 4, 0.5, self.p.seed)).clamp(0.0, 1.0);
            lerp(g0, g1, t)
        } else {
            g1
        };
        let mut phi = [0.0; FEATURE_DIM];
        phi[0] = g;
        phi
    }

    fn eval(&self, phi: &[f32; FEATURE_DIM], wi: Vec3, wo: Vec3) -> [f32; 3] {
        let Some((wi, wo)) = normalize_pair(wi, wo) else {
            return [0.0; 3];
        };
        let g = unit(phi[0]);
        sanitize(self.table.lookup(wi, wo).map(|v| v * g))
    }

    fn reciprocal(&self) -> bool {
        false
    }
}
