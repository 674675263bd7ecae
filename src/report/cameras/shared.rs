//! What the sections of the camera calibration's report share: the cameras' colours, the
//! frames that were dropped, whether a coverage grid can be drawn and whether it is poor, and
//! small number formats.

use crate::camcal::quality::{MIN_COVERED_FRACTION, MIN_RADIAL_REACH};
use crate::camcal::{CamCalResult, Coverage, FrameFit};

/// Colours of the cameras (cam n takes entry n modulo the length).
const CAM_COLORS: [&str; 6] = [
    "#1a63c2", "#e8710a", "#2a9d3a", "#c2185b", "#6a3d9a", "#8c564b",
];
pub(super) const REJECTED: &str = "#d62728";
/// Largest coverage grid drawn (a finer one is not shown).
pub(super) const MAX_GRID_CELLS: usize = 10_000;

pub(super) fn cam_color(c: usize) -> &'static str {
    CAM_COLORS[c % CAM_COLORS.len()]
}

/// Whether a coverage grid can be drawn: its counts fill it, and it has at most
/// [`MAX_GRID_CELLS`] cells.
pub(super) fn grid_ok(g: &Coverage) -> bool {
    g.cols
        .checked_mul(g.rows)
        .is_some_and(|n| n > 0 && n <= MAX_GRID_CELLS && g.counts.len() == n)
}

/// Whether a coverage leaves the distortion unmeasured over part of the image.
pub(super) fn coverage_poor(c: &Coverage) -> bool {
    !(c.covered_fraction >= MIN_COVERED_FRACTION && c.radial_reach >= MIN_RADIAL_REACH)
}

pub(super) fn plural(n: usize, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

pub(super) fn px(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.3} px")
    } else {
        "n/a".to_owned()
    }
}

/// The frames that were not used.
pub(super) fn dropped_frames(r: &CamCalResult) -> Vec<&FrameFit> {
    r.frames.iter().filter(|f| f.dropped.is_some()).collect()
}
