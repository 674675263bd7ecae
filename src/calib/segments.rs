//! A DVL clock that stepped: the recording in clock segments, each with its own clock offset,
//! sharing the extrinsics and the velocity scale.
//!
//! The longest segment is calibrated first. Each other segment's offset is then found as the lag
//! at which that result predicts the segment's velocity vectors best (every lag at which it
//! overlaps the camera trajectory by half, on a 0.1 s grid: a short segment's speeds alone can
//! match the wrong stretch of the motion), and refined with the extrinsics and the scale held;
//! its samples are moved onto the first segment's clock (`t + offset_k - offset_0`), and the
//! whole recording is calibrated once more, so the extrinsics and the scale rest on every
//! segment. A segment shorter than [`MIN_SEGMENT_S`] (or with fewer than [`MIN_SEGMENT_SAMPLES`]
//! reports) or whose offset cannot be found is left out with a warning.

use super::options::{CalibOptions, Method};
use super::outcome::CalibrationOutcome;
use super::{CoSensor, Setting, calibrate_against};
use crate::error::{Error, Result};
use crate::types::{DvlSample, PoseMeasurement};

/// A clock segment shorter than this, seconds, is left out.
pub const MIN_SEGMENT_S: f64 = 5.0;
/// A clock segment with fewer reports than this is left out.
pub const MIN_SEGMENT_SAMPLES: usize = 30;

/// What became of one clock segment.
#[derive(Clone, Debug, PartialEq)]
pub struct SegmentOffset {
    /// Its reports.
    pub samples: usize,
    /// Its span on its own clock, seconds.
    pub duration_s: f64,
    /// Its clock offset (`t_cam = t_dvl + offset` for its reports), when it was used.
    pub time_offset_s: Option<f64>,
    /// The offset's standard deviation.
    pub time_offset_std_s: Option<f64>,
    /// Why it was left out, when it was.
    pub left_out: Option<String>,
}

/// Calibrates against `poses` a DVL log in clock `segments` (time-ordered each, in file order).
/// With one segment this is [`super::calibrate`]. `names` words a segment for messages (its
/// lines in the log).
pub fn calibrate_segments(
    poses: &[PoseMeasurement],
    segments: &[&[DvlSample]],
    names: &[String],
    opts: &CalibOptions,
) -> Result<(CalibrationOutcome, Vec<SegmentOffset>)> {
    if segments.len() <= 1 {
        let dvl = segments.first().copied().unwrap_or(&[]);
        return Ok((
            calibrate_against(CoSensor::Poses(poses), dvl, opts)?,
            Vec::new(),
        ));
    }
    if opts.clock_drift {
        // One drift per clock needs one clock: a recording whose clock stepped has several.
        return Err(Error::Input(format!(
            "{} with a clock that steps ({} clock segments, the first {}): a drift is \
             estimated on one clock; calibrate each segment's reports on their own, or without \
             the drift",
            opts.name(Setting::ClockDrift),
            segments.len(),
            names.first().map_or("?", String::as_str)
        )));
    }
    let span = |s: &[DvlSample]| match (s.first(), s.last()) {
        (Some(a), Some(b)) => b.t - a.t,
        _ => 0.0,
    };
    let name = |k: usize| {
        names
            .get(k)
            .cloned()
            .unwrap_or_else(|| format!("segment {}", k + 1))
    };
    let mut out: Vec<SegmentOffset> = segments
        .iter()
        .map(|s| SegmentOffset {
            samples: s.len(),
            duration_s: span(s),
            time_offset_s: None,
            time_offset_std_s: None,
            left_out: None,
        })
        .collect();
    let mut warnings = Vec::new();
    for (k, o) in out.iter_mut().enumerate() {
        if o.duration_s < MIN_SEGMENT_S || o.samples < MIN_SEGMENT_SAMPLES {
            let why = format!(
                "too short to find its own clock offset ({} reports over {:.1} s; at least {} \
                 over {} s)",
                o.samples, o.duration_s, MIN_SEGMENT_SAMPLES, MIN_SEGMENT_S
            );
            warnings.push(format!("clock segment {} is left out: {why}", name(k)));
            o.left_out = Some(why);
        }
    }
    // The longest usable segment sets the extrinsics the others' offsets are found with.
    let Some(main) = (0..segments.len())
        .filter(|&k| out[k].left_out.is_none())
        .max_by(|&a, &b| out[a].duration_s.total_cmp(&out[b].duration_s))
    else {
        return Err(Error::Input(format!(
            "a clock stepped (the DVL's, or the camera's), and none of the {} clock segments ({}) \
             is long enough to calibrate (each needs {MIN_SEGMENT_SAMPLES} reports over \
             {MIN_SEGMENT_S} s)",
            segments.len(),
            (0..segments.len()).map(name).collect::<Vec<_>>().join(", ")
        )));
    };
    let first = calibrate_against(CoSensor::Poses(poses), segments[main], opts)?;
    if !first.status.is_ok() {
        let mut o = first;
        o.warnings.extend(warnings);
        o.warnings.push(format!(
            "the longest clock segment ({}) did not calibrate; the other segments were not used",
            name(main)
        ));
        return Ok((o, out));
    }
    let offset0 = first.params.time_offset_s;
    let mut merged: Vec<DvlSample> = segments[main].to_vec();
    let mut shifts = vec![None; segments.len()];
    shifts[main] = Some(0.0);
    for k in 0..segments.len() {
        if k == main || out[k].left_out.is_some() {
            continue;
        }
        // The segment's offset: the lag at which the held extrinsics predict its velocities
        // best, then refined with them held.
        let found = match vector_lag(&first.fitted, &first.params, segments[k]) {
            Some(lag) => {
                let mut guess = first.params;
                guess.time_offset_s = lag;
                let held = CalibOptions {
                    method: Method::Fixed {
                        guess,
                        estimate_offset: true,
                    },
                    // Searched near the lag only: the speeds alone may prefer another.
                    offset: super::offset::OffsetOptions {
                        range: Some((lag - LAG_SEARCH_S, lag + LAG_SEARCH_S)),
                        ..opts.offset.clone()
                    },
                    ..opts.clone()
                };
                calibrate_against(CoSensor::Poses(poses), segments[k], &held)
            }
            None => Err(Error::Input(
                "it does not overlap the camera trajectory at any clock offset".to_owned(),
            )),
        };
        let why = match found {
            // Its residuals, not the contradiction check, decide: the extrinsics it is held at
            // are an estimate (the whole recording is calibrated again below).
            Ok(o) if o.normalized_cost <= opts.sanity.max_normalized_cost => {
                let shift = o.params.time_offset_s - offset0;
                merged.extend(segments[k].iter().map(|s| DvlSample {
                    t: s.t + shift,
                    ..s.clone()
                }));
                shifts[k] = Some(shift);
                out[k].time_offset_std_s = Some(o.std.time_offset_s);
                continue;
            }
            Ok(o) => format!(
                "at its best clock offset ({:.3} s) its DVL residuals are {:.1} times the stated \
                 noise with the other segment's extrinsics (at most {} is credible): it does not \
                 fit this recording",
                o.params.time_offset_s, o.normalized_cost, opts.sanity.max_normalized_cost
            ),
            Err(e) => format!("its clock offset could not be found: {e}"),
        };
        warnings.push(format!("clock segment {} is left out: {why}", name(k)));
        out[k].left_out = Some(why);
    }
    // With only the longest segment left, its calibration is the result.
    let mut result = if merged.len() == segments[main].len() {
        first
    } else {
        merged.sort_by(|a, b| a.t.total_cmp(&b.t));
        calibrate_against(CoSensor::Poses(poses), &merged, opts)?
    };
    let offset = result.params.time_offset_s;
    let offset_std = result.std.time_offset_s;
    for (k, o) in out.iter_mut().enumerate() {
        if let Some(shift) = shifts[k] {
            o.time_offset_s = Some(offset + shift);
            // The segment's own offset against the others' adds to the common one's.
            let own = o.time_offset_std_s.unwrap_or(0.0);
            o.time_offset_std_s = Some((offset_std * offset_std + own * own).sqrt());
        }
    }
    let used = out.iter().filter(|o| o.time_offset_s.is_some()).count();
    result.warnings.extend(warnings);
    result.warnings.push(format!(
        "a clock stepped: {used} of {} clock segments calibrated together (shared \
         extrinsics and scale, one clock offset each: {}); the clock offset above is the one of \
         segment {}",
        segments.len(),
        out.iter()
            .enumerate()
            .map(|(k, o)| match o.time_offset_s {
                Some(t) => format!("{} {t:.4} s", name(k)),
                None => format!("{} left out", name(k)),
            })
            .collect::<Vec<_>>()
            .join(", "),
        name(main)
    ));
    Ok((result, out))
}

/// Step of the lag grid of [`vector_lag`], seconds.
const LAG_STEP_S: f64 = 0.1;
/// Half-width of the offsets searched around that lag, seconds.
const LAG_SEARCH_S: f64 = 1.0;

/// The clock offset at which `params` (its own offset aside) predict the velocities of `seg`
/// from the camera trajectory `traj` best: the least mean squared difference over the lags at
/// which at least half of the segment lies inside the trajectory's span.
fn vector_lag(
    traj: &crate::trajectory::Trajectory,
    params: &crate::types::CalibrationParams,
    seg: &[DvlSample],
) -> Option<f64> {
    let (c0, c1) = traj.span();
    let (s0, s1) = (seg.first()?.t, seg.last()?.t);
    let (lo, hi) = (c0 - s1, c1 - s0);
    let steps = ((hi - lo) / LAG_STEP_S).ceil();
    if !(0.0..1e7).contains(&steps) {
        return None;
    }
    let mut best: Option<(f64, f64)> = None;
    for i in 0..=steps as usize {
        let lag = lo + i as f64 * LAG_STEP_S;
        let mut sum = 0.0;
        let mut n = 0usize;
        for s in seg {
            if let Ok(tw) = traj.twist(s.t + lag) {
                sum += (s.v - super::model::predict(params, &tw)).norm_squared();
                n += 1;
            }
        }
        if 2 * n < seg.len() || n == 0 {
            continue;
        }
        let mean = sum / n as f64;
        if best.is_none_or(|(_, m)| mean < m) {
            best = Some((lag, mean));
        }
    }
    best.map(|(lag, _)| lag)
}
