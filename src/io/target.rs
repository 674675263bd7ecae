//! Board files (`target.yaml`): a [`Board`] read from YAML with every value checked, and written
//! back in a form this reader takes.
//!
//! [`read_board`] reads three forms of YAML:
//!
//! - a grid (dvlcal's form):
//!   ```yaml
//!   family: tag36h11      # optional, default tag36h11
//!   rows: 6
//!   cols: 6
//!   tag_size: 0.04        # black square edge, m
//!   spacing: 0.3          # gap between tags / tag_size
//!   first_id: 0           # optional, default 0
//!   paper: A4             # optional: the sheet to print it on (`dvlcal board`)
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
//!
//! Each form may name the sheet it is printed on, `paper` ([`Paper::from_name`]: `A4`,
//! `A3 landscape`, `letter`, `300x400` in mm); Kalibr's tools ignore the key.

use nalgebra::{Matrix4, Vector3};
use serde::Deserialize;
use std::path::Path;

use crate::error::{Error, Result};
use crate::lie::Se3;
use crate::types::board::{Board, BoardTag, PAPER_NAMES, Paper, TagFamily, TagPrint};

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
    #[serde(default)]
    paper: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ListFile {
    #[serde(default)]
    family: Option<String>,
    #[serde(default)]
    description: Option<String>,
    #[serde(default)]
    paper: Option<String>,
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
    #[serde(default)]
    paper: Option<String>,
}

/// The paper `--paper` names ([`Paper::from_name`]); an error saying what it takes otherwise.
pub fn paper_option(name: &str) -> Result<Paper> {
    Paper::from_name(name).ok_or_else(|| {
        Error::option(
            "--paper",
            format!("names an unknown paper '{name}': give {PAPER_NAMES}"),
        )
    })
}

/// The paper a board file names (`paper`), checked; the error names the key's line.
fn paper_of(path: &Path, text: &str, name: Option<&str>) -> Result<Option<Paper>> {
    let Some(name) = name else {
        return Ok(None);
    };
    Paper::from_name(name).map(Some).ok_or_else(|| {
        let line = text
            .lines()
            .position(|l| l.trim_start().starts_with("paper:"))
            .map_or(0, |i| i + 1);
        Error::parse(
            path,
            line,
            format!("unknown paper '{name}': give {PAPER_NAMES}"),
        )
    })
}

fn yaml_err(path: &Path, e: serde_yaml::Error) -> Error {
    let line = e.location().map(|l| l.line()).unwrap_or(0);
    Error::parse(path, line, e.to_string())
}

/// The 1-based line where the top-level `key` is set, or 0 when it cannot be found.
fn key_line(text: &str, key: &str) -> usize {
    text.lines()
        .position(|l| {
            l.strip_prefix(key)
                .is_some_and(|rest| rest.trim_start().starts_with(':'))
        })
        .map_or(0, |i| i + 1)
}

/// Why a Kalibr target of another kind than an aprilgrid cannot be used.
fn other_target(kind: &str) -> String {
    let what = match kind {
        "checkerboard" => "a Kalibr checkerboard target",
        "circlegrid" => "a Kalibr circle grid target",
        _ => "a Kalibr target of an unknown kind",
    };
    format!(
        "target_type '{kind}': {what}, which dvlcal does not detect: it finds AprilTags only \
         (their ids tell each corner apart, so a board seen in part still counts). Use an \
         aprilgrid (`target_type: 'aprilgrid'`, read as Kalibr writes it); `dvlcal board \
         --target TARGET.yaml --out board.svg` draws one to print"
    )
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

/// Reads a board YAML: dvlcal's grid or list form, or a Kalibr aprilgrid target.
pub fn read_board(path: &Path) -> Result<Board> {
    let text = crate::files::read_text(path)?;
    parse_board(&text, path)
}

/// Parses board YAML text; `path` names the source in errors.
pub fn parse_board(text: &str, path: &Path) -> Result<Board> {
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
        // The kind of target first: another kind lacks the aprilgrid's fields.
        if let Some(kind) = map
            .get(serde_yaml::Value::String("target_type".into()))
            .and_then(|v| v.as_str())
            && kind != "aprilgrid"
        {
            return Err(Error::parse(
                path,
                key_line(text, "target_type"),
                other_target(kind),
            ));
        }
        let k: KalibrFile = serde_yaml::from_str(text).map_err(|e| yaml_err(path, e))?;
        if k.target_type != "aprilgrid" {
            return Err(Error::parse(
                path,
                key_line(text, "target_type"),
                other_target(&k.target_type),
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
        let paper = paper_of(path, text, k.paper.as_deref())?;
        let mut board = Board::grid(
            TagFamily::Tag36h11,
            k.tag_rows,
            k.tag_cols,
            k.tag_size,
            k.tag_spacing,
            0,
        )
        .printed_by_kalibr();
        board.paper = paper;
        board
    } else if has("tags") {
        let l: ListFile = serde_yaml::from_str(text).map_err(|e| yaml_err(path, e))?;
        let family = family_of(&l.family)?;
        let paper = paper_of(path, text, l.paper.as_deref())?;
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
        let description = l
            .description
            .unwrap_or_else(|| format!("{} tags of {} at listed poses", tags.len(), family.name()));
        Board {
            family,
            tags,
            description,
            grid: None,
            print: TagPrint::Apriltag,
            paper,
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
        let mut board = Board::grid(family, g.rows, g.cols, g.tag_size, g.spacing, g.first_id);
        board.paper = paper_of(path, text, g.paper.as_deref())?;
        board
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

/// The board as dvlcal's YAML (grid form for grid boards, list form otherwise); [`read_board`]
/// reads it back.
pub fn board_yaml(board: &Board) -> String {
    let mut s = String::new();
    s.push_str(&format!("# {}\n", board.description.replace('\n', " ")));
    s.push_str(&format!("family: {}\n", board.family.name()));
    match &board.grid {
        Some(g) if board.print == TagPrint::Kalibr => {
            // Kalibr's own target YAML: `read_board` reads it back as a Kalibr print.
            s.clear();
            s.push_str(&format!("# {}\n", board.description.replace('\n', " ")));
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
            for t in &board.tags {
                let p = t.pose();
                let q = p.quaternion_xyzw();
                s.push_str(&format!(
                    "  - id: {}\n    size: {}\n    position: [{}, {}, {}]\n    quaternion_xyzw: [{}, {}, {}, {}]\n",
                    t.id, t.size_m, p.trans.x, p.trans.y, p.trans.z, q[0], q[1], q[2], q[3]
                ));
            }
        }
    }
    if let Some(p) = &board.paper {
        s.push_str(&format!("paper: {}\n", p.name));
    }
    s
}
