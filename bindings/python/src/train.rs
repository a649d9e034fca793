//! `neusample.train_sampler` (cargo feature `train`): the training entry point of
//! neusample-precompute, the same steps as `neusample train --material M --method X --out F`
//! (train, bake, verify the blob against the model, write it atomically).
//!
//! This is the only file of the Python crate that uses neusample-precompute.

use std::path::PathBuf;

use neusample::{DType, SamplerKind};
use neusample_precompute::jobs::sampler::train_sampler as train_job;
use neusample_precompute::materials;
use neusample_precompute::train::TrainConfig;
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// Trains `method` for `material` (a material file, TOML/JSON, a neural-material blob, or a
/// built-in material name), bakes and verifies the blob and writes it to `out`. Returns a
/// dict: `out`, `bytes`, `seconds`, `final_loss`, `max_relative` (blob vs model),
/// `tolerance`. The GIL is released while training.
#[pyfunction]
#[pyo3(signature = (material, method, out, *, seed = 0, steps_scale = 1.0, quick = false, f16 = false))]
#[allow(clippy::too_many_arguments)]
fn train_sampler<'py>(
    py: Python<'py>,
    material: String,
    method: String,
    out: PathBuf,
    seed: u64,
    steps_scale: f64,
    quick: bool,
    f16: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let method = SamplerKind::from_name(&method)
        .ok_or_else(|| PyValueError::new_err(format!("unknown method {method:?}")))?;
    if !(steps_scale > 0.0 && steps_scale.is_finite()) {
        return Err(PyValueError::new_err("steps_scale must be positive"));
    }
    let out2 = out.clone();
    let result = py.detach(move || -> anyhow::Result<_> {
        let m = materials::resolve(&material)?;
        let mut cfg = if quick {
            TrainConfig::quick()
        } else {
            TrainConfig::default()
        };
        cfg.common.seed = seed;
        if steps_scale != 1.0 {
            cfg = cfg.with_steps_scaled(steps_scale);
        }
        let dtype = if f16 { DType::F16 } else { DType::F32 };
        let (trained, bytes, v) = train_job(m.as_ref(), method, &cfg, dtype, &out2)?;
        Ok((trained, bytes.len(), v))
    });
    let (trained, len, v) = result.map_err(|e| PyRuntimeError::new_err(format!("{e:#}")))?;
    let d = PyDict::new(py);
    d.set_item("out", out.to_string_lossy().into_owned())?;
    d.set_item("bytes", len)?;
    d.set_item("seconds", trained.seconds)?;
    d.set_item("final_loss", trained.loss_history.last().copied())?;
    d.set_item("max_relative", v.max_relative)?;
    d.set_item("tolerance", v.tolerance)?;
    Ok(d)
}

/// Adds the training functions to the module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(train_sampler, m)?)
}
