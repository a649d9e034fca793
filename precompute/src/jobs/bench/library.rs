//! The library reference of `neusample bench`: the runtime's network shapes through a kept
//! GEMM (`matrixmultiply`, through `ndarray`'s safe `general_mat_mul`), one thread, so that
//! anyone can see on their own CPU how close the runtime's dense kernels come to a library's;
//! and one large product, which checks the bench's multiply-add peak estimate (no library
//! may run above it).
//!
//! Each network is a chain of products `H ← H·W` (`N × I` by `I × O`, row-major, f32) with the
//! bias added and ReLU applied to the hidden layers in one pass over the output: the cheapest
//! activation, so that the figure is the products' and the memory traffic's, not the
//! activations'. The weights are fixed pseudo-random values (timings do not depend on them).

use ndarray::linalg::general_mat_mul;
use ndarray::{Array1, Array2, Axis, Zip};
use neusample::neural_material::{
    DECODER_HIDDEN as DH, DECODER_INPUTS as DI, DECODER_OUTPUTS as DO, DECODER_PARAM_COUNT,
};
use serde::{Deserialize, Serialize};

use crate::eval::cost::time_per;
use crate::util::rng::splitmix64;

/// Batch sizes of the library reference (rows of each product).
pub const LIBRARY_BATCHES: [usize; 2] = [64, 1024];

/// The large product of the peak check: `M × K` by `K × N`.
pub const LARGE: (usize, usize, usize) = (1024, 512, 512);

/// A network of the runtime, by its layer widths (`core/ARCHITECTURES.md`).
#[derive(Copy, Clone, Debug)]
pub struct Shape {
    /// What it is.
    pub name: &'static str,
    /// Input width, then every layer's output width.
    pub widths: &'static [usize],
}

/// The shapes measured: the neural material's decoder (the bench's dense-layer figure) and
/// the samplers' networks.
pub const SHAPES: [Shape; 5] = [
    Shape {
        name: "neural material decoder",
        widths: &[DI, DH, DH, DH, DO],
    },
    Shape {
        name: "flow coupling network",
        widths: &[39, 32, 32, 59],
    },
    Shape {
        name: "histogram mixture",
        widths: &[10, 32, 32, 32, 40],
    },
    Shape {
        name: "improved baseline",
        widths: &[30, 32, 32, 32, 5],
    },
    Shape {
        name: "reparam warp",
        widths: &[32, 16, 16, 3],
    },
];

impl Shape {
    /// Multiply-adds per point.
    #[must_use]
    pub fn macs(&self) -> usize {
        self.widths.windows(2).map(|w| w[0] * w[1]).sum()
    }

    /// `"14→64→64→64→3"`.
    #[must_use]
    pub fn arrows(&self) -> String {
        self.widths
            .iter()
            .map(ToString::to_string)
            .collect::<Vec<_>>()
            .join("→")
    }
}

/// One network through the library.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct NetworkCost {
    /// [`Shape::name`].
    pub network: String,
    /// [`Shape::arrows`].
    pub widths: String,
    /// Multiply-adds per point.
    pub macs: usize,
    /// `(N, ns per point)` at each of [`LIBRARY_BATCHES`].
    pub ns_per_point: Vec<(usize, f64)>,
}

impl NetworkCost {
    /// 10⁹ multiply-adds per second at batch `n` (0 when not measured).
    #[must_use]
    pub fn gmacs(&self, n: usize) -> f64 {
        self.ns_per_point
            .iter()
            .find(|x| x.0 == n)
            .map_or(0.0, |x| self.macs as f64 / x.1)
    }
}

/// The library reference (`BenchReport::library`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct LibraryReference {
    /// The library and its kernels on this CPU.
    pub library: String,
    /// Per network.
    pub networks: Vec<NetworkCost>,
    /// The decoder's four layers through the runtime's own kernel
    /// (`neusample::wavefront::dense_layer`, chunks of 32 lanes, the run-time chosen
    /// instruction set), in the units of [`Self::networks`]: the dense layers alone, without
    /// the material's encoding and output.
    pub runtime_decoder: NetworkCost,
    /// `[M, K, N]` of the large product.
    pub large_shape: [usize; 3],
    /// The large product's multiply-adds per second, 10⁹/s.
    pub large_gmacs: f64,
}

/// Fixed pseudo-random values in `[−0.5, 0.5)`.
fn filled(rows: usize, cols: usize, seed: u64) -> Array2<f32> {
    Array2::from_shape_fn((rows, cols), |(r, c)| {
        let h = splitmix64(seed ^ ((r as u64) << 32 | c as u64));
        (h >> 40) as f32 / (1u64 << 24) as f32 - 0.5
    })
}

/// A network's weights and the activations of one batch.
struct Chain {
    weights: Vec<(Array2<f32>, Array1<f32>)>,
    /// The input, then one output per layer.
    acts: Vec<Array2<f32>>,
}

impl Chain {
    fn new(shape: &Shape, n: usize) -> Chain {
        let weights = shape
            .widths
            .windows(2)
            .enumerate()
            .map(|(l, w)| {
                let b = filled(1, w[1], 0xB1A5 + l as u64).remove_axis(Axis(0));
                (filled(w[0], w[1], 0x5EED + l as u64), b)
            })
            .collect();
        let acts = shape
            .widths
            .iter()
            .enumerate()
            .map(|(l, &w)| {
                if l == 0 {
                    filled(n, w, 0x1A7)
                } else {
                    Array2::zeros((n, w))
                }
            })
            .collect();
        Chain { weights, acts }
    }

    /// One forward pass over the batch.
    fn forward(&mut self) {
        let last = self.weights.len() - 1;
        for (l, (w, b)) in self.weights.iter().enumerate() {
            let (done, rest) = self.acts.split_at_mut(l + 1);
            let (x, y) = (&done[l], &mut rest[0]);
            general_mat_mul(1.0, x, w, 0.0, y);
            let relu = l < last;
            for mut row in y.rows_mut() {
                Zip::from(&mut row).and(b).for_each(|v, &bias| {
                    let s = *v + bias;
                    *v = if relu { s.max(0.0) } else { s };
                });
            }
        }
    }
}

/// ns per point of `shape` at batch `n`, `lanes` points per timed pass.
fn network_ns(shape: &Shape, n: usize, lanes: usize, passes: usize) -> f64 {
    let mut chain = Chain::new(shape, n);
    let calls = lanes.div_ceil(n).max(1);
    time_per(passes, calls * n, || {
        for _ in 0..calls {
            chain.forward();
        }
        std::hint::black_box(&chain.acts);
    })
}

/// Lanes per chunk of the runtime's decoder (the neural material's batched chunk).
const CHUNK: usize = 64;

/// The decoder's layers through `neusample::wavefront::dense_layer`: ns per point at batch
/// `n` (whole chunks of [`CHUNK`]; the last one partial).
fn runtime_decoder_ns(n: usize, lanes: usize, passes: usize) -> f64 {
    use neusample::nn::{Activation, ReluMlp};
    use neusample::wavefront::dense_layer;
    let [l0, l1, l2, l3] = ReluMlp::<DI, DH, DO, 4>::OFFSETS.map(|o| o as u32);
    let params = filled(1, DECODER_PARAM_COUNT, 0xDEC)
        .into_raw_vec_and_offset()
        .0;
    let w: &[f32] = &params;
    let chunks = n.div_ceil(CHUNK);
    let inputs: Vec<[[f32; CHUNK]; DI]> = (0..chunks)
        .map(|c| {
            let v = filled(DI, CHUNK, 0x1A7 + c as u64);
            core::array::from_fn(|i| core::array::from_fn(|b| v[[i, b]]))
        })
        .collect();
    let mut h = [[0.0f32; CHUNK]; DH];
    let mut g = [[0.0f32; CHUNK]; DH];
    let mut o = [[0.0f32; CHUNK]; DO];
    let calls = lanes.div_ceil(n).max(1);
    let relu = Activation::Relu;
    time_per(passes, calls * n, || {
        for _ in 0..calls {
            for (c, x) in inputs.iter().enumerate() {
                let m = (n - c * CHUNK).min(CHUNK);
                dense_layer(w, l0, x, relu, &mut h, m);
                dense_layer(w, l1, &h, relu, &mut g, m);
                dense_layer(w, l2, &g, relu, &mut h, m);
                dense_layer(w, l3, &h, Activation::Identity, &mut o, m);
                std::hint::black_box(&o);
            }
        }
    })
}

/// Runs the library reference.
#[must_use]
pub fn run(lanes: usize, passes: usize) -> LibraryReference {
    let decoder = &SHAPES[0];
    let runtime_decoder = NetworkCost {
        network: format!("{} (the runtime's kernel)", decoder.name),
        widths: decoder.arrows(),
        macs: decoder.macs(),
        ns_per_point: LIBRARY_BATCHES
            .iter()
            .map(|&n| (n, runtime_decoder_ns(n, lanes, passes)))
            .collect(),
    };
    let networks = SHAPES
        .iter()
        .map(|s| NetworkCost {
            network: s.name.to_string(),
            widths: s.arrows(),
            macs: s.macs(),
            ns_per_point: LIBRARY_BATCHES
                .iter()
                .map(|&n| (n, network_ns(s, n, lanes, passes)))
                .collect(),
        })
        .collect();
    let (m, k, n) = LARGE;
    let a = filled(m, k, 0xA);
    let b = filled(k, n, 0xB);
    let mut c = Array2::<f32>::zeros((m, n));
    let ns = time_per(passes, 1, || {
        general_mat_mul(1.0, &a, &b, 0.0, &mut c);
        std::hint::black_box(&c);
    });
    LibraryReference {
        library: library_name(),
        networks,
        runtime_decoder,
        large_shape: [m, k, n],
        large_gmacs: (m * k * n) as f64 / ns,
    }
}

/// The library and the kernels it picks on this CPU (`matrixmultiply` detects AVX2 + FMA at
/// run time; it has no AVX-512 kernels).
fn library_name() -> String {
    #[cfg(target_arch = "x86_64")]
    let kernels = if std::arch::is_x86_feature_detected!("avx2")
        && std::arch::is_x86_feature_detected!("fma")
    {
        "AVX2 + FMA kernels"
    } else {
        "SSE2 kernels"
    };
    #[cfg(not(target_arch = "x86_64"))]
    let kernels = "its kernels for this target";
    format!("matrixmultiply 0.3 (through ndarray 0.17), {kernels}, one thread")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The chain computes the products it claims: one layer against a plain triple loop.
    #[test]
    fn chain_layer_matches_a_plain_product() {
        let shape = Shape {
            name: "t",
            widths: &[5, 7],
        };
        let mut c = Chain::new(&shape, 3);
        c.forward();
        let (w, b) = &c.weights[0];
        for r in 0..3 {
            for j in 0..7 {
                let want: f32 = b[j] + (0..5).map(|i| c.acts[0][[r, i]] * w[[i, j]]).sum::<f32>();
                assert!((c.acts[1][[r, j]] - want).abs() < 1e-5, "{r} {j}");
            }
        }
    }

    #[test]
    fn shapes_count_their_multiply_adds() {
        assert_eq!(SHAPES[0].macs(), 14 * 64 + 64 * 64 * 2 + 64 * 3);
        assert_eq!(SHAPES[0].arrows(), "14→64→64→64→3");
    }
}
