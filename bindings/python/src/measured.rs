//! `neusample.MeasuredMaterial`: a measured BRDF of the RGL material database (an RGB or
//! spectral `.bsdf` file, Mitsuba's `measured` format, or a measured blob written from one)
//! with the data's own sampler, batched over numpy arrays like the other classes.
//!
//! The array methods call the runtime's batched calls (`MeasuredMaterial::eval_batch`,
//! `pdf_batch`, `sample_batch`) on chunks of lanes. Each lane is prepared at its `wi` and
//! evaluated, sampled or queried at its `wo` / `u` independently: a lane with a bad input
//! (non-finite, zero-length, at or below the horizon) gives 0 and never disturbs the others.

use std::path::PathBuf;

use neusample::wavefront::{RgbMut, SamplesMut, Vec2s, Vec3s, Vec3sMut};
use neusample::{BlobWriter, Error, MeasuredMaterial as Material, Weights};
use neusample_owned::measured::OwnedMeasured;
use neusample_owned::{measured_label, OwnedMeasuredBlob};
use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyBytes;

use crate::arrays::{output, output1, plan, rows_mut, run, same_n, split, split_mut, Rows};
use crate::errors::{blob_error, measured_error, open_io_error};

/// `(wo, pdf, weight)` of [`MeasuredMaterial::sample`].
type MeasuredSampleArrays<'py> = (
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray1<f32>>,
    Bound<'py, PyArray2<f32>>,
);

/// A measured material from the RGL database (Dupuy & Jakob 2018): an RGB or spectral
/// `.bsdf` file in Mitsuba's `measured` format (spectra are read in linear sRGB: integrated
/// against the CIE 1931 observer under D65, a flat spectrum of 1 being white), or a measured
/// blob (`neusample measured-blob`), evaluated and sampled as Mitsuba 3's `measured` BSDF does
/// (the data's visible-normal sampler, warped through its luminance).
///
/// `MeasuredMaterial(path)` reads and checks the whole `.bsdf` file; a bad file raises
/// `MeasuredFileError` (with `field` and `path`), a missing one `FileNotFoundError`.
/// `MeasuredMaterial.from_blob(path_or_bytes)` opens a blob (bad bytes raise `BlobError`).
/// Directions are in the local shading frame (z = normal, both pointing away from the
/// surface; normalised here); every pdf is a density with respect to **solid angle** of `wo`.
#[pyclass(frozen, module = "neusample")]
pub(crate) struct MeasuredMaterial {
    inner: Source,
    path: Option<String>,
}

/// Where the tables are: read from a `.bsdf` file, or in place in a blob. One per Python
/// object, built once: the size difference between the variants does not matter.
#[allow(clippy::large_enum_variant)]
enum Source {
    File(OwnedMeasured),
    Blob(OwnedMeasuredBlob),
}

/// The batched calls of a material over any table storage, behind one face.
trait Lanes: Sync {
    fn eval(&self, wi: Vec3s<'_>, wo: Vec3s<'_>, out: RgbMut<'_>) -> Result<(), Error>;
    fn pdf(&self, wi: Vec3s<'_>, wo: Vec3s<'_>, pdf: &mut [f32]) -> Result<(), Error>;
    fn sample(
        &self,
        wi: Vec3s<'_>,
        u: Vec2s<'_>,
        out: SamplesMut<'_>,
        weight: RgbMut<'_>,
    ) -> Result<(), Error>;
    fn isotropic(&self) -> bool;
}

impl<W: Weights + Sync> Lanes for Material<W> {
    fn eval(&self, wi: Vec3s<'_>, wo: Vec3s<'_>, out: RgbMut<'_>) -> Result<(), Error> {
        self.eval_batch(wi, wo, out)
    }
    fn pdf(&self, wi: Vec3s<'_>, wo: Vec3s<'_>, pdf: &mut [f32]) -> Result<(), Error> {
        self.pdf_batch(wi, wo, pdf)
    }
    fn sample(
        &self,
        wi: Vec3s<'_>,
        u: Vec2s<'_>,
        out: SamplesMut<'_>,
        weight: RgbMut<'_>,
    ) -> Result<(), Error> {
        self.sample_batch(wi, u, out, weight)
    }
    fn isotropic(&self) -> bool {
        Material::isotropic(self)
    }
}

impl MeasuredMaterial {
    fn material(&self) -> &dyn Lanes {
        match &self.inner {
            Source::File(m) => m.material(),
            Source::Blob(m) => m.get(),
        }
    }

    /// The material of an opened measured blob.
    pub(crate) fn of_blob(inner: OwnedMeasuredBlob, path: Option<String>) -> Self {
        MeasuredMaterial {
            inner: Source::Blob(inner),
            path,
        }
    }
}

fn vec3s<'a>(rows: [&'a [f32]; 3]) -> Vec3s<'a> {
    let [x, y, z] = rows;
    Vec3s { x, y, z }
}

/// The bytes of the file at `path` (read without the GIL) and the path as shown in errors;
/// a missing or unreadable file raises the matching `OSError`.
fn read_file(py: Python<'_>, path: &std::path::Path) -> PyResult<(Vec<u8>, String)> {
    let shown = path.to_string_lossy().into_owned();
    let read = path.to_path_buf();
    let bytes = py
        .detach(move || std::fs::read(&read))
        .map_err(|e| open_io_error(&e, &shown))?;
    Ok((bytes, shown))
}

#[pymethods]
impl MeasuredMaterial {
    /// Reads the measured material at `path` (an RGB or spectral `.bsdf` file).
    #[new]
    fn new(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let (bytes, shown) = read_file(py, &path)?;
        let inner = py
            .detach(|| OwnedMeasured::from_bytes(&bytes))
            .map_err(|mut e| {
                e.file = Some(path.display().to_string());
                measured_error(py, &e, &shown)
            })?;
        Ok(MeasuredMaterial {
            inner: Source::File(inner),
            path: Some(shown),
        })
    }

    /// Opens a measured blob (kind `"measured"`, written by `neusample measured-blob`) from a
    /// file path or from `bytes`. A bad blob raises `BlobError` (kind `"wrong_kind"` for a
    /// blob of another kind), a missing file `FileNotFoundError`.
    #[staticmethod]
    fn from_blob(py: Python<'_>, source: &Bound<'_, PyAny>) -> PyResult<Self> {
        if let Ok(b) = source.cast::<PyBytes>() {
            let inner = OwnedMeasuredBlob::from_bytes(b.as_bytes())
                .map_err(|e| blob_error(py, &e, None))?;
            return Ok(MeasuredMaterial::of_blob(inner, None));
        }
        let path: PathBuf = source.extract()?;
        let (bytes, shown) = read_file(py, &path)?;
        let inner = py
            .detach(|| OwnedMeasuredBlob::from_bytes(&bytes))
            .map_err(|e| blob_error(py, &e, Some(&shown)))?;
        Ok(MeasuredMaterial::of_blob(inner, Some(shown)))
    }

    /// The description of the material: the file's, or for a blob the description in its
    /// label (the whole label when it has none).
    #[getter]
    fn description(&self) -> &str {
        match &self.inner {
            Source::File(m) => m.description(),
            Source::Blob(m) => {
                let l = m.label();
                l.split_once("description: ").map_or(l, |(_, d)| d)
            }
        }
    }

    /// The material as the bytes of a measured blob (what `neusample measured-blob` writes;
    /// `from_blob` opens them). `name` is the label's `name=` field (default: the file's stem);
    /// a blob-opened material returns its blob's bytes unchanged.
    #[pyo3(signature = (*, name = None))]
    fn to_blob<'py>(&self, py: Python<'py>, name: Option<&str>) -> PyResult<Bound<'py, PyBytes>> {
        match &self.inner {
            Source::Blob(m) => Ok(PyBytes::new(py, m.blob().bytes())),
            Source::File(m) => {
                let path = std::path::Path::new(self.path.as_deref().unwrap_or(""));
                let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned());
                let name = name.map(str::to_string).or(stem).unwrap_or_default();
                if name.is_empty() || name.chars().any(char::is_whitespace) {
                    return Err(pyo3::exceptions::PyValueError::new_err(format!(
                        "name must be a non-empty word without spaces, got {name:?}"
                    )));
                }
                let source = path
                    .file_name()
                    .map_or_else(String::new, |f| f.to_string_lossy().into_owned());
                let label = measured_label(&name, &source, m.description());
                let bytes = py.detach(|| BlobWriter::measured(m.material(), &label).to_bytes());
                Ok(PyBytes::new(py, &bytes))
            }
        }
    }

    /// The blob's label (None for a material read from a `.bsdf` file).
    #[getter]
    fn label(&self) -> Option<&str> {
        match &self.inner {
            Source::File(_) => None,
            Source::Blob(m) => Some(m.label()),
        }
    }

    /// Whether the data is isotropic (at most two `φi` nodes).
    #[getter]
    fn isotropic(&self) -> bool {
        self.material().isotropic()
    }

    /// The wavelengths (nm) of a spectral `.bsdf` file, as a list (None for an RGB file or a
    /// blob).
    #[getter]
    fn wavelengths(&self) -> Option<Vec<f32>> {
        match &self.inner {
            Source::File(m) => m.wavelengths().map(<[f32]>::to_vec),
            Source::Blob(_) => None,
        }
    }

    /// The file it was read from (None for a blob from bytes).
    #[getter]
    fn path(&self) -> Option<&str> {
        self.path.as_deref()
    }

    /// The measured BRDF `f(wi, wo)` in linear RGB, **without** the cosine (Mitsuba's
    /// `eval` divided by `cos θo`).
    ///
    /// `wi`, `wo`: (3, N) float32. Returns (3, N) float32 (rows r, g, b); 0 where either
    /// direction is at or below the horizon, of zero length or not finite.
    #[pyo3(signature = (wi, wo, *, threads = 1))]
    fn eval<'py>(
        &self,
        py: Python<'py>,
        wi: &Bound<'py, PyAny>,
        wo: &Bound<'py, PyAny>,
        threads: usize,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let wi = Rows::<3>::new(wi, "wi")?;
        let wo = Rows::<3>::new(wo, "wo")?;
        let n = same_n(&[("wi", wi.n()), ("wo", wo.n())])?;
        let f_arr = output(py, 3, n);
        {
            let mut rw = f_arr.readwrite();
            let flat = rw.as_slice_mut().map_err(value_error)?;
            let (wi, wo) = (wi.rows()?, wo.rows()?);
            let m = self.material();
            let (len, parallel) = plan(n, threads);
            let jobs: Vec<_> = split(wi, len)
                .into_iter()
                .zip(split(wo, len))
                .zip(split_mut(rows_mut::<3>(flat, n), len))
                .collect();
            py.detach(|| {
                run(jobs, parallel, |((wi, wo), [r, g, b])| {
                    m.eval(vec3s(wi), vec3s(wo), RgbMut { r, g, b })
                })
            })
            .map_err(crate::errors::batch_error)?;
        }
        Ok(f_arr)
    }

    /// The density with which `sample` draws `wo` at each lane's `wi`, with respect to
    /// **solid angle** (Mitsuba's `pdf`).
    ///
    /// `wi`, `wo`: (3, N) float32. Returns (N,) float32; 0 where either direction is at or
    /// below the horizon, of zero length or not finite.
    #[pyo3(signature = (wi, wo, *, threads = 1))]
    fn pdf<'py>(
        &self,
        py: Python<'py>,
        wi: &Bound<'py, PyAny>,
        wo: &Bound<'py, PyAny>,
        threads: usize,
    ) -> PyResult<Bound<'py, PyArray1<f32>>> {
        let wi = Rows::<3>::new(wi, "wi")?;
        let wo = Rows::<3>::new(wo, "wo")?;
        let n = same_n(&[("wi", wi.n()), ("wo", wo.n())])?;
        let pdf_arr = output1(py, n);
        {
            let mut rw = pdf_arr.readwrite();
            let flat = rw.as_slice_mut().map_err(value_error)?;
            let (wi, wo) = (wi.rows()?, wo.rows()?);
            let m = self.material();
            let (len, parallel) = plan(n, threads);
            let jobs: Vec<_> = split(wi, len)
                .into_iter()
                .zip(split(wo, len))
                .zip(split_mut([flat], len))
                .collect();
            py.detach(|| {
                run(jobs, parallel, |((wi, wo), [pdf])| {
                    m.pdf(vec3s(wi), vec3s(wo), pdf)
                })
            })
            .map_err(crate::errors::batch_error)?;
        }
        Ok(pdf_arr)
    }

    /// Draws one direction per lane with the data's own sampler (Mitsuba's `sample` with
    /// `sample2 = u`: the same direction for the same `u`).
    ///
    /// `wi`: (3, N), `u`: (2, N) float32 in [0, 1). Returns `(wo, pdf, weight)`: (3, N) unit
    /// directions, (N,) densities with respect to **solid angle**, and (3, N) RGB weights
    /// `f(wi, wo) · cos θo / pdf` (what Mitsuba's `sample` returns). A refused lane (`wi` at or
    /// below the horizon or not finite, `u` outside [0, 1] or NaN, a sample below the horizon or of
    /// zero density) has `wo = 0`, `pdf = 0`, `weight = 0`.
    #[pyo3(signature = (wi, u, *, threads = 1))]
    fn sample<'py>(
        &self,
        py: Python<'py>,
        wi: &Bound<'py, PyAny>,
        u: &Bound<'py, PyAny>,
        threads: usize,
    ) -> PyResult<MeasuredSampleArrays<'py>> {
        let wi = Rows::<3>::new(wi, "wi")?;
        let u = Rows::<2>::new(u, "u")?;
        let n = same_n(&[("wi", wi.n()), ("u", u.n())])?;
        let wo_arr = output(py, 3, n);
        let pdf_arr = output1(py, n);
        let w_arr = output(py, 3, n);
        {
            let mut wo_rw = wo_arr.readwrite();
            let mut pdf_rw = pdf_arr.readwrite();
            let mut w_rw = w_arr.readwrite();
            let wo_flat = wo_rw.as_slice_mut().map_err(value_error)?;
            let pdf_flat = pdf_rw.as_slice_mut().map_err(value_error)?;
            let w_flat = w_rw.as_slice_mut().map_err(value_error)?;
            // The data's sampler draws from its pdf: the MIS densities are `pdf` again.
            let mut mis = vec![0.0f32; n];
            let (wi, u) = (wi.rows()?, u.rows()?);
            let m = self.material();
            let (len, parallel) = plan(n, threads);
            let jobs: Vec<_> = split(wi, len)
                .into_iter()
                .zip(split(u, len))
                .zip(split_mut(rows_mut::<3>(wo_flat, n), len))
                .zip(split_mut([pdf_flat, &mut mis], len))
                .zip(split_mut(rows_mut::<3>(w_flat, n), len))
                .collect();
            py.detach(|| {
                run(
                    jobs,
                    parallel,
                    |((((wi, [ux, uy]), [x, y, z]), [pdf, mis_pdf]), [r, g, b])| {
                        m.sample(
                            vec3s(wi),
                            Vec2s { x: ux, y: uy },
                            SamplesMut {
                                wo: Vec3sMut { x, y, z },
                                pdf,
                                mis_pdf,
                            },
                            RgbMut { r, g, b },
                        )
                    },
                )
            })
            .map_err(crate::errors::batch_error)?;
        }
        Ok((wo_arr, pdf_arr, w_arr))
    }

    fn __repr__(&self) -> String {
        format!(
            "neusample.MeasuredMaterial(path={:?}, description={:?}, isotropic={}, blob={})",
            self.path,
            self.description(),
            self.isotropic(),
            matches!(self.inner, Source::Blob(_))
        )
    }
}

fn value_error(e: impl std::fmt::Display) -> PyErr {
    pyo3::exceptions::PyValueError::new_err(e.to_string())
}
