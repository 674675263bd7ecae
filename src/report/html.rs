//! The pieces every report page shares: the style sheet, the colours and plot sizes of the DVL
//! report, the `put!` macro, section headings and figures, number formats and plot ranges.

use std::fmt::Write as _;

use nalgebra::Vector3;

use super::svg::{Plot, escape};

pub(super) const MEASURED: &str = "#6b6b6b";
pub(super) const BEFORE: &str = "#e8710a";
pub(super) const AFTER: &str = "#1a63c2";
pub(super) const NOISE: &str = "#2a9d3a";
pub(super) const LEVER: &str = "#c2185b";
pub(super) const OUTLIER: &str = "#d62728";
pub(super) const AXES: [&str; 3] = ["x", "y", "z"];
pub(super) const AXIS_COLORS: [&str; 3] = ["#d62728", "#2ca02c", "#1f77b4"];

/// Full width and half width of a plot, pixels.
pub(super) const WIDE: f64 = 940.0;
pub(super) const HALF: f64 = 462.0;

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
.next{border:2px solid #1f5fa8;background:#eef4fb;padding:.1em 1em .4em;margin:1em 0}\
.next h2{border:0;margin:.5em 0 .2em}.next li{margin:.3em 0}.next .why{color:#555}\
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

pub(super) fn vec3(v: &Vector3<f64>, scale: f64, decimals: usize) -> String {
    format!(
        "[{:.d$}, {:.d$}, {:.d$}]",
        v.x * scale,
        v.y * scale,
        v.z * scale,
        d = decimals
    )
}

pub(super) fn quat(q: &[f64; 4]) -> String {
    format!("[{:.5}, {:.5}, {:.5}, {:.5}]", q[0], q[1], q[2], q[3])
}

pub(super) fn percent(x: f64) -> String {
    format!("{:.1}%", 100.0 * x)
}

/// The document's start: the doctype, the head with `title` and the style, and `<body>`.
pub(super) fn page_start(s: &mut String, title: &str) {
    put!(
        s,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <meta name=\"viewport\" content=\"width=device-width,initial-scale=1\">\
         <title>{}</title><style>{STYLE}</style></head><body>\n",
        escape(title)
    );
}

/// A table of estimates with id `id`: a row per quantity, its estimate, its standard
/// deviation and its verdict (a cell of HTML; the rest is escaped).
pub(super) fn estimate_table(s: &mut String, id: &str, rows: &[(&str, String, String, &str)]) {
    put!(
        s,
        "<table id=\"{id}\"><tr><th>quantity</th><th>estimate</th>\
         <th>standard deviation</th><th>verdict</th></tr>\n"
    );
    for (name, value, sd, verdict) in rows {
        put!(
            s,
            "<tr><td>{}</td><td class=\"num\">{}</td><td class=\"num\">{}</td><td>{verdict}</td>\
             </tr>\n",
            escape(name),
            escape(value),
            escape(sd)
        );
    }
    s.push_str("</table>\n");
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

pub(super) fn join_words(w: &[&str]) -> String {
    match w {
        [] => String::new(),
        [a] => (*a).to_owned(),
        [a @ .., b] => format!("{} and {b}", a.join(", ")),
    }
}

/// Symmetric range holding all but the 0.1% most extreme values of `v`, at least `floor` wide.
pub(super) fn robust_half_range(v: &[f64], floor: f64) -> f64 {
    super::svg::abs_quantile(v, 0.999).max(floor).max(1e-6)
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
