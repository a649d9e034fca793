//! The errors of the renderer's fallible set-up calls (rendering itself cannot fail).

use std::fmt;
use std::path::PathBuf;

/// What went wrong.
#[derive(Debug)]
#[non_exhaustive]
pub enum Error {
    /// An environment map could not be read or is empty.
    EnvMap {
        /// The file.
        path: PathBuf,
        /// What happened, naming the file.
        reason: String,
    },
    /// The private thread pool of a timing run could not be built.
    ThreadPool(rayon::ThreadPoolBuildError),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::EnvMap { reason, .. } => f.write_str(reason),
            Error::ThreadPool(e) => write!(f, "cannot build the timing thread pool: {e}"),
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::EnvMap { .. } => None,
            Error::ThreadPool(e) => Some(e),
        }
    }
}

impl From<rayon::ThreadPoolBuildError> for Error {
    fn from(e: rayon::ThreadPoolBuildError) -> Self {
        Error::ThreadPool(e)
    }
}
