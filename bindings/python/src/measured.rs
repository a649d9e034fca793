//! `neusample.MeasuredMaterial`: a measured BRDF of the RGL material database (an RGB
//! `.bsdf` file, Mitsuba's `measured` format) with the data's own sampler, batched over numpy
//! arrays like the other classes.
//!
//! Each lane is prepared at its `wi` and evaluated, sampled or queried at its `wo` / `u`
//! independently: a lane with a bad input (non-finite, zero-length, at or below the horizon)
//! gives 0 and never disturbs the others.

use std::path::PathBuf;

use neusample::{MeasuredMaterial as Material, Vec2, Vec3};
use neusample_owned::measured::OwnedMeasured;
use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::prelude::*;

use crate::arrays::{output, output1, plan, rows_mut, run, same_n, split, split_mut, Rows};
use crate::errors::{measured_error, open_io_error};

/// `(wo, pdf, weight)` of [`MeasuredMaterial::sample`].
type MeasuredSampleArrays<'py> = (
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray1<f32>>,
    Bound<'py, PyArray2<f32>>,
);

/// A measured material from the RGL database (Dupuy & Jakob 2018): an RGB `.bsdf` file in
/// Mitsuba's `measured` format, evaluated and sampled as Mitsuba 3's `measured` BSDF does
/// (the data's visible-normal sampler, warped through its luminance).
///
/// `MeasuredMaterial(path)` reads and checks the whole file; a bad file raises
/// `MeasuredFileError` (with `field` and `path`), a missing one `FileNotFoundError`.
/// Directions are in the local shading frame (z = normal, both pointing away from the
/// surface; normalised here); every pdf is a density with respect to **solid angle** of `wo`.
#[pyclass(frozen, module = "neusample")]
pub(crate) struct MeasuredMaterial {
    inner: OwnedMeasured,
    path: String,
}

impl MeasuredMaterial {
    fn material(&self) -> &Material<Vec<f32>> {
        self.inner.material()
    }
}

#[inline]
fn lane3(rows: &[&[f32]; 3], i: usize) -> Vec3 {
    Vec3::new(rows[0][i], rows[1][i], rows[2][i])
}

#[pymethods]
impl MeasuredMaterial {
    /// Reads the measured material at `path` (an RGB `.bsdf` file).
    #[new]
    fn new(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let shown = path.to_string_lossy().into_owned();
        let read = path.clone();
        let bytes = py
            .detach(move || std::fs::read(&read))
            .map_err(|e| open_io_error(&e, &shown))?;
        let inner = py
            .detach(|| OwnedMeasured::from_bytes(&bytes))
            .map_err(|mut e| {
                e.file = Some(path.display().to_string());
                measured_error(py, &e, &shown)
            })?;
        Ok(MeasuredMaterial { inner, path: shown })
    }

    /// The file's description of the material.
    #[getter]
    fn description(&self) -> &str {
        self.inner.description()
    }

    /// Whether the data is isotropic (at most two `φi` nodes).
    #[getter]
    fn isotropic(&self) -> bool {
        self.material().isotropic()
    }

    /// The file it was read from.
    #[getter]
    fn path(&self) -> &str {
        &self.path
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
                    for i in 0..r.len() {
                        if let Some(p) = m.prepare(lane3(&wi, i)) {
                            [r[i], g[i], b[i]] = p.eval(lane3(&wo, i));
                        }
                    }
                    Ok(())
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
                    for (i, p_out) in pdf.iter_mut().enumerate() {
                        if let Some(p) = m.prepare(lane3(&wi, i)) {
                            *p_out = p.pdf(lane3(&wo, i));
                        }
                    }
                    Ok(())
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
            let (wi, u) = (wi.rows()?, u.rows()?);
            let m = self.material();
            let (len, parallel) = plan(n, threads);
            let jobs: Vec<_> = split(wi, len)
                .into_iter()
                .zip(split(u, len))
                .zip(split_mut(rows_mut::<3>(wo_flat, n), len))
                .zip(split_mut([pdf_flat], len))
                .zip(split_mut(rows_mut::<3>(w_flat, n), len))
                .collect();
            py.detach(|| {
                run(
                    jobs,
                    parallel,
                    |((((wi, u), [x, y, z]), [pdf]), [r, g, b])| {
                        for i in 0..pdf.len() {
                            let s = m
                                .prepare(lane3(&wi, i))
                                .and_then(|p| p.sample(Vec2::new(u[0][i], u[1][i])));
                            if let Some(s) = s {
                                (x[i], y[i], z[i]) = (s.wo.x, s.wo.y, s.wo.z);
                                pdf[i] = s.pdf;
                                [r[i], g[i], b[i]] = s.weight;
                            }
                        }
                        Ok(())
                    },
                )
            })
            .map_err(crate::errors::batch_error)?;
        }
        Ok((wo_arr, pdf_arr, w_arr))
    }

    fn __repr__(&self) -> String {
        format!(
            "neusample.MeasuredMaterial(path={:?}, description={:?}, isotropic={})",
            self.path,
            self.inner.description(),
            self.isotropic()
        )
    }
}

fn value_error(e: impl std::fmt::Display) -> PyErr {
    pyo3::exceptions::PyValueError::new_err(e.to_string())
}
