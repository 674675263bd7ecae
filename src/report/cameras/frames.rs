//! The frames: the reprojection RMS of every frame per camera, the dropped frames with their
//! reasons, and the worst frames.

use std::collections::HashMap;
use std::fmt::Write as _;

use super::shared::{REJECTED, cam_color, dropped_frames, plural};
use crate::camcal::{CamCalResult, FrameFit};
use crate::report::html::{figure, put, section, upper};
use crate::report::svg::{Plot, Series, escape};

/// Rows of the dropped-frames table before the rest is only counted.
const MAX_DROPPED_ROWS: usize = 60;
/// Rows of the worst-frames table.
const WORST_ROWS: usize = 10;

/// Reprojection RMS per camera over all corners of every dropped frame, by frame index.
fn dropped_rms(r: &CamCalResult, cams: usize) -> HashMap<usize, Vec<Option<f64>>> {
    let mut sq: HashMap<usize, Vec<(f64, usize)>> = r
        .frames
        .iter()
        .filter(|f| f.dropped.is_some())
        .map(|f| (f.frame, vec![(0.0, 0); cams]))
        .collect();
    for x in &r.residuals {
        if let Some(e) = sq.get_mut(&x.frame).and_then(|v| v.get_mut(x.cam)) {
            e.0 += x.r.norm_squared();
            e.1 += 1;
        }
    }
    sq.into_iter()
        .map(|(f, v)| {
            let rms = v
                .iter()
                .map(|&(s, n)| (n > 0).then(|| (s / n as f64).sqrt()))
                .collect();
            (f, rms)
        })
        .collect()
}

fn frame_rms_cell(v: &[Option<f64>]) -> String {
    v.iter()
        .map(|x| x.map_or("–".to_owned(), |r| format!("{r:.3}")))
        .collect::<Vec<_>>()
        .join(" / ")
}

pub(super) fn frames(s: &mut String, r: &CamCalResult) {
    section(s, "frames", "Frames");
    let cams = r.chain.cams.len();
    let dropped = dropped_frames(r);
    let dropped_rms = dropped_rms(r, cams);
    let mut plot = Plot::new(
        "frame-rms",
        "Reprojection RMS per frame",
        "frame index",
        "RMS (px)",
    )
    .size(940.0, 300.0)
    .integer_x()
    .empty_note("no frame has a reprojection RMS");
    let mut used_pts = Vec::new();
    for c in 0..cams {
        let pts: Vec<(f64, f64)> = r
            .frames
            .iter()
            .filter(|f| f.dropped.is_none())
            .filter_map(|f| {
                f.rms_px
                    .get(c)
                    .copied()
                    .flatten()
                    .map(|v| (f.frame as f64, v))
            })
            .collect();
        used_pts.extend(pts.iter().copied());
        plot = plot.series(Series::dots(&format!("cam{c}"), cam_color(c), pts).size(4.0));
    }
    let dropped_pts: Vec<(f64, f64)> = dropped
        .iter()
        .flat_map(|f| {
            dropped_rms
                .get(&f.frame)
                .into_iter()
                .flatten()
                .flatten()
                .map(move |v| (f.frame as f64, *v))
        })
        .collect();
    let top_used = upper(&used_pts);
    let top_dropped = upper(&dropped_pts);
    if !dropped_pts.is_empty() {
        plot = plot.series(
            Series::dots(
                "dropped frame (RMS of all its corners)",
                REJECTED,
                dropped_pts.clone(),
            )
            .size(6.0),
        );
    }
    if !dropped.is_empty() {
        plot = plot.spans(
            "dropped frame",
            dropped
                .iter()
                .map(|f| (f.frame as f64 - 0.5, f.frame as f64 + 0.5))
                .collect(),
        );
    }
    let positive = used_pts
        .iter()
        .chain(&dropped_pts)
        .all(|p| p.1.is_finite() && p.1 > 0.0);
    if !dropped_pts.is_empty() && top_dropped > 4.0 * top_used && positive {
        plot = plot.log_y();
    } else {
        plot = plot.y_range(0.0, top_used.max(top_dropped));
    }
    figure(
        s,
        &plot,
        &format!(
            "The reprojection RMS of every used frame per camera over the corners the fit kept{}.",
            match dropped.len() {
                0 => String::new(),
                1 => "; the dropped frame is shaded, with the RMS of all its corners at the final \
                      calibration in red"
                    .to_owned(),
                n => format!(
                    "; the {n} dropped frames are shaded, with the RMS of all their corners at the \
                     final calibration in red"
                ),
            }
        ),
    );

    s.push_str("<h3 id=\"dropped-frames\">Dropped frames</h3>");
    if dropped.is_empty() {
        s.push_str("<p>No frame was dropped.</p>");
    } else {
        put!(
            s,
            "<p>{} of {} not used, with the reason:</p>",
            escape(&plural(dropped.len(), "frame", "frames")),
            r.frames.len()
        );
        frame_table_head(s, cams, "RMS of all corners (px)", true);
        for f in dropped.iter().take(MAX_DROPPED_ROWS) {
            frame_row(s, f, dropped_rms.get(&f.frame).map_or(&[], Vec::as_slice));
        }
        s.push_str("</table>");
        if dropped.len() > MAX_DROPPED_ROWS {
            put!(
                s,
                "<p>and {} more dropped frames.</p>",
                dropped.len() - MAX_DROPPED_ROWS
            );
        }
    }

    s.push_str("<h3 id=\"worst-frames\">Frames with the largest RMS</h3>");
    let mut worst: Vec<(&FrameFit, f64)> = r
        .frames
        .iter()
        .filter(|f| f.dropped.is_none())
        .filter_map(|f| {
            let m = f
                .rms_px
                .iter()
                .flatten()
                .copied()
                .filter(|v| v.is_finite())
                .fold(f64::NEG_INFINITY, f64::max);
            m.is_finite().then_some((f, m))
        })
        .collect();
    worst.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.frame.cmp(&b.0.frame)));
    if worst.is_empty() {
        s.push_str("<p>No used frame has a reprojection RMS.</p>");
    } else {
        put!(
            s,
            "<p>The {} used frames whose RMS (largest over the cameras) is highest:</p>",
            worst.len().min(WORST_ROWS)
        );
        frame_table_head(s, cams, "RMS (px)", false);
        for (f, _) in worst.iter().take(WORST_ROWS) {
            frame_row(s, f, &f.rms_px);
        }
        s.push_str("</table>");
    }
    s.push_str("</section>\n");
}

fn frame_table_head(s: &mut String, cams: usize, rms: &str, reason: bool) {
    let cams_words = (0..cams)
        .map(|c| format!("cam{c}"))
        .collect::<Vec<_>>()
        .join(" / ");
    put!(
        s,
        "<table><tr><th>frame</th><th>name</th><th>corners ({cams_words})</th>\
         <th>{} ({cams_words})</th>{}</tr>",
        escape(rms),
        if reason { "<th>reason</th>" } else { "" }
    );
}

fn frame_row(s: &mut String, f: &FrameFit, rms: &[Option<f64>]) {
    let corners = f
        .corners
        .iter()
        .map(|n| n.to_string())
        .collect::<Vec<_>>()
        .join(" / ");
    put!(
        s,
        "<tr><td class=\"num\">{}</td><td>{}</td><td class=\"num\">{}</td>\
         <td class=\"num\">{}</td>",
        f.frame,
        escape(&f.name),
        escape(&corners),
        escape(&frame_rms_cell(rms))
    );
    if let Some(why) = &f.dropped {
        put!(s, "<td>{}</td>", escape(why));
    }
    s.push_str("</tr>");
}
