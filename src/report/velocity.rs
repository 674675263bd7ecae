//! How the DVL velocities fit: measured against predicted over time for each axis, before and
//! after the refinement, and the residual histograms against the stated noise.

use std::fmt::Write as _;

use super::data::{Derived, Sample};
use super::html::{
    AFTER, AXES, BEFORE, HALF, MEASURED, NOISE, OUTLIER, put, robust_half_range, section,
};
use super::svg::{Histogram, Plot, Series, escape};
use crate::calib::CalibrationOutcome;

pub(super) fn velocity(s: &mut String, d: &Derived) {
    section(s, "velocity", "DVL velocity: measured and predicted");
    s.push_str(
        "<p>Each panel shows one axis of the DVL frame against the DVL clock: the measured \
         velocity (grey dots) and the velocity the camera trajectory predicts through the \
         calibration. On the left with the parameters the refinement started from, on the right \
         with the final ones. Both panels of an axis share the same scale. Red dots are reports \
         the robust loss down-weighted (less than half their weight); shaded stretches have no \
         valid DVL report or no camera pose.</p>\n<div class=\"grid\">",
    );
    for (k, axis) in AXES.iter().enumerate() {
        let measured: Vec<(f64, f64)> =
            d.samples.iter().map(|x| (x.t_dvl, x.measured[k])).collect();
        let before: Vec<(f64, f64)> = d
            .samples
            .iter()
            .map(|x| (x.t_dvl, x.before.map_or(f64::NAN, |b| b[k])))
            .collect();
        let after: Vec<(f64, f64)> = d.samples.iter().map(|x| (x.t_dvl, x.after[k])).collect();
        let downweighted: Vec<(f64, f64)> = d
            .samples
            .iter()
            .filter(|x| x.weight < 0.5)
            .map(|x| (x.t_dvl, x.measured[k]))
            .collect();
        let (lo, hi) = measured
            .iter()
            .chain(&before)
            .chain(&after)
            .map(|p| p.1)
            .filter(|y| y.is_finite())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), y| {
                (a.min(y), b.max(y))
            });
        let pad = 0.05 * (hi - lo).max(1e-6);
        for (when, pred, color) in [("before", before, BEFORE), ("after", after, AFTER)] {
            let title = format!(
                "DVL {axis} velocity, {} calibration",
                if when == "before" {
                    "start of"
                } else {
                    "after"
                }
            );
            let mut plot = Plot::new(
                &format!("velocity-{when}-{axis}"),
                &title,
                "DVL time (s)",
                &format!("v_{axis} (m/s)"),
            )
            .size(HALF, 250.0)
            // The line on top: with dense logs the dots become a band it must stay visible in.
            .series(Series::dots("measured", MEASURED, measured.clone()).size(3.5))
            .series(Series::line("predicted", color, pred).size(1.2))
            .empty_note("no samples");
            if !downweighted.is_empty() {
                plot = plot
                    .series(Series::dots("down-weighted", OUTLIER, downweighted.clone()).size(5.0));
            }
            if !d.dvl_gaps.is_empty() {
                plot = plot.spans("no valid DVL report", d.dvl_gaps.clone());
            }
            if !d.pose_gaps.is_empty() {
                plot = plot.spans("no camera pose", d.pose_gaps.clone());
            }
            if lo.is_finite() && hi.is_finite() {
                plot = plot.y_range(lo - pad, hi + pad);
            }
            s.push_str(&plot.render());
        }
    }
    s.push_str("</div>\n");
    if d.skipped > 0 {
        put!(
            s,
            "<p>{} used samples fall outside the fitted trajectory at the final clock offset and \
             are not shown.</p>\n",
            d.skipped
        );
    }
    s.push_str("</section>\n");
}

pub(super) fn residuals(s: &mut String, o: &CalibrationOutcome, d: &Derived) {
    section(s, "residuals", "Residual histograms");
    s.push_str(
        "<p>Distribution of the DVL residuals (measured minus predicted) per DVL axis with the \
         final parameters (bars), with the starting parameters (dashed outline, same bins), and \
         the normal distribution of the stated DVL noise (green) for comparison.</p>\
         <div class=\"grid\">",
    );
    let mut caption = Vec::new();
    for (k, axis) in AXES.iter().enumerate() {
        let after: Vec<f64> = d
            .samples
            .iter()
            .map(|x| x.measured[k] - x.after[k])
            .collect();
        let before: Vec<f64> = d
            .samples
            .iter()
            .filter_map(|x: &Sample| x.before.map(|b| x.measured[k] - b[k]))
            .collect();
        let half = robust_half_range(&after, 3.0 * d.stated_sigma[k]);
        let bins = (after.len() / 8).clamp(10, 41);
        let ha = Histogram::new(&after, -half, half, bins);
        let hb = Histogram::new(&before, -half, half, bins);
        let sigma = d.stated_sigma[k];
        let n = ha.total() as f64;
        let gauss: Vec<(f64, f64)> = if sigma > 0.0 {
            (0..=200)
                .map(|j| {
                    let x = -half + 2.0 * half * j as f64 / 200.0;
                    let pdf = (-0.5 * (x / sigma).powi(2)).exp()
                        / (sigma * (2.0 * std::f64::consts::PI).sqrt());
                    (x * 1e3, n * ha.width * pdf)
                })
                .collect()
        } else {
            Vec::new()
        };
        // Step outline of the "before" histogram.
        let mut outline = Vec::with_capacity(2 * hb.counts.len() + 2);
        for (j, &c) in hb.counts.iter().enumerate() {
            let x0 = (hb.lo + j as f64 * hb.width) * 1e3;
            let x1 = (hb.lo + (j + 1) as f64 * hb.width) * 1e3;
            outline.push((x0, c as f64));
            outline.push((x1, c as f64));
        }
        let bars: Vec<(f64, f64)> = ha.points().iter().map(|&(x, c)| (x * 1e3, c)).collect();
        let mut plot = Plot::new(
            &format!("residuals-{axis}"),
            &format!("Residuals, DVL {axis}"),
            &format!("residual {axis} (mm/s)"),
            "samples",
        )
        .size(306.0, 250.0)
        .series(Series::bars("after", AFTER, ha.width * 1e3, bars));
        if !before.is_empty() {
            plot = plot.series(Series::line("start", BEFORE, outline).dashed());
        }
        plot = plot.series(Series::line("noise", NOISE, gauss));
        s.push_str(&plot.render());
        caption.push(format!(
            "{axis}: RMS {:.1} mm/s after{}; {} of {} samples outside the range shown after, {} \
             with the start",
            1e3 * d.rms_after[k],
            d.rms_before
                .map(|b| format!(", {:.1} mm/s at the start", 1e3 * b[k]))
                .unwrap_or_default(),
            ha.outside,
            after.len(),
            hb.outside
        ));
    }
    put!(
        s,
        "</div><p class=\"meta\">{}. Normalized cost {:.2}.</p></section>\n",
        escape(&caption.join("; ")),
        o.normalized_cost
    );
}
