//! dvlcal: spatiotemporal calibration of a Doppler velocity log (the Water Linked A50) against a
//! camera: the DVL's rotation and lever arm relative to the camera, the clock offset between the
//! two and the DVL's velocity scale, each with a standard deviation and a verdict on whether the
//! motion could observe it.
//!
//! # Use
//!
//! From data already in memory (camera poses from motion capture, VIO or your own detector; DVL
//! velocities from any log): build [`PoseMeasurement`]s and [`DvlSample`]s on one epoch and call
//! [`calibrate`]. Here the simulator stands in for a recording; the raw arrays are what a user's
//! logs would give.
//!
//! ```
//! use dvlcal::lie::Se3;
//! use dvlcal::sim::dataset::{SimConfig, simulate};
//! use dvlcal::{CalibOptions, DvlSample, PoseMeasurement, calibrate};
//! use nalgebra::Vector3;
//!
//! # fn main() -> dvlcal::Result<()> {
//! // 40 s of camera poses (10 Hz) and A50 velocities (10 Hz), with known truth.
//! let sim = simulate(&SimConfig { duration_s: 40.0, ..SimConfig::default() })?;
//! // Raw values as a user's logs give them: t, position, quaternion (xyzw); t, velocity.
//! let camera: Vec<(f64, [f64; 3], [f64; 4])> = sim
//!     .poses
//!     .iter()
//!     .map(|p| (p.t, p.pose.trans.into(), p.pose.quaternion_xyzw()))
//!     .collect();
//! let dvl: Vec<(f64, [f64; 3])> = sim.dvl.iter().map(|s| (s.t, s.v.into())).collect();
//!
//! // Camera poses T_world_cam on the camera clock; DVL velocities in the DVL frame on the DVL
//! // clock. Both are seconds from one epoch.
//! let poses: Vec<PoseMeasurement> = camera
//!     .iter()
//!     .map(|(t, p, q)| PoseMeasurement {
//!         t: *t,
//!         pose: Se3::from_quaternion_xyzw(q, Vector3::from(*p)),
//!         cov: None, // the fit estimates the pose noise
//!     })
//!     .collect();
//! let samples: Vec<DvlSample> = dvl
//!     .iter()
//!     .map(|(t, v)| DvlSample { t: *t, v: Vector3::from(*v), cov: None, valid: true })
//!     .collect();
//!
//! let out = calibrate(&poses, &samples, &CalibOptions::default())?;
//! let p = &out.params; // T_cam_dvl, time_offset_s, velocity_scale
//! println!(
//!     "lever arm {:?} m, clock offset {:.4} s (std {:.4}), scale {:.4}",
//!     p.lever_arm_cam_m(),
//!     p.time_offset_s,
//!     out.std.time_offset_s,
//!     p.velocity_scale
//! );
//! // The estimate is within a few standard deviations of the truth.
//! let truth = &sim.truth;
//! assert!((p.time_offset_s - truth.time_offset_s).abs() < 5.0 * out.std.time_offset_s);
//! assert!((p.lever_arm_cam_m() - truth.lever_arm_cam_m()).norm() < 0.02);
//! assert!(out.verdicts.rotation.ok);
//! # Ok(())
//! # }
//! ```
//!
//! From files, [`pipeline`] does what the `dvlcal` program does: find the parts of a dataset
//! folder, detect the board in stereo images and solve the poses, read any A50 log, calibrate,
//! and write the result file, its exports and the HTML report:
//!
//! ```no_run
//! use dvlcal::calib::CalibOptions;
//! use dvlcal::io::dataset::DatasetOverrides;
//! use dvlcal::io::dvl::DvlReadOptions;
//! use dvlcal::pipeline::{
//!     Dataset, OutputOptions, VisionOptions, calibrate_dataset, dataset_files, write_results,
//! };
//! use std::path::Path;
//!
//! # fn main() -> dvlcal::Result<()> {
//! let files = dataset_files(Some(Path::new("my_run")), &DatasetOverrides::default())?;
//! let data = Dataset::load(files, &VisionOptions::default(), &DvlReadOptions::default(), &mut |_| {})?;
//! let run = calibrate_dataset(&data, &CalibOptions::default(), None)?;
//! write_results(Path::new("out/calibration.yaml"), &run, &data, &OutputOptions::default())?;
//! print!("{}", run.summary(data.dvl()?));
//! # Ok(())
//! # }
//! ```
//!
//! Errors are [`Error`]s; the ones a caller may act on have variants of their own (a bad option,
//! too few samples, logs that do not overlap in time, a dataset that lacks a part, a file's line
//! that cannot be used).
//!
//! # Modules
//!
//! The modules follow the data (`docs/architecture.md` has the picture and the layering rules,
//! `docs/conventions.md` the frames, quaternions, twists and times):
//! - foundation: [`error`], [`time`], [`lie`] (SO(3), SE(3)), [`types`] (values passed between
//!   stages, the camera model and the board geometry);
//! - [`io`] (every format in and out, nothing estimated), [`trajectory`] (the
//!   white-noise-on-jerk GP on SE(3));
//! - [`vision`] (AprilTag detection and stereo PnP on what `io` reads), [`calib`] (the UIC
//!   estimator);
//! - [`camcal`] (camera intrinsics and stereo extrinsics from board images), [`sim`]
//!   (recordings with known truth);
//! - [`eval`] (accuracy and odometry checks), [`report`] (the HTML report);
//! - [`pipeline`]: the stages strung together, for the `dvlcal` program and other programs.

#![warn(missing_docs)]

pub mod calib;
pub mod camcal;
pub mod error;
pub mod eval;
pub mod files;
pub mod io;
pub mod lie;
pub mod parallel;
pub mod pipeline;
pub mod report;
pub mod rng;
pub mod sim;
pub mod time;
pub mod trajectory;
pub mod types;
pub mod vision;

pub use calib::{CalibOptions, CalibrationOutcome, Method, calibrate};
pub use error::{Error, Result};
pub use types::{CalibrationParams, DvlSample, PoseMeasurement};
