//! The refinement section of the DVL report: the cost after each round, and each round's
//! parameters.

use std::fmt::Write as _;

use super::html::{AFTER, HALF, put, section, vec3};
use super::svg::{Plot, Series, escape};
use crate::calib::CalibrationOutcome;

pub(super) fn refinement(s: &mut String, o: &CalibrationOutcome) {
    section(s, "refinement", "Refinement");
    let pts: Vec<(f64, f64)> = o
        .iterations
        .iter()
        .enumerate()
        .map(|(k, it)| ((k + 1) as f64, it.cost))
        .collect();
    let positive: Vec<f64> = pts
        .iter()
        .map(|p| p.1)
        .filter(|c| c.is_finite() && *c > 0.0)
        .collect();
    let lo = positive.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = positive.iter().copied().fold(0.0, f64::max);
    let mut plot = Plot::new(
        "cost",
        "DVL cost after each refinement round",
        "iteration",
        "weighted squared residuals",
    )
    .size(HALF, 260.0)
    .integer_x()
    .series(Series::line("", AFTER, pts.clone()).size(1.5))
    .series(Series::dots("", AFTER, pts).size(5.0));
    if positive.len() == o.iterations.len() && hi > 20.0 * lo {
        plot = plot.log_y();
    }
    if o.iterations.len() == 1 {
        plot = plot.x_range(0.5, 1.5);
    }
    s.push_str("<div class=\"grid\">");
    s.push_str(&plot.render());
    s.push_str(
        "<div><table><tr><th>round</th><th>cost</th><th>offset (s)</th><th>scale</th>\
         <th>lever arm (m)</th></tr>",
    );
    for (k, it) in o.iterations.iter().enumerate() {
        put!(
            s,
            "<tr><td>{}</td><td class=\"num\">{:.6e}</td><td class=\"num\">{:.5}</td>\
             <td class=\"num\">{:.5}</td><td class=\"num\">{}</td></tr>",
            k + 1,
            it.cost,
            it.params.time_offset_s,
            it.params.velocity_scale,
            escape(&vec3(&it.params.lever_arm_cam_m(), 1.0, 4))
        );
    }
    s.push_str("</table></div></div>");
    put!(
        s,
        "<p>{}</p></section>\n",
        escape(&format!(
            "Each round updates the calibration with the trajectory fixed, then the trajectory with \
             the calibration fixed. {} round{}.",
            o.iterations.len(),
            if o.iterations.len() == 1 { "" } else { "s" }
        ))
    );
}
