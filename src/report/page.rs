//! The HTML page of the report: sections, tables, sentences and the plots.

use std::fmt::Write as _;

use nalgebra::Vector3;

use super::data::{Derived, Sample};
use super::input::{FrameStat, ReportInput};
use super::svg::{Histogram, Plot, Series, escape};
use crate::calib::offset::OffsetMethod;
use crate::calib::{CalibrationOutcome, DeterminedBy, Method, Verdict};
use crate::io::dvl::DvlLogStats;

const MEASURED: &str = "#6b6b6b";
const BEFORE: &str = "#e8710a";
const AFTER: &str = "#1a63c2";
const NOISE: &str = "#2a9d3a";
const LEVER: &str = "#c2185b";
const OUTLIER: &str = "#d62728";
const AXES: [&str; 3] = ["x", "y", "z"];
const AXIS_COLORS: [&str; 3] = ["#d62728", "#2ca02c", "#1f77b4"];

/// Full width and half width of a plot, pixels.
const WIDE: f64 = 940.0;
const HALF: f64 = 462.0;

/// The page's style sheet (shared with the camera calibration report).
pub(super) const STYLE: &str = "\
body{font-family:system-ui,-apple-system,'Segoe UI',Roboto,'DejaVu Sans',sans-serif;\
margin:0 auto;max-width:980px;padding:16px 20px 48px;color:#1d1d1d;line-height:1.45}\
h1{font-size:1.6em;margin:.4em 0 .2em}h2{font-size:1.25em;margin:1.6em 0 .4em;\
border-bottom:1px solid #ccc;padding-bottom:.2em}\
.meta{color:#555;font-size:.92em}table{border-collapse:collapse;margin:.6em 0;font-size:.92em}\
th,td{border:1px solid #d0d0d0;padding:3px 8px;text-align:left;vertical-align:top}\
th{background:#f2f2f2}td.num{font-family:ui-monospace,'DejaVu Sans Mono',monospace;\
white-space:nowrap}.ok{color:#1b7a2a;font-weight:600}.weak{color:#b3261e;font-weight:600}\
.fixed{color:#555;font-weight:600}td.fixed-cell{color:#777;background:#f4f4f4;font-style:italic}\
table.corr td{text-align:right}.start{color:#777;font-size:.9em;font-weight:400}ul.warn li{color:#8a4b00}.failed{border:2px solid #b00020;background:#fdecee;padding:.2em 1em;margin:1em 0}.failed strong{color:#b00020}.verdicts li{margin:.25em 0}\
.grid{display:flex;flex-wrap:wrap;gap:8px 16px}figure{margin:.4em 0}\
figcaption{font-size:.88em;color:#444;max-width:940px}\
svg.plot{max-width:100%;height:auto;border:1px solid #e2e2e2}\
svg .t{font:600 13px sans-serif;fill:#222}svg .a{font:12px sans-serif;fill:#333}\
svg .k{font:11px sans-serif;fill:#444}svg .l{font:11px sans-serif;fill:#333}\
svg .m{font:11px sans-serif}svg .n{font:13px sans-serif;fill:#777}\
svg .g{stroke:#e4e4e4;stroke-width:1}svg .sp{fill:#ffe08a;fill-opacity:.55}\
pre{background:#f6f6f6;padding:8px;overflow:auto;font-size:.85em}\
details summary{cursor:pointer}";

/// Writes one formatted piece into the page (writing to a String cannot fail).
macro_rules! put {
    ($s:expr, $($arg:tt)*) => {{
        let _ = write!($s, $($arg)*);
    }};
}
pub(super) use put;

fn vec3(v: &Vector3<f64>, scale: f64, decimals: usize) -> String {
    format!(
        "[{:.d$}, {:.d$}, {:.d$}]",
        v.x * scale,
        v.y * scale,
        v.z * scale,
        d = decimals
    )
}

fn quat(q: &[f64; 4]) -> String {
    format!("[{:.5}, {:.5}, {:.5}, {:.5}]", q[0], q[1], q[2], q[3])
}

fn percent(x: f64) -> String {
    format!("{:.1}%", 100.0 * x)
}

/// Whether the method estimated a group of parameters (rotation and lever arm, or clock offset
/// and scale).
fn estimated(m: &Method, extrinsic: bool) -> bool {
    match m {
        Method::Uic | Method::Bcd(_) => true,
        Method::Fixed {
            estimate_offset, ..
        } => !extrinsic && *estimate_offset,
    }
}

fn method_words(m: &Method) -> &'static str {
    match m {
        Method::Uic => "UIC: initialised from the data alone, then refined",
        Method::Bcd(_) => "refinement from the given initial guess",
        Method::Fixed {
            estimate_offset: true,
            ..
        } => "extrinsics held at the given values; clock offset and scale estimated",
        Method::Fixed { .. } => "all parameters held at the given values (evaluation only)",
    }
}

/// The verdict cell of the results table.
fn verdict_cell(v: &Verdict, free: bool) -> &'static str {
    if !free {
        "<span class=\"fixed\">fixed (from --init)</span>"
    } else if v.by == DeterminedBy::Prior {
        "<span class=\"weak\">from the prior</span>"
    } else if v.ok {
        "<span class=\"ok\">well determined</span>"
    } else {
        "<span class=\"weak\">weakly observable</span>"
    }
}

/// One sentence on one parameter; `spread` describes its standard deviation (weak verdicts
/// already quote it in their reason).
fn verdict_sentence(name: &str, v: &Verdict, free: bool, spread: &str) -> String {
    if !free {
        format!(
            "{name} was not estimated: it stays at the value given with --init and has no \
             standard deviation."
        )
    } else if v.by == DeterminedBy::Prior {
        format!(
            "{name} comes from its prior rather than the data: {}.",
            v.reason.trim_end_matches('.')
        )
    } else if v.ok {
        format!("{name} is well determined: its standard deviation is {spread}.")
    } else {
        format!(
            "{name} is weakly observable: {}. Do not rely on this value without a recording that \
             excites it better.",
            v.reason.trim_end_matches('.')
        )
    }
}

pub(super) fn render(input: &ReportInput, d: &Derived) -> String {
    let o = input.outcome;
    let mut s = String::with_capacity(256 * 1024);
    put!(
        s,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <meta name=\"viewport\" content=\"width=device-width,initial-scale=1\">\
         <title>{}</title><style>{STYLE}</style></head><body>\n",
        escape(input.title)
    );
    summary(&mut s, input, d);
    results(&mut s, o, input.dvl_stats.and_then(|st| st.sound_speed_mps));
    s.push_str(&super::correlation::correlation_section(o));
    warnings(&mut s, input);
    s.push_str(&super::timeline::residual_time_section(
        &d.samples,
        &d.dvl_gaps,
    ));
    velocity(&mut s, d);
    robustness(&mut s, o);
    residuals(&mut s, o, d);
    motion(&mut s, o, d);
    clock_offset(&mut s, o);
    refinement(&mut s, o);
    frames(&mut s, input.frames);
    s.push_str(&super::reprojection::reprojection_section(
        input.frames,
        input.image_sizes,
    ));
    trajectory(&mut s, input, d);
    dvl_log(&mut s, input.dvl_stats, o);
    result_file(&mut s, input);
    s.push_str("</body></html>\n");
    s
}

pub(super) fn section(s: &mut String, id: &str, title: &str) {
    put!(s, "<section id=\"{id}\"><h2>{}</h2>\n", escape(title));
}

pub(super) fn figure(s: &mut String, plot: &Plot, caption: &str) {
    put!(
        s,
        "<figure>{}<figcaption>{}</figcaption></figure>\n",
        plot.render(),
        escape(caption)
    );
}

fn summary(s: &mut String, input: &ReportInput, d: &Derived) {
    let o = input.outcome;
    put!(
        s,
        "<section id=\"summary\"><h1>{}</h1><p class=\"meta\">",
        escape(input.title)
    );
    if !input.dataset.is_empty() {
        put!(s, "{}<br>", escape(input.dataset));
    }
    put!(
        s,
        "dvlcal {}; method: {}",
        env!("CARGO_PKG_VERSION"),
        escape(method_words(&o.method))
    );
    if let Some(t) = input.elapsed_s.filter(|t| t.is_finite()) {
        put!(s, "; calibration took {t:.2} s");
    }
    s.push_str("</p>\n");
    if let crate::calib::Status::Failed(reasons) = &o.status {
        s.push_str(
            "<div id=\"failed\" class=\"failed\"><p><strong>Calibration failed: this result \
             cannot be trusted.</strong> No ROS or Kalibr exports were written.</p><ul>",
        );
        for r in reasons {
            put!(s, "<li>{}</li>", escape(r));
        }
        s.push_str("</ul></div>\n");
    }

    let v = &o.verdicts;
    let ext = estimated(&o.method, true);
    let tim = estimated(&o.method, false);
    let judged = [
        ("the rotation", &v.rotation, ext),
        ("the lever arm", &v.lever_arm, ext),
        ("the clock offset", &v.time_offset, tim),
        ("the velocity scale", &v.velocity_scale, tim),
    ];
    let weak: Vec<&str> = judged
        .iter()
        .filter(|(_, v, free)| *free && !v.ok)
        .map(|(n, _, _)| *n)
        .collect();
    let free = judged.iter().filter(|j| j.2).count();
    let headline = if free == 0 {
        "Nothing was estimated: this run only evaluates the given calibration against the data."
            .to_owned()
    } else if weak.is_empty() {
        format!(
            "All {free} estimated quantities are well determined by this recording \
             (details and standard deviations below)."
        )
    } else {
        format!(
            "Attention: {} {} weakly observable with this recording; the other estimates are \
             well determined.",
            join_words(&weak),
            if weak.len() == 1 { "is" } else { "are" }
        )
    };
    put!(s, "<p><strong>{}</strong></p>\n", escape(&headline));
    let mut words = format!(
        "After calibration the DVL velocities differ from the camera's prediction by {} mm/s RMS \
         (x, y, z)",
        vec3(&d.rms_after, 1e3, 1)
    );
    if let Some(b) = d.rms_before {
        let _ = write!(
            words,
            ", against {} mm/s with the starting parameters",
            vec3(&b, 1e3, 1)
        );
    }
    let _ = write!(
        words,
        ". The stated DVL noise is {} mm/s; the weighted residuals are {:.2} times what that \
         noise explains (about 1 is right, much more means the noise is understated or the model \
         does not fit). {} DVL samples of {} were used, with {} camera poses.",
        vec3(&d.stated_sigma, 1e3, 1),
        o.normalized_cost,
        o.counts.dvl_used,
        o.counts.dvl_samples,
        o.counts.poses
    );
    put!(s, "<p>{}</p></section>\n", escape(&words));
}

pub(super) fn join_words(w: &[&str]) -> String {
    match w {
        [] => String::new(),
        [a] => (*a).to_owned(),
        [a @ .., b] => format!("{} and {b}", a.join(", ")),
    }
}

fn results(s: &mut String, o: &CalibrationOutcome, sound_speed: Option<f64>) {
    section(s, "results", "Results");
    let c = o.params;
    let c0 = o.start;
    let st = &o.std;
    let ext = estimated(&o.method, true);
    let tim = estimated(&o.method, false);
    s.push_str(
        "<table><tr><th>quantity</th><th>estimate <span class=\"start\">(refinement start)</span>\
         </th><th>standard deviation</th><th>verdict</th></tr>\n",
    );
    let rows = [
        (
            "rotation, quaternion_cam_dvl_xyzw (std about DVL x, y, z)",
            quat(&c.t_cam_dvl.quaternion_xyzw()),
            format!("{} deg", vec3(&st.rotation_deg, 1.0, 3)),
            quat(&c0.t_cam_dvl.quaternion_xyzw()),
            verdict_cell(&o.verdicts.rotation, ext),
        ),
        (
            "lever arm p_cam_dvl (m, camera frame)",
            vec3(&o.params.lever_arm_cam_m(), 1.0, 4),
            format!("{} mm", vec3(&st.lever_arm_m, 1e3, 2)),
            vec3(&o.start.lever_arm_cam_m(), 1.0, 4),
            verdict_cell(&o.verdicts.lever_arm, ext),
        ),
        (
            "clock offset time_offset_s (t_cam = t_dvl + offset)",
            format!("{:.5} s", o.params.time_offset_s),
            format!("{:.2} ms", 1e3 * st.time_offset_s),
            format!("{:.5} s", o.start.time_offset_s),
            verdict_cell(&o.verdicts.time_offset, tim),
        ),
        (
            "velocity scale",
            format!("{:.5}", o.params.velocity_scale),
            format!("{:.5}", st.velocity_scale),
            format!("{:.5}", o.start.velocity_scale),
            verdict_cell(&o.verdicts.velocity_scale, tim),
        ),
    ];
    for (name, est, sd, start, verdict) in rows {
        // A held parameter has no standard deviation.
        let sd = if verdict.contains("fixed") {
            "none (held)".to_owned()
        } else {
            sd
        };
        put!(
            s,
            "<tr><td>{}</td><td class=\"num\">{}<br><span class=\"start\">({})</span></td>\
             <td class=\"num\">{}</td><td>{verdict}</td></tr>\n",
            escape(name),
            escape(&est),
            escape(&start),
            escape(&sd)
        );
    }
    s.push_str("</table>\n<ul class=\"verdicts\">");
    let sentences = [
        verdict_sentence(
            "The rotation",
            &o.verdicts.rotation,
            ext,
            &format!("at most {:.3} deg about any axis", st.rotation_deg.max()),
        ),
        verdict_sentence(
            "The lever arm",
            &o.verdicts.lever_arm,
            ext,
            &format!(
                "at most {:.2} mm along any axis",
                1e3 * st.lever_arm_m.max()
            ),
        ),
        verdict_sentence(
            "The clock offset",
            &o.verdicts.time_offset,
            tim,
            &format!("{:.2} ms", 1e3 * st.time_offset_s),
        ),
        verdict_sentence(
            "The velocity scale",
            &o.verdicts.velocity_scale,
            tim,
            &format!(
                "{:.5} ({:.2}%)",
                st.velocity_scale,
                100.0 * st.velocity_scale
            ),
        ),
    ];
    for line in sentences {
        put!(s, "<li>{}</li>", escape(&line));
    }
    s.push_str("</ul>\n");
    if tim {
        put!(
            s,
            "<p id=\"sound-speed\">Velocity scale as a speed of sound: {}.</p>\n",
            escape(&super::words::sound_speed_words(
                c.velocity_scale,
                st.velocity_scale,
                sound_speed
            ))
        );
    }
    s.push_str(&super::rotation::rotation_table(
        &c.t_cam_dvl.rot,
        &c0.t_cam_dvl.rot,
    ));
    let r = c.t_cam_dvl.rot;
    put!(
        s,
        "<p>R_cam_dvl (rotates DVL-frame vectors into the camera frame):</p><pre>",
    );
    for i in 0..3 {
        put!(
            s,
            "[{:+.6}, {:+.6}, {:+.6}]\n",
            r[(i, 0)],
            r[(i, 1)],
            r[(i, 2)]
        );
    }
    s.push_str("</pre></section>\n");
}

/// The log's warnings, the calibration's, and one per weak verdict.
fn all_warnings(input: &ReportInput) -> Vec<String> {
    let o = input.outcome;
    let mut w: Vec<String> = input
        .dvl_stats
        .map(|st| st.warnings.clone())
        .unwrap_or_default();
    w.extend(o.warnings.iter().cloned());
    let ext = estimated(&o.method, true);
    let tim = estimated(&o.method, false);
    for (name, v, free) in [
        ("rotation", &o.verdicts.rotation, ext),
        ("lever arm", &o.verdicts.lever_arm, ext),
        ("time offset", &o.verdicts.time_offset, tim),
        ("velocity scale", &o.verdicts.velocity_scale, tim),
    ] {
        if free && !v.ok {
            w.push(format!("{name} is weakly observable: {}", v.reason));
        }
    }
    w
}

fn warnings(s: &mut String, input: &ReportInput) {
    section(s, "warnings", "Warnings");
    let w = all_warnings(input);
    if w.is_empty() {
        s.push_str("<p>No warnings.</p>");
    } else {
        put!(
            s,
            "<p>{} warning{}:</p><ul class=\"warn\">",
            w.len(),
            if w.len() == 1 { "" } else { "s" }
        );
        for line in &w {
            put!(s, "<li>{}</li>", escape(line));
        }
        s.push_str("</ul>");
    }
    s.push_str("</section>\n");
}

fn velocity(s: &mut String, d: &Derived) {
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

fn robustness(s: &mut String, o: &CalibrationOutcome) {
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

/// Symmetric range holding all but the 0.1% most extreme values of `v`, at least `floor` wide.
pub(super) fn robust_half_range(v: &[f64], floor: f64) -> f64 {
    super::svg::abs_quantile(v, 0.999).max(floor).max(1e-6)
}

fn residuals(s: &mut String, o: &CalibrationOutcome, d: &Derived) {
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

fn motion(s: &mut String, o: &CalibrationOutcome, d: &Derived) {
    section(s, "motion", "Motion: rotation and lever-arm excitation");
    let norm: Vec<(f64, f64)> = d.angular.iter().map(|(t, w)| (*t, w.norm())).collect();
    let mut plot = Plot::new(
        "angular-velocity",
        "Angular velocity of the camera (fitted trajectory)",
        "camera time (s)",
        "rad/s",
    )
    .size(WIDE, 280.0);
    if !d.calm_spans.is_empty() {
        plot = plot.spans("calm samples (clock offset)", d.calm_spans.clone());
    }
    for (k, axis) in AXES.iter().enumerate() {
        let comp: Vec<(f64, f64)> = d.angular.iter().map(|(t, w)| (*t, w[k])).collect();
        plot = plot.series(Series::line(&format!("w_{axis}"), AXIS_COLORS[k], comp).size(1.0));
    }
    plot = plot.series(Series::line("|w|", "#111", norm).size(1.6));
    let calm_words = match &o.init {
        Some(i) => format!(
            "Shaded: the {} DVL samples slow enough in rotation to be used for the clock-offset \
             search ({}).",
            i.offset.calm.len(),
            match i.offset.method {
                OffsetMethod::CalmSubset => "they were used",
                OffsetMethod::SpeedCorrelation =>
                    "too few; the search used the speed of all samples instead",
            }
        ),
        None => "No clock-offset search was run with this method, so no calm subset is shaded."
            .to_owned(),
    };
    figure(
        s,
        &plot,
        &format!(
            "Body angular velocity of the camera per axis and its norm. RMS angular speed over the \
             DVL samples used: {:.3} rad/s. {calm_words}",
            o.excitation.rms_angular_speed
        ),
    );

    let speed: Vec<(f64, f64)> = d.samples.iter().map(|x| (x.t_cam, x.speed)).collect();
    let lever: Vec<(f64, f64)> = d.samples.iter().map(|x| (x.t_cam, x.lever)).collect();
    let plot = Plot::new(
        "lever-arm",
        "Lever-arm velocity |w × p| against camera speed |v|",
        "camera time (s)",
        "m/s",
    )
    .size(WIDE, 260.0)
    .series(Series::line("|v| camera speed", AFTER, speed).size(1.2))
    .series(Series::line("|w × p| lever-arm term", LEVER, lever).size(1.4));
    let ratio = o.excitation.lever_arm_ratio;
    let lever_std_mm = 1e3 * o.std.lever_arm_m.max();
    let ext = estimated(&o.method, true);
    let judgement = if !ext {
        "The lever arm was held fixed in this run.".to_owned()
    } else if o.verdicts.lever_arm.ok {
        format!(
            "This motion makes the lever arm observable: it shows in the DVL velocities strongly \
             enough to fix it to {lever_std_mm:.2} mm (largest standard deviation)."
        )
    } else {
        format!(
            "With this motion the lever arm is weakly observable ({lever_std_mm:.2} mm largest \
             standard deviation): {}",
            o.verdicts.lever_arm.reason
        )
    };
    figure(
        s,
        &plot,
        &format!(
            "The DVL sees the camera speed plus the lever-arm term w × p; only that term carries \
             information about the lever arm. Over the samples used it is {} of the speed (RMS \
             ratio). {judgement}",
            percent(ratio)
        ),
    );
    s.push_str("</section>\n");
}

/// A y axis top for non-negative data starting at zero: the largest value and some room.
pub(super) fn upper(pts: &[(f64, f64)]) -> f64 {
    let m = pts
        .iter()
        .map(|p| p.1)
        .filter(|y| y.is_finite())
        .fold(0.0, f64::max);
    if m > 0.0 { 1.08 * m } else { 1.0 }
}

/// A curve divided by its smallest positive value.
fn relative(curve: &[(f64, f64)]) -> Vec<(f64, f64)> {
    let m = curve
        .iter()
        .map(|c| c.1)
        .filter(|v| v.is_finite() && *v > 0.0)
        .fold(f64::INFINITY, f64::min);
    if !m.is_finite() {
        return curve.to_vec();
    }
    curve.iter().map(|&(x, y)| (x, y / m)).collect()
}

fn clock_offset(s: &mut String, o: &CalibrationOutcome) {
    section(s, "clock-offset", "Clock offset");
    let init = o.init.as_ref();
    let (coarse, fine) = match init {
        Some(i) => (relative(&i.offset.coarse_curve), relative(&i.offset.curve)),
        None => (Vec::new(), Vec::new()),
    };
    let note = "no clock-offset search in this method";
    let mut global = Plot::new(
        "offset-global",
        "Speed correlation over every clock offset at which the logs overlap",
        "clock offset (s)",
        "correlation",
    )
    .size(WIDE, 240.0)
    .empty_note(note);
    if let Some(i) = init {
        let a = &i.offset.alignment;
        global = global
            .series(Series::line("", AFTER, a.curve.clone()).size(1.2))
            .marker(a.lag_s, &format!("best {:.2} s", a.lag_s), BEFORE);
        if let Some(l) = a.second_lag_s {
            global = global.marker(l, &format!("second {l:.2} s"), LEVER);
        }
    }
    s.push_str(&global.render());
    for (id, title, curve) in [
        (
            "offset-coarse",
            "Speed objective over the whole range",
            coarse,
        ),
        ("offset-fine", "Objective near the optimum", fine),
    ] {
        let mut plot = Plot::new(id, title, "clock offset (s)", "objective / minimum")
            .size(HALF, 260.0)
            .series(Series::line("", AFTER, curve.clone()).size(1.6))
            .empty_note(note);
        if curve.len() <= 80 {
            plot = plot.series(Series::dots("", AFTER, curve).size(3.5));
        }
        if let Some(i) = init {
            plot = plot.marker(
                i.offset.offset,
                &format!("search {:.4} s", i.offset.offset),
                BEFORE,
            );
        }
        if id == "offset-fine" || init.is_none() {
            plot = plot.marker(
                o.params.time_offset_s,
                &format!("final {:.4} s", o.params.time_offset_s),
                NOISE,
            );
        }
        if id == "offset-coarse" {
            s.push_str("<div class=\"grid\">");
        }
        s.push_str(&plot.render());
    }
    s.push_str("</div>");
    let words = match init {
        Some(i) => format!(
            "{} The offset search then compares DVL speeds with camera speeds shifted by each \
             candidate offset within {:.2} s of it; the velocity scale is solved exactly at each. It \
             first covers that window on a spread of samples, then the neighbourhood of its best \
             value on {}. \
             It found {:.4} s (scale {:.4}); the refinement then moved it to {:.4} s \
             (standard deviation {:.2} ms). A sharp, single minimum means a well-defined offset.",
            alignment_words(&i.offset.alignment),
            0.5 * (i.offset.searched.1 - i.offset.searched.0),
            match i.offset.method {
                OffsetMethod::CalmSubset => format!(
                    "the {} calm samples, where the lever arm cannot blur the speeds",
                    i.offset.calm.len()
                ),
                OffsetMethod::SpeedCorrelation =>
                    "all samples, since too few were calm (the lever arm adds noise)".to_owned(),
            },
            i.offset.offset,
            i.offset.scale,
            o.params.time_offset_s,
            1e3 * o.std.time_offset_s
        ),
        None => format!(
            "This method starts from the given clock offset {:.4} s without a search; final value \
             {:.4} s.",
            o.start.time_offset_s, o.params.time_offset_s
        ),
    };
    put!(s, "<p>{}</p></section>\n", escape(&words));
}

/// The global alignment in words: the lag, how well the speeds match there, and how unique it is.
fn alignment_words(a: &crate::calib::align::ClockAlignment) -> String {
    let second = match (a.second_lag_s, a.second_correlation) {
        (Some(l), Some(c)) => format!(
            "; the best other offset, {l:.2} s, reaches {c:.3} ({:.2} times less{})",
            a.uniqueness(),
            if a.ambiguous {
                ", too close: the offset is ambiguous"
            } else {
                ""
            }
        ),
        _ => String::new(),
    };
    format!(
        "Over every clock offset at which the two logs overlap ({} offsets at {:.3} s steps), the \
         DVL speeds match the camera speeds best at {:.2} s (correlation {:.3} over {:.0} s of \
         overlap){second}.",
        a.lags_considered, a.step_s, a.lag_s, a.correlation, a.overlap_s
    )
}

fn refinement(s: &mut String, o: &CalibrationOutcome) {
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

fn frames(s: &mut String, frames: Option<&[FrameStat]>) {
    section(s, "frames", "Image frames");
    let note = "no image statistics: poses read from a file";
    let fr = frames.unwrap_or(&[]);
    let unposed: Vec<(f64, f64)> = {
        let period = if fr.len() >= 2 {
            let span = fr[fr.len() - 1].t - fr[0].t;
            (span / (fr.len() - 1) as f64).abs()
        } else {
            0.1
        };
        fr.iter()
            .filter(|f| !f.posed)
            .map(|f| (f.t - 0.5 * period, f.t + 0.5 * period))
            .collect()
    };
    let detected: Vec<(f64, f64)> = fr.iter().map(|f| (f.t, f.tags_detected as f64)).collect();
    let used: Vec<(f64, f64)> = fr
        .iter()
        .filter(|f| f.posed)
        .map(|f| (f.t, f.tags_used as f64))
        .collect();
    let rms: Vec<(f64, f64)> = fr
        .iter()
        .filter_map(|f| f.rms_px.map(|r| (f.t, r)))
        .collect();
    let rms_top = upper(&rms);
    let tags_top = upper(&detected);
    let mut tags = Plot::new("frames-tags", "Tags per frame", "camera time (s)", "tags")
        .size(HALF, 250.0)
        .y_range(0.0, tags_top)
        .series(Series::dots("detected", MEASURED, detected).size(5.0))
        .series(Series::dots("used by the pose", AFTER, used).size(2.5))
        .empty_note(note);
    let mut rmsp = Plot::new(
        "frames-rms",
        "Reprojection RMS per posed frame",
        "camera time (s)",
        "px",
    )
    .size(HALF, 250.0)
    .y_range(0.0, rms_top)
    .series(Series::dots("", AFTER, rms).size(3.0))
    .empty_note(note);
    if !unposed.is_empty() {
        tags = tags.spans("no pose", unposed.clone());
        rmsp = rmsp.spans("no pose", unposed);
    }
    s.push_str("<div class=\"grid\">");
    s.push_str(&tags.render());
    s.push_str(&rmsp.render());
    s.push_str("</div>");
    if let Some(fr) = frames {
        let posed = fr.iter().filter(|f| f.posed).count();
        let rms: Vec<f64> = fr.iter().filter_map(|f| f.rms_px).collect();
        let mean_rms = if rms.is_empty() {
            f64::NAN
        } else {
            rms.iter().sum::<f64>() / rms.len() as f64
        };
        put!(
            s,
            "<p>{}</p>",
            escape(&format!(
                "{posed} of {} frames got a pose{}; mean reprojection RMS {mean_rms:.3} px.",
                fr.len(),
                if posed < fr.len() {
                    " (frames without one are shaded)"
                } else {
                    ""
                }
            ))
        );
    }
    s.push_str("</section>\n");
}

fn trajectory(s: &mut String, input: &ReportInput, d: &Derived) {
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

fn dvl_log(s: &mut String, st: Option<&DvlLogStats>, o: &CalibrationOutcome) {
    section(s, "dvl-log", "DVL log");
    let mut rows: Vec<(String, String)> = Vec::new();
    if let Some(st) = st {
        rows.push(("file".into(), st.path.display().to_string()));
        rows.push((
            "format".into(),
            st.format.map_or("unknown".into(), |f| f.to_string()),
        ));
        if !st.formats_seen.is_empty() {
            rows.push((
                "report versions".into(),
                st.formats_seen
                    .iter()
                    .map(|(k, v)| format!("{k}: {v}"))
                    .collect::<Vec<_>>()
                    .join(", "),
            ));
        }
        if let Some(t) = &st.topic {
            rows.push(("bag topic".into(), t.clone()));
        }
        rows.push(("time stamps".into(), st.time_source_used.clone()));
        rows.push(("lines (or messages) read".into(), st.lines.to_string()));
        rows.push((
            "bottom-track velocity reports".into(),
            st.velocity_reports.to_string(),
        ));
        rows.push((
            "valid / invalid".into(),
            format!("{} / {}", st.valid, st.invalid),
        ));
        rows.push(("exact duplicates".into(), st.duplicates.to_string()));
        rows.push((
            "water-track reports (not used)".into(),
            st.water_velocity_reports.to_string(),
        ));
        let other = if st.other_by_type.is_empty() {
            st.other_reports.to_string()
        } else {
            format!(
                "{} ({})",
                st.other_reports,
                st.other_by_type
                    .iter()
                    .map(|(k, v)| format!("{k}: {v}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        };
        rows.push(("other reports".into(), other));
        let rejected = if st.rejected_by_reason.is_empty() {
            st.rejected_lines.to_string()
        } else {
            format!(
                "{} ({})",
                st.rejected_lines,
                st.rejected_by_reason
                    .iter()
                    .map(|(k, v)| format!("{k}: {v}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        };
        rows.push(("rejected lines".into(), rejected));
        rows.push((
            "times going backwards / repeated".into(),
            format!("{} / {}", st.time_backwards, st.time_repeats),
        ));
        if let (Some(a), Some(b)) = (st.first_time_s, st.last_time_s) {
            rows.push((
                "time span (DVL clock, relative to the pose epoch)".into(),
                format!("{a:.3} s to {b:.3} s ({:.1} s)", b - a),
            ));
        }
        if let Some(r) = st.rate_hz(o.counts.dvl_samples) {
            rows.push(("mean rate".into(), format!("{r:.2} Hz")));
        }
    }
    let c = &o.counts;
    rows.push((
        "samples handed to the calibration".into(),
        c.dvl_samples.to_string(),
    ));
    rows.push((
        "of those invalid or non-finite".into(),
        c.dvl_invalid.to_string(),
    ));
    rows.push(("used by the refinement".into(), c.dvl_used.to_string()));
    rows.push((
        "outside the camera time span".into(),
        c.dvl_outside_span.to_string(),
    ));
    if c.dvl_in_pose_gaps > 0 {
        rows.push((
            "in gaps between camera poses".into(),
            c.dvl_in_pose_gaps.to_string(),
        ));
    }
    if o.init.is_some() {
        rows.push(("calm samples (clock offset)".into(), c.calm.to_string()));
    }
    s.push_str("<table>");
    for (k, v) in &rows {
        put!(s, "<tr><th>{}</th><td>{}</td></tr>", escape(k), escape(v));
    }
    s.push_str("</table>");
    if let Some(st) = st {
        if !st.rejected.is_empty() {
            s.push_str("<details><summary>first rejected lines</summary><ul>");
            for r in &st.rejected {
                put!(
                    s,
                    "<li>line {}: {}: {}</li>",
                    r.line,
                    escape(&r.reason),
                    escape(&r.detail)
                );
            }
            s.push_str("</ul></details>");
        }
    } else {
        s.push_str("<p>The DVL log's own counts were not given to the report.</p>");
    }
    s.push_str("</section>\n");
}

fn result_file(s: &mut String, input: &ReportInput) {
    section(s, "result-file", "Result file");
    match (input.result_name, input.result_yaml) {
        (name, Some(text)) => put!(
            s,
            "<details open><summary>{}</summary><pre>{}</pre></details>",
            escape(name.unwrap_or("result")),
            escape(text)
        ),
        (Some(name), None) => put!(s, "<p>Written to {}.</p>", escape(name)),
        (None, None) => s.push_str("<p>No result file was written with this report.</p>"),
    }
    s.push_str("</section>\n");
}
