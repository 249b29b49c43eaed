//! Typed errors of the core library. Every variant names the file and, where there is one,
//! the element (face, vertex, texel, field) and says what to do about it.

use std::path::PathBuf;

pub type Result<T, E = Error> = std::result::Result<T, E>;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The file exists but its contents are unusable: `what` names the element and the fix.
    #[error("{path}: {what}")]
    Invalid { path: PathBuf, what: String },
    #[error("{path}: unsupported file type '{ext}' ({expected})")]
    UnsupportedFormat {
        path: PathBuf,
        ext: String,
        expected: &'static str,
    },
    /// A parameter given on the command line or in a sidecar is out of range.
    #[error("{0}")]
    Param(String),
}

impl Error {
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
    pub fn invalid(path: impl Into<PathBuf>, what: impl Into<String>) -> Self {
        Error::Invalid {
            path: path.into(),
            what: what.into(),
        }
    }
}
