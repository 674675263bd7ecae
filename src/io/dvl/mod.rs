//! Water Linked A50 logs in every form a user is likely to have, read into [`DvlSample`]s.
//!
//! Accepted inputs (see `docs/formats.md`):
//! - JSON lines (the TCP stream on port 16171 captured with `nc`, JSON forwarded over UDP, or a
//!   `record-dvl` log), json_v1 to json_v3.x, LF or CRLF line ends (CR alone in a text without
//!   any LF, with a warning);
//! - serial text (`wrz`, `wrs`, `wru`, `wrp`, deprecated `wrx`/`wrt`) with CRC-8 checksums;
//! - ROS1 bags of the vendor's driver (`/dvl/json_data`, `/dvl/data`).
//!
//! The format is detected from the content unless forced. Every parser turns a line (or a bag
//! message) into a [`report::Parsed`]; the common code here removes exact duplicates, picks the
//! time stamp, chooses the epoch, checks the time order and gathers the counts. Nothing here
//! estimates anything, and no input byte sequence makes it panic: a line that cannot be used is
//! rejected with its reason (lenient mode) or stops the read with an error naming `file:line`
//! (strict mode).

pub mod a50;
pub(crate) mod bag;
pub(crate) mod detect;
pub(crate) mod json;
mod log;
pub mod polled;
pub(crate) mod record;
pub(crate) mod report;
pub(crate) mod serial;
mod summary;

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use nalgebra::{Matrix3, Vector3};

use crate::error::{Error, Result};
use crate::time::{Epoch, RawTime};
use crate::types::DvlSample;

pub use detect::detect_format;
pub use json::parse_line as parse_json_line;
pub use log::{
    ClockSegment, ClockStep, ClockStepKind, DvlFormat, DvlGap, DvlLog, DvlLogStats, DvlReadOptions,
    DvlTimeSource, GAP_MIN_INTERVALS, GAP_MIN_S, MAX_LISTED, RejectedLine, TimeProblem, cr_only,
    text_lines,
};
pub use polled::PolledCapture;
pub use record::{RecordOptions, RecordStats, add_host_time, check_address, record_tcp};
pub use report::{Parsed, Reject, VelocityReport};
pub use serial::parse_line as parse_serial_line;

/// Largest speed component of a valid velocity report, m/s: no DVL-carrying vehicle moves at 10
/// m/s (the A50 is rated far below it).
pub const MAX_SPEED_MPS: f64 = 10.0;

/// Largest time line rebuilt from `time` increments, ms: 2^63, where whole milliseconds stop
/// fitting an i64.
const MAX_REBUILT_MS: f64 = 9_223_372_036_854_775_808.0;

/// Reads a DVL log of any accepted format into valid, deduplicated, time-ordered samples.
///
/// Errors: the file cannot be read; its format cannot be recognised; it holds no usable
/// velocity report; the time source asked for is absent; or, in strict mode, the first
/// malformed line (named `file:line`).
pub fn read_dvl_log(path: &Path, opts: &DvlReadOptions) -> Result<DvlLog> {
    // A bag (a ROS 2 bag folder, or a file of tens of GB) is streamed, never read whole.
    let is_bag = crate::io::bag::is_bag(path);
    if is_bag && matches!(opts.format, None | Some(DvlFormat::RosBag)) {
        return read_bag_log(path, opts);
    }
    let bytes = crate::files::read_bytes(path)?;
    blank_log(path, &bytes)?;
    let format = match opts.format {
        Some(f) => f,
        // A file named like a bag that does not start like one: the bag reader names what its
        // first bytes are instead of the storage's magic.
        None if detect_format(&bytes).is_none()
            && crate::io::bag::Storage::of_extension(path).is_some() =>
        {
            return read_bag_log(path, opts);
        }
        None => detect_format(&bytes).ok_or_else(|| {
            Error::Input(format!(
                "{}: not a recognised DVL log (JSON lines, serial sentences or a ROS bag); \
                 use --dvl-format to force one",
                path.display()
            ))
        })?,
    };
    if format == DvlFormat::RosBag {
        return read_bag_log(path, opts);
    }
    let mut stats = DvlLogStats {
        path: path.to_path_buf(),
        format: Some(format),
        time_source: opts.time_source,
        ..Default::default()
    };
    let mut acc = Accumulator::default();
    push_text(&mut acc, path, opts.strict, &mut stats, &bytes, format)?;
    acc.finish(path, opts, stats)
}

/// [`read_dvl_log`] on a bag: its DVL topic, streamed.
fn read_bag_log(path: &Path, opts: &DvlReadOptions) -> Result<DvlLog> {
    let mut stats = DvlLogStats {
        path: path.to_path_buf(),
        format: Some(DvlFormat::RosBag),
        time_source: opts.time_source,
        ..Default::default()
    };
    let mut acc = Accumulator::default();
    bag::read_bag(path, opts, &mut stats, &mut |stats, line, parsed| {
        acc.push(path, opts.strict, stats, line, parsed)
    })?;
    acc.finish(path, opts, stats)
}

/// An error for a log without a line to read: empty, or only blanks and line ends.
fn blank_log(path: &Path, bytes: &[u8]) -> Result<()> {
    if bytes.is_empty() {
        return Err(Error::Input(format!(
            "{}: the DVL log is empty (0 bytes): the recording wrote nothing (was the DVL \
             connected, and the capture stopped cleanly?)",
            path.display()
        )));
    }
    if bytes.iter().all(|b| b.is_ascii_whitespace()) {
        return Err(Error::Input(format!(
            "{}: the DVL log holds only blanks and line ends ({} bytes, not one report)",
            path.display(),
            bytes.len()
        )));
    }
    Ok(())
}

/// Reads DVL samples from in-memory text (JSON lines or serial sentences), as [`read_dvl_log`]
/// does for a file; `name` stands for the file in messages. Bags need a file.
pub fn read_dvl_text(name: &Path, bytes: &[u8], opts: &DvlReadOptions) -> Result<DvlLog> {
    blank_log(name, bytes)?;
    let format = match opts.format.or_else(|| detect_format(bytes)) {
        Some(DvlFormat::RosBag) => {
            return Err(Error::Input(format!(
                "{}: ROS bags are read from files only",
                name.display()
            )));
        }
        Some(f) => f,
        None => {
            return Err(Error::Input(format!(
                "{}: not a recognised DVL log",
                name.display()
            )));
        }
    };
    let mut stats = DvlLogStats {
        path: name.to_path_buf(),
        format: Some(format),
        time_source: opts.time_source,
        ..Default::default()
    };
    let mut acc = Accumulator::default();
    push_text(&mut acc, name, opts.strict, &mut stats, bytes, format)?;
    acc.finish(name, opts, stats)
}

/// Lines parsed side by side by [`push_text`], at most: the parsed lines wait in memory until
/// they are handed on in order, so a log of any size holds no more than this many at a time.
const PARSE_BLOCK: usize = 1 << 16;
/// Lines per unit of work within a block.
const PARSE_PIECE: usize = 2048;

/// Every non-blank line of the text log `bytes` (JSON lines or serial sentences), parsed and
/// handed to `acc` in file order. Parsing a line depends on that line alone, so blocks of lines
/// are parsed on all cores; what depends on the lines before (duplicates, time order, counts,
/// the first error in strict mode) happens in `acc`, one line after another, exactly as in a
/// sequential read.
fn push_text(
    acc: &mut Accumulator,
    path: &Path,
    strict: bool,
    stats: &mut DvlLogStats,
    bytes: &[u8],
    format: DvlFormat,
) -> Result<()> {
    let parse = |content: &[u8]| {
        if format == DvlFormat::JsonLines {
            json::parse_line(content)
        } else {
            serial::parse_line(content)
        }
    };
    if cr_only(bytes) {
        stats.warnings.push(format!(
            "{}: its lines end with CR alone (classic Mac OS line ends, no LF anywhere): read \
             with CR as the line end",
            path.display()
        ));
    }
    let mut lines = text_lines(bytes).peekable();
    while lines.peek().is_some() {
        let block: Vec<(usize, &[u8])> = lines.by_ref().take(PARSE_BLOCK).collect();
        let parsed = crate::parallel::map_indices(block.len(), PARSE_PIECE, |j| parse(block[j].1));
        for (&(line, _), p) in block.iter().zip(parsed) {
            acc.push(path, strict, stats, line, p)?;
        }
    }
    Ok(())
}

/// Counts one more `key` without allocating when it is already there.
fn bump(map: &mut BTreeMap<String, usize>, key: &str) {
    match map.get_mut(key) {
        Some(n) => *n += 1,
        None => {
            map.insert(key.to_string(), 1);
        }
    }
}

/// Velocity reports kept (first occurrences) with their line numbers.
#[derive(Default)]
struct Accumulator {
    reports: Vec<(usize, VelocityReport)>,
    /// Hash of a report's identity -> indices into `reports` with that hash.
    seen: HashMap<u64, Vec<usize>>,
    /// The last line (or message) number seen.
    last_line: usize,
    /// Runs of one report repeated line after line, in file order: the index of the report in
    /// `reports` and the run's length (see [`PolledCapture`]).
    runs: Vec<(usize, usize)>,
}

impl Accumulator {
    fn push(
        &mut self,
        path: &Path,
        strict: bool,
        stats: &mut DvlLogStats,
        line: usize,
        parsed: std::result::Result<Parsed, Reject>,
    ) -> Result<()> {
        stats.lines += 1;
        self.last_line = line;
        match parsed {
            Err(r) => stats.reject(path, strict, line, r)?,
            // A valid report faster than any vehicle a DVL rides on is a unit or encoding error
            // (mm/s written as m/s, a corrupted number), never a velocity to fit.
            Ok(Parsed::Velocity(r))
                if r.valid && r.v.iter().any(|x| x.is_nan() || x.abs() >= MAX_SPEED_MPS) =>
            {
                stats.reject(
                    path,
                    strict,
                    line,
                    Reject::new(
                        "velocity out of range",
                        format!(
                            "velocity [{}, {}, {}] m/s has a component of {MAX_SPEED_MPS} m/s or \
                             more (millimetres per second written as metres?)",
                            r.v[0], r.v[1], r.v[2]
                        ),
                    ),
                )?;
            }
            Ok(Parsed::Velocity(r)) => {
                stats.velocity_reports += 1;
                bump(&mut stats.formats_seen, &r.label);
                if r.valid {
                    stats.valid += 1;
                } else {
                    stats.invalid += 1;
                }
                let bucket = self.seen.entry(r.key).or_default();
                let index = match bucket
                    .iter()
                    .copied()
                    .find(|&i| self.reports[i].1.same_report(&r))
                {
                    Some(i) => {
                        stats.duplicates += 1;
                        i
                    }
                    None => {
                        bucket.push(self.reports.len());
                        self.reports.push((line, r));
                        self.reports.len() - 1
                    }
                };
                match self.runs.last_mut() {
                    Some(run) if run.0 == index => run.1 += 1,
                    _ => self.runs.push((index, 1)),
                }
            }
            Ok(Parsed::WaterVelocity { label }) => {
                stats.water_velocity_reports += 1;
                bump(&mut stats.formats_seen, &label);
            }
            Ok(Parsed::Config {
                label,
                speed_of_sound,
            }) => {
                stats.other_reports += 1;
                bump(&mut stats.formats_seen, &label);
                bump(&mut stats.other_by_type, "config");
                if let Some(c) = speed_of_sound {
                    if stats.sound_speed_mps.is_some_and(|old| old != c) {
                        let at = stats.at(line);
                        stats.warnings.push(format!(
                            "{at}: the DVL's sound speed changed to {c} m/s during the log"
                        ));
                    }
                    stats.sound_speed_mps = Some(c);
                    stats.sound_speed_source = Some(stats.at(line));
                }
            }
            Ok(Parsed::Other { label, kind }) => {
                stats.other_reports += 1;
                bump(&mut stats.formats_seen, &label);
                bump(&mut stats.other_by_type, &kind);
            }
        }
        Ok(())
    }

    fn finish(self, path: &Path, opts: &DvlReadOptions, mut stats: DvlLogStats) -> Result<DvlLog> {
        if self.reports.is_empty() {
            // Say why: the commonest rejection reasons with their counts, and the first rejected
            // line with its detail.
            let mut reasons: Vec<(&String, &usize)> = stats.rejected_by_reason.iter().collect();
            reasons.sort_by(|a, b| b.1.cmp(a.1).then(a.0.cmp(b.0)));
            let why = if reasons.is_empty() {
                String::new()
            } else {
                let top: Vec<String> = reasons
                    .iter()
                    .take(3)
                    .map(|(r, n)| format!("{n} {r}"))
                    .collect();
                let first = stats
                    .rejected
                    .first()
                    .map(|r| format!("; first at {} {}: {}", stats.unit(), r.line, r.detail))
                    .unwrap_or_default();
                format!(": rejected lines: {}{first}", top.join(", "))
            };
            // Damage found on the way (a bag's lost chunks) is the likelier cause: keep it.
            let why = if stats.warnings.is_empty() {
                why
            } else {
                format!("{why}; {}", stats.warnings.join("; "))
            };
            return Err(stats.error_at(
                self.last_line.max(1),
                format!(
                    "no velocity reports in the log ({} {}s, {} rejected, {} of other types){why}",
                    stats.lines,
                    stats.unit(),
                    stats.rejected_lines,
                    stats.other_reports + stats.water_velocity_reports
                ),
            ));
        }
        let times = choose_times(path, opts.time_source, &self.reports, &mut stats)?;
        stats.polled = PolledCapture::find(
            &self.runs,
            &self.reports,
            stats.time_source_used == REBUILT_TIMES,
        );
        if let Some(p) = &stats.polled {
            stats
                .warnings
                .push(format!("{}: {}", path.display(), p.explain()));
        }
        // Epoch: given, or the whole second of the earliest time.
        let epoch = match opts.epoch {
            Some(e) => e,
            None => times
                .iter()
                .flatten()
                .min_by(|a, b| {
                    (a.sec, a.frac)
                        .partial_cmp(&(b.sec, b.frac))
                        .unwrap_or(std::cmp::Ordering::Equal)
                })
                .map(|t| Epoch::at(*t))
                .unwrap_or_default(),
        };
        // The clock's steps, over every report with a time (valid or not) in file order.
        let stamped: Vec<(usize, f64, f64, Option<f64>)> = self
            .reports
            .iter()
            .zip(&times)
            .filter_map(|((line, r), t)| {
                t.map(|t| (*line, epoch.rel(t), t.sec as f64 + t.frac, r.time_ms))
            })
            .collect();
        stats.clock_steps = clock_steps(&stamped);
        let mut samples: Vec<(usize, DvlSample)> = Vec::with_capacity(self.reports.len());
        for ((line, r), t) in self.reports.iter().zip(&times) {
            let Some(t) = t else { continue };
            if !r.valid && !opts.include_invalid {
                continue;
            }
            let cov = r.cov.map(|c| Matrix3::from_row_slice(&c));
            samples.push((
                *line,
                DvlSample {
                    t: epoch.rel(*t),
                    v: Vector3::new(r.v[0], r.v[1], r.v[2]),
                    cov,
                    valid: r.valid,
                },
            ));
        }
        // Time order as found in the file, within each clock segment.
        // The clock segment of a line: the number of steps at or before it (the steps are in
        // file order).
        let starts: Vec<usize> = stats.clock_steps.iter().map(|c| c.line).collect();
        let segment_of = |line: usize| starts.partition_point(|&l| l <= line);
        for w in 1..samples.len() {
            let step = samples[w].1.t - samples[w - 1].1.t;
            let new_segment = segment_of(samples[w].0) != segment_of(samples[w - 1].0);
            if step <= 0.0 && !new_segment {
                if step < 0.0 {
                    stats.time_backwards += 1;
                } else {
                    stats.time_repeats += 1;
                }
                if stats.time_problems.len() < MAX_LISTED {
                    stats.time_problems.push(TimeProblem {
                        line: samples[w].0,
                        step_s: step,
                    });
                }
            }
        }
        if stats.time_backwards > 0 {
            stats.warnings.push(format!(
                "{} sample times go backwards; samples were sorted by time",
                stats.time_backwards
            ));
        }
        if stats.time_repeats > 0 {
            stats.warnings.push(format!(
                "{} samples repeat the previous sample's time with different content",
                stats.time_repeats
            ));
        }
        // Each segment sorted by time on its own: across a step the times of different clocks
        // do not compare.
        samples.sort_by(|a, b| {
            segment_of(a.0)
                .cmp(&segment_of(b.0))
                .then(a.1.t.total_cmp(&b.1.t))
        });
        let mut clock_segments: Vec<ClockSegment> = Vec::new();
        for (i, (line, _)) in samples.iter().enumerate() {
            match clock_segments.last_mut() {
                Some(c) if segment_of(*line) == segment_of(c.lines.0) => {
                    c.samples.end = i + 1;
                    c.lines.0 = c.lines.0.min(*line);
                    c.lines.1 = c.lines.1.max(*line);
                }
                _ => clock_segments.push(ClockSegment {
                    samples: i..i + 1,
                    lines: (*line, *line),
                }),
            }
        }
        let steps: Vec<String> = stats
            .clock_steps
            .iter()
            .take(MAX_LISTED)
            .map(|c| {
                format!(
                    "{}: the DVL clock {} by {:.3} s after {} {}: the log is split into clock \
                     segments there, each with its own clock offset",
                    stats.at(c.line),
                    c.kind.words(),
                    c.step_s,
                    stats.unit(),
                    c.previous_line
                )
            })
            .collect();
        stats.warnings.extend(steps);
        if stats.clock_steps.len() > MAX_LISTED {
            stats.warnings.push(format!(
                "{}: {} more steps of the DVL clock after those listed",
                path.display(),
                stats.clock_steps.len() - MAX_LISTED
            ));
        }
        stats.first_time_s = samples.iter().map(|s| s.1.t).min_by(f64::total_cmp);
        stats.last_time_s = samples.iter().map(|s| s.1.t).max_by(f64::total_cmp);
        // An A50 reports at 2-26 Hz; a rate far outside that is a time unit read wrongly.
        // (over the clock segments: across a step the times do not compare)
        let spans: f64 = clock_segments
            .iter()
            .filter_map(|c| {
                Some(samples.get(c.samples.end - 1)?.1.t - samples.get(c.samples.start)?.1.t)
            })
            .sum();
        let intervals = samples.len().saturating_sub(clock_segments.len());
        let segment_rate = (spans > 0.0).then(|| intervals as f64 / spans);
        if let Some(rate) = segment_rate
            && samples.len() >= 10
            && !(0.5..=100.0).contains(&rate)
        {
            stats.warnings.push(format!(
                "{}: the reports come at {rate:.4} Hz on average, where an A50 reports at 2 to 26 \
                 Hz: the time stamps are probably in other units than the format's ({})",
                path.display(),
                if rate > 100.0 {
                    "milliseconds where microseconds are expected?"
                } else {
                    "microseconds where milliseconds are expected, or large gaps?"
                }
            ));
        }
        let (lines, samples) = samples.into_iter().unzip();
        Ok(DvlLog {
            epoch,
            samples,
            lines,
            clock_segments,
            stats,
        })
    }
}

/// The least jump of the DVL clock, seconds, that counts as a step (back, or forward beyond the
/// reports' own `time` increments): ten times the A50's slowest ping interval's jitter.
pub const CLOCK_STEP_MIN_S: f64 = 1.0;
/// A clock that jumps back to before this Unix time, seconds (1971), restarted from zero.
const RESTART_BEFORE_UNIX_S: f64 = 365.0 * 86_400.0;

/// The steps of a clock from its reports in file order: `(line, time relative to the epoch,
/// absolute Unix time, the report's `time` increment in ms)`. A step back of more than
/// [`CLOCK_STEP_MIN_S`] is always one; a step forward only when the reports' `time` increments
/// around it (the DVL's own count of milliseconds between reports) say that far less time went by:
/// without them a jump forward cannot be told from a pause of the DVL.
fn clock_steps(stamped: &[(usize, f64, f64, Option<f64>)]) -> Vec<ClockStep> {
    let mut out = Vec::new();
    for k in 1..stamped.len() {
        let (line0, t0, _, _) = stamped[k - 1];
        let (line, t, abs, _) = stamped[k];
        let step = t - t0;
        let kind = if step < -CLOCK_STEP_MIN_S {
            Some(if abs < RESTART_BEFORE_UNIX_S {
                ClockStepKind::Restart
            } else {
                ClockStepKind::Back
            })
        } else if step > CLOCK_STEP_MIN_S {
            // The `time` of a report and of its neighbours (the field's alignment to the ping
            // interval differs between firmware versions).
            let lo = k.saturating_sub(1);
            let hi = (k + 1).min(stamped.len() - 1);
            let increments: Vec<f64> = stamped[lo..=hi].iter().filter_map(|s| s.3).collect();
            (increments.len() == hi - lo + 1)
                .then(|| increments.iter().copied().fold(0.0, f64::max) / 1000.0)
                .filter(|&elapsed| step > elapsed + CLOCK_STEP_MIN_S)
                .map(|_| ClockStepKind::Forward)
        } else {
            None
        };
        if let Some(kind) = kind {
            out.push(ClockStep {
                line,
                previous_line: line0,
                step_s: step,
                kind,
            });
        }
    }
    out
}

/// [`DvlLogStats::time_source_used`] of a time line rebuilt from `time` increments.
const REBUILT_TIMES: &str = "rebuilt from `time` increments (no absolute time in this format)";

/// The raw time of every kept report (`None`: the report lacks the chosen stamp and is dropped).
fn choose_times(
    path: &Path,
    source: DvlTimeSource,
    reports: &[(usize, VelocityReport)],
    stats: &mut DvlLogStats,
) -> Result<Vec<Option<RawTime>>> {
    let pick = |r: &VelocityReport| match source {
        DvlTimeSource::Validity => r.time_of_validity_us.map(RawTime::from_micros),
        DvlTimeSource::Transmission => r.time_of_transmission_us.map(RawTime::from_micros),
        DvlTimeSource::Host => r.host_time,
    };
    let have = reports.iter().filter(|(_, r)| pick(r).is_some()).count();
    if have > 0 {
        stats.time_source_used = match source {
            DvlTimeSource::Validity => "time_of_validity (DVL clock, mid-ping)".to_string(),
            DvlTimeSource::Transmission => "time_of_transmission (DVL clock)".to_string(),
            DvlTimeSource::Host => reports
                .iter()
                .find_map(|(_, r)| r.host_time_kind)
                .unwrap_or("host receive time")
                .to_string(),
        };
        if have < reports.len() {
            let missing = reports.len() - have;
            stats.warnings.push(format!(
                "{missing} velocity reports have no {} and were dropped",
                stats.time_source_used
            ));
        }
        return Ok(reports.iter().map(|(_, r)| pick(r)).collect());
    }
    // A topic without DVL-clock stamps (the driver's `/dvl/data`) still has the host's.
    if reports.iter().any(|(_, r)| r.host_time.is_some()) {
        let kind = reports
            .iter()
            .find_map(|(_, r)| r.host_time_kind)
            .unwrap_or("host receive time");
        stats.warnings.push(format!(
            "these reports carry no {}; using the {kind} instead",
            match source {
                DvlTimeSource::Transmission => "time_of_transmission",
                _ => "time_of_validity",
            }
        ));
        stats.time_source_used = kind.to_string();
        return Ok(reports.iter().map(|(_, r)| r.host_time).collect());
    }
    if source == DvlTimeSource::Host {
        return Err(Error::Input(format!(
            "{}: no host receive times in this log (they come from ROS bags and from \
             `dvlcal record-dvl`); use --dvl-time validity",
            path.display()
        )));
    }
    // No absolute time at all (json_v1/json_v2, wrx): rebuild a time line from the `time`
    // increments (milliseconds since the previous report), starting at the epoch.
    let mut t_ms = 0.0f64;
    let mut out = Vec::with_capacity(reports.len());
    let mut missing = 0usize;
    let mut beyond = 0usize;
    for (i, (_, r)) in reports.iter().enumerate() {
        match r.time_ms {
            Some(dt) if dt >= 0.0 => {
                let next = if i > 0 { t_ms + dt } else { t_ms };
                // Increments adding up past i64 milliseconds (or to infinity) are no time line:
                // the whole milliseconds would saturate, or the fraction become NaN.
                if !next.is_finite() || next >= MAX_REBUILT_MS {
                    beyond += 1;
                    out.push(None);
                    continue;
                }
                t_ms = next;
                let ms = t_ms.floor();
                let us = (t_ms - ms) * 1e3;
                // Whole milliseconds kept exactly in the integer part.
                let total_ms = ms as i64;
                let t = RawTime {
                    sec: total_ms.div_euclid(1000),
                    frac: (total_ms.rem_euclid(1000) as f64 + us * 1e-3) * 1e-3,
                };
                out.push(Some(t));
            }
            _ => {
                missing += 1;
                out.push(None);
            }
        }
    }
    if missing == reports.len() {
        return Err(Error::Input(format!(
            "{}: velocity reports carry neither an absolute time nor `time` increments",
            path.display()
        )));
    }
    if missing + beyond == reports.len() {
        return Err(Error::Input(format!(
            "{}: velocity reports carry no absolute time, and their `time` increments add up to \
             more than {MAX_REBUILT_MS:e} ms",
            path.display()
        )));
    }
    stats.time_source_used = REBUILT_TIMES.to_string();
    stats.warnings.push(
        "this log has no absolute time (json_v1/json_v2 or wrx): sample times were rebuilt from \
         the `time` increments starting at 0; the estimated clock offset then absorbs an \
         arbitrary origin and is meaningful only relative to this log"
            .to_string(),
    );
    if missing > 0 {
        stats.warnings.push(format!(
            "{missing} velocity reports without `time` were dropped"
        ));
    }
    if beyond > 0 {
        stats.warnings.push(format!(
            "{beyond} velocity reports whose `time` increments add up to more than \
             {MAX_REBUILT_MS:e} ms were dropped"
        ));
    }
    Ok(out)
}
