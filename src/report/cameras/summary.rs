//! The top of the camera calibration's report: the key figures with a verdict in words, and the
//! warnings.

use std::fmt::Write as _;

use super::input::CamCalReportInput;
use super::shared::{coverage_poor, dropped_frames, plural, px};
use crate::camcal::CamCalResult;
use crate::report::html::{join_words, put, section};
use crate::report::svg::escape;

/// A camera calibration from board corners with a higher RMS than this is suspect, px.
const HIGH_RMS_PX: f64 = 1.0;
/// Up to this RMS a calibration from board corners fits tightly, px.
const TIGHT_RMS_PX: f64 = 0.5;

pub(super) fn summary(s: &mut String, r: &CamCalResult, input: &CamCalReportInput) {
    put!(
        s,
        "<section id=\"summary\"><h1>Camera calibration</h1><p class=\"meta\">dvlcal {}",
        env!("CARGO_PKG_VERSION")
    );
    if !input.images.is_empty() {
        put!(s, "<br>images: {}", escape(&input.images));
    }
    if !input.target.is_empty() {
        put!(s, "<br>target: {}", escape(&input.target));
    }
    if let Some(c) = &input.command {
        put!(s, "<br>command: <code>{}</code>", escape(c));
    }
    s.push_str("</p>\n");

    let (verdict, ok) = verdict(r);
    put!(
        s,
        "<p class=\"{}\"><strong>{}</strong></p>\n",
        if ok { "ok" } else { "weak" },
        escape(&verdict)
    );
    if !r.warnings.is_empty() {
        put!(
            s,
            "<div class=\"warnbox\"><strong>{}</strong> listed <a href=\"#warnings\">below</a>; \
             the first: {}</div>\n",
            escape(&plural(r.warnings.len(), "warning", "warnings")),
            escape(&r.warnings[0])
        );
    }

    let cams = r.chain.cams.len();
    let dropped = dropped_frames(r).len();
    let mut rows: Vec<(String, String)> = vec![
        ("camera model".into(), r.model.name().to_owned()),
        (
            "cameras".into(),
            if cams == 0 {
                "none".into()
            } else {
                r.chain
                    .cams
                    .iter()
                    .enumerate()
                    .map(|(i, c)| format!("cam{i} {}x{}", c.width, c.height))
                    .collect::<Vec<_>>()
                    .join(", ")
            },
        ),
        (
            "frames".into(),
            format!(
                "{} in the input, {} used, {} dropped",
                r.frames.len(),
                r.frames.len() - dropped,
                dropped
            ),
        ),
        (
            "views used (one camera in one frame)".into(),
            per_cam(&r.views_used, |v| v.to_string()),
        ),
        (
            "corners used / rejected as outliers".into(),
            format!(
                "{} / {} ({:.1}% rejected)",
                r.corners_used,
                r.corners_rejected,
                100.0 * r.corners_rejected as f64
                    / (r.corners_used + r.corners_rejected).max(1) as f64
            ),
        ),
        (
            "detections not on the board (or repeated)".into(),
            r.detections_unmatched.to_string(),
        ),
        (
            "tags left out at the image border".into(),
            r.tags_at_border.to_string(),
        ),
        ("reprojection RMS, all cameras".into(), px(r.rms_px)),
        (
            "reprojection RMS per camera".into(),
            per_cam(&r.rms_px_per_cam, |v| px(*v)),
        ),
        (
            "reprojection RMS per camera at OpenCV's start".into(),
            per_cam(&r.initial_rms_px, |v| px(*v)),
        ),
        ("estimated corner noise (per axis)".into(), px(r.sigma_px)),
        (
            "board tilt against cam0, 90th percentile of the views".into(),
            format!("{:.0} deg", r.tilt_p90_deg),
        ),
        (
            "Levenberg-Marquardt iterations (final fit)".into(),
            r.iterations.to_string(),
        ),
    ];
    if cams == 1 {
        rows.push(("extrinsics".into(), "none: a single camera".into()));
    }
    s.push_str("<table>");
    for (k, v) in &rows {
        put!(
            s,
            "<tr><th>{}</th><td class=\"num\">{}</td></tr>",
            escape(k),
            escape(v)
        );
    }
    s.push_str("</table></section>\n");
}

/// `cam0: a, cam1: b` for one value per camera.
fn per_cam<T>(v: &[T], f: impl Fn(&T) -> String) -> String {
    if v.is_empty() {
        return "none".into();
    }
    v.iter()
        .enumerate()
        .map(|(i, x)| format!("cam{i}: {}", f(x)))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The verdict in one sentence, and whether it is good news.
fn verdict(r: &CamCalResult) -> (String, bool) {
    let cams = r.chain.cams.len();
    if cams == 0 || r.corners_used == 0 {
        return (
            "Nothing was calibrated: the result holds no camera with used corners.".into(),
            false,
        );
    }
    let poor: Vec<String> = r
        .coverage
        .iter()
        .enumerate()
        .filter(|(_, c)| coverage_poor(c))
        .map(|(i, _)| format!("cam{i}"))
        .collect();
    let poor: Vec<&str> = poor.iter().map(String::as_str).collect();
    let tight = if r.rms_px <= TIGHT_RMS_PX {
        "tight"
    } else {
        "fair"
    };
    // A NaN RMS counts as high.
    if r.rms_px.is_nan() || r.rms_px > HIGH_RMS_PX {
        (
            format!(
                "Do not use this calibration as it is: the reprojection RMS of {} is high for \
                 board corners, which fit to well under {HIGH_RMS_PX} px when the board's \
                 dimensions and the camera model are right.",
                px(r.rms_px)
            ),
            false,
        )
    } else if !poor.is_empty() {
        (
            format!(
                "The fit is {tight} (RMS {}), but the board did not cover the image{} of {} well: \
                 the distortion is extrapolated where no corner was. Record more views there \
                 before relying on the image edges.",
                px(r.rms_px),
                if poor.len() == 1 { "" } else { "s" },
                join_words(&poor)
            ),
            false,
        )
    } else if !r.warnings.is_empty() {
        (
            format!(
                "The fit is {tight} (RMS {} over {} corners), with {} to read below.",
                px(r.rms_px),
                r.corners_used,
                plural(r.warnings.len(), "warning", "warnings")
            ),
            false,
        )
    } else {
        (
            format!(
                "The calibration looks sound: a {tight} fit (RMS {} over {} corners, corner noise \
                 {} per axis), corners over the whole of every image, and no warnings.",
                px(r.rms_px),
                r.corners_used,
                px(r.sigma_px)
            ),
            true,
        )
    }
}

pub(super) fn warnings(s: &mut String, r: &CamCalResult) {
    section(s, "warnings", "Warnings");
    if r.warnings.is_empty() {
        s.push_str("<p>No warnings.</p>");
    } else {
        put!(
            s,
            "<div class=\"warnbox\"><p><strong>{}:</strong></p><ul class=\"warn\">",
            escape(&plural(r.warnings.len(), "warning", "warnings"))
        );
        for w in &r.warnings {
            put!(s, "<li>{}</li>", escape(w));
        }
        s.push_str("</ul></div>");
    }
    s.push_str("</section>\n");
}
