//! A board as an SVG to print at exact scale: each tag's cells from libapriltag's family data,
//! the paper around them, and the board definition printed underneath. A board read from a
//! Kalibr aprilgrid YAML is printed as Kalibr prints it ([`TagPrint::Kalibr`]): two-bit borders
//! and the corner squares (group `corner-squares`), so that Kalibr reads the same sheet.

use std::fmt::Write as _;

use crate::vision::board::{Board, TagPrint, grid_paper};
use crate::vision::family::tags_cells;
use crate::vision::kalibr::{KALIBR_CELLS_ACROSS, kalibr_tag_cells};
use crate::{Error, Result};

/// Lines of the board definition printed under the board.
fn legend(board: &Board, source: &str) -> Vec<String> {
    let mut v = vec![format!("{}  ({})", board.description, source)];
    for l in board.to_yaml().lines().filter(|l| !l.starts_with('#')) {
        v.push(l.to_owned());
    }
    v.push("Print at 100 % scale, no fitting to the page; measure a tag's black square and correct tag_size if it differs.".into());
    v
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The SVG text of a board. Tags must lie in the board's z = 0 plane (grid boards always do).
pub fn board_svg(board: &Board, source: &str) -> Result<String> {
    let ids: Vec<u32> = board.tags.iter().map(|t| t.id).collect();
    let family_err = || {
        Error::Input(format!(
            "libapriltag could not read the family {}",
            board.family
        ))
    };
    // Cells across the whole pattern and across the black square, and each tag's cells.
    let (tw, wab, cells) = match board.print {
        TagPrint::Apriltag => {
            let (layout, cells) = tags_cells(board.family, &ids).ok_or_else(family_err)?;
            (
                layout.total_width as f64,
                layout.width_at_border.max(1) as f64,
                cells,
            )
        }
        TagPrint::Kalibr => {
            let cells = kalibr_tag_cells(&ids).ok_or_else(family_err)?;
            let n = KALIBR_CELLS_ACROSS as f64;
            (n, n, cells)
        }
    };
    let off = (tw - wab) / 2.0;
    if let Some(t) = board
        .tags
        .iter()
        .find(|t| t.corners.iter().any(|c| c.z.abs() > 1e-9))
    {
        return Err(Error::Input(format!(
            "tag {} is not in the board's z = 0 plane; only flat boards can be printed as one sheet",
            t.id
        )));
    }
    // Paper: the grid's margin, or one cell around each listed tag's pattern.
    let (lo, hi) = match &board.grid {
        Some(g) => {
            let (lo, hi) = grid_paper(board, g);
            ((lo.x, lo.y), (hi.x, hi.y))
        }
        None => {
            let (mut lo, mut hi) = ((f64::MAX, f64::MAX), (f64::MIN, f64::MIN));
            for t in &board.tags {
                let c = t.size_m / wab;
                let pose = t.pose();
                let h = t.size_m / 2.0 + (off + 1.0) * c;
                for (sx, sy) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                    let p = pose.transform_point(&nalgebra::Vector3::new(sx * h, sy * h, 0.0));
                    lo = (lo.0.min(p.x), lo.1.min(p.y));
                    hi = (hi.0.max(p.x), hi.1.max(p.y));
                }
            }
            (lo, hi)
        }
    };
    let lines = legend(board, source);
    let font = 3.0; // mm
    let margin = 2.0; // mm around the paper
    let board_w = (hi.0 - lo.0) * 1e3;
    let board_h = (hi.1 - lo.1) * 1e3;
    let page_w = board_w + 2.0 * margin;
    let page_h = board_h + 2.0 * margin + lines.len() as f64 * font * 1.3;
    let mut s = String::new();
    let _ = writeln!(
        s,
        r##"<?xml version="1.0" encoding="UTF-8"?>
<svg xmlns="http://www.w3.org/2000/svg" width="{page_w:.3}mm" height="{page_h:.3}mm" viewBox="0 0 {page_w:.4} {page_h:.4}">
<title>{}</title>
<rect x="0" y="0" width="{page_w:.4}" height="{page_h:.4}" fill="white"/>
<rect x="{margin}" y="{margin}" width="{board_w:.4}" height="{board_h:.4}" fill="white" stroke="#bbbbbb" stroke-width="0.1"/>"##,
        escape(&board.description)
    );
    // Board point (m) -> page (mm): x right from lo.x, y down from hi.y.
    for (t, c) in board.tags.iter().zip(&cells) {
        let Some(c) = c else {
            return Err(Error::Input(format!(
                "tag id {} does not exist in {}",
                t.id,
                board.family.name()
            )));
        };
        let cell = t.size_m / wab * 1e3;
        let o = t.corners[0];
        let ax = (t.corners[1] - t.corners[0]).normalize();
        let ay = (t.corners[3] - t.corners[0]).normalize();
        // Cell coordinates (u = column, v = row from the top) -> page.
        let a = cell * ax.x;
        let b = -cell * ax.y;
        let cc = -cell * ay.x;
        let d = cell * ay.y;
        let bx = o.x * 1e3 + cell * (-off * ax.x + (tw - off) * ay.x);
        let by = o.y * 1e3 + cell * (-off * ax.y + (tw - off) * ay.y);
        let e = bx - lo.0 * 1e3 + margin;
        let f = hi.1 * 1e3 - by + margin;
        let _ = writeln!(
            s,
            r#"<g id="tag{}" transform="matrix({a:.6} {b:.6} {cc:.6} {d:.6} {e:.4} {f:.4})" fill="black" shape-rendering="crispEdges">"#,
            t.id
        );
        for (r, row) in c.iter().enumerate() {
            // Runs of black cells as single rectangles (no seams between neighbours).
            let mut col = 0;
            while col < row.len() {
                if row[col] {
                    let start = col;
                    while col < row.len() && row[col] {
                        col += 1;
                    }
                    let _ = writeln!(
                        s,
                        r#"<rect x="{start}" y="{r}" width="{}" height="1"/>"#,
                        col - start
                    );
                } else {
                    col += 1;
                }
            }
        }
        s.push_str("</g>\n");
    }
    // Kalibr's corner squares: one at every crossing of the gaps between tags (each touches the
    // corners of up to four tags), edge `spacing * tag size`.
    if let (TagPrint::Kalibr, Some(g)) = (board.print, &board.grid) {
        let s_mm = g.tag_size_m * 1e3;
        let gap = g.spacing * s_mm;
        let pitch = s_mm + gap;
        s.push_str("<g id=\"corner-squares\" fill=\"black\" shape-rendering=\"crispEdges\">\n");
        for r in 0..=g.rows {
            for c in 0..=g.cols {
                // Board-plane lower-left corner of the square, then its top-left on the page.
                let x = c as f64 * pitch - gap;
                let y_top = r as f64 * pitch;
                let px = x - lo.0 * 1e3 + margin;
                let py = hi.1 * 1e3 - y_top + margin;
                let _ = writeln!(
                    s,
                    r#"<rect x="{px:.4}" y="{py:.4}" width="{gap:.4}" height="{gap:.4}"/>"#
                );
            }
        }
        s.push_str("</g>\n");
    }
    let mut y = margin + board_h + margin * 0.5 + font;
    for l in &lines {
        let _ = writeln!(
            s,
            r#"<text x="{margin}" y="{y:.3}" font-family="monospace" font-size="{font}" fill="black" xml:space="preserve">{}</text>"#,
            escape(l)
        );
        y += font * 1.3;
    }
    s.push_str("</svg>\n");
    Ok(s)
}
