//! The top of the DVL report: the headline with the verdicts in a sentence and the fit in
//! numbers, and the warnings (the log's, the calibration's and one per weak verdict).

use std::fmt::Write as _;

use super::data::Derived;
use super::guidance::{FrameLoss, NextStep, specific_reason};
use super::html::{join_words, put, section, vec3};
use super::input::ReportInput;
use super::svg::escape;
use super::words::{estimated, method_words};
use crate::calib::DeterminedBy;

pub(super) fn summary(
    s: &mut String,
    input: &ReportInput,
    d: &Derived,
    steps: &[NextStep],
    warnings: &[String],
) {
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
        s.push_str("</ul>");
        if let Some(l) = FrameLoss::of(input.frames).filter(FrameLoss::significant) {
            put!(
                s,
                "<p id=\"failed-cause\">In this run {}: camera poses this sparse cannot follow \
                 the motion, which alone can explain a disagreement with the DVL.</p>",
                escape(&l.words())
            );
        }
        s.push_str("</div>\n");
    }

    put!(
        s,
        "<p id=\"headline\"><strong>{}</strong></p>\n",
        escape(&headline(input, steps, warnings))
    );
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
    let noise = &o.noise;
    if noise.dvl.rescaled() {
        let _ = write!(
            words,
            " The noise the DVL's reports stated was {:.2} times this: the variance components of \
             the joint estimate found it misstated, and the reports are weighed by the noise the \
             data show.",
            1.0 / noise.dvl.applied.sqrt()
        );
    }
    if noise.cosensor.rescaled() {
        let _ = write!(
            words,
            " The camera poses' covariances were scaled by {:.2} (variance) for the same reason.",
            noise.cosensor.applied
        );
    }
    if let Some(c) = &o.clock_drift {
        let times = o
            .used
            .iter()
            .filter_map(|&i| o.observations.get(i).map(|x| x.t));
        let (lo, hi) = times.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), t| {
            (lo.min(t), hi.max(t))
        });
        let span_s = if hi > lo { hi - lo } else { 0.0 };
        let _ = write!(
            words,
            " The DVL clock drifts {:+.2} +- {:.2} ppm against the camera's ({:+.1} ms over the \
             recording); the clock offset given is the one at the middle of the DVL log.",
            c.ppm,
            c.std_ppm,
            1e-3 * c.ppm * span_s
        );
    }
    put!(s, "<p>{}</p></section>\n", escape(&words));
}

/// The summary's first sentence: the verdicts, and the warnings with the most serious named.
fn headline(input: &ReportInput, steps: &[NextStep], warnings: &[String]) -> String {
    let o = input.outcome;
    let v = &o.verdicts;
    let ext = estimated(&o.method, true);
    let tim = estimated(&o.method, false);
    let judged = [
        ("the rotation", &v.rotation, ext),
        ("the lever arm", &v.lever_arm, ext),
        ("the clock offset", &v.time_offset, tim),
        ("the velocity scale", &v.velocity_scale, tim),
    ];
    let free = judged.iter().filter(|j| j.2).count();
    let weak: Vec<String> = judged
        .iter()
        .filter(|(_, _, free)| *free)
        .filter_map(|(n, v, _)| {
            if v.by == DeterminedBy::Prior {
                Some(format!("{n} comes from its prior"))
            } else if !v.ok {
                Some(format!("{n} is weakly observable"))
            } else {
                None
            }
        })
        .collect();
    let mut h = if free == 0 {
        "Nothing was estimated: this run only evaluates the given calibration against the data"
            .to_owned()
    } else if weak.is_empty() {
        format!(
            "All {free} estimated quantities are well determined by this recording (details and \
             standard deviations below)"
        )
    } else {
        let weak: Vec<&str> = weak.iter().map(String::as_str).collect();
        let mut h = format!("Attention: {}", join_words(&weak));
        if weak.len() < free {
            h.push_str("; the other estimates are well determined");
        }
        h
    };
    let serious = steps
        .first()
        .map(|st| st.problem.as_str())
        .or(warnings.first().map(String::as_str));
    match (warnings.len(), serious) {
        (0, Some(p)) => {
            let _ = write!(h, ", but {p}.");
        }
        (0, None) => h.push('.'),
        (n, p) => {
            let _ = write!(
                h,
                "{} {} {n} warning{} below; the most serious: {}.",
                if weak.is_empty() {
                    ", but there"
                } else {
                    ". There"
                },
                if n == 1 { "is" } else { "are" },
                if n == 1 { "" } else { "s" },
                p.unwrap_or_default()
            );
        }
    }
    h
}

/// The log's warnings, the calibration's, the frames the image pipeline lost, and one per
/// parameter that is weak or comes from its prior (the IMU's included).
pub(super) fn all_warnings(input: &ReportInput) -> Vec<String> {
    let o = input.outcome;
    let mut w: Vec<String> = input
        .dvl_stats
        .map(|st| st.warnings.clone())
        .unwrap_or_default();
    w.extend(o.warnings.iter().cloned());
    let loss = FrameLoss::of(input.frames);
    if let Some(l) = loss.as_ref().filter(|l| l.significant()) {
        w.push(l.words());
    }
    let ext = estimated(&o.method, true);
    let tim = estimated(&o.method, false);
    for (name, v, free) in [
        ("rotation", &o.verdicts.rotation, ext),
        ("lever arm", &o.verdicts.lever_arm, ext),
        ("time offset", &o.verdicts.time_offset, tim),
        ("velocity scale", &o.verdicts.velocity_scale, tim),
    ] {
        if !free {
            continue;
        }
        let why = specific_reason(v, loss.as_ref());
        if v.by == DeterminedBy::Prior {
            w.push(format!("{name} comes from its prior, not the data: {why}"));
        } else if !v.ok {
            w.push(format!("{name} is weakly observable: {why}"));
        }
    }
    if let Some(imu) = &input.imu {
        let v = imu.verdicts;
        for v in [&v.rotation, &v.lever_arm, &v.time_offset] {
            if !v.ok {
                w.push(v.reason.clone());
            }
        }
    }
    w
}

pub(super) fn warnings(s: &mut String, w: &[String]) {
    section(s, "warnings", "Warnings");
    if w.is_empty() {
        s.push_str("<p>No warnings.</p>");
    } else {
        put!(
            s,
            "<p>{} warning{}:</p><ul class=\"warn\">",
            w.len(),
            if w.len() == 1 { "" } else { "s" }
        );
        for line in w {
            put!(s, "<li>{}</li>", escape(line));
        }
        s.push_str("</ul>");
    }
    s.push_str("</section>\n");
}
