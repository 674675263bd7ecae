//! The report of a camera calibration: one self-contained HTML page (inline CSS and SVG, no
//! scripts, no external resources) on a [`CamCalResult`].
//!
//! [`render_camcal_html`] is pure: it takes the result and a [`CamCalReportInput`] and returns the
//! page; the caller writes it. The page has the sections of [`CAMCAL_SECTION_IDS`], in order:
//! - a summary with the key figures (model, cameras, frames and corners used and dropped, the
//!   reprojection RMS overall and per camera, the estimated corner noise) and a verdict in words;
//! - the warnings of the calibration;
//! - the results per camera: intrinsics and distortion with their standard deviations beside
//!   OpenCV's initial values, and for every camera after cam0 the transform `T_cn_cnm1`;
//! - the reprojection residuals per camera: a histogram of the x and y components, and a map of
//!   the residuals over the image (every corner a dot coloured by its residual, rejected corners
//!   crossed out, the mean residual per image cell as an arrow);
//! - the coverage of every image by corners, with the parts where the distortion is not measured
//!   named in words;
//! - the reprojection RMS per frame and camera, the dropped frames with their reasons and the
//!   worst frames;
//! - the camchain file written, with the command that made it.
//!
//! Per-camera plots have the ids of [`CAMCAL_CAMERA_PLOT_IDS`] followed by `-cam0`, `-cam1`, ...;
//! the plots of the whole chain are listed in [`CAMCAL_PLOT_IDS`]; [`camcal_plot_ids`] lists
//! every plot of a chain in page order.

mod coverage;
mod frames;
mod input;
mod panel;
mod residuals;
mod results;
mod shared;
mod summary;

use std::fmt::Write as _;

pub use input::CamCalReportInput;

use crate::camcal::CamCalResult;
use crate::error::Result;
use crate::report::html::{STYLE, put, section};
use crate::report::svg::escape;
use coverage::coverage;
use frames::frames;
use residuals::residuals;
use results::results;
use summary::{summary, warnings};

/// The id of every section of the camera calibration report, in page order.
pub const CAMCAL_SECTION_IDS: &[&str] = &[
    "summary",
    "warnings",
    "results",
    "residuals",
    "coverage",
    "frames",
    "camchain",
];

/// The plots drawn once per camera, in page order within a camera: the id of cam n's plot is
/// the name followed by `-cam{n}` (`residual-hist-cam0`). Every camera of the chain has them;
/// one without data says so in the plot (`data-empty="true"`).
pub const CAMCAL_CAMERA_PLOT_IDS: &[&str] = &["residual-hist", "residual-map", "coverage-grid"];

/// The plots of the whole chain.
pub const CAMCAL_PLOT_IDS: &[&str] = &["frame-rms"];

/// The ids of every plot of the report of a chain of `cameras` cameras, in page order.
pub fn camcal_plot_ids(cameras: usize) -> Vec<String> {
    let mut ids = Vec::new();
    // The residual plots of all cameras come first, then the coverage grids.
    for c in 0..cameras {
        for base in &CAMCAL_CAMERA_PLOT_IDS[..2] {
            ids.push(format!("{base}-cam{c}"));
        }
    }
    for c in 0..cameras {
        ids.push(format!("{}-cam{c}", CAMCAL_CAMERA_PLOT_IDS[2]));
    }
    ids.extend(CAMCAL_PLOT_IDS.iter().map(|s| s.to_string()));
    ids
}

/// Extra style of this page: the warning box and the image panels.
const EXTRA_STYLE: &str = "\
.grid{align-items:flex-start}\
.warnbox{border:2px solid #c77700;background:#fff6e5;padding:.3em 1em;margin:.8em 0}\
.warnbox strong{color:#8a4b00}td.pm{font-family:ui-monospace,'DejaVu Sans Mono',monospace;\
white-space:nowrap}.chg{color:#777}svg .c{font:10px sans-serif}\
code{background:#f2f2f2;padding:0 3px}";

/// Renders the report of a camera calibration as one HTML document.
pub fn render_camcal_html(r: &CamCalResult, input: &CamCalReportInput) -> Result<String> {
    let mut s = String::with_capacity(256 * 1024);
    put!(
        s,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <meta name=\"viewport\" content=\"width=device-width,initial-scale=1\">\
         <title>Camera calibration: {}</title><style>{STYLE}{EXTRA_STYLE}</style></head>\
         <body data-report=\"camcal\">\n",
        escape(&input.images)
    );
    summary(&mut s, r, input);
    warnings(&mut s, r);
    results(&mut s, r);
    residuals(&mut s, r);
    coverage(&mut s, r);
    frames(&mut s, r);
    camchain(&mut s, input);
    s.push_str("</body></html>\n");
    Ok(s)
}

fn camchain(s: &mut String, input: &CamCalReportInput) {
    section(s, "camchain", "Camchain file");
    if input.camchain_yaml.is_empty() {
        match &input.camchain_path {
            Some(p) => put!(s, "<p>Written to {}.</p>", escape(p)),
            None => s.push_str("<p>No camchain file was written with this report.</p>"),
        }
    } else {
        put!(
            s,
            "<details open><summary>{}</summary><pre>{}</pre></details>",
            escape(input.camchain_path.as_deref().unwrap_or("camchain.yaml")),
            escape(&input.camchain_yaml)
        );
    }
    if let Some(c) = &input.command {
        put!(s, "<p>Command: <code>{}</code></p>", escape(c));
    }
    s.push_str("</section>\n");
}

#[cfg(test)]
#[path = "cameras_tests.rs"]
mod tests;
