//! Library error type. Every error that input can cause names its source (file and line) where
//! there is one.

use std::path::PathBuf;

/// Errors of the dvlcal library.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A line of an input file could not be used.
    #[error("{}:{line}: {msg}", file.display())]
    Parse {
        file: PathBuf,
        line: usize,
        msg: String,
    },
    /// A file could not be read or written.
    /// (The I/O error is part of the message and not chained as a source, so that a report of
    /// the whole chain names it once.)
    #[error("{}: {err}", path.display())]
    Io { path: PathBuf, err: std::io::Error },
    /// The input as a whole cannot be used (too short, wrong order, outside a span, ...).
    #[error("{0}")]
    Input(String),
    /// A numerical procedure failed (a matrix that should be positive definite is not, ...).
    #[error("numerical failure: {0}")]
    Numerical(String),
}

/// Result with the library's error type.
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// Shorthand for a parse error at `file:line`.
    pub fn parse(file: impl Into<PathBuf>, line: usize, msg: impl Into<String>) -> Self {
        Error::Parse {
            file: file.into(),
            line,
            msg: msg.into(),
        }
    }

    /// Shorthand for an I/O error on `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            err: source,
        }
    }
}
