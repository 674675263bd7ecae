//! The report of a camera calibration: one self-contained HTML page (inline CSS and SVG, no
//! scripts, no external resources) on a [`CamCalResult`].
//!
//! [`render_camcal_html`] is pure: it takes the result and a [`CamCalReportInput`] and returns the
//! page; the caller writes it. The page has the sections of [`CAMCAL_SECTION_IDS`], in order:
//! - a summary with the key figures (model, cameras, frames and corners used and dropped, the
//!   reprojection RMS overall and per camera, the estimated corner noise) and a verdict in words;
//! - the warnings of the calibration;
//! - the results per camera: intrinsics and distortion with their standard deviations beside
//!   OpenCV's initial values, and for every camera after cam0 the transform `T_cn_cnm1`;
//! - the reprojection residuals per camera: a histogram of the x and y components, and a map of
//!   the residuals over the image (every corner a dot coloured by its residual, rejected corners
//!   crossed out, the mean residual per image cell as an arrow);
//! - the coverage of every image by corners, with the parts where the distortion is not measured
//!   named in words;
//! - the reprojection RMS per frame and camera, the dropped frames with their reasons and the
//!   worst frames;
//! - the camchain file written, with the command that made it.
//!
//! Per-camera plots have the ids of [`CAMCAL_CAMERA_PLOT_IDS`] followed by `-cam0`, `-cam1`, ...;
//! the plots of the whole chain are listed in [`CAMCAL_PLOT_IDS`]; [`camcal_plot_ids`] lists
//! every plot of a chain in page order.

use std::collections::{HashMap, HashSet};
use std::fmt::Write as _;

use nalgebra::Vector3;

use super::page::{STYLE, figure, join_words, put, robust_half_range, section, upper};
use super::svg::{Histogram, Plot, Series, escape, format_tick, nice_ticks};
use crate::camcal::quality::{MIN_COVERED_FRACTION, MIN_RADIAL_REACH, empty_regions};
use crate::camcal::{CamCalResult, Coverage, FrameFit, Residual};
use crate::error::Result;
use crate::lie::{Se3, so3};
use crate::types::camera::{Camchain, Camera, Distortion};

/// The id of every section of the camera calibration report, in page order.
pub const CAMCAL_SECTION_IDS: &[&str] = &[
    "summary",
    "warnings",
    "results",
    "residuals",
    "coverage",
    "frames",
    "camchain",
];

/// The plots drawn once per camera, in page order within a camera: the id of cam n's plot is
/// the name followed by `-cam{n}` (`residual-hist-cam0`). Every camera of the chain has them;
/// one without data says so in the plot (`data-empty="true"`).
pub const CAMCAL_CAMERA_PLOT_IDS: &[&str] = &["residual-hist", "residual-map", "coverage-grid"];

/// The plots of the whole chain.
pub const CAMCAL_PLOT_IDS: &[&str] = &["frame-rms"];

/// The ids of every plot of the report of a chain of `cameras` cameras, in page order.
pub fn camcal_plot_ids(cameras: usize) -> Vec<String> {
    let mut ids = Vec::new();
    // The residual plots of all cameras come first, then the coverage grids.
    for c in 0..cameras {
        for base in &CAMCAL_CAMERA_PLOT_IDS[..2] {
            ids.push(format!("{base}-cam{c}"));
        }
    }
    for c in 0..cameras {
        ids.push(format!("{}-cam{c}", CAMCAL_CAMERA_PLOT_IDS[2]));
    }
    ids.extend(CAMCAL_PLOT_IDS.iter().map(|s| s.to_string()));
    ids
}

/// What the report says about the run besides the result itself.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CamCalReportInput {
    /// The folder (or bag) the images came from.
    pub images: String,
    /// The calibration target: its file or a description.
    pub target: String,
    /// The text of the camchain YAML written (shown at the end; empty: none written).
    pub camchain_yaml: String,
    /// Where the camchain was written, if it was.
    pub camchain_path: Option<String>,
    /// The command line of the run.
    pub command: Option<String>,
}

/// Colours of the cameras (cam n takes entry n modulo the length).
const CAM_COLORS: [&str; 6] = [
    "#1a63c2", "#e8710a", "#2a9d3a", "#c2185b", "#6a3d9a", "#8c564b",
];
const REJECTED: &str = "#d62728";
const NOISE: &str = "#2a9d3a";
const X_COLOR: &str = "#1a63c2";
const Y_COLOR: &str = "#e8710a";
/// A camera calibration from board corners with a higher RMS than this is suspect, px.
const HIGH_RMS_PX: f64 = 1.0;
/// Up to this RMS a calibration from board corners fits tightly, px.
const TIGHT_RMS_PX: f64 = 0.5;
/// Rows of the dropped-frames table before the rest is only counted.
const MAX_DROPPED_ROWS: usize = 60;
/// Largest coverage grid drawn (a finer one is not shown).
const MAX_GRID_CELLS: usize = 10_000;
/// Rows of the worst-frames table.
const WORST_ROWS: usize = 10;

/// Extra style of this page: the warning box and the image panels.
const EXTRA_STYLE: &str = "\
.grid{align-items:flex-start}\
.warnbox{border:2px solid #c77700;background:#fff6e5;padding:.3em 1em;margin:.8em 0}\
.warnbox strong{color:#8a4b00}td.pm{font-family:ui-monospace,'DejaVu Sans Mono',monospace;\
white-space:nowrap}.chg{color:#777}svg .c{font:10px sans-serif}\
code{background:#f2f2f2;padding:0 3px}";

fn cam_color(c: usize) -> &'static str {
    CAM_COLORS[c % CAM_COLORS.len()]
}

/// Renders the report of a camera calibration as one HTML document.
pub fn render_camcal_html(r: &CamCalResult, input: &CamCalReportInput) -> Result<String> {
    let mut s = String::with_capacity(256 * 1024);
    put!(
        s,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <meta name=\"viewport\" content=\"width=device-width,initial-scale=1\">\
         <title>Camera calibration: {}</title><style>{STYLE}{EXTRA_STYLE}</style></head>\
         <body data-report=\"camcal\">\n",
        escape(&input.images)
    );
    summary(&mut s, r, input);
    warnings(&mut s, r);
    results(&mut s, r);
    residuals(&mut s, r);
    coverage(&mut s, r);
    frames(&mut s, r);
    camchain(&mut s, input);
    s.push_str("</body></html>\n");
    Ok(s)
}

/// The residuals of camera `c`: used and rejected.
fn cam_residuals(r: &CamCalResult, c: usize) -> (Vec<&Residual>, Vec<&Residual>) {
    r.residuals
        .iter()
        .filter(|x| x.cam == c)
        .partition(|x| x.used)
}

/// Whether a coverage grid can be drawn: its counts fill it, and it has at most
/// [`MAX_GRID_CELLS`] cells.
fn grid_ok(g: &Coverage) -> bool {
    g.cols
        .checked_mul(g.rows)
        .is_some_and(|n| n > 0 && n <= MAX_GRID_CELLS && g.counts.len() == n)
}

/// Whether a coverage leaves the distortion unmeasured over part of the image.
fn coverage_poor(c: &Coverage) -> bool {
    !(c.covered_fraction >= MIN_COVERED_FRACTION && c.radial_reach >= MIN_RADIAL_REACH)
}

fn plural(n: usize, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

fn px(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.3} px")
    } else {
        "n/a".to_owned()
    }
}

/// The frames that were not used.
fn dropped_frames(r: &CamCalResult) -> Vec<&FrameFit> {
    r.frames.iter().filter(|f| f.dropped.is_some()).collect()
}

fn summary(s: &mut String, r: &CamCalResult, input: &CamCalReportInput) {
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

fn warnings(s: &mut String, r: &CamCalResult) {
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

/// Decimals that show a standard deviation with two significant digits (at most 9).
fn decimals_for(sd: f64) -> usize {
    if sd.is_finite() && sd > 0.0 {
        (1.0 - sd.log10().floor()).clamp(0.0, 9.0) as usize
    } else {
        4
    }
}

/// One row of a results table: name, final ± std, initial, change.
fn result_row(s: &mut String, name: &str, value: f64, sd: Option<f64>, initial: Option<f64>) {
    let d = sd.map_or(4, decimals_for);
    let est = match sd {
        Some(sd) if sd.is_finite() => format!("{value:.d$} ± {sd:.d$}"),
        _ => format!("{value:.d$}"),
    };
    let (init, change) = match initial {
        Some(i) => (format!("{i:.d$}"), format!("{:+.d$}", value - i)),
        None => ("–".to_owned(), String::new()),
    };
    put!(
        s,
        "<tr><td>{}</td><td class=\"pm\">{}</td><td class=\"pm\">{}</td>\
         <td class=\"pm chg\">{}</td></tr>",
        escape(name),
        escape(&est),
        escape(&init),
        escape(&change)
    );
}

/// The names of a distortion's coefficients, in Kalibr's order.
fn coeff_names(d: &Distortion) -> &'static [&'static str] {
    match d {
        Distortion::None => &[],
        Distortion::RadTan { .. } => &["k1", "k2", "p1", "p2"],
        Distortion::Equidistant { .. } => &["k1", "k2", "k3", "k4"],
    }
}

/// `T_cn_cnm1` of camera `i > 0` in a chain.
fn t_cn_cnm1(chain: &Camchain, i: usize) -> Option<Se3> {
    let n = chain.t_cn_c0.get(i)?;
    let m = chain.t_cn_c0.get(i.checked_sub(1)?)?;
    Some(*n * m.inverse())
}

fn results(s: &mut String, r: &CamCalResult) {
    section(s, "results", "Results per camera");
    if r.chain.cams.is_empty() {
        s.push_str("<p>The result holds no camera.</p></section>\n");
        return;
    }
    s.push_str(
        "<p>The final estimate of each parameter with its standard deviation (one sigma, from the \
         bundle adjustment's covariance scaled by the estimated corner noise), the value OpenCV's \
         calibrateCamera started from, and the change. Focal lengths and principal point in \
         pixels (the centre of the top-left pixel at 0).</p>\n<div class=\"grid\">",
    );
    for (i, cam) in r.chain.cams.iter().enumerate() {
        let sd = r.std.get(i);
        let init = r.initial.cams.get(i);
        put!(
            s,
            "<div><table><tr><th colspan=\"4\" style=\"color:{}\">cam{i}: {}x{} {}</th></tr>\
             <tr><th>parameter</th><th>final ± std</th><th>initial (OpenCV)</th>\
             <th>change</th></tr>",
            cam_color(i),
            cam.width,
            cam.height,
            escape(&format!(
                "pinhole-{}",
                cam.distortion.kalibr_name().replace("equidistant", "equi")
            ))
        );
        let vals = [cam.fu, cam.fv, cam.pu, cam.pv];
        let ivals = init.map(|c| [c.fu, c.fv, c.pu, c.pv]);
        for (k, name) in ["fu", "fv", "pu", "pv"].iter().enumerate() {
            result_row(
                s,
                name,
                vals[k],
                sd.map(|x| x.intrinsics[k]),
                ivals.map(|v| v[k]),
            );
        }
        let coeffs = cam.distortion.coeffs();
        let icoeffs = init.map(|c| c.distortion.coeffs());
        for (k, name) in coeff_names(&cam.distortion).iter().enumerate() {
            let Some(&v) = coeffs.get(k) else { continue };
            result_row(
                s,
                name,
                v,
                sd.and_then(|x| x.distortion.get(k).copied()),
                icoeffs.as_ref().and_then(|c| c.get(k).copied()),
            );
        }
        put!(
            s,
            "<tr><td>reprojection RMS</td><td class=\"pm\">{}</td><td class=\"pm\">{}</td>\
             <td></td></tr>",
            escape(&px(r.rms_px_per_cam.get(i).copied().unwrap_or(f64::NAN))),
            escape(&px(r.initial_rms_px.get(i).copied().unwrap_or(f64::NAN)))
        );
        s.push_str("</table></div>");
    }
    s.push_str("</div>\n");
    extrinsics(s, r);
    s.push_str("</section>\n");
}

/// The transforms between consecutive cameras.
fn extrinsics(s: &mut String, r: &CamCalResult) {
    s.push_str("<h3>Extrinsics T_cn_cnm1</h3>");
    if r.chain.cams.len() < 2 {
        s.push_str(
            "<p>No extrinsics: the chain has a single camera, so there is no transform between \
             cameras to estimate.</p>\n",
        );
        return;
    }
    s.push_str(
        "<p><code>T_cn_cnm1</code> maps points from camera n-1 into camera n (Kalibr's \
         convention). The rotation is given as a rotation vector (axis times angle, degrees) with \
         its standard deviation about cam n's x, y and z axes; the translation and the baseline \
         (its length) in millimetres.</p>\n<table><tr><th>camera</th><th>quantity</th>\
         <th>final ± std</th><th>initial (OpenCV)</th><th>change</th></tr>",
    );
    for i in 1..r.chain.cams.len() {
        let Some(t) = t_cn_cnm1(&r.chain, i) else {
            put!(
                s,
                "<tr><td>cam{i}</td><td colspan=\"4\">no transform in the result</td></tr>"
            );
            continue;
        };
        let t0 = t_cn_cnm1(&r.initial, i);
        let sd = r.std.get(i);
        let rv: Vector3<f64> = so3::log(&t.rot).map(f64::to_degrees);
        let rv0 = t0.map(|t0| so3::log(&t0.rot).map(f64::to_degrees));
        let rot_sd = sd.and_then(|x| x.rotation_rad);
        let tr_sd = sd.and_then(|x| x.translation_m);
        let rows: Vec<(String, f64, Option<f64>, Option<f64>)> = (0..3)
            .map(|k| {
                (
                    format!("rotation vector {} (deg)", ["x", "y", "z"][k]),
                    rv[k],
                    rot_sd.map(|v| v[k].to_degrees()),
                    rv0.map(|v| v[k]),
                )
            })
            .chain((0..3).map(|k| {
                (
                    format!("translation {} (mm)", ["x", "y", "z"][k]),
                    1e3 * t.trans[k],
                    tr_sd.map(|v| 1e3 * v[k]),
                    t0.map(|t0| 1e3 * t0.trans[k]),
                )
            }))
            .chain([
                (
                    "rotation angle (deg)".to_owned(),
                    rv.norm(),
                    None,
                    rv0.map(|v| v.norm()),
                ),
                (
                    "baseline (mm)".to_owned(),
                    1e3 * t.trans.norm(),
                    sd.and_then(|x| x.baseline_m).map(|b| 1e3 * b),
                    t0.map(|t0| 1e3 * t0.trans.norm()),
                ),
            ])
            .collect();
        let n = rows.len();
        for (k, (name, v, sd, init)) in rows.into_iter().enumerate() {
            if k == 0 {
                put!(
                    s,
                    "<tr><td rowspan=\"{n}\" style=\"color:{}\">cam{i} from cam{}</td>",
                    cam_color(i),
                    i - 1
                );
                // result_row opens its own row: strip its <tr>.
                let mut row = String::new();
                result_row(&mut row, &name, v, sd, init);
                s.push_str(row.trim_start_matches("<tr>"));
            } else {
                result_row(s, &name, v, sd, init);
            }
        }
    }
    s.push_str("</table>\n");
}

/// A linear colour scale from blue over amber to red, `t` in [0, 1].
fn heat(t: f64) -> String {
    const STOPS: [(f64, [f64; 3]); 3] = [
        (0.0, [43.0, 108.0, 176.0]),
        (0.5, [232.0, 161.0, 10.0]),
        (1.0, [192.0, 21.0, 27.0]),
    ];
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        1.0
    };
    let (a, b) = if t <= 0.5 {
        (STOPS[0], STOPS[1])
    } else {
        (STOPS[1], STOPS[2])
    };
    let f = (t - a.0) / (b.0 - a.0);
    let c: Vec<u8> = (0..3)
        .map(|k| (a.1[k] + f * (b.1[k] - a.1[k])).round() as u8)
        .collect();
    format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2])
}

/// A shade for a cell count, from pale (few) to dark blue (the most), `t` in [0, 1].
fn shade(t: f64) -> String {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let lo = [232.0, 240.0, 250.0];
    let hi = [20.0, 70.0, 150.0];
    let c: Vec<u8> = (0..3)
        .map(|k| (lo[k] + t * (hi[k] - lo[k])).round() as u8)
        .collect();
    format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2])
}

/// An SVG panel that shows an image: equal scale on both axes, rows growing downward as in the
/// image, the image rectangle `[-0.5, width - 0.5] x [-0.5, height - 0.5]` framed and ticked in
/// pixels.
struct ImagePanel {
    id: String,
    title: String,
    img_w: f64,
    img_h: f64,
    left: f64,
    top: f64,
    scale: f64,
    width: f64,
    height: f64,
}

impl ImagePanel {
    const LEFT: f64 = 52.0;
    const RIGHT: f64 = 14.0;
    const BOTTOM: f64 = 40.0;
    const TOP: f64 = 50.0;

    /// A panel `width` pixels wide (and at most `max_h` high) for an image of the given size.
    fn new(id: &str, title: &str, img_w: u32, img_h: u32, width: f64, max_h: f64) -> Self {
        let (iw, ih) = (img_w.max(1) as f64, img_h.max(1) as f64);
        let aw = (width - Self::LEFT - Self::RIGHT).max(40.0);
        let ah = (max_h - Self::TOP - Self::BOTTOM).max(40.0);
        let scale = (aw / iw).min(ah / ih);
        ImagePanel {
            id: id.to_owned(),
            title: title.to_owned(),
            img_w: iw,
            img_h: ih,
            left: Self::LEFT,
            top: Self::TOP,
            scale,
            width,
            height: Self::TOP + ih * scale + Self::BOTTOM,
        }
    }

    /// Panel x of image column `u`.
    fn x(&self, u: f64) -> f64 {
        self.left + (u + 0.5) * self.scale
    }

    /// Panel y of image row `v`.
    fn y(&self, v: f64) -> f64 {
        self.top + (v + 0.5) * self.scale
    }

    /// Opens the `<svg>` with its title; `empty` marks a panel without data.
    fn open(&self, s: &mut String, empty: bool) {
        let id = escape(&self.id);
        put!(
            s,
            "<svg id=\"{id}\" class=\"plot\" xmlns=\"http://www.w3.org/2000/svg\" \
             viewBox=\"0 0 {W:.0} {H:.0}\" width=\"{W:.0}\" height=\"{H:.0}\" role=\"img\" \
             aria-labelledby=\"{id}-title\"{e}><title id=\"{id}-title\">{t}</title>\
             <rect width=\"{W:.0}\" height=\"{H:.0}\" fill=\"#fff\"/>\
             <text x=\"{l:.1}\" y=\"17\" class=\"t\">{t}</text>",
            W = self.width,
            H = self.height,
            e = if empty { " data-empty=\"true\"" } else { "" },
            t = escape(&self.title),
            l = self.left
        );
    }

    /// The image rectangle (filled), its pixel ticks and the axis labels.
    fn frame(&self, s: &mut String, fill: &str) {
        let (x0, y0) = (self.x(-0.5), self.y(-0.5));
        let (w, h) = (self.img_w * self.scale, self.img_h * self.scale);
        put!(
            s,
            "<rect x=\"{x0:.1}\" y=\"{y0:.1}\" width=\"{w:.1}\" height=\"{h:.1}\" fill=\"{fill}\" \
             stroke=\"#555\"/>"
        );
        let xt = nice_ticks(0.0, self.img_w, (w / 70.0).clamp(2.0, 10.0) as usize);
        for &u in &xt {
            let x = self.x(u);
            put!(
                s,
                "<line x1=\"{x:.1}\" y1=\"{b:.1}\" x2=\"{x:.1}\" y2=\"{:.1}\" stroke=\"#555\"/>\
                 <text x=\"{x:.1}\" y=\"{:.1}\" text-anchor=\"middle\" class=\"k\">{}</text>",
                y0 + h + 4.0,
                y0 + h + 16.0,
                escape(&format_tick(u, 1.0)),
                b = y0 + h
            );
        }
        let yt = nice_ticks(0.0, self.img_h, (h / 45.0).clamp(2.0, 10.0) as usize);
        for &v in &yt {
            let y = self.y(v);
            put!(
                s,
                "<line x1=\"{:.1}\" y1=\"{y:.1}\" x2=\"{x0:.1}\" y2=\"{y:.1}\" stroke=\"#555\"/>\
                 <text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\" class=\"k\">{}</text>",
                x0 - 4.0,
                x0 - 6.0,
                y + 4.0,
                escape(&format_tick(v, 1.0))
            );
        }
        put!(
            s,
            "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\" class=\"a\">image column u (px)\
             </text><text transform=\"translate(13 {:.1}) rotate(-90)\" text-anchor=\"middle\" \
             class=\"a\">image row v (px, down)</text>",
            x0 + w / 2.0,
            self.height - 6.0,
            y0 + h / 2.0
        );
    }

    /// A note across an empty panel.
    fn note(&self, s: &mut String, text: &str) {
        put!(
            s,
            "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\" class=\"n\">{}</text>",
            self.x(self.img_w / 2.0 - 0.5),
            self.y(self.img_h / 2.0 - 0.5),
            escape(text)
        );
    }
}

fn residuals(s: &mut String, r: &CamCalResult) {
    section(s, "residuals", "Reprojection residuals");
    s.push_str(
        "<p>Left: the x and y components of the residuals (reprojected minus detected) of the \
         corners the fit used, against a normal distribution with the estimated corner noise. \
         Right: every used corner at its place in the image, coloured by the length of its \
         residual; crosses mark the corners rejected as outliers (alone or with their frame), and \
         the black arrows the mean residual over each cell of the coverage grid, magnified. A \
         pattern in the arrows (rings, a swirl, one side against the other) is a lens effect the \
         model does not capture; random arrows are noise.</p>\n",
    );
    let cams = r.chain.cams.len();
    if cams == 0 {
        s.push_str("<p>The result holds no camera.</p></section>\n");
        return;
    }
    for (c, cam) in r.chain.cams.iter().enumerate() {
        let (used, rejected) = cam_residuals(r, c);
        s.push_str("<div class=\"grid\">");
        let hist_caption = residual_histogram(s, r, c, &used);
        let map_caption = residual_map(s, r, c, cam, &used, &rejected);
        put!(
            s,
            "</div><p class=\"meta\">{} {}</p>\n",
            escape(&hist_caption),
            escape(&map_caption)
        );
    }
    s.push_str("</section>\n");
}

/// The histogram of camera `c`'s residual components; returns its caption.
fn residual_histogram(s: &mut String, r: &CamCalResult, c: usize, used: &[&Residual]) -> String {
    let xs: Vec<f64> = used.iter().map(|x| x.r.x).collect();
    let ys: Vec<f64> = used.iter().map(|x| x.r.y).collect();
    let all: Vec<f64> = xs.iter().chain(&ys).copied().collect();
    let sigma = if r.sigma_px.is_finite() && r.sigma_px > 0.0 {
        r.sigma_px
    } else {
        0.0
    };
    let half = robust_half_range(&all, (3.0 * sigma).max(0.05));
    // An odd number of bins puts zero in the middle of one.
    let bins = ((used.len() / 10).clamp(5, 20)) * 2 + 1;
    let hx = Histogram::new(&xs, -half, half, bins);
    let hy = Histogram::new(&ys, -half, half, bins);
    let mut plot = Plot::new(
        &format!("residual-hist-cam{c}"),
        &format!("cam{c}: residual components"),
        "residual (px)",
        "corners",
    )
    .size(462.0, 300.0)
    .empty_note(&format!("cam{c} has no used corners"));
    if !used.is_empty() {
        let mut outline = Vec::with_capacity(2 * hy.counts.len());
        for (j, &n) in hy.counts.iter().enumerate() {
            let x0 = hy.lo + j as f64 * hy.width;
            outline.push((x0, n as f64));
            outline.push((x0 + hy.width, n as f64));
        }
        plot = plot
            .series(Series::bars("x", X_COLOR, hx.width, hx.points()))
            .series(Series::line("y", Y_COLOR, outline).size(1.8));
        if sigma > 0.0 {
            let n = used.len() as f64;
            let gauss: Vec<(f64, f64)> = (0..=160)
                .map(|j| {
                    let x = -half + 2.0 * half * j as f64 / 160.0;
                    let pdf = (-0.5 * (x / sigma).powi(2)).exp()
                        / (sigma * (2.0 * std::f64::consts::PI).sqrt());
                    (x, n * hx.width * pdf)
                })
                .collect();
            plot = plot.series(Series::line("noise", NOISE, gauss).dashed());
        }
    }
    s.push_str(&plot.render());
    if used.is_empty() {
        return format!("cam{c}: no used corners, so no residuals to show.");
    }
    let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt();
    format!(
        "cam{c}: {} used corners, RMS {:.3} px in x and {:.3} px in y; {} of {} components fall \
         outside ±{:.2} px and are not drawn.",
        used.len(),
        rms(&xs),
        rms(&ys),
        hx.outside + hy.outside,
        all.len(),
        half
    )
}

/// The map of camera `c`'s residuals over its image; returns its caption.
fn residual_map(
    s: &mut String,
    r: &CamCalResult,
    c: usize,
    cam: &Camera,
    used: &[&Residual],
    rejected: &[&Residual],
) -> String {
    let p = ImagePanel::new(
        &format!("residual-map-cam{c}"),
        &format!("cam{c}: residuals over the image"),
        cam.width,
        cam.height,
        462.0,
        420.0,
    );
    let empty = used.is_empty() && rejected.is_empty();
    p.open(s, empty);
    p.frame(s, "#fcfcfc");
    if empty {
        p.note(s, "no corners");
        s.push_str("</svg>");
        return format!("cam{c}: no corners to map.");
    }
    let id = escape(&p.id);
    let (x0, y0) = (p.x(-0.5), p.y(-0.5));
    let (w, h) = (p.img_w * p.scale, p.img_h * p.scale);
    put!(
        s,
        "<clipPath id=\"{id}-clip\"><rect x=\"{x0:.1}\" y=\"{y0:.1}\" width=\"{w:.1}\" \
         height=\"{h:.1}\"/></clipPath><g clip-path=\"url(#{id}-clip)\">"
    );
    // The colour scale ends at the 99th percentile of the residual lengths.
    let mut mags: Vec<f64> = used
        .iter()
        .map(|x| x.r.norm())
        .filter(|m| m.is_finite())
        .collect();
    mags.sort_by(f64::total_cmp);
    let top = mags
        .get(((mags.len() as f64 * 0.99) as usize).min(mags.len().saturating_sub(1)))
        .copied()
        .filter(|m| *m > 0.0)
        .unwrap_or(1.0);
    // One dot per 3-pixel cell of the panel: the corner with the largest residual there. The
    // dots are drawn as round line caps, one path per colour level, so that a page with tens of
    // thousands of corners stays small.
    let mut cells: HashMap<(i64, i64), (f64, f64, f64)> = HashMap::new();
    for x in used {
        let (sx, sy, m) = (p.x(x.px.x), p.y(x.px.y), x.r.norm());
        if !(sx.is_finite() && sy.is_finite() && m.is_finite()) {
            continue;
        }
        let key = ((sx / 3.0).floor() as i64, (sy / 3.0).floor() as i64);
        let e = cells.entry(key).or_insert((sx, sy, m));
        if m > e.2 {
            *e = (sx, sy, m);
        }
    }
    let mut dots: Vec<(f64, f64, f64)> = cells.into_values().collect();
    // A fixed order (the map's is not) so that the page is the same on every run.
    dots.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    const LEVELS: usize = 16;
    let mut paths = vec![String::new(); LEVELS];
    for (sx, sy, m) in &dots {
        let level = ((m / top).clamp(0.0, 1.0) * (LEVELS - 1) as f64).round() as usize;
        put!(paths[level.min(LEVELS - 1)], "M{sx:.1} {sy:.1}h0");
    }
    // Small residuals first so that the large ones are drawn on top.
    for (level, d) in paths.iter().enumerate() {
        if d.is_empty() {
            continue;
        }
        let t = level as f64 / (LEVELS - 1) as f64;
        put!(
            s,
            "<path d=\"{d}\" stroke=\"{}\" stroke-width=\"{:.1}\" stroke-linecap=\"round\" \
             stroke-opacity=\"0.85\" fill=\"none\"/>",
            heat(t),
            2.8 + 2.8 * t
        );
    }
    // Rejected corners as crosses, one path.
    if !rejected.is_empty() {
        let mut seen = HashSet::new();
        let mut d = String::new();
        for x in rejected {
            let (sx, sy) = (p.x(x.px.x), p.y(x.px.y));
            let fresh = sx.is_finite()
                && sy.is_finite()
                && seen.insert(((sx / 3.0).floor() as i64, (sy / 3.0).floor() as i64));
            if !fresh {
                continue;
            }
            put!(d, "M{:.1} {:.1}l6 6m0 -6l-6 6", sx - 3.0, sy - 3.0);
        }
        put!(
            s,
            "<path d=\"{d}\" stroke=\"{REJECTED}\" stroke-width=\"1.3\" fill=\"none\"/>"
        );
    }
    // The mean residual per coverage cell as arrows.
    let (cols, rows) = r
        .coverage
        .get(c)
        .filter(|g| grid_ok(g))
        .map(|g| (g.cols, g.rows))
        .unwrap_or((12, 9));
    let mut sum = vec![(0.0f64, 0.0f64, 0usize); cols * rows];
    for x in used {
        let cx = ((x.px.x + 0.5) / p.img_w * cols as f64).floor();
        let cy = ((x.px.y + 0.5) / p.img_h * rows as f64).floor();
        if cx >= 0.0 && cy >= 0.0 && (cx as usize) < cols && (cy as usize) < rows {
            let e = &mut sum[cy as usize * cols + cx as usize];
            e.0 += x.r.x;
            e.1 += x.r.y;
            e.2 += 1;
        }
    }
    let means: Vec<(usize, f64, f64)> = sum
        .iter()
        .enumerate()
        .filter(|(_, e)| e.2 >= 3)
        .map(|(k, e)| (k, e.0 / e.2 as f64, e.1 / e.2 as f64))
        .filter(|m| m.1.is_finite() && m.2.is_finite())
        .collect();
    let longest = means.iter().map(|m| m.1.hypot(m.2)).fold(0.0f64, f64::max);
    let cell_px = (w / cols as f64).min(h / rows as f64);
    // Panel pixels per residual pixel; the longest arrow spans 45 % of a cell.
    let gain = if longest > 0.0 {
        0.45 * cell_px / longest
    } else {
        0.0
    };
    let mut d = String::new();
    for &(k, mx, my) in &means {
        let (cx, cy) = (k % cols, k / cols);
        let bx = x0 + (cx as f64 + 0.5) * w / cols as f64;
        let by = y0 + (cy as f64 + 0.5) * h / rows as f64;
        let (dx, dy) = (gain * mx, gain * my);
        let len = dx.hypot(dy);
        if len < 1.0 {
            put!(d, "M{:.1} {by:.1}h2", bx - 1.0);
            continue;
        }
        let (ux, uy) = (dx / len, dy / len);
        let head = len.min(5.0);
        let (ex, ey) = (bx + dx, by + dy);
        put!(
            d,
            "M{bx:.1} {by:.1}L{ex:.1} {ey:.1}M{:.1} {:.1}L{ex:.1} {ey:.1}L{:.1} {:.1}",
            ex - head * (ux - 0.5 * uy),
            ey - head * (uy + 0.5 * ux),
            ex - head * (ux + 0.5 * uy),
            ey - head * (uy - 0.5 * ux)
        );
    }
    if !d.is_empty() {
        put!(
            s,
            "<path d=\"{d}\" stroke=\"#111\" stroke-width=\"1.3\" fill=\"none\" \
             stroke-linecap=\"round\"/>"
        );
    }
    s.push_str("</g>");
    // Legend: colour bar, the rejected mark, the arrow scale.
    let ly = 34.0;
    let lx = p.left;
    put!(
        s,
        "<defs><linearGradient id=\"{id}-cb\" x1=\"0\" x2=\"1\" y1=\"0\" y2=\"0\">\
         <stop offset=\"0\" stop-color=\"{}\"/><stop offset=\"0.5\" stop-color=\"{}\"/>\
         <stop offset=\"1\" stop-color=\"{}\"/></linearGradient></defs>\
         <text x=\"{lx:.1}\" y=\"{:.1}\" class=\"l\">0</text>\
         <rect x=\"{:.1}\" y=\"{:.1}\" width=\"70\" height=\"9\" fill=\"url(#{id}-cb)\"/>\
         <text x=\"{:.1}\" y=\"{:.1}\" class=\"l\">{:.2} px</text>\
         <path d=\"M{:.1} {:.1}l6 6m0 -6l-6 6\" stroke=\"{REJECTED}\" stroke-width=\"1.3\"/>\
         <text x=\"{:.1}\" y=\"{:.1}\" class=\"l\">rejected</text>",
        heat(0.0),
        heat(0.5),
        heat(1.0),
        ly + 1.0,
        lx + 10.0,
        ly - 8.0,
        lx + 84.0,
        ly + 1.0,
        top,
        lx + 150.0,
        ly - 7.0,
        lx + 160.0,
        ly + 1.0
    );
    let magnify = if p.scale > 0.0 { gain / p.scale } else { 0.0 };
    if magnify > 0.0 {
        put!(
            s,
            "<text x=\"{:.1}\" y=\"{:.1}\" class=\"l\">arrows x{}</text>",
            lx + 218.0,
            ly + 1.0,
            escape(&format_tick(magnify, magnify.abs().max(1e-9) / 10.0))
        );
    }
    s.push_str("</svg>");
    format!(
        "The map shows {} used and {} rejected corners{}; dot colours run up to {:.2} px (the 99th \
         percentile of the residual lengths); the arrows are the mean residual of each cell with \
         at least 3 corners, magnified {:.0} times (the longest is {:.3} px).",
        used.len(),
        rejected.len(),
        if dots.len() < used.len() {
            format!(" ({} dots drawn, one per spot)", dots.len())
        } else {
            String::new()
        },
        top,
        magnify,
        longest
    )
}

/// The sentence on one camera's coverage.
fn coverage_words(c: usize, g: &Coverage) -> String {
    let empty = empty_regions(g);
    let fig = format!(
        "cam{c}: board corners fell in {:.0}% of the {} grid cells and reach {:.0}% of the way \
         from the principal point to the farthest image corner.",
        100.0 * g.covered_fraction,
        g.cols * g.rows,
        100.0 * g.radial_reach
    );
    if coverage_poor(g) || !empty.is_empty() {
        let where_ = if empty.is_empty() {
            if g.radial_reach < MIN_RADIAL_REACH {
                "the outer parts of the image, towards its corners".to_owned()
            } else {
                "the empty cells, scattered over the image".to_owned()
            }
        } else {
            format!("the {}", join_words(&empty))
        };
        format!(
            "{fig} Where there are no corners the distortion is a guess: nothing measured it in \
             {where_}. Record more views with the board there (moved to the image edges and \
             corners, and tilted) before relying on those parts of the image."
        )
    } else {
        format!("{fig} The distortion is measured over the whole image.")
    }
}

fn coverage(s: &mut String, r: &CamCalResult) {
    section(s, "coverage", "Coverage of the images");
    s.push_str(
        "<p>Each image divided into a grid; a cell's shade is the number of used corners in it \
         (darker: more), hatched red cells have none. The dashed ellipse is the reach of the \
         corners from the principal point (+): outside it the distortion is extrapolated.</p>\n",
    );
    if r.chain.cams.is_empty() {
        s.push_str("<p>The result holds no camera.</p></section>\n");
        return;
    }
    s.push_str("<div class=\"grid\">");
    let mut words = Vec::new();
    for (c, cam) in r.chain.cams.iter().enumerate() {
        let g = r.coverage.get(c).filter(|g| grid_ok(g));
        coverage_grid(s, c, cam, g);
        words.push(match g {
            Some(g) => coverage_words(c, g),
            None => format!("cam{c}: the result holds no coverage grid."),
        });
    }
    s.push_str("</div><ul>");
    for w in &words {
        put!(s, "<li>{}</li>", escape(w));
    }
    s.push_str("</ul></section>\n");
}

/// The coverage grid of camera `c`.
fn coverage_grid(s: &mut String, c: usize, cam: &Camera, g: Option<&Coverage>) {
    let p = ImagePanel::new(
        &format!("coverage-grid-cam{c}"),
        &format!("cam{c}: corners per image cell"),
        cam.width,
        cam.height,
        462.0,
        420.0,
    );
    p.open(s, g.is_none());
    let id = escape(&p.id);
    put!(
        s,
        "<defs><pattern id=\"{id}-hatch\" width=\"6\" height=\"6\" patternUnits=\"userSpaceOnUse\" \
         patternTransform=\"rotate(45)\"><rect width=\"6\" height=\"6\" fill=\"#fdecec\"/>\
         <line x1=\"0\" y1=\"0\" x2=\"0\" y2=\"6\" stroke=\"{REJECTED}\" stroke-width=\"1.2\"/>\
         </pattern></defs>"
    );
    p.frame(s, "#fcfcfc");
    let Some(g) = g else {
        p.note(s, "no coverage grid");
        s.push_str("</svg>");
        return;
    };
    let (x0, y0) = (p.x(-0.5), p.y(-0.5));
    let (w, h) = (p.img_w * p.scale, p.img_h * p.scale);
    let (cw, ch) = (w / g.cols as f64, h / g.rows as f64);
    let most = g.counts.iter().copied().max().unwrap_or(0);
    let label = cw >= 24.0 && ch >= 14.0;
    for (k, &n) in g.counts.iter().enumerate() {
        let (cx, cy) = ((k % g.cols) as f64, (k / g.cols) as f64);
        let (x, y) = (x0 + cx * cw, y0 + cy * ch);
        let fill = if n == 0 {
            format!("url(#{id}-hatch)")
        } else {
            shade((n as f64).ln_1p() / (most as f64).ln_1p().max(1e-9))
        };
        put!(
            s,
            "<rect x=\"{x:.1}\" y=\"{y:.1}\" width=\"{cw:.1}\" height=\"{ch:.1}\" fill=\"{fill}\" \
             stroke=\"#fff\" stroke-width=\"0.8\"/>"
        );
        if label && n > 0 {
            let dark = (n as f64).ln_1p() / (most as f64).ln_1p().max(1e-9) > 0.5;
            put!(
                s,
                "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\" class=\"c\" fill=\"{}\">{n}\
                 </text>",
                x + cw / 2.0,
                y + ch / 2.0 + 3.5,
                if dark { "#fff" } else { "#333" }
            );
        }
    }
    // The reach of the corners: the radius in normalised coordinates, drawn through fu and fv.
    let corner = [
        (0.0, 0.0),
        (p.img_w, 0.0),
        (0.0, p.img_h),
        (p.img_w, p.img_h),
    ]
    .iter()
    .map(|&(x, y)| ((x - 0.5 - cam.pu) / cam.fu).hypot((y - 0.5 - cam.pv) / cam.fv))
    .fold(0.0f64, f64::max);
    let reach = g.radial_reach * corner;
    let (ppx, ppy) = (p.x(cam.pu), p.y(cam.pv));
    put!(
        s,
        "<clipPath id=\"{id}-clip\"><rect x=\"{x0:.1}\" y=\"{y0:.1}\" width=\"{w:.1}\" \
         height=\"{h:.1}\"/></clipPath><g clip-path=\"url(#{id}-clip)\">"
    );
    if reach.is_finite() && reach > 0.0 {
        let (rx, ry) = (reach * cam.fu * p.scale, reach * cam.fv * p.scale);
        if rx.is_finite() && ry.is_finite() && ppx.is_finite() && ppy.is_finite() {
            put!(
                s,
                "<ellipse cx=\"{ppx:.1}\" cy=\"{ppy:.1}\" rx=\"{:.1}\" ry=\"{:.1}\" fill=\"none\" \
                 stroke=\"#111\" stroke-width=\"1.2\" stroke-dasharray=\"5 3\"/>",
                rx.abs(),
                ry.abs()
            );
        }
    }
    if ppx.is_finite() && ppy.is_finite() {
        put!(
            s,
            "<path d=\"M{:.1} {ppy:.1}h12M{ppx:.1} {:.1}v12\" stroke=\"#111\" \
             stroke-width=\"1.6\"/>",
            ppx - 6.0,
            ppy - 6.0
        );
    }
    s.push_str("</g>");
    // Legend.
    let (lx, ly) = (p.left, 34.0);
    put!(
        s,
        "<rect x=\"{lx:.1}\" y=\"{:.1}\" width=\"16\" height=\"10\" fill=\"url(#{id}-hatch)\" \
         stroke=\"#999\"/><text x=\"{:.1}\" y=\"{:.1}\" class=\"l\">no corner</text>\
         <rect x=\"{:.1}\" y=\"{:.1}\" width=\"16\" height=\"10\" fill=\"{}\"/>\
         <rect x=\"{:.1}\" y=\"{:.1}\" width=\"16\" height=\"10\" fill=\"{}\"/>\
         <text x=\"{:.1}\" y=\"{:.1}\" class=\"l\">1 to {most} corners per cell; {:.0}% of cells \
         covered</text>",
        ly - 9.0,
        lx + 20.0,
        ly,
        lx + 90.0,
        ly - 9.0,
        shade(0.0),
        lx + 106.0,
        ly - 9.0,
        shade(1.0),
        lx + 126.0,
        ly,
        100.0 * g.covered_fraction
    );
    s.push_str("</svg>");
}

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

fn frames(s: &mut String, r: &CamCalResult) {
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

fn camchain(s: &mut String, input: &CamCalReportInput) {
    section(s, "camchain", "Camchain file");
    if input.camchain_yaml.is_empty() {
        match &input.camchain_path {
            Some(p) => put!(s, "<p>Written to {}.</p>", escape(p)),
            None => s.push_str("<p>No camchain file was written with this report.</p>"),
        }
    } else {
        put!(
            s,
            "<details open><summary>{}</summary><pre>{}</pre></details>",
            escape(input.camchain_path.as_deref().unwrap_or("camchain.yaml")),
            escape(&input.camchain_yaml)
        );
    }
    if let Some(c) = &input.command {
        put!(s, "<p>Command: <code>{}</code></p>", escape(c));
    }
    s.push_str("</section>\n");
}

#[cfg(test)]
#[path = "cameras_tests.rs"]
mod tests;
