//! # neusample-python — the `neusample` Python module
//!
//! pyo3 + rust-numpy bindings of the neusample runtime, built by maturin
//! (`pip install bindings/python`). Every batched call takes float32 numpy arrays of shape
//! `(k, N)` (`arrays`), releases the GIL while it runs, and can split the work over rayon
//! threads (`threads=`). The Python side (`python/neusample/`) adds the Mitsuba 3 plugin and
//! the type stubs.
//!
//! Classes: `Blob` (a validated blob and its header), `Sampler` (any kind, or cosine),
//! `NeuralMaterial` (feature texture + decoder), `MeasuredMaterial` (an RGL measured BRDF
//! and the data's own sampler, `measured`); functions: `inspect`, and with the
//! `train` feature the training entry points (`train`).

use std::path::PathBuf;

use neusample::wavefront::{
    BatchSampler, Features, FeaturesMut, RgbMut, SamplesMut, Vec2s, Vec3s, Vec3sMut,
};
use neusample::{
    Prepared, Sampler as _, SamplerKind, TensorRole, Vec2, Vec3, Weights, FEATURE_DIM,
};
use neusample_owned::{OwnedBlob, OwnedMaterial, OwnedMeasuredBlob, OwnedSampler};
use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};

mod arrays;
mod errors;
mod measured;
#[cfg(feature = "train")]
mod train;

use arrays::{output, output1, plan, rows_mut, run, same_n, split, split_mut, Rows};
use errors::{batch_error, blob_error, open_error, BlobError, MeasuredFileError};

fn path_str(p: &std::path::Path) -> String {
    p.to_string_lossy().into_owned()
}

fn open_blob(py: Python<'_>, path: &std::path::Path) -> PyResult<OwnedBlob> {
    let bytes_path = path.to_path_buf();
    py.detach(move || OwnedBlob::open(&bytes_path))
        .map_err(|e| open_error(py, e, &path_str(path)))
}

/// A validated neusample blob (a sampler of any kind, a neural or a measured material), owning a
/// copy of its bytes. Opening checks everything once (checksum, header, every tensor); a bad
/// file raises `BlobError` (with `kind`), a missing one `FileNotFoundError`.
#[pyclass(frozen, module = "neusample")]
struct Blob {
    inner: OwnedBlob,
    path: Option<String>,
}

#[pymethods]
impl Blob {
    /// Opens the blob file at `path`.
    #[new]
    fn new(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        Ok(Blob {
            inner: open_blob(py, &path)?,
            path: Some(path_str(&path)),
        })
    }

    /// A blob from bytes in memory (copied).
    #[staticmethod]
    fn from_bytes(py: Python<'_>, data: &Bound<'_, PyBytes>) -> PyResult<Self> {
        let inner = OwnedBlob::from_bytes(data.as_bytes()).map_err(|e| blob_error(py, &e, None))?;
        Ok(Blob { inner, path: None })
    }

    /// What the blob holds: `"flow"`, `"histogram-mixture"`, …, or `"neural-material"`.
    #[getter]
    fn kind(&self) -> &'static str {
        self.inner.kind().name()
    }

    /// The file it was read from (None for `from_bytes`).
    #[getter]
    fn path(&self) -> Option<String> {
        self.path.clone()
    }

    /// The header as a dict (see `inspect`).
    #[getter]
    fn header<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        header_dict(py, &self.inner)
    }

    /// The sampler it holds (`BlobError` with kind `"not_a_sampler"` for a material).
    fn sampler(&self, py: Python<'_>) -> PyResult<Sampler> {
        OwnedSampler::new(&self.inner)
            .map(|inner| Sampler { inner })
            .map_err(|e| blob_error(py, &e, self.path.as_deref()))
    }

    /// The neural material it holds (`BlobError` with kind `"wrong_kind"` for a sampler).
    fn neural_material(&self, py: Python<'_>) -> PyResult<NeuralMaterial> {
        OwnedMaterial::new(&self.inner)
            .map(|inner| NeuralMaterial { inner })
            .map_err(|e| blob_error(py, &e, self.path.as_deref()))
    }

    /// The measured material it holds (`BlobError` with kind `"wrong_kind"` for any other
    /// kind).
    fn measured(&self, py: Python<'_>) -> PyResult<measured::MeasuredMaterial> {
        OwnedMeasuredBlob::new(&self.inner)
            .map(|m| measured::MeasuredMaterial::of_blob(m, self.path.clone()))
            .map_err(|e| blob_error(py, &e, self.path.as_deref()))
    }

    /// The values of the tensor with role `role` (`"params"`, `"mass"`, `"table"`,
    /// `"marginal"`, `"conditional"`, `"features"`, `"shape"` or `"tables"`) as a float32 array, exactly as the
    /// runtime reads them (f16 widened, u16 CDF integers as floats); None when the blob has
    /// no such tensor. `ValueError` for an unknown role.
    fn tensor<'py>(
        &self,
        py: Python<'py>,
        role: &str,
    ) -> PyResult<Option<Bound<'py, PyArray1<f32>>>> {
        let role = TensorRole::ALL
            .into_iter()
            .find(|r| r.name() == role)
            .ok_or_else(|| {
                pyo3::exceptions::PyValueError::new_err(format!("unknown tensor role {role:?}"))
            })?;
        let Some(t) = self.inner.blob().tensor(role) else {
            return Ok(None);
        };
        let values: Vec<f32> = (0..t.len()).map(|i| t.at(i)).collect();
        Ok(Some(PyArray1::from_vec(py, values)))
    }

    fn __len__(&self) -> usize {
        self.inner.bytes().len()
    }

    fn __repr__(&self) -> String {
        format!(
            "neusample.Blob(kind={:?}, bytes={}, path={:?})",
            self.kind(),
            self.inner.bytes().len(),
            self.path
        )
    }
}

fn header_dict<'py>(py: Python<'py>, blob: &OwnedBlob) -> PyResult<Bound<'py, PyDict>> {
    let h = blob.blob().header();
    let d = PyDict::new(py);
    d.set_item("kind", h.kind.name())?;
    d.set_item("dtype", h.dtype.name())?;
    d.set_item("feature_dim", h.feature_dim)?;
    d.set_item("param_count", h.param_count)?;
    d.set_item("basis", h.basis)?;
    d.set_item("t_levels", h.t_levels)?;
    d.set_item("resolution", h.resolution)?;
    d.set_item(
        "interpolation",
        match h.interpolation {
            neusample::Interpolation::Nearest => "nearest",
            neusample::Interpolation::Linear => "linear",
        },
    )?;
    d.set_item("label", h.label)?;
    d.set_item("format_version", blob.blob().version())?;
    d.set_item("defensive", blob.blob().defensive())?;
    d.set_item("isotropic", blob.blob().isotropic())?;
    d.set_item("tensor_count", h.tensor_count)?;
    Ok(d)
}

/// The header and every tensor of the blob at `path`, as `neusample inspect --json` prints
/// them: `file`, `bytes`, `format_version`, the header fields, `checksum` ("ok": a corrupted
/// blob raises instead) and `tensors` (a list of dicts: `role`, `dtype`, `offset`, `count`,
/// `min`, `max`, `mean`).
#[pyfunction]
fn inspect<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let blob = open_blob(py, &path)?;
    let d = header_dict(py, &blob)?;
    d.set_item("file", path_str(&path))?;
    d.set_item("bytes", blob.bytes().len())?;
    d.set_item("checksum", "ok")?;
    let tensors = PyList::empty(py);
    for role in TensorRole::ALL {
        let (Some(e), Some(t)) = (blob.blob().entry(role), blob.blob().tensor(role)) else {
            continue;
        };
        let (mut lo, mut hi, mut sum) = (f32::INFINITY, f32::NEG_INFINITY, 0.0f64);
        for i in 0..t.len() {
            let v = t.at(i);
            lo = lo.min(v);
            hi = hi.max(v);
            sum += f64::from(v);
        }
        let td = PyDict::new(py);
        td.set_item("role", role.name())?;
        td.set_item("dtype", e.dtype.name())?;
        td.set_item("offset", e.offset)?;
        td.set_item("count", e.count)?;
        td.set_item("min", if e.count > 0 { lo } else { 0.0 })?;
        td.set_item("max", if e.count > 0 { hi } else { 0.0 })?;
        td.set_item(
            "mean",
            if e.count > 0 {
                sum / f64::from(e.count)
            } else {
                0.0
            },
        )?;
        tensors.append(td)?;
    }
    d.set_item("tensors", tensors)?;
    Ok(d)
}

/// A learned sampler of outgoing directions (any kind), or the cosine sampler.
///
/// `Sampler(path)` opens a sampler blob; `Sampler()` or `Sampler.cosine()` is
/// cosine-hemisphere sampling. Directions are in the local shading frame (z = normal, both
/// pointing away from the surface); pdfs are densities with respect to **solid angle**.
#[pyclass(frozen, module = "neusample")]
struct Sampler {
    inner: OwnedSampler,
}

#[pymethods]
impl Sampler {
    #[new]
    #[pyo3(signature = (path = None))]
    fn new(py: Python<'_>, path: Option<PathBuf>) -> PyResult<Self> {
        match path {
            None => Ok(Sampler {
                inner: OwnedSampler::cosine(),
            }),
            Some(p) => {
                let blob = open_blob(py, &p)?;
                OwnedSampler::new(&blob)
                    .map(|inner| Sampler { inner })
                    .map_err(|e| blob_error(py, &e, Some(&path_str(&p))))
            }
        }
    }

    /// The cosine-hemisphere sampler (no blob).
    #[staticmethod]
    fn cosine() -> Self {
        Sampler {
            inner: OwnedSampler::cosine(),
        }
    }

    /// The sampler's kind (`"cosine"`, `"flow"`, …).
    #[getter]
    fn kind(&self) -> &'static str {
        self.inner.kind().name()
    }

    /// The defensive weight α: the sampler draws from `(1 − α)·p_learned + α·cos θ/π` and
    /// reports that density (0: the learned sampler alone).
    #[getter]
    fn alpha(&self) -> f32 {
        self.inner.get().alpha()
    }

    /// Prepares the sampler for each lane's `(phi, wi)` and draws one direction from `u`.
    ///
    /// `phi`: (8, N), `wi`: (3, N), `u`: (2, N) float32 in [0, 1). Returns
    /// `(wo, pdf, mis_pdf)`: (3, N) directions, (N,) solid-angle densities they were drawn
    /// with (divide `f·cos` by them) and (N,) solid-angle densities MIS weighs them with
    /// (`pdf(wo)`; equal to `pdf` for every kind but `"reparam"`, whose samples carry the
    /// density of its warp). A refused lane (`wi` below the horizon, NaN input, sample
    /// outside the support) is all zeros.
    #[pyo3(signature = (phi, wi, u, *, threads = 1))]
    fn sample<'py>(
        &self,
        py: Python<'py>,
        phi: &Bound<'py, PyAny>,
        wi: &Bound<'py, PyAny>,
        u: &Bound<'py, PyAny>,
        threads: usize,
    ) -> PyResult<SampleArrays<'py>> {
        let phi = Rows::<FEATURE_DIM>::new(phi, "phi")?;
        let wi = Rows::<3>::new(wi, "wi")?;
        let u = Rows::<2>::new(u, "u")?;
        let n = same_n(&[("phi", phi.n()), ("wi", wi.n()), ("u", u.n())])?;
        let wo_arr = output(py, 3, n);
        let pdf_arr = output1(py, n);
        let mis_arr = output1(py, n);
        {
            let mut wo_rw = wo_arr.readwrite();
            let mut pdf_rw = pdf_arr.readwrite();
            let mut mis_rw = mis_arr.readwrite();
            let wo_flat = wo_rw
                .as_slice_mut()
                .map_err(|e| batch_error_s(e.to_string()))?;
            let pdf_flat = pdf_rw
                .as_slice_mut()
                .map_err(|e| batch_error_s(e.to_string()))?;
            let mis_flat = mis_rw
                .as_slice_mut()
                .map_err(|e| batch_error_s(e.to_string()))?;
            let (phi, wi, u) = (phi.rows()?, wi.rows()?, u.rows()?);
            let sampler = self.inner.get();
            let (len, parallel) = plan(n, threads);
            let jobs: Vec<_> = split(phi, len)
                .into_iter()
                .zip(split(wi, len))
                .zip(split(u, len))
                .zip(split_mut(rows_mut::<3>(wo_flat, n), len))
                .zip(split_mut([pdf_flat, mis_flat], len))
                .collect();
            py.detach(|| {
                run(
                    jobs,
                    parallel,
                    |((((phi, wi), u), [x, y, z]), [pdf, mis_pdf])| {
                        let out = SamplesMut {
                            wo: Vec3sMut { x, y, z },
                            pdf,
                            mis_pdf,
                        };
                        sampler.sample_fused(
                            Features { channels: phi },
                            Vec3s {
                                x: wi[0],
                                y: wi[1],
                                z: wi[2],
                            },
                            Vec2s { x: u[0], y: u[1] },
                            out,
                        )
                    },
                )
            })
            .map_err(batch_error)?;
        }
        Ok((wo_arr, pdf_arr, mis_arr))
    }

    /// The solid-angle density with which `sample` draws `wo` at each lane's `(phi, wi)`.
    ///
    /// `phi`: (8, N), `wi`, `wo`: (3, N) float32. Returns (N,) float32; 0 for `wo` below the
    /// horizon and for refused lanes.
    #[pyo3(signature = (phi, wi, wo, *, threads = 1))]
    fn pdf<'py>(
        &self,
        py: Python<'py>,
        phi: &Bound<'py, PyAny>,
        wi: &Bound<'py, PyAny>,
        wo: &Bound<'py, PyAny>,
        threads: usize,
    ) -> PyResult<Bound<'py, PyArray1<f32>>> {
        let phi = Rows::<FEATURE_DIM>::new(phi, "phi")?;
        let wi = Rows::<3>::new(wi, "wi")?;
        let wo = Rows::<3>::new(wo, "wo")?;
        let n = same_n(&[("phi", phi.n()), ("wi", wi.n()), ("wo", wo.n())])?;
        let pdf_arr = output1(py, n);
        {
            let mut pdf_rw = pdf_arr.readwrite();
            let pdf_flat = pdf_rw
                .as_slice_mut()
                .map_err(|e| batch_error_s(e.to_string()))?;
            let (phi, wi, wo) = (phi.rows()?, wi.rows()?, wo.rows()?);
            let sampler = self.inner.get();
            let (len, parallel) = plan(n, threads);
            let jobs: Vec<_> = split(phi, len)
                .into_iter()
                .zip(split(wi, len))
                .zip(split(wo, len))
                .zip(split_mut([pdf_flat], len))
                .collect();
            py.detach(|| {
                run(jobs, parallel, |(((phi, wi), wo), [pdf])| {
                    sampler.pdf_fused(
                        Features { channels: phi },
                        Vec3s {
                            x: wi[0],
                            y: wi[1],
                            z: wi[2],
                        },
                        Vec3s {
                            x: wo[0],
                            y: wo[1],
                            z: wo[2],
                        },
                        pdf,
                    )
                })
            })
            .map_err(batch_error)?;
        }
        Ok(pdf_arr)
    }

    /// `sample` through the scalar API, one lane at a time (`prepare`, then `sample`): the
    /// reference that the batched and the Dr.Jit paths are compared with. Same arguments
    /// and results as `sample` (no `threads`).
    fn sample_scalar<'py>(
        &self,
        py: Python<'py>,
        phi: &Bound<'py, PyAny>,
        wi: &Bound<'py, PyAny>,
        u: &Bound<'py, PyAny>,
    ) -> PyResult<SampleArrays<'py>> {
        let phi = Rows::<FEATURE_DIM>::new(phi, "phi")?;
        let wi = Rows::<3>::new(wi, "wi")?;
        let u = Rows::<2>::new(u, "u")?;
        let n = same_n(&[("phi", phi.n()), ("wi", wi.n()), ("u", u.n())])?;
        let (phi, wi, u) = (phi.rows()?, wi.rows()?, u.rows()?);
        let sampler = self.inner.get();
        let mut wo = vec![0.0f32; 3 * n];
        let mut pdf = vec![0.0f32; n];
        let mut mis = vec![0.0f32; n];
        for i in 0..n {
            let s = sampler
                .prepare(&lane_phi(&phi, i), Vec3::new(wi[0][i], wi[1][i], wi[2][i]))
                .and_then(|p| p.sample(Vec2::new(u[0][i], u[1][i])));
            if let Some(s) = s {
                (wo[i], wo[n + i], wo[2 * n + i]) = (s.wo.x, s.wo.y, s.wo.z);
                (pdf[i], mis[i]) = (s.pdf, s.mis_pdf);
            }
        }
        Ok((
            PyArray1::from_vec(py, wo).reshape([3, n])?,
            PyArray1::from_vec(py, pdf),
            PyArray1::from_vec(py, mis),
        ))
    }

    /// `pdf` through the scalar API, one lane at a time (the reference; see
    /// `sample_scalar`).
    fn pdf_scalar<'py>(
        &self,
        py: Python<'py>,
        phi: &Bound<'py, PyAny>,
        wi: &Bound<'py, PyAny>,
        wo: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray1<f32>>> {
        let phi = Rows::<FEATURE_DIM>::new(phi, "phi")?;
        let wi = Rows::<3>::new(wi, "wi")?;
        let wo = Rows::<3>::new(wo, "wo")?;
        let n = same_n(&[("phi", phi.n()), ("wi", wi.n()), ("wo", wo.n())])?;
        let (phi, wi, wo) = (phi.rows()?, wi.rows()?, wo.rows()?);
        let sampler = self.inner.get();
        let pdf: Vec<f32> = (0..n)
            .map(|i| {
                sampler
                    .prepare(&lane_phi(&phi, i), Vec3::new(wi[0][i], wi[1][i], wi[2][i]))
                    .map_or(0.0, |p| p.pdf(Vec3::new(wo[0][i], wo[1][i], wo[2][i])))
            })
            .collect();
        Ok(PyArray1::from_vec(py, pdf))
    }

    fn __repr__(&self) -> String {
        format!("neusample.Sampler(kind={:?})", self.kind())
    }
}

/// `(wo, pdf)` of [`Sampler::sample`].
type SampleArrays<'py> = (
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray1<f32>>,
    Bound<'py, PyArray1<f32>>,
);

/// Lane `i` of a `(8, N)` feature array.
fn lane_phi(phi: &[&[f32]; FEATURE_DIM], i: usize) -> [f32; FEATURE_DIM] {
    core::array::from_fn(|c| phi[c][i])
}

fn batch_error_s(msg: String) -> PyErr {
    pyo3::exceptions::PyValueError::new_err(msg)
}

/// A NeuMIP-style neural material: a feature texture φ(uv) and a decoder MLP giving the
/// RGB BRDF `f(φ, wi, wo)` (without the cosine). `NeuralMaterial(path)` opens a
/// neural-material blob.
#[pyclass(frozen, module = "neusample")]
struct NeuralMaterial {
    inner: OwnedMaterial,
}

#[pymethods]
impl NeuralMaterial {
    #[new]
    fn new(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let blob = open_blob(py, &path)?;
        OwnedMaterial::new(&blob)
            .map(|inner| NeuralMaterial { inner })
            .map_err(|e| blob_error(py, &e, Some(&path_str(&path))))
    }

    /// Texture width (texels along u).
    #[getter]
    fn width(&self) -> u32 {
        self.inner.get().width()
    }

    /// Texture height (texels along v).
    #[getter]
    fn height(&self) -> u32 {
        self.inner.get().height()
    }

    /// φ(uv): bilinear lookup of the (wrapping) feature texture. `uv`: (2, N) float32;
    /// returns (8, N) float32. Non-finite coordinates read as 0.
    #[pyo3(signature = (uv, *, threads = 1))]
    fn features<'py>(
        &self,
        py: Python<'py>,
        uv: &Bound<'py, PyAny>,
        threads: usize,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let uv = Rows::<2>::new(uv, "uv")?;
        let n = uv.n();
        let phi_arr = output(py, FEATURE_DIM, n);
        {
            let mut rw = phi_arr.readwrite();
            let flat = rw
                .as_slice_mut()
                .map_err(|e| batch_error_s(e.to_string()))?;
            let uv = uv.rows()?;
            let m = self.inner.get();
            let (len, parallel) = plan(n, threads);
            let jobs: Vec<_> = split(uv, len)
                .into_iter()
                .zip(split_mut(rows_mut::<FEATURE_DIM>(flat, n), len))
                .collect();
            py.detach(|| {
                run(jobs, parallel, |(uv, channels)| {
                    m.features_batch(Vec2s { x: uv[0], y: uv[1] }, FeaturesMut { channels })
                })
            })
            .map_err(batch_error)?;
        }
        Ok(phi_arr)
    }

    /// The BRDF `f(phi, wi, wo)` in linear RGB, **without** the cosine. `phi`: (8, N),
    /// `wi`, `wo`: (3, N) float32; returns (3, N) float32 (rows r, g, b). 0 where either
    /// direction is at or below the horizon or an input is not finite.
    #[pyo3(signature = (phi, wi, wo, *, threads = 1))]
    fn eval<'py>(
        &self,
        py: Python<'py>,
        phi: &Bound<'py, PyAny>,
        wi: &Bound<'py, PyAny>,
        wo: &Bound<'py, PyAny>,
        threads: usize,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let phi = Rows::<FEATURE_DIM>::new(phi, "phi")?;
        let wi = Rows::<3>::new(wi, "wi")?;
        let wo = Rows::<3>::new(wo, "wo")?;
        let n = same_n(&[("phi", phi.n()), ("wi", wi.n()), ("wo", wo.n())])?;
        let f_arr = output(py, 3, n);
        {
            let mut rw = f_arr.readwrite();
            let flat = rw
                .as_slice_mut()
                .map_err(|e| batch_error_s(e.to_string()))?;
            let (phi, wi, wo) = (phi.rows()?, wi.rows()?, wo.rows()?);
            let m = self.inner.get();
            let (len, parallel) = plan(n, threads);
            let jobs: Vec<_> = split(phi, len)
                .into_iter()
                .zip(split(wi, len))
                .zip(split(wo, len))
                .zip(split_mut(rows_mut::<3>(flat, n), len))
                .collect();
            py.detach(|| {
                run(jobs, parallel, |(((phi, wi), wo), [r, g, b])| {
                    m.eval_batch(
                        Features { channels: phi },
                        Vec3s {
                            x: wi[0],
                            y: wi[1],
                            z: wi[2],
                        },
                        Vec3s {
                            x: wo[0],
                            y: wo[1],
                            z: wo[2],
                        },
                        RgbMut { r, g, b },
                    )
                })
            })
            .map_err(batch_error)?;
        }
        Ok(f_arr)
    }

    /// `features` through the scalar API, one lane at a time (the reference).
    fn features_scalar<'py>(
        &self,
        py: Python<'py>,
        uv: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let uv = Rows::<2>::new(uv, "uv")?;
        let n = uv.n();
        let uv = uv.rows()?;
        let m = self.inner.get();
        let mut out = vec![0.0f32; FEATURE_DIM * n];
        for i in 0..n {
            let f = m.features(Vec2::new(uv[0][i], uv[1][i]));
            for (c, v) in f.iter().enumerate() {
                out[c * n + i] = *v;
            }
        }
        PyArray1::from_vec(py, out).reshape([FEATURE_DIM, n])
    }

    /// `eval` through the scalar API, one lane at a time (the reference).
    fn eval_scalar<'py>(
        &self,
        py: Python<'py>,
        phi: &Bound<'py, PyAny>,
        wi: &Bound<'py, PyAny>,
        wo: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let phi = Rows::<FEATURE_DIM>::new(phi, "phi")?;
        let wi = Rows::<3>::new(wi, "wi")?;
        let wo = Rows::<3>::new(wo, "wo")?;
        let n = same_n(&[("phi", phi.n()), ("wi", wi.n()), ("wo", wo.n())])?;
        let (phi, wi, wo) = (phi.rows()?, wi.rows()?, wo.rows()?);
        let m = self.inner.get();
        let mut out = vec![0.0f32; 3 * n];
        for i in 0..n {
            let f = m.eval(
                &lane_phi(&phi, i),
                Vec3::new(wi[0][i], wi[1][i], wi[2][i]),
                Vec3::new(wo[0][i], wo[1][i], wo[2][i]),
            );
            for (c, v) in f.iter().enumerate() {
                out[c * n + i] = *v;
            }
        }
        PyArray1::from_vec(py, out).reshape([3, n])
    }

    fn __repr__(&self) -> String {
        format!(
            "neusample.NeuralMaterial(width={}, height={})",
            self.width(),
            self.height()
        )
    }
}

/// The `neusample` extension module (`neusample._neusample`; import `neusample`).
#[pymodule]
fn _neusample(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add_class::<Blob>()?;
    m.add_class::<Sampler>()?;
    m.add_class::<NeuralMaterial>()?;
    m.add_class::<measured::MeasuredMaterial>()?;
    m.add_function(wrap_pyfunction!(inspect, m)?)?;
    m.add("BlobError", py.get_type::<BlobError>())?;
    m.add("MeasuredFileError", py.get_type::<MeasuredFileError>())?;
    m.add("FEATURE_DIM", FEATURE_DIM)?;
    m.add(
        "SAMPLER_KINDS",
        SamplerKind::ALL
            .iter()
            .map(|k| k.name())
            .collect::<Vec<_>>(),
    )?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    #[cfg(feature = "train")]
    train::register(m)?;
    Ok(())
}
