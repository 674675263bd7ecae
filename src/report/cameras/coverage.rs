//! The coverage of every image by board corners: the grid of corner counts with the reach of
//! the corners drawn over it, and the parts of the image the distortion is not measured in.

use std::fmt::Write as _;

use super::panel::{ImagePanel, shade};
use super::shared::{REJECTED, coverage_poor, grid_ok};
use crate::camcal::quality::{MIN_RADIAL_REACH, empty_regions};
use crate::camcal::{CamCalResult, Coverage};
use crate::report::html::{join_words, put, section};
use crate::report::svg::escape;
use crate::types::camera::Camera;

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

pub(super) fn coverage(s: &mut String, r: &CamCalResult) {
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
