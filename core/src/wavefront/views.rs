//! Structure-of-arrays views of a wavefront's inputs and outputs, checked for equal lengths.

use glam::{Vec2, Vec3};

use crate::error::{Error, Result};
use crate::nn::FEATURE_DIM;
use crate::samplers::Sample;

/// `N` two-dimensional values in structure-of-arrays form (e.g. the random numbers `u`).
#[derive(Copy, Clone, Debug)]
pub struct Vec2s<'a> {
    /// First components.
    pub x: &'a [f32],
    /// Second components.
    pub y: &'a [f32],
}

/// `N` directions in structure-of-arrays form (local shading frame).
#[derive(Copy, Clone, Debug)]
pub struct Vec3s<'a> {
    /// x components.
    pub x: &'a [f32],
    /// y components.
    pub y: &'a [f32],
    /// z components (the normal's axis).
    pub z: &'a [f32],
}

/// Writable [`Vec2s`].
#[derive(Debug)]
pub struct Vec2sMut<'a> {
    /// First components.
    pub x: &'a mut [f32],
    /// Second components.
    pub y: &'a mut [f32],
}

/// Writable [`Vec3s`].
#[derive(Debug)]
pub struct Vec3sMut<'a> {
    /// x components.
    pub x: &'a mut [f32],
    /// y components.
    pub y: &'a mut [f32],
    /// z components.
    pub z: &'a mut [f32],
}

/// The feature vectors φ of `N` shading points, one slice per channel (`channels[c][i]` is
/// channel `c` of point `i`).
#[derive(Copy, Clone, Debug)]
pub struct Features<'a> {
    /// The [`FEATURE_DIM`] channels.
    pub channels: [&'a [f32]; FEATURE_DIM],
}

/// Writable [`Features`].
#[derive(Debug)]
pub struct FeaturesMut<'a> {
    /// The [`FEATURE_DIM`] channels.
    pub channels: [&'a mut [f32]; FEATURE_DIM],
}

/// Where [`BatchSampler::sample_batch`](super::BatchSampler::sample_batch) writes: the sampled directions and their
/// solid-angle densities (`wo = 0`, `pdf = mis_pdf = 0` for a refused sample).
#[derive(Debug)]
pub struct SamplesMut<'a> {
    /// Sampled directions (local shading frame, unit length).
    pub wo: Vec3sMut<'a>,
    /// Their densities with respect to solid angle ([`Sample::pdf`]): what `f · cos θo` is
    /// divided by.
    pub pdf: &'a mut [f32],
    /// Their MIS densities with respect to solid angle ([`Sample::mis_pdf`]).
    pub mis_pdf: &'a mut [f32],
}

/// Where [`NeuralMaterial::eval_batch`](crate::NeuralMaterial::eval_batch) writes: the BRDF (no cosine) per RGB channel.
#[derive(Debug)]
pub struct RgbMut<'a> {
    /// Red.
    pub r: &'a mut [f32],
    /// Green.
    pub g: &'a mut [f32],
    /// Blue.
    pub b: &'a mut [f32],
}

impl Vec2s<'_> {
    /// Point `i` (panics when `i` is out of range, as slice indexing does).
    #[inline(always)]
    #[must_use]
    pub fn at(&self, i: usize) -> Vec2 {
        Vec2::new(self.x[i], self.y[i])
    }
}

impl Vec3s<'_> {
    /// Direction `i` (panics when `i` is out of range, as slice indexing does).
    #[inline(always)]
    #[must_use]
    pub fn at(&self, i: usize) -> Vec3 {
        Vec3::new(self.x[i], self.y[i], self.z[i])
    }
}

impl Vec2sMut<'_> {
    #[inline(always)]
    pub(crate) fn set(&mut self, i: usize, v: Vec2) {
        self.x[i] = v.x;
        self.y[i] = v.y;
    }
}

impl Vec3sMut<'_> {
    #[inline(always)]
    pub(crate) fn set(&mut self, i: usize, v: Vec3) {
        self.x[i] = v.x;
        self.y[i] = v.y;
        self.z[i] = v.z;
    }
}

impl RgbMut<'_> {
    #[inline(always)]
    pub(crate) fn set(&mut self, i: usize, v: [f32; 3]) {
        self.r[i] = v[0];
        self.g[i] = v[1];
        self.b[i] = v[2];
    }
}

/// The methods of a view whose components are named slices: `from_rows` (one row per
/// component, in field order), `check` (every component `n` long), `range` (lanes `a .. b`)
/// and, for read-only views, `len` and `is_empty`.
macro_rules! component_views {
    (@one $c:ident) => {
        1
    };
    ($view:ident: [$c0:ident $(, $c:ident)*]) => {
        impl<'a> $view<'a> {
            /// The row-major array `rows`, one row of `n` values per component in field
            /// order, as one slice per component; `None` unless `rows.len()` is the number of
            /// components times `n`.
            #[must_use]
            pub fn from_rows(rows: &'a [f32], n: usize) -> Option<Self> {
                if rows.len() != (1 $(+ component_views!(@one $c))*) * n {
                    return None;
                }
                let ($c0, rest) = rows.split_at(n);
                $(let ($c, rest) = rest.split_at(n);)*
                let _ = rest;
                Some($view { $c0 $(, $c)* })
            }

            /// Number of values (the length of the first component).
            #[must_use]
            pub fn len(&self) -> usize {
                self.$c0.len()
            }

            /// `true` when there are no values.
            #[must_use]
            pub fn is_empty(&self) -> bool {
                self.len() == 0
            }

            pub(crate) fn check(&self, n: usize) -> Result<()> {
                check_len(stringify!($c0), self.$c0.len(), n)?;
                $(check_len(stringify!($c), self.$c.len(), n)?;)*
                Ok(())
            }

            pub(crate) fn range(&self, a: usize, b: usize) -> $view<'a> {
                $view { $c0: &self.$c0[a..b] $(, $c: &self.$c[a..b])* }
            }
        }
    };
    (mut $view:ident: [$c0:ident $(, $c:ident)*]) => {
        impl<'a> $view<'a> {
            /// The row-major array `rows`, one row of `n` values per component in field
            /// order, as one slice per component; `None` unless `rows.len()` is the number of
            /// components times `n`.
            #[must_use]
            pub fn from_rows(rows: &'a mut [f32], n: usize) -> Option<Self> {
                if rows.len() != (1 $(+ component_views!(@one $c))*) * n {
                    return None;
                }
                let ($c0, rest) = rows.split_at_mut(n);
                $(let ($c, rest) = rest.split_at_mut(n);)*
                let _ = rest;
                Some($view { $c0 $(, $c)* })
            }

            pub(crate) fn check(&self, n: usize) -> Result<()> {
                check_len(stringify!($c0), self.$c0.len(), n)?;
                $(check_len(stringify!($c), self.$c.len(), n)?;)*
                Ok(())
            }
        }
    };
    (mut $view:ident: [$c0:ident $(, $c:ident)*], range) => {
        component_views!(mut $view: [$c0 $(, $c)*]);

        impl $view<'_> {
            pub(crate) fn range(&mut self, a: usize, b: usize) -> $view<'_> {
                $view { $c0: &mut self.$c0[a..b] $(, $c: &mut self.$c[a..b])* }
            }
        }
    };
}

component_views!(Vec2s: [x, y]);
component_views!(Vec3s: [x, y, z]);
component_views!(mut Vec2sMut: [x, y], range);
component_views!(mut Vec3sMut: [x, y, z], range);
component_views!(mut RgbMut: [r, g, b]);

impl<'a> Features<'a> {
    /// The `(FEATURE_DIM, n)` row-major array `rows` (channel-major) as one slice per
    /// channel; `None` unless `rows.len() == FEATURE_DIM · n`.
    #[must_use]
    pub fn from_rows(rows: &'a [f32], n: usize) -> Option<Self> {
        if rows.len() != FEATURE_DIM * n {
            return None;
        }
        let mut channels: [&'a [f32]; FEATURE_DIM] = [&[]; FEATURE_DIM];
        let mut rest = rows;
        for c in channels.iter_mut() {
            let (head, tail) = rest.split_at(n);
            *c = head;
            rest = tail;
        }
        Some(Features { channels })
    }

    /// Number of points (the length of channel 0).
    #[must_use]
    pub fn len(&self) -> usize {
        self.channels[0].len()
    }

    /// `true` when there are no points.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.channels[0].is_empty()
    }

    /// φ of point `i`.
    #[inline(always)]
    #[must_use]
    pub fn at(&self, i: usize) -> [f32; FEATURE_DIM] {
        let mut phi = [0.0f32; FEATURE_DIM];
        for (p, c) in phi.iter_mut().zip(self.channels.iter()) {
            *p = c[i];
        }
        phi
    }

    pub(crate) fn check(&self, n: usize) -> Result<()> {
        for c in self.channels.iter() {
            check_len("phi", c.len(), n)?;
        }
        Ok(())
    }

    pub(crate) fn range(&self, a: usize, b: usize) -> Features<'a> {
        let mut channels: [&'a [f32]; FEATURE_DIM] = [&[]; FEATURE_DIM];
        for (dst, src) in channels.iter_mut().zip(self.channels.iter()) {
            *dst = &src[a..b];
        }
        Features { channels }
    }
}

impl<'a> FeaturesMut<'a> {
    /// The `(FEATURE_DIM, n)` row-major array `rows` as one slice per channel; `None` unless
    /// `rows.len() == FEATURE_DIM · n`.
    #[must_use]
    pub fn from_rows(rows: &'a mut [f32], n: usize) -> Option<Self> {
        if rows.len() != FEATURE_DIM * n {
            return None;
        }
        let mut it = rows.chunks_exact_mut(n.max(1));
        let channels: [&'a mut [f32]; FEATURE_DIM] = core::array::from_fn(|_| match it.next() {
            Some(c) if n > 0 => c,
            _ => &mut [],
        });
        Some(FeaturesMut { channels })
    }

    /// Read-only view.
    #[must_use]
    pub fn as_features(&self) -> Features<'_> {
        let mut channels: [&[f32]; FEATURE_DIM] = [&[]; FEATURE_DIM];
        for (dst, src) in channels.iter_mut().zip(self.channels.iter()) {
            *dst = src;
        }
        Features { channels }
    }

    pub(crate) fn check(&self, n: usize) -> Result<()> {
        for c in self.channels.iter() {
            check_len("phi", c.len(), n)?;
        }
        Ok(())
    }

    #[inline(always)]
    pub(crate) fn set(&mut self, i: usize, phi: &[f32; FEATURE_DIM]) {
        for (c, v) in self.channels.iter_mut().zip(phi.iter()) {
            c[i] = *v;
        }
    }
}

impl<'a> SamplesMut<'a> {
    /// Writes lane `i`: the sample, or a refusal (`wo = 0`, `pdf = mis_pdf = 0`).
    #[inline(always)]
    pub(crate) fn set(&mut self, i: usize, s: Option<Sample>) {
        match s {
            Some(s) => {
                self.wo.set(i, s.wo);
                self.pdf[i] = s.pdf;
                self.mis_pdf[i] = s.mis_pdf;
            }
            None => {
                self.wo.set(i, Vec3::ZERO);
                self.pdf[i] = 0.0;
                self.mis_pdf[i] = 0.0;
            }
        }
    }

    pub(crate) fn check(&self, n: usize) -> Result<()> {
        self.wo.check(n)?;
        check_len("pdf", self.pdf.len(), n)?;
        check_len("mis_pdf", self.mis_pdf.len(), n)
    }

    pub(crate) fn range(&mut self, a: usize, b: usize) -> SamplesMut<'_> {
        SamplesMut {
            wo: self.wo.range(a, b),
            pdf: &mut self.pdf[a..b],
            mis_pdf: &mut self.mis_pdf[a..b],
        }
    }
}

/// [`Error::BatchLength`] unless `found == expected`.
#[inline]
pub(crate) fn check_len(what: &'static str, found: usize, expected: usize) -> Result<()> {
    if found == expected {
        Ok(())
    } else {
        Err(Error::BatchLength {
            what,
            expected: clamp_u32(expected),
            found: clamp_u32(found),
        })
    }
}

fn clamp_u32(x: usize) -> u32 {
    u32::try_from(x).unwrap_or(u32::MAX)
}
