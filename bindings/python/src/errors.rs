//! Python exceptions: `neusample.BlobError` (a `ValueError`) carries the typed error of the
//! runtime as `kind` (the stable names of `neusample_owned::error_kind`);
//! `neusample.MeasuredFileError` (a `ValueError`) a measured-material file's error with the
//! `field` at fault; a missing or unreadable file is the usual `OSError`
//! (`FileNotFoundError`, …) with the file name.

use neusample_owned::measured::MeasuredError;
use neusample_owned::{error_kind, OpenError};
use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::prelude::*;

pyo3::create_exception!(
    neusample,
    BlobError,
    PyValueError,
    "A blob could not be opened or used: its bytes are not a valid neusample blob, or it \
     holds another kind than asked for. `kind` names the error (`\"checksum_mismatch\"`, \
     `\"not_a_sampler\"`, …), `path` the file (or None)."
);

pyo3::create_exception!(
    neusample,
    MeasuredFileError,
    PyValueError,
    "A measured-material file (`.bsdf`) could not be read: truncated, not a tensor file, or \
     a field missing, of the wrong type or shape, or holding non-finite or negative values. \
     `field` names the field at fault (None for the file as a whole), `path` the file."
);

/// A `MeasuredFileError` for `e` (its Display as the message) with its `field` and `path`.
pub(crate) fn measured_error(py: Python<'_>, e: &MeasuredError, path: &str) -> PyErr {
    let err = MeasuredFileError::new_err(e.to_string());
    let value = err.value(py);
    // As in `blob_error`: the exception without its attributes is still the right one.
    let _ = value.setattr("field", e.field.as_deref());
    let _ = value.setattr("path", path);
    err
}

/// The `OSError` subclass (`FileNotFoundError`, …) for an I/O error on `path`.
pub(crate) fn open_io_error(io: &std::io::Error, path: &str) -> PyErr {
    // OSError(errno, strerror, filename) picks the subclass (FileNotFoundError, …).
    PyOSError::new_err((
        io.raw_os_error().unwrap_or(0),
        io.to_string(),
        path.to_string(),
    ))
}

/// A `BlobError` with its `kind` and `path` attributes.
pub(crate) fn blob_error(py: Python<'_>, e: &neusample::Error, path: Option<&str>) -> PyErr {
    let msg = match path {
        Some(p) => format!("{p}: {e}"),
        None => e.to_string(),
    };
    let err = BlobError::new_err(msg);
    let value = err.value(py);
    // Setting attributes on a fresh exception instance cannot fail in practice; if it did,
    // the exception without them is still the right one to raise.
    let _ = value.setattr("kind", error_kind(e));
    let _ = value.setattr("path", path);
    err
}

/// The exception for a failed open of `path`.
pub(crate) fn open_error(py: Python<'_>, e: OpenError, path: &str) -> PyErr {
    match e {
        OpenError::Io(io) => open_io_error(&io, path),
        OpenError::Blob(b) => blob_error(py, &b, Some(path)),
    }
}

/// A batched call's error (lengths were checked before, so this is not expected).
pub(crate) fn batch_error(e: neusample::Error) -> PyErr {
    PyValueError::new_err(e.to_string())
}
