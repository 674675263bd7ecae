//! The camera trajectory section of the DVL report: the pose residuals against the fitted
//! trajectory, a top view of both, and the fit's settings and figures.

use std::fmt::Write as _;

use nalgebra::Vector3;

use super::data::Derived;
use super::html::{AFTER, BEFORE, HALF, MEASURED, WIDE, figure, put, section, upper};
use super::input::ReportInput;
use super::svg::{Plot, Series, escape};

pub(super) fn trajectory(s: &mut String, input: &ReportInput, d: &Derived) {
    let o = input.outcome;
    section(s, "trajectory-fit", "Camera trajectory and its fit");
    let pos: Vec<(f64, f64)> = d.pose_residuals.iter().map(|r| (r.0, 1e3 * r.1)).collect();
    let rot: Vec<(f64, f64)> = d
        .pose_residuals
        .iter()
        .map(|r| (r.0, r.2.to_degrees()))
        .collect();
    s.push_str("<div class=\"grid\">");
    for (id, title, unit, pts) in [
        ("pose-residual-pos", "Position residual per pose", "mm", pos),
        (
            "pose-residual-rot",
            "Rotation residual per pose",
            "deg",
            rot,
        ),
    ] {
        let top = upper(&pts);
        let plot = Plot::new(id, title, "camera time (s)", unit)
            .size(HALF, 230.0)
            .y_range(0.0, top)
            .series(Series::dots("", AFTER, pts).size(2.5));
        s.push_str(&plot.render());
    }
    s.push_str("</div>");
    let (i, j) = d.plane;
    let names = ["x", "y", "z"];
    let proj = |p: &[Vector3<f64>]| -> Vec<(f64, f64)> { p.iter().map(|v| (v[i], v[j])).collect() };
    let mut plot = Plot::new(
        "trajectory",
        "Camera positions, top view",
        &format!("world {} (m)", names[i]),
        &format!("world {} (m)", names[j]),
    )
    .size(WIDE, 520.0)
    .equal_aspect()
    .series(Series::line("GP fit", AFTER, proj(&d.fitted_path)).size(1.5))
    .series(Series::dots("measured poses", MEASURED, proj(&d.measured_path)).size(2.5));
    if let Some(first) = d.measured_path.first() {
        plot = plot.series(Series::dots("start", BEFORE, vec![(first[i], first[j])]).size(9.0));
    }
    let fit = &o.trajectory;
    figure(
        s,
        &plot,
        &format!(
            "Measured camera positions and the fitted continuous-time trajectory, seen along world \
             {} (the axis of least spread). Pose residuals against the fit: {:.2} mm and {:.3} deg \
             RMS.",
            names[3 - i - j],
            1e3 * fit.residual_rms_pos,
            fit.residual_rms_rot.to_degrees()
        ),
    );
    let q = &fit.qc;
    s.push_str("<table>");
    let rows = [
        (
            "GP jerk power spectral density Qc (v; w)",
            format!(
                "[{:.3e}, {:.3e}, {:.3e}; {:.3e}, {:.3e}, {:.3e}]{}",
                q[0],
                q[1],
                q[2],
                q[3],
                q[4],
                q[5],
                if fit.qc_estimated {
                    " (estimated)"
                } else {
                    " (given)"
                }
            ),
        ),
        (
            "default pose noise (m, rad)",
            format!(
                "{:.2e}, {:.2e}{}",
                fit.pose_sigma.0,
                fit.pose_sigma.1,
                if fit.pose_sigma_estimated {
                    " (estimated)"
                } else {
                    ""
                }
            ),
        ),
        (
            "pose residual RMS",
            format!(
                "{:.2} mm, {:.3} deg",
                1e3 * fit.residual_rms_pos,
                fit.residual_rms_rot.to_degrees()
            ),
        ),
        (
            "fit iterations",
            format!(
                "{}{}",
                fit.iterations,
                if fit.converged {
                    ", converged"
                } else {
                    ", NOT converged"
                }
            ),
        ),
        ("poses", o.counts.poses.to_string()),
    ];
    for (k, v) in rows {
        put!(
            s,
            "<tr><th>{}</th><td class=\"num\">{}</td></tr>",
            escape(k),
            escape(&v)
        );
    }
    s.push_str("</table></section>\n");
}
