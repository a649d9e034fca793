//! The procedural sky: a zenith-to-horizon gradient, a ground colour, a small bright sun and
//! its aureole.

use glam::Vec3;

/// A procedural sky: a zenith-to-horizon gradient, a uniform ground below the horizon, a sun
/// disc of small angular radius and high radiance, and a soft aureole around it.
#[derive(Clone, Debug, PartialEq)]
pub struct Sky {
    /// Radiance at the zenith (linear RGB).
    pub zenith: [f32; 3],
    /// Radiance at the horizon.
    pub horizon: [f32; 3],
    /// Radiance of every direction below the horizon.
    pub ground: [f32; 3],
    /// Unit direction towards the sun (z-up world).
    pub sun_dir: Vec3,
    /// Sun colour (multiplied by `sun_radiance`).
    pub sun_color: [f32; 3],
    /// Radiance of the sun disc (0: no sun).
    pub sun_radiance: f32,
    /// Angular radius of the sun disc, degrees.
    pub sun_radius_deg: f32,
    /// Peak radiance of the aureole `a · exp(−γ² / 2w²)` (γ: angle to the sun).
    pub aureole: f32,
    /// Angular width `w` of the aureole, degrees.
    pub aureole_width_deg: f32,
}

impl Sky {
    /// A clear daylight sky with the sun at `elevation_deg` above the horizon and
    /// `azimuth_deg` (0 = +y, positive towards +x).
    #[must_use]
    pub fn daylight(
        elevation_deg: f32,
        azimuth_deg: f32,
        sun_radiance: f32,
        sun_radius_deg: f32,
    ) -> Sky {
        let (el, az) = (elevation_deg.to_radians(), azimuth_deg.to_radians());
        Sky {
            zenith: [0.25, 0.45, 0.95],
            horizon: [0.85, 0.9, 1.0],
            ground: [0.32, 0.28, 0.24],
            sun_dir: Vec3::new(az.sin() * el.cos(), az.cos() * el.cos(), el.sin()),
            sun_color: [1.0, 0.93, 0.82],
            sun_radiance,
            sun_radius_deg,
            aureole: 2.0,
            aureole_width_deg: 6.0,
        }
    }

    /// The same radiance `rgb` from every direction (no sun): the white-furnace environment.
    #[must_use]
    pub fn constant(rgb: [f32; 3]) -> Sky {
        Sky {
            zenith: rgb,
            horizon: rgb,
            ground: rgb,
            sun_dir: Vec3::Z,
            sun_color: [1.0; 3],
            sun_radiance: 0.0,
            sun_radius_deg: 0.5,
            aureole: 0.0,
            aureole_width_deg: 1.0,
        }
    }

    /// Cosine of the sun's angular radius.
    #[must_use]
    pub fn cos_sun_radius(&self) -> f32 {
        self.sun_radius_deg.to_radians().cos()
    }

    /// Sky radiance without the sun disc (gradient, ground, aureole).
    #[must_use]
    pub fn background(&self, d: Vec3) -> [f32; 3] {
        if d.z < 0.0 {
            return self.ground;
        }
        let t = d.z.sqrt();
        let mut c = [0.0; 3];
        for k in 0..3 {
            c[k] = self.horizon[k] + (self.zenith[k] - self.horizon[k]) * t;
        }
        if self.aureole > 0.0 {
            let gamma = d.dot(self.sun_dir).clamp(-1.0, 1.0).acos();
            let w = self.aureole_width_deg.to_radians().max(1e-4);
            let a = self.aureole * (-0.5 * gamma * gamma / (w * w)).exp();
            for k in 0..3 {
                c[k] += a * self.sun_color[k];
            }
        }
        c
    }
}
