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

/// A camera clock that steps back by less than this, s, is a file out of order (an error); by
/// more, a clock corrected mid-recording (NTP) or restarted.
pub const CLOCK_STEP_MIN_S: f64 = 1.0;

/// A step back of the camera clock between two lines of a TUM file.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraClockStep {
    /// The 1-based line of the first pose on the new clock.
    pub line: usize,
    /// The line of the pose before it.
    pub previous_line: usize,
    /// The step, s (negative: back).
    pub step_s: f64,
}

/// A stretch of a TUM file's poses on one camera clock.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraSegment {
    /// Its poses (indices into [`TumPoses::poses`]).
    pub poses: std::ops::Range<usize>,
    /// Its first and last line.
    pub lines: (usize, usize),
    /// What was added to its times to make them follow the segment before it (0 for the
    /// first): its poses' times are `t_own + shift_s`.
    pub shift_s: f64,
}

/// Poses read from a TUM file.
#[derive(Clone, Debug)]
pub struct TumPoses {
    /// The epoch the pose times are relative to.
    pub epoch: Epoch,
    /// The poses, in file order, in strictly increasing time: the poses of a camera clock
    /// segment after the first follow the one before it by the median interval between poses
    /// (their times moved by the segment's `shift_s`).
    pub poses: Vec<PoseMeasurement>,
    /// The 1-based source line of each pose.
    pub lines: Vec<usize>,
    /// The camera clock's steps back, in file order (none for a steady clock).
    pub clock_steps: Vec<CameraClockStep>,
    /// The camera clock's segments, one more than its steps.
    pub segments: Vec<CameraSegment>,
}

impl TumPoses {
    /// The time of pose `k` on its own camera clock (before its segment's shift).
    pub fn own_time(&self, k: usize) -> f64 {
        let shift = self
            .segments
            .iter()
            .find(|s| s.poses.contains(&k))
            .map_or(0.0, |s| s.shift_s);
        self.poses.get(k).map_or(f64::NAN, |p| p.t - shift)
    }
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
    refuse_euroc(text, path)?;
    let mut epoch = epoch;
    let mut poses = Vec::new();
    let mut lines = Vec::new();
    let mut prev: Option<(RawTime, usize)> = None;
    let mut clock_steps = Vec::new();
    // The first pose of each camera clock segment.
    let mut starts = vec![0usize];

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
        if let Some((p, pline)) = prev
            && (t_raw.sec, t_raw.frac) <= (p.sec, p.frac)
        {
            let back = (p.sec - t_raw.sec) as f64 + (p.frac - t_raw.frac);
            if back < CLOCK_STEP_MIN_S {
                return Err(Error::parse(
                    path,
                    line,
                    format!(
                        "time stamp {} is not after the one on line {pline} (lines out of order \
                         or repeated; a camera clock stepping back by {CLOCK_STEP_MIN_S} s or \
                         more starts a new clock segment)",
                        fields[0]
                    ),
                ));
            }
            clock_steps.push(CameraClockStep {
                line,
                previous_line: pline,
                step_s: -back,
            });
            starts.push(poses.len());
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

    check_time_unit(&poses, &lines, text, path)?;
    let segments = clock_segments(&mut poses, &lines, &starts);
    match epoch {
        Some(epoch) if !poses.is_empty() => Ok(TumPoses {
            epoch,
            poses,
            lines,
            clock_steps,
            segments,
        }),
        _ => Err(Error::parse(path, last_line(text), "no poses in file")),
    }
}

/// A median interval between poses longer than this, s, is no camera's: the times are in
/// another unit than seconds (or the file holds no trajectory to calibrate against).
pub const MAX_POSE_INTERVAL_S: f64 = 5.0;

/// Refuses a EuRoC ground-truth CSV (`#timestamp, p_RS_R_x [m], ..., q_RS_w [], ...`, as in
/// `mav0/state_groundtruth_estimate0/data.csv`, `vicon0/` or `leica0/`), recognised by its
/// header: its times are nanoseconds, its quaternion comes w first, and its poses are of the
/// body (the IMU frame S), not of the camera. Reading it needs the camera's pose on the body
/// (cam0's `T_BS` in `mav0/cam0/sensor.yaml`), which the file does not hold: calibrating
/// against the body's poses would give the DVL's pose on the IMU labelled as on the camera.
fn refuse_euroc(text: &str, path: &Path) -> Result<()> {
    let Some((k, header)) = text.lines().enumerate().find(|(_, l)| !l.trim().is_empty()) else {
        return Ok(());
    };
    if !(header.trim_start().starts_with('#') && header.contains("p_RS_R_x")) {
        return Ok(());
    }
    let what = if header.contains("q_RS_w") {
        "its times are nanoseconds, its quaternion is w first (q_RS_w q_RS_x q_RS_y q_RS_z), and \
         its poses are of the body (EuRoC's IMU frame S) in the world, not of the camera"
    } else {
        "it holds positions only (no orientation), of the body (EuRoC's IMU frame S) in the \
         world, in nanoseconds"
    };
    Err(Error::parse(
        path,
        k + 1,
        format!(
            "this is a EuRoC ground-truth CSV (header '#timestamp, p_RS_R_x [m], ...'), not a TUM \
             pose file: {what}. dvlcal needs camera poses T_world_cam in TUM (seconds; tx ty tz \
             qx qy qz qw): calibrate from the images instead (--images mav0 with the board), or \
             convert each pose to T_world_cam = T_world_S * T_BS, with T_BS of cam0 from \
             mav0/cam0/sensor.yaml, writing the time in seconds and the quaternion x y z w"
        ),
    ))
}

/// Refuses pose times that are not seconds: a median interval between poses longer than
/// [`MAX_POSE_INTERVAL_S`] names the unit the times appear to be in (the one that makes the
/// interval a camera's, 0.5 to 500 Hz, preferring one that makes the first stamp a Unix time of
/// 2000 to 2100) and how to convert them. Reading them in that unit instead would rest the
/// clock offset, the calibration's own result, on a guess.
fn check_time_unit(
    poses: &[PoseMeasurement],
    lines: &[usize],
    text: &str,
    path: &Path,
) -> Result<()> {
    let mut gaps: Vec<f64> = poses
        .windows(2)
        .map(|w| w[1].t - w[0].t)
        .filter(|g| *g > 0.0)
        .collect();
    gaps.sort_by(f64::total_cmp);
    let Some(&gap) = gaps.get(gaps.len() / 2) else {
        return Ok(());
    };
    if gap <= MAX_POSE_INTERVAL_S {
        return Ok(());
    }
    let line = lines.first().copied().unwrap_or(1);
    let first = content_lines(text)
        .next()
        .and_then(|(_, l)| l.split(|c: char| c.is_whitespace() || c == ',').next())
        .and_then(|t| t.parse::<f64>().ok())
        .unwrap_or(f64::NAN);
    const UNITS: [(&str, &str, f64); 3] = [
        ("milliseconds", "1e3", 1e-3),
        ("microseconds", "1e6", 1e-6),
        ("nanoseconds", "1e9", 1e-9),
    ];
    let camera = |u: f64| (0.002..=2.0).contains(&(gap * u));
    let unix = |u: f64| (946_684_800.0..=4_102_444_800.0).contains(&(first * u));
    let unit = UNITS
        .iter()
        .find(|(_, _, u)| camera(*u) && unix(*u))
        .or_else(|| UNITS.iter().find(|(_, _, u)| camera(*u)));
    let msg = match unit {
        Some((name, div, u)) => format!(
            "the time stamps appear to be in {name}, not seconds: read as seconds the poses are \
             {gap} s apart (the median interval), in {name} a camera at {:.3} Hz{}. TUM times are \
             seconds: divide \
             the first column by {div}, e.g. awk '!/^#/ {{ $1 = sprintf(\"%.9f\", $1 / {div}) }} \
             1' POSES > POSES_s.txt",
            1.0 / (gap * u),
            if unix(*u) {
                format!(", and the first stamp a Unix time in {name}")
            } else {
                String::new()
            }
        ),
        None => format!(
            "the poses are {gap} s apart (the median interval): no camera gives a trajectory \
             from poses that far apart; TUM times are seconds: if these are in another unit, \
             convert them"
        ),
    };
    Err(Error::parse(path, line, msg))
}

/// The camera clock segments starting at the poses `starts`, each after the first moved to
/// follow the one before it by the median interval between poses within the segments (a clock
/// corrected while the camera kept recording: the true interval across the step is one frame's).
fn clock_segments(
    poses: &mut [PoseMeasurement],
    lines: &[usize],
    starts: &[usize],
) -> Vec<CameraSegment> {
    let n = poses.len();
    let ranges: Vec<std::ops::Range<usize>> = starts
        .iter()
        .enumerate()
        .map(|(k, &a)| a..starts.get(k + 1).copied().unwrap_or(n))
        .filter(|r| !r.is_empty())
        .collect();
    let mut gaps: Vec<f64> = ranges
        .iter()
        .flat_map(|r| poses[r.clone()].windows(2).map(|w| w[1].t - w[0].t))
        .collect();
    gaps.sort_by(f64::total_cmp);
    let period = gaps.get(gaps.len() / 2).copied().unwrap_or(0.1);
    let mut out: Vec<CameraSegment> = Vec::with_capacity(ranges.len());
    for r in ranges {
        let shift_s = match out.last() {
            Some(before) => poses[before.poses.end - 1].t + period - poses[r.start].t,
            None => 0.0,
        };
        for p in &mut poses[r.clone()] {
            p.t += shift_s;
        }
        out.push(CameraSegment {
            lines: (lines[r.start], lines[r.end - 1]),
            poses: r,
            shift_s,
        });
    }
    out
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_camera_clock_stepping_back_starts_a_segment_that_follows_by_one_frame() {
        let text = "# t x y z qx qy qz qw\n\
                    100.0 0 0 0 0 0 0 1\n\
                    100.1 0 0 0 0 0 0 1\n\
                    100.2 0 0 0 0 0 0 1\n\
                    90.3 0 0 0 0 0 0 1\n\
                    90.4 0 0 0 0 0 0 1\n";
        let p = parse_tum(text, Path::new("p.txt"), None).unwrap();
        assert_eq!(p.clock_steps.len(), 1);
        assert_eq!(
            (p.clock_steps[0].line, p.clock_steps[0].previous_line),
            (5, 4)
        );
        assert!((p.clock_steps[0].step_s + 9.9).abs() < 1e-9);
        assert_eq!(p.segments.len(), 2);
        assert_eq!(
            (p.segments[1].poses.clone(), p.segments[1].lines),
            (3..5, (5, 6))
        );
        // Moved by 10 s: one frame after line 4, then the segment's own spacing.
        assert!((p.segments[1].shift_s - 10.0).abs() < 1e-9);
        let t: Vec<f64> = p.poses.iter().map(|x| x.t).collect();
        for (a, b) in t.iter().zip([0.0, 0.1, 0.2, 0.3, 0.4]) {
            assert!((a - b).abs() < 1e-9, "{t:?}");
        }
        assert!((p.own_time(3) - (-9.7)).abs() < 1e-9);
        // Back by less than a second: lines out of order, an error naming the line.
        let e = parse_tum(
            "1.0 0 0 0 0 0 0 1\n1.5 0 0 0 0 0 0 1\n1.2 0 0 0 0 0 0 1\n",
            Path::new("p.txt"),
            None,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("p.txt:3") && e.contains("out of order"), "{e}");
    }
}
