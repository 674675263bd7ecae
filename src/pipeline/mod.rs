//! The whole calibration as a library: what the `dvlcal` program runs, for other programs.
//!
//! The stages below string the modules together with plain option structs (no command-line
//! types); each option struct checks itself with `validate()`, and each step returns typed
//! values the next step takes:
//!
//! 1. [`dataset_files`] finds the parts of a dataset folder (or takes them one by one), and
//!    [`Dataset::load`] reads them: camera poses from a pose file or from images
//!    ([`poses_from_images`]: detection and stereo PnP), and the DVL log on the same epoch.
//!    Images without a camchain are first calibrated with [`calibrate_cameras_from_images`]
//!    (the run is kept in [`Dataset::cameras`]).
//! 2. [`calibrate_dataset`] runs the estimator ([`crate::calib::calibrate`]) and builds the
//!    result file; [`write_results`] and [`write_report`] write it, its exports and the report;
//!    when it returns an error, [`write_failure_report`] writes what was found and why it failed.
//! 3. [`odometry_table`] and [`cross_validate`] check calibrations on data.
//! 4. [`calibrate_cameras_from_images`] calibrates the cameras themselves from board images
//!    (intrinsics, distortion, stereo extrinsics) and writes a Kalibr camchain and its report.
//! 5. [`write_simulated_dataset`] writes a dataset folder with known truth.
//! 6. A bag (ROS 1 or ROS 2) is a dataset too: opened with the parts of its topics
//!    ([`crate::io::bag::open::OpenBag`]) and its frames planned
//!    ([`crate::io::bag::frames::plan_frames`]), [`poses_from_bag`] streams its images through
//!    the same pipeline; its poses and its listing are read by [`crate::io::bag::poses`] and
//!    [`crate::io::bag::info`].
//!
//! Long steps take a worker-thread count; results never depend on it.

mod board;
mod calibration;
mod cameras;
pub mod chain_order;
mod dataset;
pub mod dvl_imu;
mod evaluate;
mod exports;
pub mod imu;
mod imu_bag;
pub mod imu_only;
pub mod live_dvl;
mod outputs;
mod simulate;
pub mod unused;
mod vision;
pub mod watch;
mod watch_bag;
mod watch_cameras;

pub use board::write_board_svg;
pub use calibration::{
    CalibrationRun, OutputOptions, ResultPaths, calibrate_dataset, calibration_context,
    dataset_inputs, frame_names, method_name, result_file, sibling, write_failure_report,
    write_report, write_results,
};
pub use cameras::{
    CameraCalOptions, CameraCalRun, SEPARATE_CAMERA_RECORDING, calibrate_cameras_from_bag,
    calibrate_cameras_from_images,
};
pub use dataset::{Dataset, dataset_files, dataset_files_checked, describe_files};
pub use evaluate::{
    Baseline, CrossValidation, baselines, cross_validate, odometry_check, odometry_table,
};
pub use imu::ImuCalibration;
pub use imu_only::{
    CameraImuRun, calibrate_camera_imu_dataset, write_camera_imu_results, wrote_words,
};
pub use outputs::{CameraOutputs, RESULT_EXPORTS, check_result_outputs};
pub use simulate::{
    ImageRequest, SimulateRequest, SimulatedRecording, simulated_imu_config,
    write_simulated_dataset, write_simulated_imu,
};
pub use vision::{
    MAX_REPROJECTION_RMS_PX, VisionOptions, VisionRun, detector_settings, frames_csv_path,
    posed_frames, poses_from_bag, poses_from_images, poses_from_images_with_chain,
};

pub use crate::parallel::worker_pool;
