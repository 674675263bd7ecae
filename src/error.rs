//! Library error type. Every error that input can cause names its source (file and line) where
//! there is one, and the failures a caller may want to act on have a variant of their own.

use std::path::PathBuf;

/// Errors of the dvlcal library.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A line (or record, or field) of an input file could not be used.
    #[error("{}:{line}: {msg}", file.display())]
    Parse {
        /// The file.
        file: PathBuf,
        /// 1-based line number (0 when the problem is with the file as a whole).
        line: usize,
        /// What is wrong with it.
        msg: String,
    },
    /// A file could not be read or written.
    /// (The I/O error is part of the message and not chained as a source, so that a report of
    /// the whole chain names it once.)
    #[error("{}: {err}", path.display())]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// What the operating system said.
        err: std::io::Error,
    },
    /// An option value that cannot be used. `option` names it as its caller knows it: the
    /// estimator's settings by their field (`offset.range`) unless the caller gave other words
    /// (`calib::CalibOptions::names`; the program's flags), the stages' options by their flag.
    #[error("{option} {msg}")]
    InvalidOption {
        /// The option (`offset.range`, `--offset-range`).
        option: &'static str,
        /// What is wrong with the value.
        msg: String,
    },
    /// An option the run would not use (accepted, it would be ignored): why, and what to use
    /// instead. A program treats it as a usage error.
    #[error("{0}")]
    UnusedOption(String),
    /// A stage had fewer usable samples than it needs.
    #[error("{found} {what}: at least {needed} are needed")]
    TooFewSamples {
        /// What was counted ("valid DVL velocity reports").
        what: String,
        /// How many there were.
        found: usize,
        /// How many the stage needs.
        needed: usize,
    },
    /// The camera trajectory and the DVL log do not overlap in time (at the clock offsets
    /// tried): the clocks differ by more than the search covers, or the logs are of different
    /// recordings.
    #[error("{0}")]
    NoTimeOverlap(String),
    /// A dataset lacks a part it needs (no camera data, no DVL log, images without a camera
    /// chain), or has two candidates for one part.
    #[error("{}: {msg}", path.display())]
    Dataset {
        /// The dataset folder (or the file concerned).
        path: PathBuf,
        /// What is missing or ambiguous.
        msg: String,
    },
    /// An error of one step of a longer run (a calibration of one of several datasets), with
    /// what the step was. The inner error is kept whole for callers that match on it.
    #[error("{context}: {inner}")]
    During {
        /// The step ("UIC on runs/dive2").
        context: String,
        /// What went wrong in it.
        inner: Box<Error>,
    },
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

    /// Shorthand for an unusable option value.
    pub fn option(option: &'static str, msg: impl Into<String>) -> Self {
        Error::InvalidOption {
            option,
            msg: msg.into(),
        }
    }

    /// This error, as part of `context`.
    pub fn during(self, context: impl Into<String>) -> Self {
        Error::During {
            context: context.into(),
            inner: Box::new(self),
        }
    }

    /// Shorthand for a dataset that lacks a part.
    pub fn dataset(path: impl Into<PathBuf>, msg: impl Into<String>) -> Self {
        Error::Dataset {
            path: path.into(),
            msg: msg.into(),
        }
    }
}
