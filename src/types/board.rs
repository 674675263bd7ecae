//! Calibration boards: which AprilTags there are, and where each tag's corners lie in the board
//! frame. Pure geometry: the board files are read and written by `io::target`, the tags drawn
//! and detected by `vision`.
//!
//! Board frame (Kalibr's): origin at the bottom-left corner of the first tag's black square, x
//! along the columns, y along the rows, z out of the board (towards a camera that sees it).
//! Tags are printed in apriltag's canonical orientation: upright when the board is viewed from the
//! front with x to the right and y up.
//!
//! # Corner order
//!
//! [`BoardTag::corners`] lists the corners of the tag's black square (its `width_at_border`
//! square for the families whose data bits lie outside the border) in the order libapriltag
//! reports `p[0..4]`: counter-clockwise seen from the front, starting at the bottom-left:
//!
//! ```text
//!   3 ---- 2        y
//!   |  tag |        ^
//!   0 ---- 1        +--> x
//! ```
//!
//! `tests/vision_render.rs` checks this order against the detector on rendered images.

use nalgebra::Vector3;

use crate::lie::Se3;

/// One tag of a board.
#[derive(Clone, Debug, PartialEq)]
pub struct BoardTag {
    /// The tag's id (code index) in the board's family.
    pub id: u32,
    /// Edge of the tag's black square, m.
    pub size_m: f64,
    /// The four corners of the tag's black square in the board frame, in the order libapriltag
    /// reports detected corners (`p[0..4]`): bottom-left, bottom-right, top-right, top-left of the
    /// tag seen upright from the front (counter-clockwise; see the module documentation).
    pub corners: [Vector3<f64>; 4],
}

impl BoardTag {
    /// A tag of edge `size_m` whose own frame (origin at the centre of the black square, x right,
    /// y up, z out of the tag) is at `t_board_tag`.
    pub fn from_pose(id: u32, size_m: f64, t_board_tag: &Se3) -> BoardTag {
        let h = 0.5 * size_m;
        let local = [
            Vector3::new(-h, -h, 0.0),
            Vector3::new(h, -h, 0.0),
            Vector3::new(h, h, 0.0),
            Vector3::new(-h, h, 0.0),
        ];
        BoardTag {
            id,
            size_m,
            corners: local.map(|p| t_board_tag.transform_point(&p)),
        }
    }

    /// The tag's own frame in the board frame: origin at the centre of the black square, x to
    /// the right, y up, z out of the tag.
    pub fn pose(&self) -> Se3 {
        let c = &self.corners;
        let centre = (c[0] + c[1] + c[2] + c[3]) * 0.25;
        let x = (c[1] - c[0] + c[2] - c[3]).normalize();
        let y0 = c[3] - c[0] + c[2] - c[1];
        let z = x.cross(&y0).normalize();
        let y = z.cross(&x);
        let rot = nalgebra::Matrix3::from_columns(&[x, y, z]);
        Se3::new(rot, centre)
    }
}

/// How a board's tags are printed (the detector reads both; the printer and the renderer draw
/// the one the board says).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TagPrint {
    /// As libapriltag draws its tags: the family's own pattern, for tag36h11 a black border one
    /// bit wide inside a white ring. dvlcal's own board YAML prints this way.
    Apriltag,
    /// As Kalibr prints an aprilgrid (`kalibr_create_target_pdf`): tag36h11 codes inside a black
    /// border two bits wide (bit = tag size / 10), no white ring, and a black square of edge
    /// `spacing * tag size` in the gap at every tag corner, touching it diagonally. A Kalibr
    /// aprilgrid YAML prints this way, so that one printed board serves Kalibr and dvlcal.
    Kalibr,
}

/// A calibration board: a set of tags of one family at known positions.
#[derive(Clone, Debug, PartialEq)]
pub struct Board {
    /// The AprilTag family of all the board's tags.
    pub family: TagFamily,
    /// The board's tags with their corners in the board frame.
    pub tags: Vec<BoardTag>,
    /// One line saying what the board is (printed on the SVG, in logs).
    pub description: String,
    /// For grid boards: rows, cols, spacing (gap / tag size) and first id; `None` for list
    /// boards.
    pub grid: Option<GridLayout>,
    /// How the tags are printed: [`TagPrint::Kalibr`] for a board read from a Kalibr aprilgrid
    /// YAML, [`TagPrint::Apriltag`] otherwise. The tag corners (the outer black squares) are the
    /// same either way.
    pub print: TagPrint,
    /// The sheet the board is laid out for (a board file's `paper` key, or `dvlcal board
    /// --paper`): the printed SVG is then exactly that size, the board centred in it. `None`: the
    /// SVG is as large as the board and its margins.
    pub paper: Option<Paper>,
}

/// A sheet of paper to print a board on.
#[derive(Clone, Debug, PartialEq)]
pub struct Paper {
    /// The name as [`Paper::from_name`] reads it back: `A4`, `A3 landscape`, `letter`,
    /// `300x400`.
    pub name: String,
    /// Width of the sheet as it is printed (landscape: the longer side), mm.
    pub width_mm: f64,
    /// Height of the sheet, mm.
    pub height_mm: f64,
}

/// The paper sizes [`Paper::from_name`] knows by name (portrait, mm): ISO 216 A0 to A5 and the
/// North American letter, legal and tabloid.
pub const PAPER_SIZES: [(&str, f64, f64); 9] = [
    ("A0", 841.0, 1189.0),
    ("A1", 594.0, 841.0),
    ("A2", 420.0, 594.0),
    ("A3", 297.0, 420.0),
    ("A4", 210.0, 297.0),
    ("A5", 148.0, 210.0),
    ("letter", 215.9, 279.4),
    ("legal", 215.9, 355.6),
    ("tabloid", 279.4, 431.8),
];

/// What [`Paper::from_name`] accepts, in words (for error messages).
pub const PAPER_NAMES: &str = "A0 to A5, letter, legal or tabloid (case-insensitive), each \
     optionally followed by 'landscape', or WIDTHxHEIGHT in mm (as 300x400)";

/// Largest sheet edge [`Paper::from_name`] accepts, mm.
pub const MAX_PAPER_MM: f64 = 5000.0;

impl Paper {
    /// The paper named `text`: a name of [`PAPER_SIZES`] (case-insensitive), portrait unless
    /// followed by `landscape`, or `WIDTHxHEIGHT` in millimetres; `None` for anything else
    /// (see [`PAPER_NAMES`]).
    pub fn from_name(text: &str) -> Option<Paper> {
        let words: Vec<&str> = text.split_whitespace().collect();
        let (name, landscape) = match words.as_slice() {
            [n] => (*n, false),
            [n, o] if o.eq_ignore_ascii_case("landscape") => (*n, true),
            [n, o] if o.eq_ignore_ascii_case("portrait") => (*n, false),
            _ => return None,
        };
        if let Some((n, w, h)) = PAPER_SIZES
            .iter()
            .find(|(n, _, _)| n.eq_ignore_ascii_case(name))
        {
            let (w, h) = if landscape { (*h, *w) } else { (*w, *h) };
            let name = if landscape {
                format!("{n} landscape")
            } else {
                (*n).to_owned()
            };
            return Some(Paper {
                name,
                width_mm: w,
                height_mm: h,
            });
        }
        if landscape {
            return None;
        }
        let (w, h) = name.split_once(['x', 'X'])?;
        let (w, h): (f64, f64) = (w.parse().ok()?, h.parse().ok()?);
        let fine = |v: f64| v.is_finite() && v > 0.0 && v <= MAX_PAPER_MM;
        (fine(w) && fine(h)).then(|| Paper {
            name: format!("{w}x{h}"),
            width_mm: w,
            height_mm: h,
        })
    }
}

impl std::fmt::Display for Paper {
    /// `A4 paper (210 x 297 mm)`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} paper ({} x {} mm)",
            self.name, self.width_mm, self.height_mm
        )
    }
}

/// The layout of a grid board.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridLayout {
    /// Number of tag rows (along the board's y axis).
    pub rows: u32,
    /// Number of tag columns (along the board's x axis).
    pub cols: u32,
    /// Edge of each tag's black square, m.
    pub tag_size_m: f64,
    /// Gap between neighbouring tags divided by the tag size (dimensionless).
    pub spacing: f64,
    /// Id of the tag in row 0, column 0; ids increase along each row.
    pub first_id: u32,
}

/// The tag families libapriltag ships.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TagFamily {
    /// The `tag36h11` family (587 codes).
    Tag36h11,
    /// The `tag36h10` family (2320 codes).
    Tag36h10,
    /// The `tag25h9` family (35 codes).
    Tag25h9,
    /// The `tag16h5` family (30 codes).
    Tag16h5,
    /// The `tagCircle21h7` family (38 codes).
    TagCircle21h7,
    /// The `tagCircle49h12` family (65535 codes).
    TagCircle49h12,
    /// The `tagStandard41h12` family (2115 codes).
    TagStandard41h12,
    /// The `tagStandard52h13` family (48714 codes).
    TagStandard52h13,
    /// The `tagCustom48h12` family (42211 codes).
    TagCustom48h12,
}

impl TagFamily {
    /// Every family, in a fixed order.
    pub const ALL: [TagFamily; 9] = [
        TagFamily::Tag36h11,
        TagFamily::Tag36h10,
        TagFamily::Tag25h9,
        TagFamily::Tag16h5,
        TagFamily::TagCircle21h7,
        TagFamily::TagCircle49h12,
        TagFamily::TagStandard41h12,
        TagFamily::TagStandard52h13,
        TagFamily::TagCustom48h12,
    ];

    /// The family's name as libapriltag spells it ("tag36h11", "tagStandard41h12", ...).
    pub fn name(&self) -> &'static str {
        match self {
            TagFamily::Tag36h11 => "tag36h11",
            TagFamily::Tag36h10 => "tag36h10",
            TagFamily::Tag25h9 => "tag25h9",
            TagFamily::Tag16h5 => "tag16h5",
            TagFamily::TagCircle21h7 => "tagCircle21h7",
            TagFamily::TagCircle49h12 => "tagCircle49h12",
            TagFamily::TagStandard41h12 => "tagStandard41h12",
            TagFamily::TagStandard52h13 => "tagStandard52h13",
            TagFamily::TagCustom48h12 => "tagCustom48h12",
        }
    }

    /// Number of codes (valid ids are `0..code_count()`; checked against libapriltag's `ncodes`
    /// by `tests/vision_board.rs`).
    pub fn code_count(&self) -> usize {
        match self {
            TagFamily::Tag36h11 => 587,
            TagFamily::Tag36h10 => 2320,
            TagFamily::Tag25h9 => 35,
            TagFamily::Tag16h5 => 30,
            TagFamily::TagCircle21h7 => 38,
            TagFamily::TagCircle49h12 => 65535,
            TagFamily::TagStandard41h12 => 2115,
            TagFamily::TagStandard52h13 => 48714,
            TagFamily::TagCustom48h12 => 42211,
        }
    }

    /// The family of a name; case-insensitive ("tag36h11", "TAG36H11", "tagStandard41h12").
    pub fn from_name(s: &str) -> Option<TagFamily> {
        let s = s.trim();
        TagFamily::ALL
            .into_iter()
            .find(|f| f.name().eq_ignore_ascii_case(s))
    }
}

impl std::fmt::Display for TagFamily {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl Board {
    /// A grid board in Kalibr's geometry: the tag in row `r`, column `c` has id
    /// `first_id + r * cols + c` and its black square spans
    /// `[c d, c d + s] x [r d, r d + s]` in the board plane, with `s = tag_size_m` and
    /// `d = s (1 + spacing)`.
    pub fn grid(
        family: TagFamily,
        rows: u32,
        cols: u32,
        tag_size_m: f64,
        spacing: f64,
        first_id: u32,
    ) -> Board {
        let s = tag_size_m;
        let d = s * (1.0 + spacing);
        let mut tags = Vec::with_capacity((rows * cols) as usize);
        for r in 0..rows {
            for c in 0..cols {
                let x = c as f64 * d;
                let y = r as f64 * d;
                tags.push(BoardTag {
                    id: first_id + r * cols + c,
                    size_m: s,
                    corners: [
                        Vector3::new(x, y, 0.0),
                        Vector3::new(x + s, y, 0.0),
                        Vector3::new(x + s, y + s, 0.0),
                        Vector3::new(x, y + s, 0.0),
                    ],
                });
            }
        }
        Board {
            family,
            tags,
            description: format!(
                "{} grid {} rows x {} cols, tag {:.1} mm, spacing {}, ids {}..{}",
                family.name(),
                rows,
                cols,
                s * 1e3,
                spacing,
                first_id,
                first_id + rows * cols - 1
            ),
            grid: Some(GridLayout {
                rows,
                cols,
                tag_size_m,
                spacing,
                first_id,
            }),
            print: TagPrint::Apriltag,
            paper: None,
        }
    }

    /// The same board printed the way Kalibr prints an aprilgrid ([`TagPrint::Kalibr`]). Only a
    /// tag36h11 grid with ids from 0 is a Kalibr aprilgrid; any other board is returned as it is.
    pub fn printed_by_kalibr(mut self) -> Board {
        if let (TagFamily::Tag36h11, Some(g)) = (self.family, &self.grid)
            && g.first_id == 0
        {
            self.print = TagPrint::Kalibr;
            self.description = format!(
                "Kalibr aprilgrid {} rows x {} cols (tag36h11, two-bit border, corner squares), \
                 tag {:.1} mm, spacing {}, ids 0..{}",
                g.rows,
                g.cols,
                g.tag_size_m * 1e3,
                g.spacing,
                g.rows * g.cols - 1
            );
        }
        self
    }

    /// The same board printed `scale` times as large: every corner (about the board's origin),
    /// tag size and, for a grid, the tag size of its layout (the spacing is relative and stays).
    /// A board printed at 97 % of its file is `board.scaled(0.97)`.
    pub fn scaled(&self, scale: f64) -> Board {
        let mut b = self.clone();
        for t in &mut b.tags {
            t.size_m *= scale;
            for c in &mut t.corners {
                *c *= scale;
            }
        }
        if let Some(g) = &mut b.grid {
            g.tag_size_m *= scale;
        }
        b.description = format!("{} (scaled by {scale:.5})", self.description);
        b
    }

    /// The tag with this id.
    pub fn tag(&self, id: u32) -> Option<&BoardTag> {
        self.tags.iter().find(|t| t.id == id)
    }
}
