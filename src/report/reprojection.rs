//! Reprojection errors of the poses per camera: where on the image the corners fell and how far
//! their reprojection missed them, and each camera's error over time (image runs).
//!
//! The poses keep an evenly drawn sample of their corners (at most
//! [`CORNER_SAMPLE_PER_CAMERA`] per camera and frame, see [`crate::vision::pnp`]); over the
//! recording at most [`MAX_CORNERS_PER_CAMERA`] of them are drawn per camera, from every frame
//! or every k-th one, and the page says which.

use std::fmt::Write as _;

use super::input::FrameStat;
use super::svg::{Plot, Series, escape};
use crate::vision::pnp::{CORNER_SAMPLE_PER_CAMERA, CornerResidual};

/// Most corners drawn per camera over the whole recording.
pub(super) const MAX_CORNERS_PER_CAMERA: usize = 20_000;

/// Cameras whose plots are always on the page (empty when the run has fewer).
pub(super) const ALWAYS_SHOWN: usize = 2;

/// Error classes of the map, pixels: upper bounds, the last open.
const CLASSES: [(f64, &str, &str); 4] = [
    (0.25, "< 0.25 px", "#2ca25f"),
    (0.5, "0.25–0.5 px", "#a1d76a"),
    (1.0, "0.5–1 px", "#f1a340"),
    (f64::INFINITY, "≥ 1 px", "#d7301f"),
];

/// What one camera's plots show.
#[derive(Clone, Debug, Default)]
pub(super) struct CameraErrors {
    /// Drawn corners of the camera.
    pub corners: Vec<(f64, CornerResidual)>,
    /// Per posed frame with corners in the camera: time and RMS, px.
    pub rms: Vec<(f64, f64)>,
    /// Corners the frames kept for this camera.
    pub sampled: usize,
    /// Every `stride`-th frame's corners were drawn.
    pub stride: usize,
}

/// The corners and per-frame RMS of camera `c`.
pub(super) fn camera_errors(frames: &[FrameStat], c: usize) -> CameraErrors {
    let with: Vec<&FrameStat> = frames
        .iter()
        .filter(|f| f.corners.iter().any(|x| x.cam as usize == c))
        .collect();
    let sampled: usize = with
        .iter()
        .map(|f| f.corners.iter().filter(|x| x.cam as usize == c).count())
        .sum();
    // Every stride-th frame, so that even the fullest frames stay within the cap.
    let most = with
        .iter()
        .map(|f| f.corners.iter().filter(|x| x.cam as usize == c).count())
        .max()
        .unwrap_or(1);
    let frames_allowed = (MAX_CORNERS_PER_CAMERA / most.max(1)).max(1);
    let stride = with.len().div_ceil(frames_allowed).max(1);
    let corners = with
        .iter()
        .step_by(stride)
        .flat_map(|f| {
            f.corners
                .iter()
                .filter(|x| x.cam as usize == c)
                .map(|x| (f.t, *x))
        })
        .collect();
    let rms = frames
        .iter()
        .filter_map(|f| f.rms_px_per_cam.get(c).copied().flatten().map(|r| (f.t, r)))
        .collect();
    CameraErrors {
        corners,
        rms,
        sampled,
        stride,
    }
}

/// Cameras of the run: the most any frame has, or the image sizes given.
fn camera_count(frames: &[FrameStat], sizes: Option<&[(u32, u32)]>) -> usize {
    let from_frames = frames
        .iter()
        .map(|f| f.rms_px_per_cam.len())
        .max()
        .unwrap_or(0);
    from_frames.max(sizes.map_or(0, |s| s.len()))
}

/// The section: per camera a map over the image and the errors over time.
pub(super) fn reprojection_section(
    frames: Option<&[FrameStat]>,
    sizes: Option<&[(u32, u32)]>,
) -> String {
    let mut s =
        String::from("<section id=\"reprojection\"><h2>Reprojection errors per camera</h2>\n");
    let fr = frames.unwrap_or(&[]);
    let cams = camera_count(fr, sizes);
    let note = if frames.is_none() {
        "no image statistics: poses read from a file".to_owned()
    } else {
        String::new()
    };
    if frames.is_some() {
        let _ = writeln!(
            s,
            "<p>Left: the board corners each camera saw, at their detected position, coloured \
             by how far the pose reprojects them (a pattern here points at the lens model: \
             errors that grow toward the image edge mean a poor distortion model). Right: each \
             frame's reprojection RMS in that camera (dots) and the drawn corners' errors (grey) \
             over time. Each frame keeps up to {CORNER_SAMPLE_PER_CAMERA} of its corners per \
             camera for these plots, evenly spaced through the board; at most \
             {MAX_CORNERS_PER_CAMERA} per camera are drawn over the recording.</p>"
        );
    }
    let mut words = Vec::new();
    for c in 0..cams.max(ALWAYS_SHOWN) {
        let e = camera_errors(fr, c);
        let empty_note = if !note.is_empty() {
            note.clone()
        } else if c >= cams {
            format!("no cam{c} in this run")
        } else {
            format!("no corners of cam{c}")
        };
        let size = sizes.and_then(|v| v.get(c)).copied();
        let mut map = Plot::new(
            &format!("reprojection-map-cam{c}"),
            &format!("cam{c}: reprojection error over the image"),
            "u (px)",
            "v (px)",
        )
        .size(462.0, 340.0)
        .equal_aspect()
        .y_down()
        .empty_note(&empty_note);
        if let Some((w, h)) = size.filter(|_| !e.corners.is_empty()) {
            map = map
                .x_range(-0.5, w as f64 - 0.5)
                .y_range(-0.5, h as f64 - 0.5);
        }
        let mut counts = [0usize; 4];
        let mut lower = 0.0;
        for (k, &(upper, label, colour)) in CLASSES.iter().enumerate() {
            let pts: Vec<(f64, f64)> = e
                .corners
                .iter()
                .filter(|(_, x)| {
                    let m = x.norm();
                    m >= lower && m < upper
                })
                .map(|(_, x)| (x.u as f64, x.v as f64))
                .collect();
            lower = upper;
            counts[k] = pts.len();
            if !pts.is_empty() {
                map = map.series(Series::dots(label, colour, pts).size(3.0 + k as f64));
            }
        }
        let mut errs: Vec<f64> = e.corners.iter().map(|(_, x)| x.norm()).collect();
        errs.sort_by(f64::total_cmp);
        let p99 = errs
            .get(((errs.len() as f64 * 0.99) as usize).min(errs.len().saturating_sub(1)))
            .copied()
            .unwrap_or(0.0);
        let rms_top = e.rms.iter().map(|r| r.1).fold(0.0, f64::max);
        let top = (1.1 * p99.max(rms_top)).max(0.05);
        let beyond = errs.iter().filter(|&&m| m > top).count();
        let corner_pts: Vec<(f64, f64)> = e
            .corners
            .iter()
            .map(|(t, x)| (*t, x.norm().min(top)))
            .collect();
        let time = Plot::new(
            &format!("reprojection-time-cam{c}"),
            &format!("cam{c}: reprojection error over time"),
            "camera time (s)",
            "px",
        )
        .size(462.0, 340.0)
        .y_range(0.0, top)
        .empty_note(&empty_note)
        .series(Series::dots("corner", "#9e9e9e", corner_pts).size(2.0))
        .series(Series::dots("frame RMS", "#1a63c2", e.rms.clone()).size(3.5));
        s.push_str("<div class=\"grid\">");
        s.push_str(&map.render());
        s.push_str(&time.render());
        s.push_str("</div>\n");
        if !e.rms.is_empty() || !e.corners.is_empty() {
            let sq: f64 = e.rms.iter().map(|r| r.1 * r.1).sum();
            let mut w = format!(
                "cam{c}: {} frames with corners, per-frame RMS {:.3} px on average (quadratic \
                 mean); {} corners drawn of the {} kept ({}); by error {} / {} / {} / {} \
                 (< 0.25, 0.25–0.5, 0.5–1, ≥ 1 px)",
                e.rms.len(),
                (sq / e.rms.len().max(1) as f64).sqrt(),
                e.corners.len(),
                e.sampled,
                if e.stride == 1 {
                    "from every frame".to_owned()
                } else {
                    format!("from one frame in {}", e.stride)
                },
                counts[0],
                counts[1],
                counts[2],
                counts[3]
            );
            if beyond > 0 {
                let _ = write!(
                    w,
                    "; {beyond} corners beyond {top:.2} px drawn on the top edge over time"
                );
            }
            words.push(w);
        }
    }
    if !words.is_empty() {
        let _ = write!(
            s,
            "<p class=\"meta\" id=\"reprojection-words\">{}.</p>",
            escape(&words.join(". "))
        );
    }
    s.push_str("</section>\n");
    s
}
