//! numpy arguments: the checks every batched call makes (type, dtype, shape, contiguity,
//! one `N` for all arguments), the output arrays, and the split of a call into chunks for
//! `threads > 1`.
//!
//! Arrays are `(k, N)` float32, C-contiguous: row `c` holds component `c` of every lane
//! (structure of arrays: what `neusample::wavefront` takes and what Dr.Jit's
//! `Vector3f.numpy()` gives). An `(N, k)` array `a` is passed as `np.ascontiguousarray(a.T)`.

use numpy::{
    dtype, PyArray1, PyArray2, PyArrayDescrMethods, PyArrayMethods, PyReadonlyArray2,
    PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use rayon::prelude::*;

/// A checked `(K, N)` float32 input: its rows.
pub(crate) struct Rows<'py, const K: usize> {
    array: PyReadonlyArray2<'py, f32>,
}

impl<'py, const K: usize> Rows<'py, K> {
    /// Checks `obj` as the argument `name` with `K` rows.
    pub(crate) fn new(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<Self> {
        let py = obj.py();
        let untyped = obj.cast::<PyUntypedArray>().map_err(|_| {
            let ty = obj
                .get_type()
                .name()
                .map(|n| n.to_string())
                .unwrap_or_default();
            PyTypeError::new_err(format!(
                "`{name}` must be a numpy.ndarray of float32 with shape ({K}, N), got {ty}"
            ))
        })?;
        if !untyped.dtype().is_equiv_to(&dtype::<f32>(py)) {
            return Err(PyTypeError::new_err(format!(
                "`{name}` must have dtype float32, got {} (convert with .astype(np.float32))",
                untyped.dtype()
            )));
        }
        let shape = untyped.shape();
        if shape.len() != 2 || shape[0] != K {
            return Err(PyValueError::new_err(format!(
                "`{name}` must have shape ({K}, N), got {shape:?} \
                 (an (N, {K}) array `a` is passed as np.ascontiguousarray(a.T))"
            )));
        }
        let typed = untyped
            .cast::<PyArray2<f32>>()
            .map_err(|e| PyTypeError::new_err(format!("`{name}`: {e}")))?;
        let array = typed
            .try_readonly()
            .map_err(|e| PyValueError::new_err(format!("`{name}`: {e}")))?;
        if !array.is_c_contiguous() {
            return Err(PyValueError::new_err(format!(
                "`{name}` must be C-contiguous (use np.ascontiguousarray)"
            )));
        }
        Ok(Rows { array })
    }

    /// N.
    pub(crate) fn n(&self) -> usize {
        self.array.shape()[1]
    }

    /// The rows as slices.
    pub(crate) fn rows(&self) -> PyResult<[&[f32]; K]> {
        let flat = self
            .array
            .as_slice()
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        let n = self.n();
        Ok(core::array::from_fn(|k| &flat[k * n..(k + 1) * n]))
    }
}

/// `N` of the first argument, checked against the others.
pub(crate) fn same_n(args: &[(&str, usize)]) -> PyResult<usize> {
    let (first, n) = args[0];
    for (name, m) in &args[1..] {
        if *m != n {
            return Err(PyValueError::new_err(format!(
                "`{name}` has N = {m} lanes, `{first}` has N = {n}"
            )));
        }
    }
    Ok(n)
}

/// A new `(K, N)` float32 output, zeroed.
pub(crate) fn output<'py>(py: Python<'py>, k: usize, n: usize) -> Bound<'py, PyArray2<f32>> {
    PyArray2::zeros(py, [k, n], false)
}

/// A new `(N,)` float32 output, zeroed.
pub(crate) fn output1<'py>(py: Python<'py>, n: usize) -> Bound<'py, PyArray1<f32>> {
    PyArray1::zeros(py, [n], false)
}

/// The rows of a `(K, N)` output, mutably.
pub(crate) fn rows_mut<const K: usize>(flat: &mut [f32], n: usize) -> [&mut [f32]; K] {
    let mut it = flat.chunks_mut(n.max(1));
    core::array::from_fn(|_| {
        if n == 0 {
            &mut [][..]
        } else {
            it.next().unwrap_or(&mut [])
        }
    })
}

/// Lanes per chunk for `threads` workers (at least 256 lanes a chunk).
fn chunk_len(n: usize, threads: usize) -> usize {
    n.div_ceil(threads.max(1)).max(256)
}

/// `threads`: 1 runs on the calling thread, 0 uses every thread of rayon's global pool,
/// k > 1 splits the call into k chunks run on that pool.
pub(crate) fn workers(threads: usize) -> usize {
    if threads == 0 {
        rayon::current_num_threads()
    } else {
        threads
    }
}

/// Splits `K` input rows into chunks of `len` lanes.
pub(crate) fn split<const K: usize>(rows: [&[f32]; K], len: usize) -> Vec<[&[f32]; K]> {
    let n = rows[0].len();
    (0..n.div_ceil(len))
        .map(|c| {
            let (a, b) = (c * len, ((c + 1) * len).min(n));
            core::array::from_fn(|k| &rows[k][a..b])
        })
        .collect()
}

/// Splits `K` output rows into chunks of `len` lanes.
pub(crate) fn split_mut<'a, const K: usize>(
    rows: [&'a mut [f32]; K],
    len: usize,
) -> Vec<[&'a mut [f32]; K]> {
    let mut iters = rows.map(|r| r.chunks_mut(len));
    let mut out = Vec::new();
    loop {
        let next: [Option<&'a mut [f32]>; K] = core::array::from_fn(|k| iters[k].next());
        if next.iter().any(|x| x.is_none()) {
            break;
        }
        out.push(next.map(|x| x.unwrap_or(&mut [])));
    }
    out
}

/// Runs `f(a, b)`-shaped work over chunks: on this thread when `threads == 1` or the call
/// is small, else on rayon's pool. `jobs` are the per-chunk arguments.
pub(crate) fn run<J: Send>(
    jobs: Vec<J>,
    parallel: bool,
    f: impl Fn(J) -> Result<(), neusample::Error> + Sync + Send,
) -> Result<(), neusample::Error> {
    if parallel {
        jobs.into_par_iter().try_for_each(f)
    } else {
        jobs.into_iter().try_for_each(f)
    }
}

/// The chunk length of a call of `n` lanes with `threads` (see [`workers`]): `n` (one
/// chunk) when running on this thread.
pub(crate) fn plan(n: usize, threads: usize) -> (usize, bool) {
    let w = workers(threads);
    if w <= 1 || n <= 256 {
        (n.max(1), false)
    } else {
        (chunk_len(n, w), true)
    }
}
