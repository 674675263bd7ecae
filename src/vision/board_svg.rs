//! A board as an SVG to print at exact scale: each tag's cells from libapriltag's family data,
//! the paper around them, and the board definition printed underneath. A board read from a
//! Kalibr aprilgrid YAML is printed as Kalibr prints it ([`TagPrint::Kalibr`]): two-bit borders
//! and the corner squares (group `corner-squares`), so that Kalibr reads the same sheet.
//!
//! Outside the board's paper, where nothing can disturb the detector, the sheet carries what a
//! user needs to check and use the print:
//! - a scale bar of known length (group `scale-bar`, its length in `data-length-mm`), to measure
//!   after printing;
//! - the tag ids of each row of tags in the left and right margins (group `id-labels`): the
//!   first and last id of the row, or every id of a row whose ids do not run one by one;
//! - the board frame (group `board-axes`): ticks at the origin's x and y on the board's bottom
//!   and left edges, and arrows for x (right) and y (up); z points out of the page.
//!
//! A board that names its paper ([`Board::paper`]) is printed on a sheet of exactly that size:
//! the SVG's width and height are the paper's, the board is centred across it and as near its
//! middle as the legend below allows, and everything drawn keeps [`PRINTER_MARGIN_MM`] from the
//! edges, the margin printers cannot print. A board too large for its paper is an error that
//! says how large the sheet would have to be and, for a grid, the largest tag size that fits.

use std::fmt::Write as _;

use nalgebra::Vector2;

use crate::error::{Error, Result};
use crate::io::target::board_yaml;
use crate::types::board::{Board, GridLayout, Paper, TagPrint};
use crate::vision::family::{family_layout, tags_cells};
use crate::vision::kalibr::{KALIBR_CELLS_ACROSS, kalibr_tag_cells};

/// Lines of the board definition printed under the board.
fn legend(board: &Board, source: &str) -> Vec<String> {
    let mut v = vec![format!("{}  ({})", board.description, source)];
    for l in board_yaml(board).lines().filter(|l| !l.starts_with('#')) {
        v.push(l.to_owned());
    }
    v.push("Print at 100 % scale, no fitting to the page; measure a tag's black square and correct tag_size if it differs.".into());
    v
}

/// `line` cut at spaces into lines of at most `columns` characters (a longer word stays whole);
/// continuation lines keep the first line's indentation.
fn wrap(line: &str, columns: usize) -> Vec<String> {
    let indent: String = line.chars().take_while(|c| *c == ' ').collect();
    let mut out: Vec<String> = Vec::new();
    let mut cur = indent.clone();
    for word in line.split(' ').filter(|w| !w.is_empty()) {
        let len = cur.chars().count();
        if len > indent.len() && len + 1 + word.chars().count() > columns {
            out.push(std::mem::replace(&mut cur, indent.clone()));
        }
        if cur.len() > indent.len() {
            cur.push(' ');
        }
        cur.push_str(word);
    }
    out.push(cur);
    out
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The margin kept free at each edge of a named paper, mm: most printers cannot print the
/// outer 3 to 6 mm, and some scale a page to fit what they can print.
pub const PRINTER_MARGIN_MM: f64 = 10.0;

/// Where the sheet drawn at its natural size (`page`: width and height, mm, holding a board of
/// `board_h` mm at `top` mm from its top) goes on `paper`: the offset of its top-left corner.
/// Centred across; down, the board's middle at the paper's as far as the margins allow. An
/// error when it does not fit inside the margins; `grid_tag` (a grid board's tag size, m, with
/// the board's width and height, mm) gives the largest tag size that fits.
fn place_on_paper(
    paper: &Paper,
    page: (f64, f64),
    board: (f64, f64),
    top: f64,
    grid_tag: Option<f64>,
) -> Result<(f64, f64)> {
    let m = PRINTER_MARGIN_MM;
    let (room_w, room_h) = (paper.width_mm - 2.0 * m, paper.height_mm - 2.0 * m);
    if page.0 > room_w + 1e-9 || page.1 > room_h + 1e-9 {
        let fit = match grid_tag {
            Some(tag) => {
                // Only the board grows with the tag size; the bands around it stay.
                let f = ((room_w - (page.0 - board.0)) / board.0)
                    .min((room_h - (page.1 - board.1)) / board.1);
                let mm = (tag * f * 1e3 * 10.0).floor() / 10.0;
                if mm > 0.0 {
                    format!("a tag_size of at most {:.4} m fits", mm * 1e-3)
                } else {
                    "no tag size fits: fewer rows or columns".to_owned()
                }
            }
            None => "smaller tags or tags closer together".to_owned(),
        };
        return Err(Error::Input(format!(
            "the board and its margins need {:.1} x {:.1} mm, and {paper} leaves {:.1} x {:.1} \
             mm inside its {m} mm printer margins: {fit}, or name a larger paper",
            page.0, page.1, room_w, room_h
        )));
    }
    let dx = (paper.width_mm - page.0) / 2.0;
    let centred = paper.height_mm / 2.0 - (top + board.1 / 2.0);
    let dy = centred.clamp(m, paper.height_mm - m - page.1);
    Ok((dx, dy))
}

/// The SVG text of a board. Tags must lie in the board's z = 0 plane (grid boards always do).
/// With [`Board::paper`], the SVG is the paper's size (see the module documentation).
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
    let mut lines = legend(board, source);
    let font = 3.0; // mm
    let margin = 2.0; // mm around the paper
    let board_w = (hi.0 - lo.0) * 1e3;
    let board_h = (hi.1 - lo.1) * 1e3;
    let rows = tag_rows(board);
    // Bands outside the paper: ids left and right, axes and the scale bar below.
    let label_w = |row: &TagRow| row.label(true).len().max(row.label(false).len()) as f64;
    let chars = rows.iter().map(label_w).fold(4.0, f64::max);
    let side = margin + chars * LABEL_FONT * 0.62 + ID_GAP;
    let bottom = 24.0;
    let scale_mm = scale_bar_length(board_w + side - margin);
    let origin_mm = (-lo.0 * 1e3, -lo.1 * 1e3);
    lines.push(format!(
        "Board frame: origin at the ticks marked 0 ({:.1} mm from the left edge of the board's \
         paper, {:.1} mm from its bottom edge); x to the right, y up, z out of the page.",
        origin_mm.0, origin_mm.1
    ));
    let page_w = board_w + 2.0 * side;
    // Monospace characters are about 0.6 of the font size wide; wrap to the page.
    let columns = ((page_w - side) / (font * 0.6)).floor().max(20.0) as usize;
    let lines: Vec<String> = lines.iter().flat_map(|l| wrap(l, columns)).collect();
    let page_h = board_h + margin + bottom + lines.len() as f64 * font * 1.3;
    // On a named paper the whole drawing moves by (dx, dy) and the sheet is the paper.
    let (dx, dy, sheet_w, sheet_h) = match &board.paper {
        Some(p) => {
            let tag = board.grid.map(|g| g.tag_size_m);
            let (dx, dy) = place_on_paper(p, (page_w, page_h), (board_w, board_h), margin, tag)?;
            (dx, dy, p.width_mm, p.height_mm)
        }
        None => (0.0, 0.0, page_w, page_h),
    };
    // The board's paper: its top-left corner on the sheet.
    let (x0, y0) = (dx + side, dy + margin);
    let mut s = String::new();
    let _ = writeln!(
        s,
        r##"<?xml version="1.0" encoding="UTF-8"?>
<svg xmlns="http://www.w3.org/2000/svg" width="{sheet_w:.3}mm" height="{sheet_h:.3}mm" viewBox="0 0 {sheet_w:.4} {sheet_h:.4}">
<title>{}</title>
<rect x="0" y="0" width="{sheet_w:.4}" height="{sheet_h:.4}" fill="white"/>
<rect x="{x0:.4}" y="{y0:.4}" width="{board_w:.4}" height="{board_h:.4}" fill="white" stroke="#bbbbbb" stroke-width="0.1"/>"##,
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
        let e = bx - lo.0 * 1e3 + x0;
        let f = hi.1 * 1e3 - by + y0;
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
                let px = x - lo.0 * 1e3 + x0;
                let py = hi.1 * 1e3 - y_top + y0;
                let _ = writeln!(
                    s,
                    r#"<rect x="{px:.4}" y="{py:.4}" width="{gap:.4}" height="{gap:.4}"/>"#
                );
            }
        }
        s.push_str("</g>\n");
    }
    // Board point (mm) -> page (mm).
    let page = |x: f64, y: f64| (x - lo.0 * 1e3 + x0, hi.1 * 1e3 - y + y0);
    id_labels(&mut s, &rows, &page, x0, board_w);
    let paper_bottom = y0 + board_h;
    board_axes(&mut s, page(0.0, 0.0), (x0, x0 + board_w), paper_bottom, dy);
    scale_bar(&mut s, x0, paper_bottom + 14.0, scale_mm);
    let mut y = paper_bottom + bottom + font;
    for l in &lines {
        let _ = writeln!(
            s,
            r#"<text x="{x0:.3}" y="{y:.3}" font-family="monospace" font-size="{font}" fill="black" xml:space="preserve">{}</text>"#,
            escape(l)
        );
        y += font * 1.3;
    }
    s.push_str("</svg>\n");
    Ok(s)
}

/// Font size of the margin labels, mm.
const LABEL_FONT: f64 = 3.5;

/// Room between the left id labels and the paper, for the y axis, mm.
const ID_GAP: f64 = 9.0;

/// Tags whose centres lie at one height of the board: a printed row.
struct TagRow {
    /// Centre height, mm in the board frame.
    y_mm: f64,
    /// Ids in order of x.
    ids: Vec<u32>,
}

impl TagRow {
    /// The label beside the row: its first (left) or last (right) id when the ids run one by
    /// one from left to right, otherwise every id on the left and nothing on the right.
    fn label(&self, left: bool) -> String {
        let run = self.ids.windows(2).all(|w| w[1] == w[0] + 1);
        match (run, left, self.ids.first(), self.ids.last()) {
            (true, true, Some(a), _) => format!("{a}"),
            (true, false, _, Some(b)) if self.ids.len() > 1 => format!("{b}"),
            (false, true, _, _) => self
                .ids
                .iter()
                .map(u32::to_string)
                .collect::<Vec<_>>()
                .join(" "),
            _ => String::new(),
        }
    }
}

/// The board's tags grouped into rows by the height of their centres (within half the smallest
/// tag), bottom row first.
fn tag_rows(board: &Board) -> Vec<TagRow> {
    let mut centres: Vec<(f64, f64, u32, f64)> = board
        .tags
        .iter()
        .map(|t| {
            let c = t.pose().trans * 1e3;
            (c.y, c.x, t.id, t.size_m * 1e3)
        })
        .collect();
    centres.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    // Per row: the first centre's height, the smallest tag, and (x, id, y) of each member.
    type Members = Vec<(f64, u32, f64)>;
    let mut rows: Vec<(f64, f64, Members)> = Vec::new();
    for (y, x, id, size) in centres {
        match rows.last_mut() {
            Some((y0, s0, members)) if (y - *y0).abs() < 0.5 * size.min(*s0) => {
                *s0 = s0.min(size);
                members.push((x, id, y));
            }
            _ => rows.push((y, size, vec![(x, id, y)])),
        }
    }
    rows.into_iter()
        .map(|(_, _, mut m)| {
            m.sort_by(|a, b| a.0.total_cmp(&b.0));
            TagRow {
                y_mm: m.iter().map(|r| r.2).sum::<f64>() / m.len() as f64,
                ids: m.into_iter().map(|(_, id, _)| id).collect(),
            }
        })
        .collect()
}

/// The ids of each row in the side margins, level with the row's centres.
fn id_labels(
    s: &mut String,
    rows: &[TagRow],
    page: &dyn Fn(f64, f64) -> (f64, f64),
    side: f64,
    board_w: f64,
) {
    let _ = writeln!(
        s,
        r#"<g id="id-labels" font-family="monospace" font-size="{LABEL_FONT}" fill="black">"#
    );
    for row in rows {
        let (_, y) = page(0.0, row.y_mm);
        let y = y + LABEL_FONT * 0.35;
        let (left, right) = (row.label(true), row.label(false));
        let _ = writeln!(
            s,
            r#"<text x="{:.3}" y="{y:.3}" text-anchor="end" data-ids="{}">{}</text>"#,
            side - ID_GAP,
            row.ids
                .iter()
                .map(u32::to_string)
                .collect::<Vec<_>>()
                .join(" "),
            escape(&left)
        );
        if !right.is_empty() {
            let _ = writeln!(
                s,
                r#"<text x="{:.3}" y="{y:.3}">{}</text>"#,
                side + board_w + 2.0,
                escape(&right)
            );
        }
    }
    s.push_str("</g>\n");
}

/// Ticks at the board origin's x (below the paper) and y (left of it), marked 0, and arrows
/// along the board's x and y axes in the margins. `origin` is the origin on the page; `span` the
/// paper's left and right edges; `bottom` its bottom edge; `top` the top of the drawing (all
/// mm).
fn board_axes(s: &mut String, origin: (f64, f64), span: (f64, f64), bottom: f64, top: f64) {
    let (ox, oy) = origin;
    let (left, right) = span;
    let red = "#c0392b";
    let green = "#1e8449";
    let _ = writeln!(
        s,
        r#"<g id="board-axes" data-origin-x-mm="{ox:.4}" data-origin-y-mm="{oy:.4}" stroke-width="0.3" font-family="monospace" font-size="{LABEL_FONT}">"#
    );
    // x: a tick under the paper at the origin's x, an arrow to the right.
    if (left..=right).contains(&ox) {
        let _ = writeln!(
            s,
            r#"<line x1="{ox:.4}" y1="{bottom:.4}" x2="{ox:.4}" y2="{:.4}" stroke="{red}"/>"#,
            bottom + 4.0
        );
        let y = bottom + 2.5;
        let end = (ox + 25.0).min(right + 8.0);
        let _ = writeln!(
            s,
            r#"<line x1="{ox:.4}" y1="{y:.4}" x2="{end:.4}" y2="{y:.4}" stroke="{red}"/>"#
        );
        let _ = writeln!(
            s,
            r#"<path d="M {end:.4} {y:.4} l -2 -1 l 0 2 z" fill="{red}" stroke="none"/>"#
        );
        let _ = writeln!(
            s,
            r#"<text x="{:.4}" y="{:.4}" fill="{red}" stroke="none">0</text>"#,
            ox - 1.0,
            bottom + 4.0 + LABEL_FONT
        );
        let _ = writeln!(
            s,
            r#"<text x="{:.4}" y="{:.4}" fill="{red}" stroke="none">x</text>"#,
            end + 1.0,
            y + 1.2
        );
    }
    // y: a tick left of the paper at the origin's y, an arrow up.
    if oy >= top && oy <= bottom {
        let x = left - 3.5;
        let _ = writeln!(
            s,
            r#"<line x1="{left:.4}" y1="{oy:.4}" x2="{:.4}" y2="{oy:.4}" stroke="{green}"/>"#,
            left - 5.0
        );
        let end = (oy - 25.0).max(top + 1.0);
        let _ = writeln!(
            s,
            r#"<line x1="{x:.4}" y1="{oy:.4}" x2="{x:.4}" y2="{end:.4}" stroke="{green}"/>"#
        );
        let _ = writeln!(
            s,
            r#"<path d="M {x:.4} {end:.4} l -1 2 l 2 0 z" fill="{green}" stroke="none"/>"#
        );
        let _ = writeln!(
            s,
            r#"<text x="{:.4}" y="{:.4}" fill="{green}" stroke="none" text-anchor="end">0</text>"#,
            left - 5.5,
            oy + 1.2
        );
        let _ = writeln!(
            s,
            r#"<text x="{:.4}" y="{:.4}" fill="{green}" stroke="none" text-anchor="end">y</text>"#,
            x - 1.0,
            end + 2.0
        );
    }
    s.push_str("</g>\n");
}

/// The longest of 200, 100, 50, 20 and 10 mm that fits in `room` mm (10 mm at the least).
fn scale_bar_length(room: f64) -> f64 {
    [200.0, 100.0, 50.0, 20.0, 10.0]
        .into_iter()
        .find(|&l| l <= room)
        .unwrap_or(10.0)
}

/// A scale bar of `length` mm from (x, y): alternate black and white 10 mm (or 5 mm) segments
/// in a black outline, its length written beside it.
fn scale_bar(s: &mut String, x: f64, y: f64, length: f64) {
    let step = if length >= 50.0 { 10.0 } else { 5.0 };
    let h = 2.0;
    let _ = writeln!(
        s,
        r#"<g id="scale-bar" data-length-mm="{length}" shape-rendering="crispEdges">"#
    );
    let n = (length / step).round() as usize;
    for k in (0..n).step_by(2) {
        let _ = writeln!(
            s,
            r#"<rect x="{:.4}" y="{y:.4}" width="{step}" height="{h}" fill="black"/>"#,
            x + k as f64 * step
        );
    }
    let _ = writeln!(
        s,
        r#"<rect x="{x:.4}" y="{y:.4}" width="{length}" height="{h}" fill="none" stroke="black" stroke-width="0.2"/>"#
    );
    let _ = writeln!(
        s,
        r#"<text x="{x:.4}" y="{:.4}" font-family="monospace" font-size="3" fill="black">{length} mm: measure this bar after printing; if it is not {length} mm, the print was scaled</text>"#,
        y + h + 4.0
    );
    s.push_str("</g>\n");
}

/// The white paper of a grid board in the board plane: lower-left and upper-right corners. The
/// margin around the outer tags' black squares is the gap between tags, and at least the pattern's
/// own white ring plus one cell; for a Kalibr print, the gap (where the outer corner squares
/// end) plus two bits.
pub fn grid_paper(board: &Board, g: &GridLayout) -> (Vector2<f64>, Vector2<f64>) {
    let layout = family_layout(board.family);
    let (tw, wab) = layout
        .map(|l| (l.total_width as f64, l.width_at_border.max(1) as f64))
        .unwrap_or((10.0, 8.0));
    let cell = g.tag_size_m / wab;
    let margin = match board.print {
        TagPrint::Apriltag => (g.spacing * g.tag_size_m).max(((tw - wab) / 2.0 + 1.0) * cell),
        // The outer corner squares reach `spacing * tag size` out; two bits of white beyond.
        TagPrint::Kalibr => (g.spacing + 0.2) * g.tag_size_m,
    };
    let d = g.tag_size_m * (1.0 + g.spacing);
    let w = (g.cols as f64 - 1.0) * d + g.tag_size_m;
    let h = (g.rows as f64 - 1.0) * d + g.tag_size_m;
    (
        Vector2::new(-margin, -margin),
        Vector2::new(w + margin, h + margin),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lie::Se3;
    use crate::types::board::{BoardTag, TagFamily};
    use nalgebra::{Matrix3, Vector3};

    fn list_board(tags: &[(u32, f64, f64)]) -> Board {
        Board {
            family: TagFamily::Tag36h11,
            tags: tags
                .iter()
                .map(|&(id, x, y)| {
                    BoardTag::from_pose(
                        id,
                        0.05,
                        &Se3::new(Matrix3::identity(), Vector3::new(x, y, 0.0)),
                    )
                })
                .collect(),
            description: "list".into(),
            grid: None,
            print: TagPrint::Apriltag,
            paper: None,
        }
    }

    #[test]
    fn rows_group_by_height_and_read_left_to_right() {
        // Two rows; the upper one slightly uneven and its ids out of order.
        let b = list_board(&[
            (7, 0.2, 0.0),
            (5, 0.0, 0.0),
            (6, 0.1, 0.0),
            (9, 0.1, 0.101),
            (3, 0.0, 0.1),
            (12, 0.2, 0.099),
        ]);
        let rows = tag_rows(&b);
        assert_eq!(rows.len(), 2);
        assert_eq!(rows[0].ids, vec![5, 6, 7]);
        assert_eq!(
            (rows[0].label(true), rows[0].label(false)),
            ("5".into(), "7".into())
        );
        assert!((rows[0].y_mm - 0.0).abs() < 1e-9);
        assert_eq!(rows[1].ids, vec![3, 9, 12]);
        assert_eq!(rows[1].label(true), "3 9 12");
        assert_eq!(rows[1].label(false), "");
        assert!((rows[1].y_mm - 100.0).abs() < 1e-9);
    }

    #[test]
    fn a_list_board_prints_every_id_and_the_origin() {
        let b = list_board(&[(1, 0.0, 0.0), (4, 0.1, 0.0), (2, 0.05, 0.1)]);
        let svg = board_svg(&b, "list.yaml").unwrap_or_default();
        assert!(svg.contains(r#"data-ids="1 4""#), "{svg}");
        assert!(svg.contains(r#"data-ids="2""#));
        assert!(svg.contains(r#"<g id="board-axes""#));
        assert!(svg.contains(r#"<g id="scale-bar" data-length-mm="100""#));
    }

    #[test]
    fn the_scale_bar_is_the_longest_round_length_that_fits() {
        assert_eq!(scale_bar_length(500.0), 200.0);
        assert_eq!(scale_bar_length(199.0), 100.0);
        assert_eq!(scale_bar_length(60.0), 50.0);
        assert_eq!(scale_bar_length(12.0), 10.0);
        assert_eq!(scale_bar_length(3.0), 10.0);
    }

    #[test]
    fn long_legend_lines_wrap_at_spaces_keeping_their_indent() {
        let w = wrap("  aaa bbb ccc ddd", 9);
        assert_eq!(w, vec!["  aaa bbb", "  ccc ddd"]);
        assert_eq!(
            wrap("averyveryverylongword x", 5),
            vec!["averyveryverylongword", "x"]
        );
        assert_eq!(wrap("short", 80), vec!["short"]);
    }
}
