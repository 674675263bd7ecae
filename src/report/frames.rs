//! The image frames section of the DVL report: tags detected and used per frame, the
//! reprojection RMS per posed frame, and the frames without a pose.

use std::fmt::Write as _;

use super::html::{AFTER, HALF, MEASURED, put, section, upper};
use super::input::FrameStat;
use super::svg::{Plot, Series, escape};

pub(super) fn frames(s: &mut String, frames: Option<&[FrameStat]>) {
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
