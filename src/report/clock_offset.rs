//! The clock-offset section of the DVL report: the speed correlation over every overlap, the
//! search's objective over its range and near its optimum, and the search in words.

use std::fmt::Write as _;

use super::html::{AFTER, BEFORE, HALF, LEVER, NOISE, WIDE, put, section};
use super::svg::{Plot, Series, escape};
use crate::calib::CalibrationOutcome;
use crate::calib::offset::OffsetMethod;

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

pub(super) fn clock_offset(s: &mut String, o: &CalibrationOutcome) {
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
