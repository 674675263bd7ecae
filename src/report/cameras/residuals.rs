//! The reprojection residuals per camera: a histogram of their components against the
//! estimated corner noise, and a map of them over the image.

use std::collections::{HashMap, HashSet};
use std::fmt::Write as _;

use super::panel::{ImagePanel, heat};
use super::shared::{REJECTED, grid_ok};
use crate::camcal::{CamCalResult, Residual};
use crate::report::html::{put, robust_half_range, section};
use crate::report::svg::{Histogram, Plot, Series, escape, format_tick};
use crate::types::camera::Camera;

const NOISE: &str = "#2a9d3a";
const X_COLOR: &str = "#1a63c2";
const Y_COLOR: &str = "#e8710a";

/// The residuals of camera `c`: used and rejected.
fn cam_residuals(r: &CamCalResult, c: usize) -> (Vec<&Residual>, Vec<&Residual>) {
    r.residuals
        .iter()
        .filter(|x| x.cam == c)
        .partition(|x| x.used)
}

pub(super) fn residuals(s: &mut String, r: &CamCalResult) {
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
