//! `model = "tiles"`: a grid of tiles with a different material per tile (paper: Moroccan
//! Tiles): each tile draws one of `params.kinds` (glazed ceramic, brushed metal, rough stone…)
//! by a hash of its index; tiles have bevelled edges (strong normal tilt near the border) and
//! are separated by grout. A star-shaped inlay in the centre of each tile uses the kind's
//! `inlay_color`.
//!
//! Anisotropic tiles are brushed along the tile's u axis for `anisotropy > 0` and along v for
//! `< 0` (smoother along the brushing, see [`super::surface::aniso_alphas`]).
//!
//! # φ layout
//!
//! | index | meaning                                                | range     |
//! |-------|--------------------------------------------------------|-----------|
//! | 0–2   | base colour (RGB): albedo, or F0 for metals            | `[0, 1]`  |
//! | 3     | metallic `m` (`F0 = lerp(0.04, colour, m)`)            | `[0, 1]`  |
//! | 4     | perceptual roughness `r`                               | `[0, 1]`  |
//! | 5     | signed anisotropy `a` (`|a|` as in `wood`; sign = axis) | `[−1, 1]` |
//! | 6, 7  | shading normal `n.x`, `n.y`                            | `|(n.x, n.y)| ≤ 0.9` |

use glam::{Vec2, Vec3};

use super::check::{self, params};
use super::microfacet::{clamp_tilt, ShadingFrame};
use super::model::FEATURE_DIM;
use super::noise::{fbm, hash, smoothstep};
use super::surface::{aniso_alphas, lerp3, signed, unit, unit3, Surface, SurfaceModel};

params! {
    /// One tile material.
    pub struct Kind {
        /// Base colour.
        pub color: [f32; 3] => range_n(0.0..=1.0),
        /// Colour of the central inlay (defaults to `color`).
        #[serde(default)]
        pub inlay_color: Option<[f32; 3]> => range_n(0.0..=1.0),
        /// Metallic.
        pub metallic: f32 => range(0.0..=1.0),
        /// Perceptual roughness.
        pub roughness: f32 => range(0.0..=1.0),
        /// Signed anisotropy.
        #[serde(default)]
        pub anisotropy: f32 => range(-1.0..=1.0),
    }
}

params! {
    /// `[params]` of a `tiles` material.
    pub struct Params {
        /// Noise seed.
        pub seed: u32,
        /// Tiles per uv unit (each direction).
        pub tiles: u32 => count(1..=64),
        /// Grout width as a fraction of a tile.
        pub grout_width: f32 => range(0.0..=0.3),
        /// Bevel width as a fraction of a tile.
        pub bevel_width: f32 => range(0.0..=0.3),
        /// Bevel tilt `|(n.x, n.y)|` at the tile border.
        pub bevel_tilt: f32 => range(0.0..=0.9),
        /// Grout material.
        pub grout: Kind,
        /// Tile materials (1..=16), chosen per tile by hash.
        pub kinds: Vec<Kind>,
    }
}

/// A `tiles` material.
#[derive(Clone, Debug)]
pub struct Tiles {
    p: Params,
}

impl SurfaceModel for Tiles {
    type Params = Params;

    fn from_params(p: Params) -> anyhow::Result<Self> {
        p.check()?;
        p.grout.check_in("grout.")?;
        check::count("kinds (number of entries)", p.kinds.len() as u32, 1, 16)?;
        for (i, k) in p.kinds.iter().enumerate() {
            k.check_in(&format!("kinds[{i}]."))?;
        }
        Ok(Tiles { p })
    }

    fn features(&self, uv: Vec2) -> [f32; FEATURE_DIM] {
        let p = &self.p;
        let q = uv * p.tiles as f32;
        let cell = q.floor();
        let l = q - cell; // position inside the tile, [0,1)²
        let d = l.min(Vec2::ONE - l); // distance to the four edges
        let edge = d.x.min(d.y);
        let half_grout = 0.5 * p.grout_width;
        if edge < half_grout {
            let k = &p.grout;
            let tint = 1.0 + 0.2 * fbm(uv, 64, 2, 0.5, p.seed ^ 0x6);
            let c = k.color.map(|x| (x * tint).clamp(0.0, 1.0));
            return [
                c[0],
                c[1],
                c[2],
                k.metallic,
                k.roughness,
                k.anisotropy,
                0.0,
                0.0,
            ];
        }
        let (ci, cj) = (cell.x as u32 % p.tiles, cell.y as u32 % p.tiles);
        let h = hash(ci, cj, p.seed);
        let k = &p.kinds[(h % p.kinds.len() as u32) as usize];
        // Bevel: the normal tilts outward over `bevel_width` from the grout.
        let mut n2 = Vec2::ZERO;
        if p.bevel_width > 0.0 {
            let w = 1.0 - smoothstep(half_grout, half_grout + p.bevel_width, edge);
            let dir = if d.x < d.y {
                Vec2::new(if l.x < 0.5 { -1.0 } else { 1.0 }, 0.0)
            } else {
                Vec2::new(0.0, if l.y < 0.5 { -1.0 } else { 1.0 })
            };
            n2 = dir * (w * p.bevel_tilt);
        }
        // Eight-pointed star inlay: |x|+|y| and max(|x|,|y|) rosettes around the centre.
        let c = (l - Vec2::splat(0.5)).abs();
        let star = (c.x + c.y).min(c.x.max(c.y) * std::f32::consts::SQRT_2);
        let inlay = 1.0 - smoothstep(0.22, 0.25, star);
        let color = lerp3(k.color, k.inlay_color.unwrap_or(k.color), inlay);
        let glaze = 1.0 + 0.1 * fbm(uv, p.tiles * 8, 2, 0.5, p.seed ^ h);
        let color = color.map(|x| (x * glaze).clamp(0.0, 1.0));
        let n = Vec3::new(n2.x, n2.y, 1.0).normalize();
        let (nx, ny) = clamp_tilt(n.x, n.y);
        [
            color[0],
            color[1],
            color[2],
            k.metallic,
            k.roughness,
            k.anisotropy,
            nx,
            ny,
        ]
    }

    fn decode(&self, phi: &[f32; FEATURE_DIM]) -> Surface {
        let a = signed(phi[5]);
        let (along, across) = aniso_alphas(unit(phi[4]), a.abs()); // α_t ≤ α_b
        let (ax, ay) = if a >= 0.0 {
            (along, across)
        } else {
            (across, along)
        };
        let mut s = Surface::metallic(ax, unit3(phi, 0), unit(phi[3]));
        s.ay = ay;
        s.frame = ShadingFrame::new(signed(phi[6]), signed(phi[7]), 1.0, 0.0);
        s
    }
}
