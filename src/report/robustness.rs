//! The robustness section of the DVL report: the outliers and their weights, the residuals'
//! autocorrelation, and the comparison of the recording's two halves.

use std::fmt::Write as _;

use super::html::{AXES, AXIS_COLORS, NOISE, WIDE, figure, put, section};
use super::svg::{Plot, Series, escape};
use crate::calib::CalibrationOutcome;

pub(super) fn robustness(s: &mut String, o: &CalibrationOutcome) {
    section(
        s,
        "robustness",
        "Outliers, correlated errors and consistency",
    );
    put!(
        s,
        "<p>{}. Loss: <b>{}</b>{}.</p>\n",
        escape(&o.usable_words()),
        o.robust.loss.name(),
        match (&o.robust.dvl.applied, &o.robust.poses.applied) {
            (None, None) => " (not applied: no residual was an outlier)",
            _ => "",
        }
    );
    for (what, sum, clock) in [
        ("DVL reports", &o.robust.dvl, "DVL"),
        ("camera poses", &o.robust.poses, "camera"),
    ] {
        if sum.worst.is_empty() {
            continue;
        }
        put!(
            s,
            "<p>The worst {what} ({} outliers of {}; threshold {:.1} variances, noise {:.2} times \
             the stated variance):</p>\n<table><tr><th>time ({clock} clock, s)</th>\
             <th>squared residual (variances)</th><th>weight</th></tr>",
            sum.outliers,
            sum.factors,
            sum.threshold,
            sum.noise_scale
        );
        for w in &sum.worst {
            put!(
                s,
                "<tr><td>{:.3}</td><td>{:.0}</td><td>{:.3}</td></tr>",
                w.t,
                w.s,
                w.weight
            );
        }
        s.push_str("</table>\n");
    }
    let wh = &o.whiteness;
    if !wh.lag_s.is_empty() {
        let shown = wh
            .lag_s
            .len()
            .min(((10.0 * wh.window.max(10) as f64) as usize).max(20));
        let mut plot = Plot::new(
            "residual-acf",
            "Autocorrelation of the DVL residuals",
            "lag (s)",
            "autocorrelation",
        )
        .size(WIDE, 260.0);
        for (k, axis) in AXES.iter().enumerate() {
            let pts: Vec<(f64, f64)> = wh.lag_s[..shown]
                .iter()
                .zip(&wh.acf[k])
                .map(|(&l, &r)| (l, r))
                .collect();
            plot = plot.series(
                Series::line(
                    &format!("{axis} (tau {:.1})", wh.tau[k]),
                    AXIS_COLORS[k],
                    pts,
                )
                .size(1.2),
            );
        }
        let n = o.used.len().max(1) as f64;
        let band = 2.0 / n.sqrt();
        let end = wh.lag_s[shown - 1];
        plot = plot
            .series(
                Series::line("white-noise band", NOISE, vec![(0.0, band), (end, band)]).dashed(),
            )
            .series(Series::line("", NOISE, vec![(0.0, -band), (end, -band)]).dashed());
        figure(
            s,
            &plot,
            &if wh.correlated {
                format!(
                    "The residuals are correlated: an integrated autocorrelation time of {:.1} \
                     samples ({:.2} s) where white noise gives 1 ± {:.2}. The DVL reports' \
                     information was divided by {:.1} (an effective sample size) before the \
                     standard deviations were computed.",
                    wh.inflation,
                    wh.inflation * wh.sample_interval_s,
                    wh.tau_noise,
                    wh.inflation
                )
            } else {
                format!(
                    "The residuals are white within what chance allows (integrated \
                     autocorrelation times {:.1}, {:.1}, {:.1} samples; white noise gives \
                     1 ± {:.2}): the standard deviations need no inflation for correlation.",
                    wh.tau[0], wh.tau[1], wh.tau[2], wh.tau_noise
                )
            },
        );
    }
    if let Some(h) = &o.halves {
        put!(
            s,
            "<p>The recording split at DVL time {:.2} s and each half calibrated on its own. A \
             parameter whose halves differ by more than three standard deviations has its \
             standard deviation inflated to cover the difference; one that a half does not \
             determine is not compared.</p>\n<table><tr><th>parameter</th><th>first half</th>\
             <th>second half</th><th>difference</th><th>std of difference</th>\
             <th>difference / std</th><th>std inflated by</th></tr>",
            h.split_t
        );
        let value = |p: &crate::types::CalibrationParams, k: usize| -> String {
            match k {
                3..=5 => format!("{:.1}", 1e3 * p.lever_arm_cam_m()[k - 3]),
                6 => format!("{:.5}", p.velocity_scale),
                7 => format!("{:.2}", 1e3 * p.time_offset_s),
                _ => "".into(),
            }
        };
        for (k, &(name, f, unit)) in crate::calib::PARAM_NAMES.iter().enumerate() {
            let name = if unit.is_empty() {
                name.to_string()
            } else {
                format!("{name} ({unit})")
            };
            let z = if h.compared[k] {
                format!("{:.1}", h.z(k))
            } else {
                "not compared".into()
            };
            put!(
                s,
                "<tr><td>{name}</td><td>{}</td><td>{}</td><td>{:+.4}</td><td>{:.4}</td>\
                 <td>{z}</td><td>{}</td></tr>",
                value(&h.first, k),
                value(&h.second, k),
                h.difference[k] * f,
                h.difference_std[k] * f,
                if h.inflation[k] > 1.0 {
                    format!("<b>{:.1}</b>", h.inflation[k])
                } else {
                    "1".into()
                }
            );
        }
        s.push_str("</table>\n");
    }
    s.push_str("</section>\n");
}
