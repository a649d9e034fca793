//! The neural material over wavefronts: features per lane (texture reads), the decoder as
//! matrix products over a chunk's lanes: [`NeuralMaterial::features`] bit for bit,
//! [`NeuralMaterial::eval`] within the `wavefront` tolerances.

use super::*;
use crate::error::Result;
use crate::wavefront::simd::{dispatch, Kernel};
use crate::wavefront::{Features, FeaturesMut, RgbMut, Soa, Vec2s, Vec3s};

/// Lanes per chunk (two 64-wide activations of 64 lanes: 32 KiB). Each register tile
/// of the dense kernel widens its weights once per chunk, so 64 lanes amortise that
/// over twice the work of 32 (`neusample bench` prints the kernel's throughput).
const CHUNK: usize = 64;

impl<W: Weights> NeuralMaterial<W> {
    /// [`NeuralMaterial::features`] of every `uv[i]`, written to `phi` (structure of
    /// arrays). Lengths must agree ([`crate::Error::BatchLength`]).
    pub fn features_batch(&self, uv: Vec2s<'_>, phi: FeaturesMut<'_>) -> Result<()> {
        let n = uv.len();
        uv.check(n)?;
        phi.check(n)?;
        dispatch(FeaturesJob { m: self, uv, phi });
        Ok(())
    }

    /// [`NeuralMaterial::eval`] of every `(phi[i], wi[i], wo[i])`: the RGB BRDF without
    /// the cosine, `[0, 0, 0]` for refused lanes. Lengths must agree
    /// ([`crate::Error::BatchLength`]).
    pub fn eval_batch(
        &self,
        phi: Features<'_>,
        wi: Vec3s<'_>,
        wo: Vec3s<'_>,
        out: RgbMut<'_>,
    ) -> Result<()> {
        let n = wi.len();
        phi.check(n)?;
        wi.check(n)?;
        wo.check(n)?;
        out.check(n)?;
        dispatch(EvalJob {
            m: self,
            phi,
            wi,
            wo,
            out,
        });
        Ok(())
    }

    /// [`NeuralMaterial::eval`] of lanes `a .. b` (at most [`CHUNK`]).
    #[inline(always)]
    fn eval_chunk(
        &self,
        args: &EvalArgs<'_>,
        out: &mut RgbMut<'_>,
        (a, b): (usize, usize),
        s: &mut Scratch,
    ) {
        let w = &self.params;
        let m = b - a;
        let Scratch { x, valid, h, o } = s;
        encode_chunk(args, a, b, x, valid);
        Decoder::forward_lanes_in(w, x, h, o, m);
        // Per channel over the lanes, without branches: the exponentials vectorise.
        let channels = [&mut *out.r, &mut *out.g, &mut *out.b];
        for (dst, o) in channels.into_iter().zip(o.iter()) {
            for ((d, y), ok) in dst[a..b].iter_mut().zip(&o[..m]).zip(&valid[..m]) {
                let f = output_to_brdf(*y);
                *d = if *ok { f } else { 0.0 };
            }
        }
    }
}

/// [`decoder_input`] of lanes `a .. b` into `x`, with `valid[l]` whether lane `a + l` is
/// accepted (its inputs are then exactly [`decoder_input`]'s; a refused lane's are
/// meaningless and its outputs are not read). Channel by channel and lane by lane
/// without branches, so that the loops vectorise.
#[inline(always)]
fn encode_chunk(
    args: &EvalArgs<'_>,
    a: usize,
    b: usize,
    x: &mut Soa<DECODER_INPUTS, CHUNK>,
    valid: &mut [bool; CHUNK],
) {
    let m = b - a;
    let valid = &mut valid[..m];
    valid.fill(true);
    for (xk, c) in x.iter_mut().zip(&args.phi.channels) {
        let c = &c[a..b];
        xk[..m].copy_from_slice(c);
        for (v, p) in valid.iter_mut().zip(c) {
            *v &= math::is_finite(*p);
        }
    }
    let (wi, wo) = (&args.wi, &args.wo);
    let lanes = (wi.x[a..b].iter().zip(&wi.y[a..b]).zip(&wi.z[a..b]))
        .zip(wo.x[a..b].iter().zip(&wo.y[a..b]).zip(&wo.z[a..b]));
    for (l, (((ix, iy), iz), ((ox, oy), oz))) in lanes.enumerate() {
        let (d, ok) = direction_inputs(Vec3::new(*ix, *iy, *iz), Vec3::new(*ox, *oy, *oz));
        for (k, e) in d.iter().enumerate() {
            x[FEATURE_DIM + k][l] = *e;
        }
        valid[l] &= ok;
    }
}

/// One chunk's activations, initialised once per call and reused by its chunks: the
/// kernel writes every lane it reads.
struct Scratch {
    x: Soa<DECODER_INPUTS, CHUNK>,
    valid: [bool; CHUNK],
    h: [Soa<DECODER_HIDDEN, CHUNK>; 2],
    o: Soa<DECODER_OUTPUTS, CHUNK>,
}

/// The inputs of [`NeuralMaterial::eval_batch`].
struct EvalArgs<'a> {
    phi: Features<'a>,
    wi: Vec3s<'a>,
    wo: Vec3s<'a>,
}

struct EvalJob<'a, 'm, W> {
    m: &'m NeuralMaterial<W>,
    phi: Features<'a>,
    wi: Vec3s<'a>,
    wo: Vec3s<'a>,
    out: RgbMut<'a>,
}

impl<W: Weights> Kernel for EvalJob<'_, '_, W> {
    type Output = ();
    #[inline(always)]
    fn run(mut self) {
        let args = EvalArgs {
            phi: self.phi,
            wi: self.wi,
            wo: self.wo,
        };
        let n = args.wi.len();
        let mut s = Scratch {
            x: [[0.0; CHUNK]; DECODER_INPUTS],
            valid: [false; CHUNK],
            h: [[[0.0; CHUNK]; DECODER_HIDDEN]; 2],
            o: [[0.0; CHUNK]; DECODER_OUTPUTS],
        };
        for ab in crate::wavefront::chunks(n, CHUNK) {
            self.m.eval_chunk(&args, &mut self.out, ab, &mut s);
        }
    }
}

struct FeaturesJob<'a, 'm, W> {
    m: &'m NeuralMaterial<W>,
    uv: Vec2s<'a>,
    phi: FeaturesMut<'a>,
}

impl<W: Weights> Kernel for FeaturesJob<'_, '_, W> {
    type Output = ();
    #[inline(always)]
    fn run(mut self) {
        for i in 0..self.uv.len() {
            self.phi.set(i, &self.m.features(self.uv.at(i)));
        }
    }
}
