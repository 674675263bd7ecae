//! The closing sections of the DVL report: the DVL log's counts (what was read, rejected and
//! used) and the result file.

use std::fmt::Write as _;

use super::html::{put, section};
use super::input::ReportInput;
use super::svg::escape;
use crate::calib::CalibrationOutcome;
use crate::io::dvl::DvlLogStats;

pub(super) fn dvl_log(s: &mut String, st: Option<&DvlLogStats>, o: &CalibrationOutcome) {
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

pub(super) fn result_file(s: &mut String, input: &ReportInput) {
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
