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

/// [`dispatch`] without x86's baseline copy: on x86, `k` runs only with AVX2 or AVX-512 and
/// comes back as `Err(k)`, not run, on a CPU without them or when [`Isa::Portable`] is
/// chosen, so that the kernel is never compiled for SSE2 (its caller has a scalar path for
/// those machines). Elsewhere (aarch64, wasm) it runs as compiled for the target.
#[inline(always)]
pub(crate) fn dispatch_wide<K: Kernel>(k: K) -> Result<K::Output, K> {
    #[cfg(any(target_arch = "x86", target_arch = "x86_64"))]
    return x86_wide(k);
    #[cfg(not(any(target_arch = "x86", target_arch = "x86_64")))]
    Ok(k.run())
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

/// Proof that the batched kernels run with AVX2 or AVX-512 now ([`current`] is
/// [`Isa::X86V3`] or [`Isa::X86V4`] and the CPU has it), so that a table read of sixteen
/// lanes is gather instructions: one with AVX-512, two of eight lanes with AVX2. LLVM does
/// not form gathers on its own here: rustc compiles for the generic x86-64 CPU, whose cost
/// model prices them high, and the reads stay scalar loads and inserts.
#[derive(Copy, Clone)]
pub(crate) struct Gather16 {
    #[cfg(target_arch = "x86_64")]
    isa: GatherIsa,
}

/// The instruction set a [`Gather16`] proves.
#[cfg(target_arch = "x86_64")]
#[derive(Copy, Clone)]
enum GatherIsa {
    V3(pulp::x86::V3),
    V4(pulp::x86::V4),
}

impl Gather16 {
    /// The proof, where AVX2 or AVX-512 is in use; `None` elsewhere (the portable path,
    /// other architectures).
    #[inline]
    pub(crate) fn new() -> Option<Self> {
        Self::for_isa(current())
    }

    /// The proof for `isa`, where it is AVX2 or AVX-512 and the CPU has it.
    #[inline]
    fn for_isa(isa: Isa) -> Option<Self> {
        #[cfg(target_arch = "x86_64")]
        match isa {
            Isa::X86V4 => {
                return pulp::x86::V4::try_new().map(|v4| Gather16 {
                    isa: GatherIsa::V4(v4),
                })
            }
            Isa::X86V3 => {
                return pulp::x86::V3::try_new().map(|v3| Gather16 {
                    isa: GatherIsa::V3(v3),
                })
            }
            _ => {}
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = isa;
        None
    }

    /// `t[min(i[l], t.len() − 1)]` on each of sixteen lanes (zeros for an empty `t`): a
    /// branch-free read of a table whose indices are in range.
    #[inline(always)]
    #[allow(unsafe_code)]
    pub(crate) fn read(self, t: &[f32], i: &[u32; 16]) -> [f32; 16] {
        let mut out = [0.0f32; 16];
        if t.is_empty() {
            return out;
        }
        #[cfg(target_arch = "x86_64")]
        {
            use core::arch::x86_64::{
                _mm256_i32gather_ps, _mm256_loadu_si256, _mm256_min_epu32, _mm256_set1_epi32,
                _mm256_storeu_ps, _mm512_i32gather_ps, _mm512_loadu_si512, _mm512_min_epu32,
                _mm512_set1_epi32, _mm512_storeu_ps,
            };
            // The gathers sign-extend their 32-bit offsets: clamp below 2³¹ too.
            let last = (t.len() - 1).min(i32::MAX as usize) as i32;
            match self.isa {
                // SAFETY: `GatherIsa::V4` exists only where `V4::try_new` succeeded, so the
                // CPU has AVX-512F. The unaligned load and store move exactly the 64 bytes
                // of `i` and `out`. Every offset is clamped to `last`, which is below
                // `t.len()` and 2³¹, so the gather reads elements of `t` only.
                GatherIsa::V4(_) => unsafe {
                    let idx = _mm512_min_epu32(
                        _mm512_loadu_si512(i.as_ptr().cast()),
                        _mm512_set1_epi32(last),
                    );
                    _mm512_storeu_ps(
                        out.as_mut_ptr(),
                        _mm512_i32gather_ps::<4>(idx, t.as_ptr().cast()),
                    );
                },
                // SAFETY: `GatherIsa::V3` exists only where `V3::try_new` succeeded, so the
                // CPU has AVX2. Each half's unaligned load and store move exactly 32 bytes
                // of `i` and `out` (lanes 0..8, then 8..16). Every offset is clamped to
                // `last`, which is below `t.len()` and 2³¹, so the gathers read elements of
                // `t` only.
                GatherIsa::V3(_) => unsafe {
                    let last = _mm256_set1_epi32(last);
                    for h in [0, 8] {
                        let idx =
                            _mm256_min_epu32(_mm256_loadu_si256(i.as_ptr().add(h).cast()), last);
                        _mm256_storeu_ps(
                            out.as_mut_ptr().add(h),
                            _mm256_i32gather_ps::<4>(t.as_ptr().cast(), idx),
                        );
                    }
                },
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        for l in 0..16 {
            out[l] = t[(i[l] as usize).min(t.len() - 1)];
        }
        out
    }

    /// `(t[j], t[j + 1])` with `j = min(i[l], t.len() − 2)` on each of sixteen lanes: two
    /// adjacent elements per lane (a bilinear cell's row, a node interval), read as 64-bit
    /// gathers, which move half the elements of two 32-bit ones. For a `t` of fewer than two
    /// elements, [`Self::read`] of `i` and `i + 1`.
    #[inline(always)]
    #[allow(unsafe_code)]
    pub(crate) fn read_pair(self, t: &[f32], i: &[u32; 16]) -> ([f32; 16], [f32; 16]) {
        if t.len() < 2 {
            let next = core::array::from_fn(|l| i[l].saturating_add(1));
            return (self.read(t, i), self.read(t, &next));
        }
        // A pair starts at most at len − 2; offsets below 2³¹ (gathers sign-extend them).
        let last = (t.len() - 2).min(i32::MAX as usize - 1) as u32;
        let (mut a, mut b) = ([0.0f32; 16], [0.0f32; 16]);
        #[cfg(target_arch = "x86_64")]
        match self.isa {
            // SAFETY: `GatherIsa::V4` exists only where `V4::try_new` succeeded, so the CPU
            // has AVX-512F. The unaligned load and stores move exactly the 64 bytes of `i`,
            // `a` and `b`. Every offset is clamped to `last` ≤ `t.len()` − 2, so each 8-byte
            // read (scale 4: offsets count f32s) covers elements `j` and `j + 1` of `t` only;
            // gathers need no alignment.
            GatherIsa::V4(_) => unsafe {
                use core::arch::x86_64::{
                    _mm512_castsi512_ps, _mm512_castsi512_si256, _mm512_extracti64x4_epi64,
                    _mm512_i32gather_epi64, _mm512_loadu_si512, _mm512_min_epu32,
                    _mm512_permutex2var_ps, _mm512_set1_epi32, _mm512_setr_epi32, _mm512_storeu_ps,
                };
                let base = t.as_ptr().cast::<i64>();
                let idx = _mm512_min_epu32(
                    _mm512_loadu_si512(i.as_ptr().cast()),
                    _mm512_set1_epi32(last as i32),
                );
                // Lanes 0..8 and 8..16 as (a, b) pairs: [a0 b0 a1 b1 … a7 b7], then the
                // even and odd elements of the two picked out.
                let g0 = _mm512_castsi512_ps(_mm512_i32gather_epi64::<4>(
                    _mm512_castsi512_si256(idx),
                    base,
                ));
                let g1 = _mm512_castsi512_ps(_mm512_i32gather_epi64::<4>(
                    _mm512_extracti64x4_epi64::<1>(idx),
                    base,
                ));
                let even =
                    _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30);
                let odd =
                    _mm512_setr_epi32(1, 3, 5, 7, 9, 11, 13, 15, 17, 19, 21, 23, 25, 27, 29, 31);
                _mm512_storeu_ps(a.as_mut_ptr(), _mm512_permutex2var_ps(g0, even, g1));
                _mm512_storeu_ps(b.as_mut_ptr(), _mm512_permutex2var_ps(g0, odd, g1));
            },
            // SAFETY: `GatherIsa::V3` exists only where `V3::try_new` succeeded, so the CPU
            // has AVX2. Each half's unaligned load and stores move exactly 32 bytes of `i`,
            // `a` and `b` (lanes 0..8, then 8..16). Every offset is clamped to `last` ≤
            // `t.len()` − 2, so each 8-byte read (scale 4: offsets count f32s) covers elements
            // `j` and `j + 1` of `t` only; gathers need no alignment.
            GatherIsa::V3(_) => unsafe {
                use core::arch::x86_64::{
                    _mm256_castpd_ps, _mm256_castps_pd, _mm256_castsi256_ps,
                    _mm256_castsi256_si128, _mm256_extracti128_si256, _mm256_i32gather_epi64,
                    _mm256_loadu_si256, _mm256_min_epu32, _mm256_permute4x64_pd, _mm256_set1_epi32,
                    _mm256_shuffle_ps, _mm256_storeu_ps,
                };
                let base = t.as_ptr().cast::<i64>();
                let last = _mm256_set1_epi32(last as i32);
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
            },
        }
        #[cfg(not(target_arch = "x86_64"))]
        for l in 0..16 {
            let j = i[l].min(last) as usize;
            (a[l], b[l]) = (t[j], t[j + 1]);
        }
        (a, b)
    }
}

#[cfg(test)]
mod tests {
    use super::{Gather16, Isa};

    /// Every gathering instruction set this CPU has reads what indexing reads: in-range
    /// indices, indices past the end (clamped), 2³¹ and above (the gathers' sign), and
    /// tables of zero, one and two elements.
    #[test]
    fn gathers_read_what_indexing_reads() {
        let mut state = 0x9e37_79b9_u32;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state
        };
        let table: [f32; 1000] = core::array::from_fn(|k| k as f32 * 0.5 - 3.0);
        for isa in [Isa::X86V3, Isa::X86V4] {
            let Some(g) = Gather16::for_isa(isa) else {
                continue;
            };
            for len in [0usize, 1, 2, 3, 5, 16, 37, 1000] {
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
                        let want = if len == 0 {
                            0.0
                        } else {
                            t[(i[l] as usize).min(len - 1)]
                        };
                        assert_eq!(
                            read[l].to_bits(),
                            want.to_bits(),
                            "{isa:?} read {len} {i:?}"
                        );
                        let (wa, wb) = match len {
                            0 => (0.0, 0.0),
                            1 => (t[0], t[0]),
                            _ => {
                                let j = (i[l] as usize).min(len - 2);
                                (t[j], t[j + 1])
                            }
                        };
                        assert_eq!(
                            (a[l].to_bits(), b[l].to_bits()),
                            (wa.to_bits(), wb.to_bits()),
                            "{isa:?} read_pair {len} lane {l} of {i:?}"
                        );
                    }
                }
            }
        }
    }
}
