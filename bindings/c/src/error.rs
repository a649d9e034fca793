//! Errors of the ABI: what a call can fail with, its status code, the per-thread message, and
//! [`guard`], which runs every entry point under `catch_unwind`.

use std::cell::RefCell;
use std::ffi::CString;
use std::panic::{catch_unwind, AssertUnwindSafe};

use neusample_owned::measured::MeasuredError;
use neusample_owned::{error_kind, OpenError};

use crate::types::NsStatus;

/// Why a call failed (or was refused).
#[derive(Debug)]
pub(crate) enum CallError {
    Null(&'static str),
    Invalid(String),
    NotFinite(&'static str),
    Io(String),
    Blob(neusample::Error),
    /// A measured-material file's error (it names the file and the field).
    MeasuredFile(MeasuredError),
    /// Not an error: the scalar call's condition or sample was refused.
    Refused,
}

impl From<neusample::Error> for CallError {
    fn from(e: neusample::Error) -> Self {
        CallError::Blob(e)
    }
}

pub(crate) fn open_error(path: &str, e: OpenError) -> CallError {
    match e {
        OpenError::Io(e) => CallError::Io(format!("{path}: {e}")),
        OpenError::Blob(e) => CallError::Blob(e),
    }
}

/// The status of a blob error, through the shared kind names of `neusample-owned`.
fn blob_status(e: &neusample::Error) -> NsStatus {
    use NsStatus::*;
    match error_kind(e) {
        "truncated" => NS_ERR_TRUNCATED,
        "bad_magic" => NS_ERR_BAD_MAGIC,
        "unsupported_version" => NS_ERR_UNSUPPORTED_VERSION,
        "checksum_mismatch" => NS_ERR_CHECKSUM_MISMATCH,
        "header_decode" => NS_ERR_HEADER_DECODE,
        "header_invalid" => NS_ERR_HEADER_INVALID,
        "wrong_kind" => NS_ERR_WRONG_KIND,
        "not_a_sampler" => NS_ERR_NOT_A_SAMPLER,
        "dimension_mismatch" => NS_ERR_DIMENSION_MISMATCH,
        "tensor_missing" => NS_ERR_TENSOR_MISSING,
        "tensor_shape" => NS_ERR_TENSOR_SHAPE,
        "tensor_bounds" => NS_ERR_TENSOR_BOUNDS,
        "tensor_dtype" => NS_ERR_TENSOR_DTYPE,
        "non_finite" => NS_ERR_NON_FINITE,
        "batch_length" => NS_ERR_BATCH_LENGTH,
        "table_not_normalized" => NS_ERR_TABLE_NOT_NORMALIZED,
        _ => NS_ERR_BLOB_OTHER,
    }
}

/// The stable name of a status (`"NS_OK"`, `"NS_ERR_IO"`, …), NUL-terminated.
pub(crate) fn status_name(s: NsStatus) -> &'static [u8] {
    use NsStatus::*;
    match s {
        NS_OK => b"NS_OK\0",
        NS_REFUSED => b"NS_REFUSED\0",
        NS_ERR_NULL_POINTER => b"NS_ERR_NULL_POINTER\0",
        NS_ERR_INVALID_ARGUMENT => b"NS_ERR_INVALID_ARGUMENT\0",
        NS_ERR_NOT_FINITE => b"NS_ERR_NOT_FINITE\0",
        NS_ERR_IO => b"NS_ERR_IO\0",
        NS_ERR_PANIC => b"NS_ERR_PANIC\0",
        NS_ERR_MEASURED_FILE => b"NS_ERR_MEASURED_FILE\0",
        NS_ERR_TRUNCATED => b"NS_ERR_TRUNCATED\0",
        NS_ERR_BAD_MAGIC => b"NS_ERR_BAD_MAGIC\0",
        NS_ERR_UNSUPPORTED_VERSION => b"NS_ERR_UNSUPPORTED_VERSION\0",
        NS_ERR_CHECKSUM_MISMATCH => b"NS_ERR_CHECKSUM_MISMATCH\0",
        NS_ERR_HEADER_DECODE => b"NS_ERR_HEADER_DECODE\0",
        NS_ERR_HEADER_INVALID => b"NS_ERR_HEADER_INVALID\0",
        NS_ERR_WRONG_KIND => b"NS_ERR_WRONG_KIND\0",
        NS_ERR_NOT_A_SAMPLER => b"NS_ERR_NOT_A_SAMPLER\0",
        NS_ERR_DIMENSION_MISMATCH => b"NS_ERR_DIMENSION_MISMATCH\0",
        NS_ERR_TENSOR_MISSING => b"NS_ERR_TENSOR_MISSING\0",
        NS_ERR_TENSOR_SHAPE => b"NS_ERR_TENSOR_SHAPE\0",
        NS_ERR_TENSOR_BOUNDS => b"NS_ERR_TENSOR_BOUNDS\0",
        NS_ERR_TENSOR_DTYPE => b"NS_ERR_TENSOR_DTYPE\0",
        NS_ERR_NON_FINITE => b"NS_ERR_NON_FINITE\0",
        NS_ERR_BATCH_LENGTH => b"NS_ERR_BATCH_LENGTH\0",
        NS_ERR_TABLE_NOT_NORMALIZED => b"NS_ERR_TABLE_NOT_NORMALIZED\0",
        NS_ERR_BLOB_OTHER => b"NS_ERR_BLOB_OTHER\0",
    }
}

thread_local! {
    /// The message of the last failed call on this thread (NUL-terminated).
    static LAST_ERROR: RefCell<CString> = RefCell::new(CString::default());
}

fn set_last_error(msg: String) {
    // Interior NULs cannot occur in our messages; replace them rather than fail.
    let c = CString::new(msg.replace('\0', " ")).unwrap_or_default();
    LAST_ERROR.with(|e| *e.borrow_mut() = c);
}

/// Calls `f` with a pointer to this thread's last error message (valid until the next call
/// into the library on this thread).
pub(crate) fn with_last_error<R>(f: impl FnOnce(*const std::ffi::c_char) -> R) -> R {
    LAST_ERROR.with(|e| f(e.borrow().as_ptr()))
}

fn report(e: CallError) -> NsStatus {
    let (status, msg) = match e {
        CallError::Refused => return NsStatus::NS_REFUSED,
        CallError::Null(what) => (NsStatus::NS_ERR_NULL_POINTER, format!("`{what}` is NULL")),
        CallError::Invalid(m) => (NsStatus::NS_ERR_INVALID_ARGUMENT, m),
        CallError::NotFinite(what) => (
            NsStatus::NS_ERR_NOT_FINITE,
            format!("`{what}` has a NaN or infinite component"),
        ),
        CallError::Io(m) => (NsStatus::NS_ERR_IO, m),
        CallError::Blob(e) => (blob_status(&e), e.to_string()),
        CallError::MeasuredFile(e) => (NsStatus::NS_ERR_MEASURED_FILE, e.to_string()),
    };
    set_last_error(msg);
    status
}

/// Runs one entry point: its error becomes a status and this thread's message, a panic
/// becomes [`NsStatus::NS_ERR_PANIC`] (it never unwinds into C).
pub(crate) fn guard(f: impl FnOnce() -> Result<(), CallError>) -> NsStatus {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(())) => NsStatus::NS_OK,
        Ok(Err(e)) => report(e),
        Err(payload) => {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            // Dropping the payload could itself panic; leak it instead.
            std::mem::forget(payload);
            set_last_error(format!("internal panic caught at the C boundary: {what}"));
            NsStatus::NS_ERR_PANIC
        }
    }
}

/// Runs a `*_free` function body; a panic is swallowed (there is no status to return).
pub(crate) fn guard_void(f: impl FnOnce()) {
    if let Err(payload) = catch_unwind(AssertUnwindSafe(f)) {
        std::mem::forget(payload);
    }
}
