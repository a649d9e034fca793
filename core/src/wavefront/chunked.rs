//! [`ChunkedSampler`]: what a sampler writes to be batched; [`BatchSampler`] follows
//! (argument checks, chunking, instruction-set dispatch).

use super::simd::{dispatch, Isa, Kernel};
use super::{
    check_invert_args, check_pdf_args, check_prepare_args, check_sample_args, chunks, BatchSampler,
    Features, SamplesMut, Scratch, Vec2s, Vec2sMut, Vec3s,
};
use crate::error::Result;

/// How a sampler computes one chunk of at most `CHUNK` lanes (arguments already checked).
/// Every method must be `#[inline(always)]`, so that [`dispatch`] compiles it for the
/// chosen instruction set. Public only to name it in [`BatchSampler`]'s blanket impl; the
/// module is private.
pub trait ChunkedSampler {
    /// See [`BatchSampler::Lane`].
    type Lane: super::LaneState;
    /// See [`BatchSampler::Scratch`]: one for all the chunks of a call.
    type Scratch: Scratch;
    /// Lanes per chunk.
    const CHUNK: usize;
    /// The widest instruction set its chunks are compiled for ([`Kernel::WIDEST`]).
    const WIDEST: Isa = Isa::X86V4;
    /// [`BatchSampler::prepare_batch`] of one chunk.
    fn prepare_chunk(&self, phi: Features<'_>, wi: Vec3s<'_>, lanes: &mut [Self::Lane]);
    /// [`BatchSampler::sample_batch`] of one chunk.
    fn sample_chunk(
        &self,
        lanes: &[Self::Lane],
        u: Vec2s<'_>,
        out: SamplesMut<'_>,
        scratch: &mut Self::Scratch,
    );
    /// [`BatchSampler::pdf_batch`] of one chunk.
    fn pdf_chunk(
        &self,
        lanes: &[Self::Lane],
        wo: Vec3s<'_>,
        pdf: &mut [f32],
        scratch: &mut Self::Scratch,
    );
    /// [`BatchSampler::invert_batch`] of one chunk.
    fn invert_chunk(
        &self,
        lanes: &[Self::Lane],
        wo: Vec3s<'_>,
        u: Vec2sMut<'_>,
        ok: &mut [bool],
        scratch: &mut Self::Scratch,
    );
}

struct Prepare<'a, 's, S: ChunkedSampler> {
    s: &'s S,
    phi: Features<'a>,
    wi: Vec3s<'a>,
    lanes: &'a mut [S::Lane],
}

impl<S: ChunkedSampler> Kernel for Prepare<'_, '_, S> {
    type Output = ();
    const WIDEST: Isa = S::WIDEST;
    #[inline(always)]
    fn run(self) {
        let n = self.lanes.len();
        for (a, b) in chunks(n, S::CHUNK) {
            let (phi, wi) = (self.phi.range(a, b), self.wi.range(a, b));
            self.s.prepare_chunk(phi, wi, &mut self.lanes[a..b]);
        }
    }
}

struct Sample<'a, 's, S: ChunkedSampler> {
    s: &'s S,
    lanes: &'a [S::Lane],
    u: Vec2s<'a>,
    out: SamplesMut<'a>,
    scratch: &'a mut S::Scratch,
}

/// [`Kernel`] for the pass `$kernel` (a struct holding `s: &S`, `lanes` and `scratch`): the
/// lanes in chunks of `S::CHUNK`, which share the one scratch. `$chunk` computes chunk
/// `$a .. $b`, with `$k` the kernel (`&mut`).
macro_rules! chunk_pass {
    ($kernel:ident, |$k:ident, $a:ident, $b:ident| $chunk:expr) => {
        impl<S: ChunkedSampler> Kernel for $kernel<'_, '_, S> {
            type Output = ();
            const WIDEST: Isa = S::WIDEST;
            #[inline(always)]
            fn run(mut self) {
                let $k = &mut self;
                let n = $k.lanes.len();
                for ($a, $b) in chunks(n, S::CHUNK) {
                    $chunk;
                }
            }
        }
    };
}

chunk_pass!(Sample, |k, a, b| {
    let (lanes, u) = (&k.lanes[a..b], k.u.range(a, b));
    k.s.sample_chunk(lanes, u, k.out.range(a, b), k.scratch)
});

struct Pdf<'a, 's, S: ChunkedSampler> {
    s: &'s S,
    lanes: &'a [S::Lane],
    wo: Vec3s<'a>,
    pdf: &'a mut [f32],
    scratch: &'a mut S::Scratch,
}

chunk_pass!(Pdf, |k, a, b| {
    let (lanes, wo) = (&k.lanes[a..b], k.wo.range(a, b));
    k.s.pdf_chunk(lanes, wo, &mut k.pdf[a..b], k.scratch)
});

struct Invert<'a, 's, S: ChunkedSampler> {
    s: &'s S,
    lanes: &'a [S::Lane],
    wo: Vec3s<'a>,
    u: Vec2sMut<'a>,
    ok: &'a mut [bool],
    scratch: &'a mut S::Scratch,
}

chunk_pass!(Invert, |k, a, b| {
    let (lanes, wo) = (&k.lanes[a..b], k.wo.range(a, b));
    let (u, ok) = (k.u.range(a, b), &mut k.ok[a..b]);
    k.s.invert_chunk(lanes, wo, u, ok, k.scratch)
});

impl<S: ChunkedSampler> BatchSampler for S {
    type Lane = S::Lane;
    type Scratch = S::Scratch;

    fn prepare_batch(&self, phi: Features<'_>, wi: Vec3s<'_>, lanes: &mut [S::Lane]) -> Result<()> {
        check_prepare_args(&phi, &wi, lanes)?;
        dispatch(Prepare {
            s: self,
            phi,
            wi,
            lanes,
        });
        Ok(())
    }

    fn sample_batch_in(
        &self,
        lanes: &[S::Lane],
        u: Vec2s<'_>,
        out: SamplesMut<'_>,
        scratch: &mut S::Scratch,
    ) -> Result<()> {
        check_sample_args(lanes, &u, &out)?;
        dispatch(Sample {
            s: self,
            lanes,
            u,
            out,
            scratch,
        });
        Ok(())
    }

    fn pdf_batch_in(
        &self,
        lanes: &[S::Lane],
        wo: Vec3s<'_>,
        pdf: &mut [f32],
        scratch: &mut S::Scratch,
    ) -> Result<()> {
        check_pdf_args(lanes, &wo, pdf)?;
        dispatch(Pdf {
            s: self,
            lanes,
            wo,
            pdf,
            scratch,
        });
        Ok(())
    }

    fn invert_batch(
        &self,
        lanes: &[S::Lane],
        wo: Vec3s<'_>,
        u: Vec2sMut<'_>,
        ok: &mut [bool],
    ) -> Result<()> {
        check_invert_args(lanes, &wo, &u, ok)?;
        let mut scratch = <S::Scratch as Scratch>::NEW;
        dispatch(Invert {
            s: self,
            lanes,
            wo,
            u,
            ok,
            scratch: &mut scratch,
        });
        Ok(())
    }
}

/// How a chunk of `Option<Self>` lanes (a scalar [`Prepared`](crate::Prepared) state that
/// needs no weights) is sampled, evaluated and inverted: by default the scalar code lane by
/// lane; a state with a faster whole-chunk path overrides the methods. Every method must be
/// `#[inline(always)]` (see [`ChunkedSampler`]).
pub(crate) trait LaneChunks: crate::Prepared + Sized {
    /// [`ChunkedSampler::sample_chunk`] of these lanes.
    #[inline(always)]
    fn sample_lanes(lanes: &[Option<Self>], u: Vec2s<'_>, mut out: SamplesMut<'_>) {
        for (i, l) in lanes.iter().enumerate() {
            out.set(i, l.as_ref().and_then(|p| p.sample(u.at(i))));
        }
    }

    /// [`ChunkedSampler::pdf_chunk`] of these lanes.
    #[inline(always)]
    fn pdf_lanes(lanes: &[Option<Self>], wo: Vec3s<'_>, pdf: &mut [f32]) {
        for (i, l) in lanes.iter().enumerate() {
            pdf[i] = l.as_ref().map_or(0.0, |p| p.pdf(wo.at(i)));
        }
    }

    /// [`ChunkedSampler::invert_chunk`] of these lanes.
    #[inline(always)]
    fn invert_lanes(lanes: &[Option<Self>], wo: Vec3s<'_>, mut u: Vec2sMut<'_>, ok: &mut [bool]) {
        for (i, l) in lanes.iter().enumerate() {
            match l.as_ref().and_then(|p| p.invert(wo.at(i))) {
                Some(v) => {
                    u.set(i, v);
                    ok[i] = true;
                }
                None => ok[i] = false,
            }
        }
    }
}

/// [`ChunkedSampler`]'s `sample_chunk`, `pdf_chunk` and `invert_chunk` for lanes that are
/// `Option<P>` of a [`LaneChunks`] state `P`.
macro_rules! per_lane_chunks {
    ($p:ty) => {
        #[inline(always)]
        fn sample_chunk(
            &self,
            lanes: &[Option<$p>],
            u: $crate::wavefront::Vec2s<'_>,
            out: $crate::wavefront::SamplesMut<'_>,
            _scratch: &mut Self::Scratch,
        ) {
            <$p as $crate::wavefront::chunked::LaneChunks>::sample_lanes(lanes, u, out);
        }

        #[inline(always)]
        fn pdf_chunk(
            &self,
            lanes: &[Option<$p>],
            wo: $crate::wavefront::Vec3s<'_>,
            pdf: &mut [f32],
            _scratch: &mut Self::Scratch,
        ) {
            <$p as $crate::wavefront::chunked::LaneChunks>::pdf_lanes(lanes, wo, pdf);
        }

        #[inline(always)]
        fn invert_chunk(
            &self,
            lanes: &[Option<$p>],
            wo: $crate::wavefront::Vec3s<'_>,
            u: $crate::wavefront::Vec2sMut<'_>,
            ok: &mut [bool],
            _scratch: &mut Self::Scratch,
        ) {
            <$p as $crate::wavefront::chunked::LaneChunks>::invert_lanes(lanes, wo, u, ok);
        }
    };
}
pub(crate) use per_lane_chunks;

/// The [`ChunkedSampler`] of a sampler whose prepare is one [`ReluMlp`](crate::nn::ReluMlp)
/// `net` of the encoded condition with `outputs` outputs, followed by its scalar
/// [`Prepared`](crate::Prepared) state's [`FromOutputs`](super::FromOutputs), in chunks of
/// `chunk` lanes; sample, pdf and invert run [`per_lane_chunks`].
macro_rules! mlp_lane_sampler {
    (
        $sampler:ident => $prepared:ident,
        chunk: $chunk:expr,
        net: $net:ty,
        outputs: $outputs:expr $(,)?
    ) => {
        impl<W: $crate::weights::Weights> $crate::wavefront::chunked::ChunkedSampler
            for $sampler<W>
        {
            type Lane = Option<$prepared>;
            type Scratch = ();
            const CHUNK: usize = $chunk;

            #[inline(always)]
            fn prepare_chunk(
                &self,
                phi: $crate::wavefront::Features<'_>,
                wi: $crate::wavefront::Vec3s<'_>,
                lanes: &mut [Self::Lane],
            ) {
                use $crate::wavefront::lanes::{head, NARROW};
                use $crate::wavefront::{encoded_conditions, FromOutputs, Soa};
                const CHUNK: usize = $chunk;
                let m = lanes.len();
                let (c, valid) = encoded_conditions::<CHUNK>(&phi, &wi);
                let mut o: Soa<{ $outputs }, CHUNK> = [[0.0; CHUNK]; $outputs];
                <$net>::forward_lanes(&self.params, &c, &mut o, m);
                // A small chunk gives row-wise constructors rows of `NARROW` lanes (the same
                // bits).
                if <$prepared as FromOutputs<{ $outputs }>>::ROWS && m <= NARROW {
                    let o: Soa<{ $outputs }, NARROW> = head(&o);
                    let [valid] = head::<_, 1, NARROW, CHUNK>(&[valid]);
                    <$prepared as FromOutputs<{ $outputs }>>::lanes(&o, &valid, lanes);
                } else {
                    <$prepared as FromOutputs<{ $outputs }>>::lanes(&o, &valid, lanes);
                }
            }

            $crate::wavefront::per_lane_chunks!($prepared);
        }
    };
}
pub(crate) use mlp_lane_sampler;
