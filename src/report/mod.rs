//! The calibration report: one self-contained HTML page (inline CSS and SVG, no scripts, no
//! external resources) that explains a calibration run.
//!
//! [`render_html`] is pure: it takes a [`ReportInput`] and returns the page; the caller writes it.
//! The page holds the estimates with their standard deviations and the observability verdicts
//! in words, every warning, and the plots listed in [`PLOT_IDS`] (each an `<svg>` with that id):
//! measured against predicted DVL velocities per axis before and after the refinement, residual
//! histograms, the angular velocity with the calm samples of the clock-offset search shaded, the
//! lever-arm velocity against the speed, the clock-offset objective, the cost per iteration,
//! per-frame detection statistics, pose residuals and a top view of the trajectory, followed by
//! the DVL log's summary and the result file.

mod data;
mod input;
mod page;
mod svg;

pub use input::{FrameStat, ReportInput, frame_stats};

use crate::error::Result;

/// The id of every plot of the report, in page order. Plots without data (no clock-offset search
/// for `--method bcd`, no image statistics for `--poses` runs) are still present, marked
/// `data-empty="true"` and saying why.
pub const PLOT_IDS: &[&str] = &[
    "velocity-before-x",
    "velocity-after-x",
    "velocity-before-y",
    "velocity-after-y",
    "velocity-before-z",
    "velocity-after-z",
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
    "pose-residual-pos",
    "pose-residual-rot",
    "trajectory",
];

/// The id of every section of the report, in page order.
pub const SECTION_IDS: &[&str] = &[
    "summary",
    "results",
    "warnings",
    "velocity",
    "residuals",
    "motion",
    "clock-offset",
    "refinement",
    "frames",
    "trajectory-fit",
    "dvl-log",
    "result-file",
];

/// The velocity scale read as a speed of sound. A piston-array DVL like the A50 reports the true
/// velocity times `c_assumed / c_water`, so with the sound speed the DVL assumed the scale says
/// what the water's was; without it, how far apart the two are in per cent.
pub fn sound_speed_words(scale: f64, scale_std: f64, assumed_mps: Option<f64>) -> String {
    match assumed_mps {
        Some(c) if scale > 0.0 => {
            let water = c / scale;
            format!(
                "the DVL assumes a sound speed of {c:.0} m/s; the data say the water's is about \
                 {water:.0} m/s (+- {:.0} m/s)",
                water * scale_std / scale
            )
        }
        _ if scale > 0.0 => format!(
            "the DVL's velocities are {:.2} % {} than the camera's (+- {:.2} %): the sound speed it \
             assumes is that much {} than the water's",
            100.0 * (scale - 1.0).abs(),
            if scale >= 1.0 { "higher" } else { "lower" },
            100.0 * scale_std,
            if scale >= 1.0 { "higher" } else { "lower" }
        ),
        _ => "the velocity scale is not positive: no sound speed can be read from it".into(),
    }
}

/// Renders the report as one HTML document.
pub fn render_html(input: &ReportInput) -> Result<String> {
    let d = data::Derived::compute(input)?;
    Ok(page::render(input, &d))
}
