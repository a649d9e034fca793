//! Samplers whose prepare is one ReLU MLP of the encoded condition ([`mlp_sampler!`]).

/// A sampler `pub struct $sampler<W> { params: W }` (with the attributes `$attr`) whose
/// prepared state `$prepared` is `$from` (a function of `&[f32; $outputs]`) of one
/// [`ReluMlp`](crate::nn::ReluMlp) `$net` of the encoded condition: the struct,
/// `flat_params_sampler!` for kind `$kind` (`$count` documents the parameter count), its
/// `forward`, the [`Sampler`](super::Sampler) (the condition checked and encoded, then the
/// network) and, off the GPU, the batched path in chunks of `$chunk` lanes
/// (`mlp_lane_sampler!`).
macro_rules! mlp_sampler {
    (
        $(#[$attr:meta])*
        pub struct $sampler:ident => $prepared:ident {
            kind: $kind:ident,
            net: $net:ty,
            outputs: $outputs:expr,
            from: $from:path,
            chunk: $chunk:expr,
            count: $count:literal $(,)?
        }
    ) => {
        $(#[$attr])*
        #[derive(Copy, Clone, Debug)]
        pub struct $sampler<W> {
            params: W,
        }

        $crate::samplers::traits::flat_params_sampler!($sampler, $kind, <$net>::LEN, $count);

        impl<W: $crate::Weights> $sampler<W> {
            /// The raw network outputs for an encoded condition (what
            #[doc = concat!("[`", stringify!($from), "`]")]
            /// reads).
            #[inline]
            #[must_use]
            pub fn forward(&self, c: &[f32; $crate::nn::CONDITION_DIM]) -> [f32; $outputs] {
                <$net>::forward(&self.params, c)
            }
        }

        impl<W: $crate::Weights> $crate::samplers::Sampler for $sampler<W> {
            type Prepared<'s>
                = $prepared
            where
                Self: 's;

            #[inline]
            fn prepare(
                &self,
                phi: &[f32; $crate::nn::FEATURE_DIM],
                wi: glam::Vec3,
            ) -> Option<$prepared> {
                let wi = $crate::nn::check_condition(phi, wi)?;
                let c = $crate::nn::encode_condition(phi, wi);
                let o: [f32; $outputs] = <$net>::forward(&self.params, &c);
                Some($from(&o))
            }
        }

        #[cfg(not(target_arch = "spirv"))]
        $crate::wavefront::mlp_lane_sampler!(
            $sampler => $prepared,
            chunk: $chunk,
            net: $net,
            outputs: $outputs,
        );
    };
}
pub(crate) use mlp_sampler;
