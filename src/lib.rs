//! dvlcal: spatiotemporal calibration of a Doppler velocity log against a camera.
//!
//! Data flows through the modules in this order:
//! - [`io`]: file formats in and out (TUM poses, A50 logs, CSV, YAML). No estimation here.
//! - [`trajectory`]: Lie groups and the white-noise-on-jerk Gaussian-process trajectory on SE(3).
//! - [`calib`]: the UIC calibration (initialisation, refinement, uncertainty).
//! - [`sim`]: synthetic datasets with known truth.
//! - [`eval`]: accuracy of estimates against known truth.
//! - [`report`]: the self-contained HTML report of a calibration.
//!
//! Conventions (frames, time offsets, twist order) are in `docs/conventions.md`.

#![warn(missing_docs)]

pub mod calib;
pub mod error;
pub mod eval;
pub mod io;
pub mod lie;
mod parallel;
pub mod pipeline;
pub mod report;
pub mod sim;
pub mod time;
pub mod trajectory;
pub mod types;
pub mod vision;

pub use error::{Error, Result};
