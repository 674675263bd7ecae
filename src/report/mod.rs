//! The calibration report: one self-contained HTML page (inline CSS and SVG, no scripts, no
//! external resources) that explains a calibration run.
//!
//! [`render_html`] is pure: it takes a [`ReportInput`] and returns the page; the caller writes it.
//! The page holds the estimates with their standard deviations and the observability verdicts
//! in words (the rotation also as roll, pitch, yaw and axis-angle), the correlation matrix of the
//! estimates, every warning, and the plots listed in [`PLOT_IDS`] (each an `<svg>` with that id):
//! the DVL residuals over time with the stated 3-sigma band, measured against predicted DVL
//! velocities per axis before and after the refinement, residual
//! histograms, the angular velocity with the calm samples of the clock-offset search shaded, the
//! lever-arm velocity against the speed, the clock-offset objective, the cost per iteration,
//! per-frame detection statistics, each camera's reprojection errors over the image and over
//! time, pose residuals and a top view of the trajectory, followed by the DVL log's summary and
//! the result file. A run that calibrated an IMU beside the DVL has a section of the IMU's
//! ([`IMU_SECTION_ID`]): `T_cam_imu`, its clock offset, gravity, biases and noise factors with
//! their verdicts and the motion that observed them.
//!
//! A calibration that stopped with an error gets [`render_failure_html`]: what was found and why
//! it stopped.

mod cameras;
mod clock_offset;
mod correlation;
mod data;
mod dvl_log;
mod failure;
mod frames;
mod guidance;
mod html;
mod imu;
mod imu_only;
mod input;
mod motion;
mod page;
mod refinement;
mod reprojection;
mod results;
mod robustness;
mod rotation;
mod summary;
mod svg;
mod timeline;
mod trajectory_fit;
mod velocity;
mod words;

pub use cameras::{
    CAMCAL_CAMERA_PLOT_IDS, CAMCAL_PLOT_IDS, CAMCAL_SECTION_IDS, CamCalReportInput,
    camcal_plot_ids, render_camcal_html,
};
pub use failure::{FAILURE_PLOT_IDS, FAILURE_SECTION_IDS, FailureReportInput, render_failure_html};
pub use guidance::{NextStep, StepKind, next_steps};
pub use imu_only::{
    CAMERA_IMU_SECTION_IDS, DVL_IMU_SECTION_IDS, ImuOnlyKind, ImuOnlyReportInput,
    render_imu_only_html,
};
pub use input::{
    BLUR_FACTOR, BLUR_MARGIN_PX, BLURRED_EDGE_PX, FrameDrop, FrameStat, ImuReportInput,
    ReportInput, frame_stats, posed_edge_width_px,
};
pub use words::{WATER_SOUND_SPEED_MPS, implausible_water, sound_speed_words};

use crate::error::Result;

/// The id of every plot of the report, in page order. Plots without data (no clock-offset search
/// for `--method bcd`, no image statistics for `--poses` runs) are still present, marked
/// `data-empty="true"` and saying why.
pub const PLOT_IDS: &[&str] = &[
    "residual-time-x",
    "residual-time-y",
    "residual-time-z",
    "velocity-before-x",
    "velocity-after-x",
    "velocity-before-y",
    "velocity-after-y",
    "velocity-before-z",
    "velocity-after-z",
    "residual-acf",
    "residuals-x",
    "residuals-y",
    "residuals-z",
    "angular-velocity",
    "lever-arm",
    "offset-global",
    "offset-coarse",
    "offset-fine",
    "cost",
    "frames-tags",
    "frames-rms",
    "reprojection-map-cam0",
    "reprojection-time-cam0",
    "reprojection-map-cam1",
    "reprojection-time-cam1",
    "pose-residual-pos",
    "pose-residual-rot",
    "trajectory",
];

/// The id of every section of the report, in page order.
pub const SECTION_IDS: &[&str] = &[
    "summary",
    "next-steps",
    "results",
    "correlation",
    "warnings",
    "residual-time",
    "velocity",
    "robustness",
    "residuals",
    "motion",
    "clock-offset",
    "refinement",
    "frames",
    "reprojection",
    "trajectory-fit",
    "dvl-log",
    "result-file",
];

/// The id of the IMU's section, present (after `correlation`) when the run calibrated an IMU.
pub const IMU_SECTION_ID: &str = "imu";

/// Renders the report as one HTML document.
pub fn render_html(input: &ReportInput) -> Result<String> {
    let d = data::Derived::compute(input)?;
    Ok(page::render(input, &d))
}

#[cfg(test)]
#[path = "report_tests.rs"]
mod report_tests;
