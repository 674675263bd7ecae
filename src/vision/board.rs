//! Calibration boards: which AprilTags there are, and where each tag's corners lie in the board
//! frame.
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
//!
//! # Files
//!
//! [`Board::load`] reads three forms of YAML:
//!
//! - a grid (dvlcal's form):
//!   ```yaml
//!   family: tag36h11      # optional, default tag36h11
//!   rows: 6
//!   cols: 6
//!   tag_size: 0.04        # black square edge, m
//!   spacing: 0.3          # gap between tags / tag_size
//!   first_id: 0           # optional, default 0
//!   ```
//! - a list of tags with their own size and pose (tags scattered on a pool wall):
//!   ```yaml
//!   family: tag36h11
//!   tags:
//!     - id: 3
//!       size: 0.16
//!       position: [0.0, 0.5, 0.0]          # tag centre in the board frame, m
//!       quaternion_xyzw: [0, 0, 0, 1]      # R_board_tag
//!     - id: 4
//!       size: 0.16
//!       T_board_tag: [[1,0,0,1.0],[0,1,0,0.5],[0,0,1,0],[0,0,0,1]]
//!   ```
//!   A tag's own frame has its origin at the centre of the black square, x to the right and y up
//!   when the tag is upright, z out of the tag.
//! - Kalibr's aprilgrid target YAML, unchanged (`target_type: 'aprilgrid'`, `tagCols`,
//!   `tagRows`, `tagSize`, `tagSpacing`), with tag ids from 0. Such a board is printed the way
//!   Kalibr prints it ([`TagPrint::Kalibr`]: two-bit borders, corner squares); the other forms
//!   as libapriltag draws its tags.

use nalgebra::{Matrix4, Vector2, Vector3};
use serde::Deserialize;
use std::path::Path;

use crate::error::{Error, Result};
use crate::lie::Se3;
pub use crate::vision::family::TagFamily;

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

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GridFile {
    #[serde(default)]
    family: Option<String>,
    rows: u32,
    cols: u32,
    tag_size: f64,
    spacing: f64,
    #[serde(default)]
    first_id: u32,
    #[serde(default)]
    #[allow(dead_code)]
    description: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ListFile {
    #[serde(default)]
    family: Option<String>,
    #[serde(default)]
    description: Option<String>,
    tags: Vec<ListTag>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ListTag {
    id: u32,
    size: f64,
    #[serde(default)]
    position: Option<[f64; 3]>,
    #[serde(default)]
    quaternion_xyzw: Option<[f64; 4]>,
    #[serde(default, rename = "T_board_tag")]
    t_board_tag: Option<[[f64; 4]; 4]>,
}

#[derive(Deserialize)]
#[serde(rename_all = "camelCase")]
struct KalibrFile {
    #[serde(rename = "target_type")]
    target_type: String,
    tag_cols: u32,
    tag_rows: u32,
    tag_size: f64,
    tag_spacing: f64,
}

fn yaml_err(path: &Path, e: serde_yaml::Error) -> Error {
    let line = e.location().map(|l| l.line()).unwrap_or(0);
    Error::parse(path, line, e.to_string())
}

/// Largest tag edge accepted, m: a printed calibration tag is far smaller.
pub const MAX_TAG_SIZE_M: f64 = 1.0;

/// Most tags a grid board may have (a 100 x 100 grid), checked before anything is allocated.
pub const MAX_GRID_TAGS: usize = 10_000;

/// A tag size: positive, and at most [`MAX_TAG_SIZE_M`] (a size in millimetres is the usual
/// mistake).
fn check_positive(path: &Path, what: &str, v: f64) -> Result<()> {
    if !(v.is_finite() && v > 0.0) {
        return Err(Error::parse(
            path,
            0,
            format!("{what} must be positive, got {v}"),
        ));
    }
    if v > MAX_TAG_SIZE_M {
        return Err(Error::parse(
            path,
            0,
            format!(
                "{what} is {v} m: tag sizes are in metres (millimetres given? {v} mm is {} m)",
                v / 1000.0
            ),
        ));
    }
    Ok(())
}

/// A grid's size, bounded before the tags are made.
fn check_grid(path: &Path, rows: u32, cols: u32) -> Result<()> {
    if rows == 0 || cols == 0 {
        return Err(Error::parse(path, 0, "rows and cols must be positive"));
    }
    if (rows as usize).saturating_mul(cols as usize) > MAX_GRID_TAGS {
        return Err(Error::parse(
            path,
            0,
            format!("a grid of {rows} x {cols} tags: at most {MAX_GRID_TAGS} tags are supported"),
        ));
    }
    Ok(())
}

/// A grid's ids `first_id .. first_id + rows * cols` all exist in the family, checked before
/// the tags are made (so the ids cannot overflow `u32` either).
fn check_grid_ids(
    path: &Path,
    family: TagFamily,
    rows: u32,
    cols: u32,
    first_id: u32,
) -> Result<()> {
    let n = family.code_count() as u64;
    let end = u64::from(first_id) + u64::from(rows) * u64::from(cols);
    if end > n {
        // The first id outside the family, as the check of listed tags names it.
        let id = u64::from(first_id).max(n);
        return Err(Error::parse(
            path,
            0,
            format!(
                "tag id {id} does not exist in {} ({n} codes)",
                family.name()
            ),
        ));
    }
    Ok(())
}

impl Board {
    /// Reads a board YAML: dvlcal's grid or list form, or a Kalibr aprilgrid target.
    pub fn load(path: &Path) -> Result<Board> {
        let text = crate::files::read_text(path)?;
        Board::parse(&text, path)
    }

    /// Parses board YAML text; `path` names the source in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Board> {
        let value: serde_yaml::Value = serde_yaml::from_str(text).map_err(|e| yaml_err(path, e))?;
        let map = value
            .as_mapping()
            .ok_or_else(|| Error::parse(path, 1, "a board YAML must be a mapping"))?;
        let has = |k: &str| map.contains_key(serde_yaml::Value::String(k.into()));
        let family_of = |f: &Option<String>| -> Result<TagFamily> {
            match f {
                None => Ok(TagFamily::Tag36h11),
                Some(name) => TagFamily::from_name(name).ok_or_else(|| {
                    Error::parse(
                        path,
                        0,
                        format!(
                            "unknown tag family '{name}' (known: {})",
                            TagFamily::ALL.map(|f| f.name()).join(", ")
                        ),
                    )
                }),
            }
        };
        let board = if has("target_type") {
            let k: KalibrFile = serde_yaml::from_str(text).map_err(|e| yaml_err(path, e))?;
            if k.target_type != "aprilgrid" {
                return Err(Error::parse(
                    path,
                    0,
                    format!(
                        "Kalibr target_type '{}' is not supported (only 'aprilgrid')",
                        k.target_type
                    ),
                ));
            }
            check_positive(path, "tagSize", k.tag_size)?;
            if !(k.tag_spacing.is_finite() && k.tag_spacing >= 0.0) {
                return Err(Error::parse(path, 0, "tagSpacing must be >= 0"));
            }
            if k.tag_cols == 0 || k.tag_rows == 0 {
                return Err(Error::parse(
                    path,
                    0,
                    "tagCols and tagRows must be positive",
                ));
            }
            check_grid(path, k.tag_rows, k.tag_cols)?;
            check_grid_ids(path, TagFamily::Tag36h11, k.tag_rows, k.tag_cols, 0)?;
            Board::grid(
                TagFamily::Tag36h11,
                k.tag_rows,
                k.tag_cols,
                k.tag_size,
                k.tag_spacing,
                0,
            )
            .printed_by_kalibr()
        } else if has("tags") {
            let l: ListFile = serde_yaml::from_str(text).map_err(|e| yaml_err(path, e))?;
            let family = family_of(&l.family)?;
            if l.tags.is_empty() {
                return Err(Error::parse(path, 0, "the board lists no tags"));
            }
            let mut tags = Vec::with_capacity(l.tags.len());
            let mut ids = std::collections::HashSet::with_capacity(l.tags.len());
            for t in &l.tags {
                check_positive(path, &format!("size of tag {}", t.id), t.size)?;
                let pose = match (&t.position, &t.quaternion_xyzw, &t.t_board_tag) {
                    (Some(p), q, None) => {
                        let q = q.unwrap_or([0.0, 0.0, 0.0, 1.0]);
                        let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
                        if !(n.is_finite() && n > 1e-9) {
                            return Err(Error::parse(
                                path,
                                0,
                                format!("tag {}: quaternion_xyzw has no direction", t.id),
                            ));
                        }
                        Se3::from_quaternion_xyzw(&q, Vector3::new(p[0], p[1], p[2]))
                    }
                    (None, None, Some(m)) => {
                        let mut mm = Matrix4::zeros();
                        for (r, row) in m.iter().enumerate() {
                            for (c, v) in row.iter().enumerate() {
                                mm[(r, c)] = *v;
                            }
                        }
                        if !mm.iter().all(|v| v.is_finite()) {
                            return Err(Error::parse(
                                path,
                                0,
                                format!("tag {}: T_board_tag is not finite", t.id),
                            ));
                        }
                        Se3::from_matrix(&mm)
                    }
                    _ => {
                        return Err(Error::parse(
                            path,
                            0,
                            format!(
                                "tag {}: give either position (+ quaternion_xyzw) or T_board_tag",
                                t.id
                            ),
                        ));
                    }
                };
                if !ids.insert(t.id) {
                    return Err(Error::parse(
                        path,
                        0,
                        format!("tag id {} listed twice", t.id),
                    ));
                }
                tags.push(BoardTag::from_pose(t.id, t.size, &pose));
            }
            let description = l.description.unwrap_or_else(|| {
                format!("{} tags of {} at listed poses", tags.len(), family.name())
            });
            Board {
                family,
                tags,
                description,
                grid: None,
                print: TagPrint::Apriltag,
            }
        } else {
            let g: GridFile = serde_yaml::from_str(text).map_err(|e| yaml_err(path, e))?;
            let family = family_of(&g.family)?;
            check_positive(path, "tag_size", g.tag_size)?;
            if !(g.spacing.is_finite() && g.spacing >= 0.0) {
                return Err(Error::parse(path, 0, "spacing must be >= 0"));
            }
            check_grid(path, g.rows, g.cols)?;
            check_grid_ids(path, family, g.rows, g.cols, g.first_id)?;
            Board::grid(family, g.rows, g.cols, g.tag_size, g.spacing, g.first_id)
        };
        let n = board.family.code_count();
        if let Some(t) = board.tags.iter().find(|t| t.id as usize >= n) {
            return Err(Error::parse(
                path,
                0,
                format!(
                    "tag id {} does not exist in {} ({} codes)",
                    t.id,
                    board.family.name(),
                    n
                ),
            ));
        }
        Ok(board)
    }

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

    /// The tag with this id.
    pub fn tag(&self, id: u32) -> Option<&BoardTag> {
        self.tags.iter().find(|t| t.id == id)
    }

    /// The board as dvlcal's YAML (grid form for grid boards, list form otherwise); `load` reads
    /// it back.
    pub fn to_yaml(&self) -> String {
        let mut s = String::new();
        s.push_str(&format!("# {}\n", self.description.replace('\n', " ")));
        s.push_str(&format!("family: {}\n", self.family.name()));
        match &self.grid {
            Some(g) if self.print == TagPrint::Kalibr => {
                // Kalibr's own target YAML: `load` reads it back as a Kalibr print.
                s.clear();
                s.push_str(&format!("# {}\n", self.description.replace('\n', " ")));
                s.push_str(&format!(
                    "target_type: 'aprilgrid'\ntagCols: {}\ntagRows: {}\ntagSize: {}\ntagSpacing: {}\n",
                    g.cols, g.rows, g.tag_size_m, g.spacing
                ));
            }
            Some(g) => {
                s.push_str(&format!(
                    "rows: {}\ncols: {}\ntag_size: {}\nspacing: {}\nfirst_id: {}\n",
                    g.rows, g.cols, g.tag_size_m, g.spacing, g.first_id
                ));
            }
            None => {
                s.push_str("tags:\n");
                for t in &self.tags {
                    let p = t.pose();
                    let q = p.quaternion_xyzw();
                    s.push_str(&format!(
                        "  - id: {}\n    size: {}\n    position: [{}, {}, {}]\n    quaternion_xyzw: [{}, {}, {}, {}]\n",
                        t.id, t.size_m, p.trans.x, p.trans.y, p.trans.z, q[0], q[1], q[2], q[3]
                    ));
                }
            }
        }
        s
    }
}

/// The white paper of a grid board in the board plane: lower-left and upper-right corners. The
/// margin around the outer tags' black squares is the gap between tags, and at least the pattern's
/// own white ring plus one cell; for a Kalibr print, the gap (where the outer corner squares
/// end) plus two bits.
pub fn grid_paper(board: &Board, g: &GridLayout) -> (Vector2<f64>, Vector2<f64>) {
    let layout = crate::vision::family::family_layout(board.family);
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
