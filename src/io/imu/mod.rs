//! IMU files. The stream is EuRoC's IMU CSV (also TUM-VI's), `imu0/data.csv`:
//!
//! ```text
//! #timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]
//! 1403715279262142976,0.0300,-0.1138,0.0726,5.4754,0.4004,-1.1523
//! ```
//!
//! one sample a line: integer nanoseconds on the IMU clock, the angular rate (rad/s) and the
//! specific force (m/s^2, gravity included), both in the IMU frame. [`read_imu_csv`] checks
//! every line and the stream as a whole (order, repeats, gaps, saturation, units) and
//! [`write_imu_csv`] writes the same form. The noise files (Kalibr's `imu.yaml`, EuRoC's
//! `sensor.yaml`) are in [`noise`]; the simulator's truth files in [`truth`].
//!
//! Decisions: a stamp equal to the one before is a repeated sample, skipped and counted (the
//! first is kept); a stamp before the one before is an error naming both lines (an IMU logs in
//! time order, so the file was cut and pasted or merged). Units other than rad/s and m/s^2 are
//! refused, not converted: a converted guess would scale every later figure silently.

pub mod noise;
pub mod truth;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use nalgebra::Vector3;

use super::{fmt_f64, last_line, non_finite, parse_finite};
use crate::error::{Error, Result};
use crate::time::{Epoch, RawTime};
use crate::types::imu::ImuSample;
use crate::types::imu_units::{
    AccelUnit, DEG_PER_RAD, GyroScale, GyroScaleCheck, gyro_scale_from_gravity, median, quantile,
};

/// The header EuRoC and TUM-VI write, and [`write_imu_csv`] writes.
pub const EUROC_IMU_HEADER: &str = "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],\
                                    w_RS_S_z [rad s^-1],a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],\
                                    a_RS_S_z [m s^-2]";

/// An interval between samples longer than this many median intervals is a gap.
pub const GAP_FACTOR: f64 = 2.5;

/// A 99th percentile of the gyro's rates above this, rad/s, is no rad/s gyro's (1146 deg/s,
/// beyond the range of the gyros of robots: deg/s are meant).
pub const MAX_RADPS_P99: f64 = 20.0;

/// Samples an axis must hold one value at its full scale for to count as saturated.
pub const SATURATION_MIN_RUN: usize = 3;

/// Full scales below these (rad/s, m/s^2) are not a saturation: a gyro's range is at least
/// 125 deg/s (2.2 rad/s), an accelerometer's at least 2 g with gravity on one axis.
pub const SATURATION_FLOOR: [f64; 2] = [2.0, 15.0];

/// How many repeated stamps and saturated runs are listed with their lines.
pub const MAX_LISTED: usize = 20;

const AXES: [&str; 6] = [
    "gyro x", "gyro y", "gyro z", "accel x", "accel y", "accel z",
];
const COLUMNS: [&str; 7] = [
    "timestamp [ns]",
    "w_RS_S_x",
    "w_RS_S_y",
    "w_RS_S_z",
    "a_RS_S_x",
    "a_RS_S_y",
    "a_RS_S_z",
];

/// The longest interval between two samples.
#[derive(Clone, Debug, PartialEq)]
pub struct ImuGap {
    /// The line of the sample before the gap.
    pub previous_line: usize,
    /// The line of the sample after it.
    pub line: usize,
    /// IMU-clock time of the sample before the gap, seconds from the epoch.
    pub t_s: f64,
    /// The interval, s.
    pub duration_s: f64,
}

/// A run of samples in which one axis holds its full-scale value.
#[derive(Clone, Debug, PartialEq)]
pub struct SaturatedRun {
    /// `gyro x` ... `accel z`.
    pub axis: &'static str,
    /// The value held (rad/s or m/s^2).
    pub value: f64,
    /// First and last line of the run.
    pub lines: (usize, usize),
    /// Samples in the run.
    pub samples: usize,
}

/// What a read found besides the samples.
#[derive(Clone, Debug, PartialEq)]
pub struct ImuStats {
    /// The header's line, when the file has one.
    pub header_line: Option<usize>,
    /// Data lines read (repeated stamps included).
    pub rows: usize,
    /// Samples with a stamp equal to the one before (skipped).
    pub duplicates: usize,
    /// The lines of the first [`MAX_LISTED`] of them.
    pub duplicate_lines: Vec<usize>,
    /// The median interval between samples, s (NaN for one sample).
    pub median_interval_s: f64,
    /// Its inverse, Hz.
    pub rate_hz: f64,
    /// From the first sample to the last, s.
    pub span_s: f64,
    /// Intervals longer than [`GAP_FACTOR`] median intervals.
    pub gaps: usize,
    /// The longest interval, when it is a gap.
    pub longest_gap: Option<ImuGap>,
    /// Samples in which an axis sits at its full scale (in a run of [`SATURATION_MIN_RUN`]).
    pub saturated_samples: usize,
    /// Saturated runs, all of them.
    pub saturated_run_count: usize,
    /// The first [`MAX_LISTED`] runs.
    pub saturated_runs: Vec<SaturatedRun>,
    /// The median norm of the specific force, m/s^2.
    pub accel_median_norm: f64,
    /// The 99th percentile of the gyro's rate, rad/s.
    pub gyro_p99_radps: f64,
    /// The gyro's scale against gravity turning in the accelerometer.
    pub gyro_scale: GyroScaleCheck,
}

/// An IMU stream as read.
#[derive(Clone, Debug)]
pub struct ImuLog {
    /// The file.
    pub path: PathBuf,
    /// The epoch the sample times count from.
    pub epoch: Epoch,
    /// The samples, strictly increasing in time, repeated stamps left out.
    pub samples: Vec<ImuSample>,
    /// The 1-based line of each sample.
    pub lines: Vec<usize>,
    /// Counts, gaps, saturation and the unit checks.
    pub stats: ImuStats,
}

impl ImuLog {
    /// What was found, one statement a line (for a summary or a note).
    pub fn summary(&self) -> Vec<String> {
        let s = &self.stats;
        let mut out = vec![format!(
            "{}: {} IMU samples at {:.1} Hz over {:.3} s ({} {} read), specific force {:.2} \
             m/s^2 (median norm), gyro 99th percentile {:.3} rad/s, {}",
            self.path.display(),
            self.samples.len(),
            s.rate_hz,
            s.span_s,
            s.rows,
            // A bag's samples are its messages, counted as the bag's reader used them.
            if crate::io::bag::is_bag(&self.path) {
                "messages"
            } else {
                "lines"
            },
            s.accel_median_norm,
            s.gyro_p99_radps,
            s.gyro_scale
                .describe()
                .replace("reference", "tilt rate of gravity")
        )];
        if s.duplicates > 0 {
            out.push(format!(
                "{} repeated time stamps skipped (lines {})",
                s.duplicates,
                list(&s.duplicate_lines, s.duplicates)
            ));
        }
        if let Some(g) = &s.longest_gap {
            out.push(format!(
                "{} gaps longer than {GAP_FACTOR} sample intervals; the longest {:.3} s after \
                 {} (t = {:.3} s from the epoch, lines {}-{})",
                s.gaps,
                g.duration_s,
                self.epoch.format_abs(g.t_s, 9),
                g.t_s,
                g.previous_line,
                g.line
            ));
        }
        if s.saturated_run_count > 0 {
            let runs: Vec<String> = s
                .saturated_runs
                .iter()
                .map(|r| {
                    format!(
                        "{} at {} on lines {}-{}",
                        r.axis,
                        fmt_f64(r.value),
                        r.lines.0,
                        r.lines.1
                    )
                })
                .collect();
            out.push(format!(
                "{} saturated samples in {} runs (an axis held at its full scale): {}{}",
                s.saturated_samples,
                s.saturated_run_count,
                runs.join(", "),
                if s.saturated_run_count > runs.len() {
                    ", ..."
                } else {
                    ""
                }
            ));
        }
        out
    }
}

fn list(lines: &[usize], total: usize) -> String {
    let mut s = lines
        .iter()
        .map(|l| l.to_string())
        .collect::<Vec<_>>()
        .join(", ");
    if total > lines.len() {
        s.push_str(", ...");
    }
    s
}

/// Reads an IMU CSV. Times are made relative to `epoch`, or, when it is `None`, to the whole
/// second of the first stamp.
///
/// Errors (each names the file and line): a line without 7 fields, a stamp that is not an
/// integer number of nanoseconds (seconds, scientific notation), a value that is not a finite
/// number, a stamp before the one on the line before, a header giving other units; and, for
/// the file as a whole, no samples, or a stream whose numbers are not in rad/s and m/s^2
/// (the message names the unit they look like and the conversion).
pub fn read_imu_csv(path: &Path, epoch: Option<Epoch>) -> Result<ImuLog> {
    let text = crate::files::read_text(path)?;
    parse_imu_csv(&text, path, epoch)
}

/// Parses the text of an IMU CSV as [`read_imu_csv`] does; `path` names the file in messages.
pub fn parse_imu_csv(text: &str, path: &Path, epoch: Option<Epoch>) -> Result<ImuLog> {
    let mut header_line = None;
    let mut stamps: Vec<i64> = Vec::new();
    let mut samples: Vec<ImuSample> = Vec::new();
    let mut lines = Vec::new();
    let (mut rows, mut duplicates, mut duplicate_lines) = (0usize, 0usize, Vec::new());
    let mut epoch = epoch;
    let mut seen_content = false;
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let content = raw.trim();
        if content.is_empty() {
            continue;
        }
        // The header: the first `#` line naming the timestamp before any data, or a first line
        // that names the columns without the `#`.
        let first_line = !std::mem::replace(&mut seen_content, true);
        let before_data = header_line.is_none() && rows == 0;
        if content.starts_with('#') || (first_line && starts_like_header(content)) {
            if before_data && content.to_ascii_lowercase().contains("timestamp") {
                check_header(path, line, content)?;
                header_line = Some(line);
            }
            continue;
        }
        let fields: Vec<&str> = content.split(',').map(str::trim).collect();
        if fields.len() != 7 {
            return Err(Error::parse(
                path,
                line,
                format!(
                    "expected 7 fields (timestamp [ns], w x y z [rad/s], a x y z [m/s^2]), \
                     found {}",
                    fields.len()
                ),
            ));
        }
        let ns = parse_nanos(path, line, fields[0])?;
        let mut v = [0.0; 6];
        for (k, slot) in v.iter_mut().enumerate() {
            *slot = parse_finite(path, line, COLUMNS[k + 1], fields[k + 1])?;
        }
        rows += 1;
        if let (Some(&prev), Some(&prev_line)) = (stamps.last(), lines.last()) {
            if ns == prev {
                duplicates += 1;
                if duplicate_lines.len() < MAX_LISTED {
                    duplicate_lines.push(line);
                }
                continue;
            }
            if ns < prev {
                return Err(Error::parse(
                    path,
                    line,
                    format!(
                        "time stamp {ns} is {} ns before the one on line {prev_line} ({prev}): \
                         time goes backwards (lines out of order, or two logs joined); an IMU \
                         CSV must be in time order",
                        i128::from(prev) - i128::from(ns)
                    ),
                ));
            }
        }
        let raw_t = RawTime::from_nanos(ns);
        let ep = *epoch.get_or_insert_with(|| Epoch::at(raw_t));
        stamps.push(ns);
        lines.push(line);
        samples.push(ImuSample {
            t: ep.rel(raw_t),
            gyro: Vector3::new(v[0], v[1], v[2]),
            accel: Vector3::new(v[3], v[4], v[5]),
        });
    }
    let Some(epoch) = epoch.filter(|_| !samples.is_empty()) else {
        return Err(Error::parse(
            path,
            last_line(text),
            "no IMU samples in the file",
        ));
    };
    let stats = stream_stats(&samples, &stamps, &lines, header_line, rows, duplicates);
    let stats = ImuStats {
        duplicate_lines,
        ..stats
    };
    check_units(path, lines[0], &stats)?;
    Ok(ImuLog {
        path: path.to_path_buf(),
        epoch,
        samples,
        lines,
        stats,
    })
}

/// An IMU stream read from elsewhere than a CSV (a bag's topic, `path` the bag): `samples` in
/// time order, strictly increasing, relative to `epoch`; the figures number them from 1 where
/// a CSV's name lines. Checked as a CSV is (the units), and an error without samples.
pub fn imu_log_of(path: &Path, epoch: Epoch, samples: Vec<ImuSample>) -> Result<ImuLog> {
    if samples.is_empty() {
        return Err(Error::Input(format!("{}: no IMU samples", path.display())));
    }
    let lines: Vec<usize> = (1..=samples.len()).collect();
    let stamps: Vec<i64> = samples.iter().map(|s| (s.t * 1e9).round() as i64).collect();
    let stats = stream_stats(&samples, &stamps, &lines, None, samples.len(), 0);
    check_units(path, 1, &stats)?;
    Ok(ImuLog {
        path: path.to_path_buf(),
        epoch,
        samples,
        lines,
        stats,
    })
}

/// A first line without `#` that names the columns (`timestamp [ns],w_RS_S_x ...`).
fn starts_like_header(content: &str) -> bool {
    content
        .chars()
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic())
}

/// Refuses a header whose columns are not the 7 of an IMU CSV, or that names units other than
/// rad/s and m/s^2.
fn check_header(path: &Path, line: usize, header: &str) -> Result<()> {
    let cols: Vec<String> = header
        .trim_start_matches('#')
        .split(',')
        .map(|c| c.trim().to_ascii_lowercase())
        .collect();
    if cols.len() != 7 {
        return Err(Error::parse(
            path,
            line,
            format!(
                "the header has {} columns; an IMU CSV has 7: {EUROC_IMU_HEADER}",
                cols.len()
            ),
        ));
    }
    if let Some(c) = cols[1..4].iter().find(|c| c.contains("deg")) {
        return Err(Error::parse(
            path,
            line,
            format!(
                "the header gives the gyro in degrees ('{c}'): dvlcal reads rad/s; multiply the \
                 three w_RS_S columns by pi/180 = 0.017453293 and write '[rad s^-1]'"
            ),
        ));
    }
    let in_g = |c: &str| {
        c.contains("[g]") || c.contains("[g ]") || c.contains("(g)") || c.contains("[mg]")
    };
    if let Some(c) = cols[4..7].iter().find(|c| in_g(c)) {
        return Err(Error::parse(
            path,
            line,
            format!(
                "the header gives the accelerometer in g ('{c}'): dvlcal reads m/s^2; multiply \
                 the three a_RS_S columns by 9.80665 (by 0.00980665 from mg) and write \
                 '[m s^-2]'"
            ),
        ));
    }
    Ok(())
}

/// Parses an integer number of nanoseconds, or says what the stamp looks like instead.
fn parse_nanos(path: &Path, line: usize, s: &str) -> Result<i64> {
    if let Ok(ns) = s.parse::<i64>() {
        return Ok(ns);
    }
    let why = if s.contains(['e', 'E']) && s.parse::<f64>().is_ok() {
        "is in scientific notation, which has lost the nanoseconds (a file saved by a \
         spreadsheet?): write the stamps as whole nanoseconds"
            .to_string()
    } else if s.contains('.') && s.parse::<f64>().is_ok() {
        let whole = s.split('.').next().unwrap_or("").trim_start_matches('-');
        let unit = match whole.len() {
            9..=10 => "seconds (Unix time)",
            12..=13 => "milliseconds",
            15..=16 => "microseconds",
            _ => "another unit",
        };
        format!(
            "is not in integer nanoseconds: it looks like {unit}; write whole nanoseconds (for \
             seconds, the digits without the point, padded to nine decimals)"
        )
    } else if s.is_empty() {
        "is empty".to_string()
    } else {
        "is not an integer number of nanoseconds (within +-9.2e18)".to_string()
    };
    Err(Error::parse(path, line, format!("time stamp '{s}' {why}")))
}

/// The stream's figures: intervals, gaps, saturation, and the numbers the unit checks use.
fn stream_stats(
    samples: &[ImuSample],
    stamps: &[i64],
    lines: &[usize],
    header_line: Option<usize>,
    rows: usize,
    duplicates: usize,
) -> ImuStats {
    let intervals: Vec<f64> = stamps
        .windows(2)
        .map(|w| (i128::from(w[1]) - i128::from(w[0])) as f64 * 1e-9)
        .collect();
    let median_interval_s = median(&mut intervals.clone());
    let (mut gaps, mut longest_gap) = (0, None::<ImuGap>);
    for (k, &d) in intervals.iter().enumerate() {
        if d > GAP_FACTOR * median_interval_s {
            gaps += 1;
            if longest_gap.as_ref().is_none_or(|g| d > g.duration_s) {
                longest_gap = Some(ImuGap {
                    previous_line: lines[k],
                    line: lines[k + 1],
                    t_s: samples[k].t,
                    duration_s: d,
                });
            }
        }
    }
    let span_s = match (stamps.first(), stamps.last()) {
        (Some(a), Some(b)) => (i128::from(*b) - i128::from(*a)) as f64 * 1e-9,
        _ => 0.0,
    };
    let (saturated_samples, saturated_run_count, saturated_runs) = saturation(samples, lines);
    let mut accel: Vec<f64> = samples.iter().map(|s| s.accel.norm()).collect();
    let mut gyro: Vec<f64> = samples.iter().map(|s| s.gyro.norm()).collect();
    ImuStats {
        header_line,
        rows,
        duplicates,
        duplicate_lines: Vec::new(),
        median_interval_s,
        rate_hz: 1.0 / median_interval_s,
        span_s,
        gaps,
        longest_gap,
        saturated_samples,
        saturated_run_count,
        saturated_runs,
        accel_median_norm: median(&mut accel),
        gyro_p99_radps: quantile(&mut gyro, 0.99),
        gyro_scale: gyro_scale_from_gravity(samples),
    }
}

fn axis_value(s: &ImuSample, axis: usize) -> f64 {
    if axis < 3 {
        s.gyro[axis]
    } else {
        s.accel[axis - 3]
    }
}

/// Runs of at least [`SATURATION_MIN_RUN`] samples in which one axis holds exactly one value
/// whose size is the sensor's full scale (the largest size any of its three axes reaches, or
/// within 0.1 % of it: a range's two ends differ by one step), when that full scale is above
/// [`SATURATION_FLOOR`]. Returns the samples concerned, the number of runs, and the first runs.
fn saturation(samples: &[ImuSample], lines: &[usize]) -> (usize, usize, Vec<SaturatedRun>) {
    let mut hit = vec![false; samples.len()];
    let mut runs = Vec::new();
    let mut count = 0;
    for (sensor, floor) in SATURATION_FLOOR.iter().enumerate() {
        let axes = 3 * sensor..3 * sensor + 3;
        let full = samples
            .iter()
            .flat_map(|s| axes.clone().map(move |k| axis_value(s, k).abs()))
            .fold(0.0, f64::max);
        if full < *floor {
            continue;
        }
        for (axis, name) in AXES.iter().enumerate().skip(3 * sensor).take(3) {
            let mut start = 0;
            while start < samples.len() {
                let v = axis_value(&samples[start], axis);
                let mut end = start + 1;
                while end < samples.len() && axis_value(&samples[end], axis) == v {
                    end += 1;
                }
                if end - start >= SATURATION_MIN_RUN && v.abs() >= full * (1.0 - 1e-3) {
                    count += 1;
                    hit[start..end].iter_mut().for_each(|h| *h = true);
                    if runs.len() < MAX_LISTED {
                        runs.push(SaturatedRun {
                            axis: name,
                            value: v,
                            lines: (lines[start], lines[end - 1]),
                            samples: end - start,
                        });
                    }
                }
                start = end;
            }
        }
    }
    runs.sort_by_key(|r| r.lines.0);
    (hit.iter().filter(|h| **h).count(), count, runs)
}

/// Refuses a stream whose numbers are not rad/s and m/s^2, naming the unit they look like and
/// the conversion; `line` is the first sample's.
fn check_units(path: &Path, line: usize, s: &ImuStats) -> Result<()> {
    let m = s.accel_median_norm;
    let unit = AccelUnit::from_median_norm(m);
    let accel = match unit {
        AccelUnit::MetresPerSecondSquared => None,
        AccelUnit::G => Some("in g".to_string()),
        AccelUnit::MilliG => Some("in milli-g".to_string()),
        AccelUnit::MillimetresPerSecondSquared => Some("in mm/s^2".to_string()),
        AccelUnit::GravityRemoved => Some(
            "a linear acceleration with gravity removed, not a specific force: give the \
             accelerometer's raw output (gravity included)"
                .to_string(),
        ),
        AccelUnit::Unknown => Some("in no unit dvlcal knows".to_string()),
    };
    if let Some(what) = accel {
        let convert = if unit.to_si().is_finite() {
            format!(
                "; multiply the three a_RS_S columns by {}",
                fmt_f64(unit.to_si())
            )
        } else {
            String::new()
        };
        return Err(Error::parse(
            path,
            line,
            format!(
                "the accelerometer does not read m/s^2: the median norm of its specific force \
                 is {m:.4} where a vehicle's is gravity's, about 9.81 m/s^2; it looks {what}\
                 {convert}"
            ),
        ));
    }
    let p99 = s.gyro_p99_radps;
    let deg = |evidence: String| {
        Error::parse(
            path,
            line,
            format!(
                "the gyro looks like it is in degrees per second, not rad/s: {evidence}; \
                 multiply the three w_RS_S columns by pi/180 = 0.017453293"
            ),
        )
    };
    if p99 > MAX_RADPS_P99 {
        return Err(deg(format!(
            "1 % of its rates exceed {p99:.1}, which as rad/s ({:.0} deg/s) is beyond a robot \
             gyro's range and as deg/s ({:.2} rad/s) is an ordinary motion",
            p99 * DEG_PER_RAD,
            p99 / DEG_PER_RAD
        )));
    }
    if s.gyro_scale.scale == GyroScale::DegreesPerSecond {
        return Err(deg(format!(
            "it says the IMU tilts {:.1} times faster than gravity turns in its accelerometer \
             (median over {} stretches of 0.2 s)",
            s.gyro_scale.ratio, s.gyro_scale.pairs
        )));
    }
    Ok(())
}

/// The text of an IMU CSV: [`EUROC_IMU_HEADER`], then one line per sample with its absolute
/// time in integer nanoseconds (`epoch` plus `t`, rounded to the nanosecond) and the values with
/// the shortest digits that read back exactly.
pub fn imu_csv_text(path: &Path, epoch: Epoch, samples: &[ImuSample]) -> Result<String> {
    let mut out = String::with_capacity(160 * (samples.len() + 1));
    out.push_str(EUROC_IMU_HEADER);
    out.push('\n');
    for (i, s) in samples.iter().enumerate() {
        let values = s.gyro.iter().chain(s.accel.iter());
        if !s.t.is_finite() || values.clone().any(|x| !x.is_finite()) {
            return Err(non_finite(path, format!("IMU sample {i}")));
        }
        let ns = i128::from(epoch.sec) * 1_000_000_000 + (s.t * 1e9).round() as i128;
        let ns = i64::try_from(ns).map_err(|_| {
            Error::Input(format!(
                "{}: IMU sample {i}: its time is beyond the nanoseconds an i64 holds",
                path.display()
            ))
        })?;
        let _ = write!(out, "{ns}");
        for x in values {
            let _ = write!(out, ",{}", fmt_f64(*x));
        }
        out.push('\n');
    }
    Ok(out)
}

/// Writes an IMU CSV ([`imu_csv_text`]) atomically.
pub fn write_imu_csv(path: &Path, epoch: Epoch, samples: &[ImuSample]) -> Result<()> {
    let text = imu_csv_text(path, epoch, samples)?;
    super::write_atomic(path, text.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn csv(rows: &[String]) -> String {
        let mut s = String::from(EUROC_IMU_HEADER);
        s.push('\n');
        for r in rows {
            s.push_str(r);
            s.push('\n');
        }
        s
    }

    fn still_rows(n: usize) -> Vec<String> {
        (0..n)
            .map(|k| {
                format!(
                    "{},0.001,-0.002,0.003,0.1,0.2,9.8",
                    1_700_000_000_000_000_000i64 + 5_000_000 * k as i64
                )
            })
            .collect()
    }

    #[test]
    fn times_keep_their_nanoseconds() {
        let text = csv(&[
            "1700000000123456789,0,0,0,0,0,9.81".into(),
            "1700000000128456789,0,0,0,0,0,9.81".into(),
        ]);
        let log = parse_imu_csv(&text, Path::new("imu.csv"), None).unwrap();
        assert_eq!(log.epoch.sec, 1_700_000_000);
        assert!((log.samples[0].t - 0.123456789).abs() < 1e-15);
        let back = imu_csv_text(Path::new("x"), log.epoch, &log.samples).unwrap();
        assert_eq!(back, text);
    }

    #[test]
    fn a_header_without_hash_and_crlf_lines_read() {
        let mut text = EUROC_IMU_HEADER.trim_start_matches('#').to_string() + "\r\n";
        for r in still_rows(3) {
            text.push_str(&r);
            text.push_str("\r\n");
        }
        let log = parse_imu_csv(&text, Path::new("imu.csv"), None).unwrap();
        assert_eq!((log.samples.len(), log.stats.header_line), (3, Some(1)));
        assert_eq!(log.lines, vec![2, 3, 4]);
    }

    #[test]
    fn stamps_in_other_units_are_named() {
        for (stamp, want) in [
            ("1700000000.005", "seconds"),
            ("1700000000005.0", "milliseconds"),
            ("1.7E+18", "scientific notation"),
            ("abc", "not an integer"),
        ] {
            let text = csv(&[format!("{stamp},0,0,0,0,0,9.8")]);
            let e = parse_imu_csv(&text, Path::new("imu.csv"), None)
                .unwrap_err()
                .to_string();
            assert!(e.starts_with("imu.csv:2: "), "{e}");
            assert!(e.contains(want), "{stamp}: {e}");
        }
    }

    #[test]
    fn a_full_scale_run_is_saturation_and_a_resting_repeat_is_not() {
        let mut rows = still_rows(40);
        // Gyro x pinned at its range's end (4.3633 rad/s, 250 deg/s) for 4 samples, after
        // reaching -4.3634 (the other end) once.
        rows[9] = rows[9].replacen(",0.001,", ",-4.3634,", 1);
        for r in &mut rows[20..24] {
            *r = r.replacen(",0.001,", ",4.3633,", 1);
        }
        let log = parse_imu_csv(&csv(&rows), Path::new("imu.csv"), None).unwrap();
        assert_eq!(log.stats.saturated_samples, 4);
        assert_eq!(log.stats.saturated_run_count, 1);
        let run = &log.stats.saturated_runs[0];
        assert_eq!((run.axis, run.lines, run.samples), ("gyro x", (22, 25), 4));
        // The resting rows repeat their values too, far below any range: not saturation.
        let log = parse_imu_csv(&csv(&still_rows(40)), Path::new("imu.csv"), None).unwrap();
        assert_eq!(log.stats.saturated_samples, 0);
    }
}
