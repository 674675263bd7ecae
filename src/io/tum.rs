//! TUM trajectory files: one pose `T_world_cam` per line,
//! `timestamp tx ty tz qx qy qz qw` (white space or commas between fields).

use std::fmt::Write as _;
use std::path::Path;

use nalgebra::Vector3;

use super::{content_lines, fmt_f64, last_line, non_finite, parse_finite, parse_time};
use crate::error::{Error, Result};
use crate::lie::Se3;
use crate::time::{Epoch, RawTime};
use crate::types::PoseMeasurement;

/// Largest accepted difference between a quaternion's norm and 1; smaller deviations are
/// normalised away.
pub const QUATERNION_NORM_TOL: f64 = 1e-3;

/// Poses read from a TUM file.
#[derive(Clone, Debug)]
pub struct TumPoses {
    /// The epoch the pose times are relative to.
    pub epoch: Epoch,
    /// The poses, in file order (strictly increasing time).
    pub poses: Vec<PoseMeasurement>,
    /// The 1-based source line of each pose.
    pub lines: Vec<usize>,
}

const FIELD_NAMES: [&str; 8] = ["timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw"];

/// Reads a TUM file. Times are made relative to `epoch`, or, when it is `None`, to the whole
/// second of the first time stamp. `cov` of every pose is `None`.
pub fn read_tum(path: &Path, epoch: Option<Epoch>) -> Result<TumPoses> {
    let text = crate::files::read_text(path)?;
    parse_tum(&text, path, epoch)
}

/// Parses the text of a TUM file as [`read_tum`] does; `path` names the file in messages.
pub fn parse_tum(text: &str, path: &Path, epoch: Option<Epoch>) -> Result<TumPoses> {
    let mut epoch = epoch;
    let mut poses = Vec::new();
    let mut lines = Vec::new();
    let mut prev: Option<(RawTime, usize)> = None;

    for (line, content) in content_lines(text) {
        let fields: Vec<&str> = content
            .split(|c: char| c.is_whitespace() || c == ',')
            .filter(|s| !s.is_empty())
            .collect();
        if fields.len() != 8 {
            return Err(Error::parse(
                path,
                line,
                format!(
                    "expected 8 fields (timestamp tx ty tz qx qy qz qw), found {}",
                    fields.len()
                ),
            ));
        }
        let t_raw = parse_time(path, line, fields[0])?;
        let mut v = [0.0; 7];
        for (k, slot) in v.iter_mut().enumerate() {
            *slot = parse_finite(path, line, FIELD_NAMES[k + 1], fields[k + 1])?;
        }
        let q = [v[3], v[4], v[5], v[6]];
        let norm = q.iter().map(|c| c * c).sum::<f64>().sqrt();
        if (norm - 1.0).abs() > QUATERNION_NORM_TOL {
            return Err(Error::parse(
                path,
                line,
                format!("quaternion norm {norm} differs from 1 by more than {QUATERNION_NORM_TOL}"),
            ));
        }
        if let Some((p, pline)) = prev {
            if (t_raw.sec, t_raw.frac) <= (p.sec, p.frac) {
                return Err(Error::parse(
                    path,
                    line,
                    format!(
                        "time stamp {} is not after the one on line {pline}",
                        fields[0]
                    ),
                ));
            }
        }
        prev = Some((t_raw, line));
        let ep = *epoch.get_or_insert_with(|| Epoch::at(t_raw));
        poses.push(PoseMeasurement {
            t: ep.rel(t_raw),
            pose: pose_from_quaternion(&q, Vector3::new(v[0], v[1], v[2])),
            cov: None,
        });
        lines.push(line);
    }

    match epoch {
        Some(epoch) if !poses.is_empty() => Ok(TumPoses {
            epoch,
            poses,
            lines,
        }),
        _ => Err(Error::parse(path, last_line(text), "no poses in file")),
    }
}

/// The pose of a TUM line: the quaternion normalised, then turned into a rotation matrix.
fn pose_from_quaternion(q: &[f64; 4], trans: Vector3<f64>) -> Se3 {
    let norm = q.iter().map(|c| c * c).sum::<f64>().sqrt();
    Se3::from_quaternion_xyzw(&[q[0] / norm, q[1] / norm, q[2] / norm, q[3] / norm], trans)
}

/// `pose` as [`write_tum`] writes it and [`read_tum`] reads it back, to the last bit: the rotation
/// passed through its quaternion. Poses handed on in memory go through this too, so that a run
/// from images and a run from the TUM file written of the same poses compute the same digits.
pub fn as_read_back(pose: &Se3) -> Se3 {
    pose_from_quaternion(&pose.quaternion_xyzw(), pose.trans)
}

/// Writes poses as a TUM file (time with 9 decimals, other values with full precision),
/// atomically.
pub fn write_tum(path: &Path, epoch: Epoch, poses: &[PoseMeasurement]) -> Result<()> {
    let mut out = String::from("# timestamp tx ty tz qx qy qz qw (T_world_cam)\n");
    for (i, p) in poses.iter().enumerate() {
        let q = p.pose.quaternion_xyzw();
        let tr = p.pose.trans;
        let values = [tr.x, tr.y, tr.z, q[0], q[1], q[2], q[3]];
        if !p.t.is_finite() || values.iter().any(|v| !v.is_finite()) {
            return Err(non_finite(path, format!("pose {i}")));
        }
        out.push_str(&epoch.format_abs(p.t, 9));
        for v in values {
            let _ = write!(out, " {}", fmt_f64(v));
        }
        out.push('\n');
    }
    super::write_atomic(path, out.as_bytes())
}
