//! Run-time choice of the instruction set the batched kernels are compiled for.
//!
//! The kernels are plain Rust over small fixed arrays ([`super::lanes::V8`]) that LLVM turns
//! into SIMD instructions. [`dispatch`] runs a kernel inside a function compiled for the
//! best instruction set the CPU reports up to the kernel's [`Kernel::WIDEST`] (on x86-64,
//! through `pulp`'s safe run-time detection: AVX-512 (x86-64-v4), else AVX2 + FMA
//! (x86-64-v3)), or as compiled for the build's target (the portable path: SSE2 on x86-64,
//! NEON on aarch64, simd128 where the build enables it, scalar elsewhere). On aarch64, where
//! NEON is part of the target, [`Isa::Neon`] is that compiled code with the dense layers'
//! own NEON tiles. The dense layers ([`super::dense`]) use fused multiply-adds on the x86-64
//! and NEON paths and separate ones on the portable path, so the paths agree within a
//! tolerance, not bit for bit (`wavefront` documents it); each path is deterministic. This
//! module and [`super::dense`] are the only ones that name `pulp`.

use core::sync::atomic::{AtomicU8, Ordering};

/// An instruction set the batched kernels can run with.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Isa {
    /// As compiled for the build's target, without run-time dispatch.
    Portable,
    /// x86-64-v3: AVX2, FMA, BMI (chosen at run time).
    X86V3,
    /// x86-64-v4: AVX-512 F/BW/CD/DQ/VL on top of x86-64-v3 (chosen at run time).
    X86V4,
    /// aarch64 with NEON (Advanced SIMD, part of every aarch64 target): fused multiply-add
    /// tiles in the dense layers.
    Neon,
}

impl Isa {
    /// Its short name (`portable`, `x86-64-v3`, `x86-64-v4`, `aarch64-neon`).
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Isa::Portable => "portable",
            Isa::X86V3 => "x86-64-v3",
            Isa::X86V4 => "x86-64-v4",
            Isa::Neon => "aarch64-neon",
        }
    }

    /// Every instruction set: the portable path, then each architecture's from the
    /// narrowest up (a later one of an architecture includes the earlier ones).
    pub const ALL: [Isa; 4] = [Isa::Portable, Isa::X86V3, Isa::X86V4, Isa::Neon];

    /// Whether this CPU runs it.
    #[must_use]
    pub fn is_available(self) -> bool {
        match self {
            Isa::Portable => true,
            #[cfg(any(target_arch = "x86", target_arch = "x86_64"))]
            Isa::X86V3 => pulp::x86::V3::is_available(),
            #[cfg(any(target_arch = "x86", target_arch = "x86_64"))]
            Isa::X86V4 => pulp::x86::V4::is_available(),
            #[cfg(target_arch = "aarch64")]
            Isa::Neon => pulp::aarch64::Neon::is_available(),
            #[allow(unreachable_patterns)]
            _ => false,
        }
    }
}

/// No preference set: use the best detected instruction set.
const AUTO: u8 = u8::MAX;

/// The instruction set [`prefer`] asked for, as its discriminant; [`AUTO`] by default.
static PREFERRED: AtomicU8 = AtomicU8::new(AUTO);

/// The best instruction set this CPU supports.
#[must_use]
pub fn detected() -> Isa {
    for isa in [Isa::X86V4, Isa::X86V3, Isa::Neon] {
        if isa.is_available() {
            return isa;
        }
    }
    Isa::Portable
}

/// Makes the batched kernels of this process run with `isa` (for benchmarks and tests that
/// compare instruction sets), or with the best detected one for `None`. An `isa` the CPU
/// does not support is ignored (the best supported one is used). Returns the instruction
/// set now in use.
pub fn prefer(isa: Option<Isa>) -> Isa {
    PREFERRED.store(
        match isa {
            None => AUTO,
            Some(i) => i as u8,
        },
        Ordering::Relaxed,
    );
    current()
}

/// The instruction set the batched kernels run with now.
#[must_use]
pub fn current() -> Isa {
    let p = PREFERRED.load(Ordering::Relaxed);
    match Isa::ALL.into_iter().find(|i| *i as u8 == p) {
        Some(i) if i.is_available() => i,
        _ => detected(),
    }
}

/// A batched computation that [`dispatch`] runs. Its `run` (and everything `run` calls that
/// should use the chosen instruction set) must be `#[inline(always)]`: an instruction set
/// reaches code only by inlining into the function compiled for it.
pub(crate) trait Kernel {
    /// The widest instruction set worth compiling the computation for: each one below it
    /// is another copy of the code. Code written in eight-lane groups gains nothing from
    /// AVX-512's sixteen lanes ([`Isa::X86V3`] then; the dense layers it calls still
    /// dispatch on their own). Read on x86-64 only.
    #[cfg_attr(
        not(any(target_arch = "x86", target_arch = "x86_64")),
        allow(dead_code)
    )]
    const WIDEST: Isa = Isa::X86V4;
    /// What the computation returns.
    type Output;
    /// The computation.
    fn run(self) -> Self::Output;
}

/// A [`Kernel`] as `pulp` takes it.
#[cfg(any(target_arch = "x86", target_arch = "x86_64"))]
struct Job<K>(K);

#[cfg(any(target_arch = "x86", target_arch = "x86_64"))]
impl<K: Kernel> pulp::NullaryFnOnce for Job<K> {
    type Output = K::Output;
    #[inline(always)]
    fn call(self) -> K::Output {
        self.0.run()
    }
}

/// Runs `k` compiled for [`current`]'s instruction set, or for [`Kernel::WIDEST`] if that
/// is narrower.
#[inline(always)]
pub(crate) fn dispatch<K: Kernel>(k: K) -> K::Output {
    #[cfg(any(target_arch = "x86", target_arch = "x86_64"))]
    let k = match x86_wide(k) {
        Ok(out) => return out,
        Err(k) => k,
    };
    // aarch64: NEON is part of the target, so the code as compiled is the NEON path; only
    // the dense layers choose between their tiles.
    k.run()
}

/// `k` compiled for AVX-512 or AVX2 where [`current`] is one of them (and not above
/// [`Kernel::WIDEST`]); `Err(k)` otherwise.
#[cfg(any(target_arch = "x86", target_arch = "x86_64"))]
#[inline(always)]
fn x86_wide<K: Kernel>(k: K) -> Result<K::Output, K> {
    match current() {
        isa @ (Isa::X86V4 | Isa::X86V3) => {
            // A constant per kernel: the copy for an instruction set above `K::WIDEST` is
            // never compiled.
            if const { K::WIDEST as u8 >= Isa::X86V4 as u8 } && isa == Isa::X86V4 {
                if let Some(v4) = pulp::x86::V4::try_new() {
                    return Ok(v4.vectorize(Job(k)));
                }
            }
            if let Some(v3) = pulp::x86::V3::try_new() {
                return Ok(v3.vectorize(Job(k)));
            }
            Err(k)
        }
        Isa::Portable | Isa::Neon => Err(k),
    }
}

/// Table reads of sixteen lanes, as an instruction set does them: gathers with AVX-512
/// ([`Avx512`]) or AVX2 ([`Avx2`]), a load per lane elsewhere ([`Loads`]). LLVM does not
/// form gathers on its own here: rustc compiles for the generic x86-64 CPU, whose cost model
/// prices them high, and the reads stay scalar loads and inserts. A [`GatherKernel`] gets
/// the reads as a type, so that each compiled copy of it reads one way, without a branch.
pub(crate) trait Gather: Copy {
    /// `t[min(i[l], t.len() − 1)]` on each lane: a branch-free read of a table whose
    /// indices are in range. A [`Loads`] read needs a non-empty `t`; the gathers read zeros
    /// from an empty one.
    fn read(self, t: &[f32], i: &[u32; 16]) -> [f32; 16];

    /// Two adjacent elements per lane (a bilinear cell's row, a node interval): `t[j]` and
    /// `t[j + 1]`. The gathers read them as one 64-bit element, which moves half the
    /// elements of two 32-bit reads, at `j = min(i[l], t.len() − 2)` (for a `t` of fewer
    /// than two elements, [`Self::read`] of `i` and `i + 1`); [`Loads`] reads
    /// [`Self::read`] of `i` and of `i + 1`. The two agree on in-range indices.
    fn read_pair(self, t: &[f32], i: &[u32; 16]) -> ([f32; 16], [f32; 16]);
}

/// A batched computation that reads tables: [`dispatch_gathers`] runs it compiled for the
/// instruction set in use, with that set's [`Gather`]. Its `run` (and what it calls) must be
/// `#[inline(always)]`, as [`Kernel::run`].
pub(crate) trait GatherKernel {
    /// What the computation returns.
    type Output;
    /// The computation, its table reads done by `g`.
    fn run<G: Gather>(self, g: G) -> Self::Output;
}

/// Runs `k` with AVX-512 or AVX2 gathers where [`current`] is one of them; on x86 otherwise
/// (a CPU without AVX2, or [`Isa::Portable`] chosen) `k` comes back as `Err(k)`, not run,
/// so that it is never compiled for SSE2 (its caller has a scalar path for those machines).
/// Elsewhere (aarch64, wasm) it runs as compiled for the target, with [`Loads`].
#[inline(always)]
pub(crate) fn dispatch_gathers<K: GatherKernel>(k: K) -> Result<K::Output, K> {
    #[cfg(target_arch = "x86_64")]
    return match current() {
        Isa::X86V4 => match pulp::x86::V4::try_new() {
            Some(v4) => Ok(v4.vectorize(WithReads(k, Avx512(v4)))),
            None => Err(k),
        },
        Isa::X86V3 => match pulp::x86::V3::try_new() {
            Some(v3) => Ok(v3.vectorize(WithReads(k, Avx2(v3)))),
            None => Err(k),
        },
        _ => Err(k),
    };
    // 32-bit x86: the wide copies, reading with loads.
    #[cfg(target_arch = "x86")]
    return x86_wide(WithReads(k, Loads)).map_err(|w| w.0);
    #[cfg(not(any(target_arch = "x86", target_arch = "x86_64")))]
    Ok(k.run(Loads))
}

/// A [`GatherKernel`] with its reads, as `pulp` (or [`Kernel`]) takes it.
#[cfg(any(target_arch = "x86", target_arch = "x86_64"))]
struct WithReads<K, G>(K, G);

#[cfg(any(target_arch = "x86", target_arch = "x86_64"))]
impl<K: GatherKernel, G: Gather> pulp::NullaryFnOnce for WithReads<K, G> {
    type Output = K::Output;
    #[inline(always)]
    fn call(self) -> K::Output {
        self.0.run(self.1)
    }
}

#[cfg(target_arch = "x86")]
impl<K: GatherKernel, G: Gather> Kernel for WithReads<K, G> {
    type Output = K::Output;
    #[inline(always)]
    fn run(self) -> K::Output {
        self.0.run(self.1)
    }
}

/// Table reads as a load per lane (the targets without gather instructions).
#[derive(Copy, Clone)]
#[cfg_attr(all(target_arch = "x86_64", not(test)), allow(dead_code))]
pub(crate) struct Loads;

impl Gather for Loads {
    #[inline(always)]
    fn read(self, t: &[f32], i: &[u32; 16]) -> [f32; 16] {
        let last = t.len() - 1;
        let mut out = [0.0f32; 16];
        for l in 0..16 {
            out[l] = t[(i[l] as usize).min(last)];
        }
        out
    }

    #[inline(always)]
    fn read_pair(self, t: &[f32], i: &[u32; 16]) -> ([f32; 16], [f32; 16]) {
        let next = core::array::from_fn(|l| i[l].saturating_add(1));
        (self.read(t, i), self.read(t, &next))
    }
}

/// AVX-512 gathers: one instruction per sixteen lanes (two of 64-bit pairs for
/// [`Gather::read_pair`]). Holds the proof that the CPU has AVX-512.
#[cfg(target_arch = "x86_64")]
#[derive(Copy, Clone)]
pub(crate) struct Avx512(pulp::x86::V4);

/// AVX2 gathers: two instructions per sixteen lanes (four of 64-bit pairs for
/// [`Gather::read_pair`]). Holds the proof that the CPU has AVX2.
#[cfg(target_arch = "x86_64")]
#[derive(Copy, Clone)]
pub(crate) struct Avx2(pulp::x86::V3);

/// `read_pair` for a table of fewer than two elements: `read` of `i` and `i + 1`.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn short_pair<G: Gather>(g: G, t: &[f32], i: &[u32; 16]) -> ([f32; 16], [f32; 16]) {
    let next = core::array::from_fn(|l| i[l].saturating_add(1));
    (g.read(t, i), g.read(t, &next))
}

/// The last offset a 32-bit read may take (gathers sign-extend offsets: below 2³¹ too),
/// and the last a 64-bit pair may start at; `t` has at least two elements for the latter.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn last_offsets(t: &[f32]) -> (i32, i32) {
    let last = (t.len().saturating_sub(1)).min(i32::MAX as usize) as i32;
    let pair = (t.len().saturating_sub(2)).min(i32::MAX as usize - 1) as i32;
    (last, pair)
}

#[cfg(target_arch = "x86_64")]
impl Gather for Avx512 {
    #[inline(always)]
    #[allow(unsafe_code)]
    fn read(self, t: &[f32], i: &[u32; 16]) -> [f32; 16] {
        use core::arch::x86_64::{
            _mm512_i32gather_ps, _mm512_loadu_si512, _mm512_min_epu32, _mm512_set1_epi32,
            _mm512_storeu_ps,
        };
        let mut out = [0.0f32; 16];
        if t.is_empty() {
            return out;
        }
        let (last, _) = last_offsets(t);
        // SAFETY: an `Avx512` exists only where `V4::try_new` succeeded, so the CPU has
        // AVX-512F. The unaligned load and store move exactly the 64 bytes of `i` and `out`.
        // Every offset is clamped to `last`, which is below `t.len()` and 2³¹, so the gather
        // reads elements of `t` only.
        unsafe {
            let idx = _mm512_min_epu32(
                _mm512_loadu_si512(i.as_ptr().cast()),
                _mm512_set1_epi32(last),
            );
            _mm512_storeu_ps(
                out.as_mut_ptr(),
                _mm512_i32gather_ps::<4>(idx, t.as_ptr().cast()),
            );
        }
        out
    }

    #[inline(always)]
    #[allow(unsafe_code)]
    fn read_pair(self, t: &[f32], i: &[u32; 16]) -> ([f32; 16], [f32; 16]) {
        use core::arch::x86_64::{
            _mm512_castsi512_ps, _mm512_castsi512_si256, _mm512_extracti64x4_epi64,
            _mm512_i32gather_epi64, _mm512_loadu_si512, _mm512_min_epu32, _mm512_permutex2var_ps,
            _mm512_set1_epi32, _mm512_setr_epi32, _mm512_storeu_ps,
        };
        if t.len() < 2 {
            return short_pair(self, t, i);
        }
        let (_, last) = last_offsets(t);
        let (mut a, mut b) = ([0.0f32; 16], [0.0f32; 16]);
        // SAFETY: an `Avx512` exists only where `V4::try_new` succeeded, so the CPU has
        // AVX-512F. The unaligned load and stores move exactly the 64 bytes of `i`, `a` and
        // `b`. Every offset is clamped to `last` ≤ `t.len()` − 2, so each 8-byte read (scale
        // 4: offsets count f32s) covers elements `j` and `j + 1` of `t` only; gathers need no
        // alignment.
        unsafe {
            let base = t.as_ptr().cast::<i64>();
            let idx = _mm512_min_epu32(
                _mm512_loadu_si512(i.as_ptr().cast()),
                _mm512_set1_epi32(last),
            );
            // Lanes 0..8 and 8..16 as (a, b) pairs: [a0 b0 a1 b1 … a7 b7], then the even and
            // odd elements of the two picked out.
            let g0 = _mm512_castsi512_ps(_mm512_i32gather_epi64::<4>(
                _mm512_castsi512_si256(idx),
                base,
            ));
            let g1 = _mm512_castsi512_ps(_mm512_i32gather_epi64::<4>(
                _mm512_extracti64x4_epi64::<1>(idx),
                base,
            ));
            let even = _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30);
            let odd = _mm512_setr_epi32(1, 3, 5, 7, 9, 11, 13, 15, 17, 19, 21, 23, 25, 27, 29, 31);
            _mm512_storeu_ps(a.as_mut_ptr(), _mm512_permutex2var_ps(g0, even, g1));
            _mm512_storeu_ps(b.as_mut_ptr(), _mm512_permutex2var_ps(g0, odd, g1));
        }
        (a, b)
    }
}

#[cfg(target_arch = "x86_64")]
impl Gather for Avx2 {
    #[inline(always)]
    #[allow(unsafe_code)]
    fn read(self, t: &[f32], i: &[u32; 16]) -> [f32; 16] {
        use core::arch::x86_64::{
            _mm256_i32gather_ps, _mm256_loadu_si256, _mm256_min_epu32, _mm256_set1_epi32,
            _mm256_storeu_ps,
        };
        let mut out = [0.0f32; 16];
        if t.is_empty() {
            return out;
        }
        let (last, _) = last_offsets(t);
        // SAFETY: an `Avx2` exists only where `V3::try_new` succeeded, so the CPU has AVX2.
        // Each half's unaligned load and store move exactly 32 bytes of `i` and `out` (lanes
        // 0..8, then 8..16). Every offset is clamped to `last`, which is below `t.len()` and
        // 2³¹, so the gathers read elements of `t` only.
        unsafe {
            let last = _mm256_set1_epi32(last);
            for h in [0, 8] {
                let idx = _mm256_min_epu32(_mm256_loadu_si256(i.as_ptr().add(h).cast()), last);
                _mm256_storeu_ps(
                    out.as_mut_ptr().add(h),
                    _mm256_i32gather_ps::<4>(t.as_ptr().cast(), idx),
                );
            }
        }
        out
    }

    #[inline(always)]
    #[allow(unsafe_code)]
    fn read_pair(self, t: &[f32], i: &[u32; 16]) -> ([f32; 16], [f32; 16]) {
        use core::arch::x86_64::{
            _mm256_castpd_ps, _mm256_castps_pd, _mm256_castsi256_ps, _mm256_castsi256_si128,
            _mm256_extracti128_si256, _mm256_i32gather_epi64, _mm256_loadu_si256, _mm256_min_epu32,
            _mm256_permute4x64_pd, _mm256_set1_epi32, _mm256_shuffle_ps, _mm256_storeu_ps,
        };
        if t.len() < 2 {
            return short_pair(self, t, i);
        }
        let (_, last) = last_offsets(t);
        let (mut a, mut b) = ([0.0f32; 16], [0.0f32; 16]);
        // SAFETY: an `Avx2` exists only where `V3::try_new` succeeded, so the CPU has AVX2.
        // Each half's unaligned load and stores move exactly 32 bytes of `i`, `a` and `b`
        // (lanes 0..8, then 8..16). Every offset is clamped to `last` ≤ `t.len()` − 2, so
        // each 8-byte read (scale 4: offsets count f32s) covers elements `j` and `j + 1` of
        // `t` only; gathers need no alignment.
        unsafe {
            let base = t.as_ptr().cast::<i64>();
            let last = _mm256_set1_epi32(last);
            for h in [0, 8] {
                let idx = _mm256_min_epu32(_mm256_loadu_si256(i.as_ptr().add(h).cast()), last);
                // Lanes h..h+4 and h+4..h+8 as (a, b) pairs.
                let g0 = _mm256_castsi256_ps(_mm256_i32gather_epi64::<4>(
                    base,
                    _mm256_castsi256_si128(idx),
                ));
                let g1 = _mm256_castsi256_ps(_mm256_i32gather_epi64::<4>(
                    base,
                    _mm256_extracti128_si256::<1>(idx),
                ));
                // Per 128-bit half [x0 x1 x4 x5 | x2 x3 x6 x7], then the 64-bit quarters
                // reordered to x0..x7.
                let even = _mm256_castps_pd(_mm256_shuffle_ps::<0b10_00_10_00>(g0, g1));
                let odd = _mm256_castps_pd(_mm256_shuffle_ps::<0b11_01_11_01>(g0, g1));
                let (even, odd) = (
                    _mm256_permute4x64_pd::<0b11_01_10_00>(even),
                    _mm256_permute4x64_pd::<0b11_01_10_00>(odd),
                );
                _mm256_storeu_ps(a.as_mut_ptr().add(h), _mm256_castpd_ps(even));
                _mm256_storeu_ps(b.as_mut_ptr().add(h), _mm256_castpd_ps(odd));
            }
        }
        (a, b)
    }
}

#[cfg(test)]
mod tests {
    use super::{Gather, Loads};

    /// `g` reads what indexing reads: in-range indices, indices past the end (clamped), 2³¹
    /// and above (the gathers' sign), and tables of `lens` elements; `clamps_pairs`: a pair
    /// starts at most at `len − 2`.
    fn reads_what_indexing_reads<G: Gather>(g: G, name: &str, lens: &[usize], clamps_pairs: bool) {
        let mut state = 0x9e37_79b9_u32;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state
        };
        let table: [f32; 1000] = core::array::from_fn(|k| k as f32 * 0.5 - 3.0);
        for &len in lens {
            let t = &table[..len];
            for round in 0..64 {
                let i: [u32; 16] = core::array::from_fn(|l| match (round + l) % 5 {
                    0 => next(),
                    1 => u32::MAX - (next() % 4),
                    2 => (1 << 31) + next() % 4,
                    _ => next() % (len as u32 + 3),
                });
                let read = g.read(t, &i);
                let (a, b) = g.read_pair(t, &i);
                for l in 0..16 {
                    let at = |k: u32| {
                        if len == 0 {
                            0.0
                        } else {
                            t[(k as usize).min(len - 1)]
                        }
                    };
                    assert_eq!(
                        read[l].to_bits(),
                        at(i[l]).to_bits(),
                        "{name} read {len} {i:?}"
                    );
                    // Gathers clamp a pair's start to len − 2; loads read i and i + 1.
                    let (wa, wb) = if clamps_pairs && len >= 2 {
                        let j = (i[l] as usize).min(len - 2);
                        (t[j], t[j + 1])
                    } else {
                        (at(i[l]), at(i[l].saturating_add(1)))
                    };
                    assert_eq!(
                        (a[l].to_bits(), b[l].to_bits()),
                        (wa.to_bits(), wb.to_bits()),
                        "{name} read_pair {len} lane {l} of {i:?}"
                    );
                }
            }
        }
    }

    /// Every gathering instruction set this CPU has, and the loads, read what indexing
    /// reads (the loads need a non-empty table).
    #[test]
    fn gathers_read_what_indexing_reads() {
        let lens = [0usize, 1, 2, 3, 5, 16, 37, 1000];
        reads_what_indexing_reads(Loads, "loads", &lens[1..], false);
        #[cfg(target_arch = "x86_64")]
        {
            if let Some(v4) = pulp::x86::V4::try_new() {
                reads_what_indexing_reads(super::Avx512(v4), "avx512", &lens, true);
            }
            if let Some(v3) = pulp::x86::V3::try_new() {
                reads_what_indexing_reads(super::Avx2(v3), "avx2", &lens, true);
            }
        }
    }
}
