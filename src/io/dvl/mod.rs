//! Water Linked A50 logs in every form a user is likely to have, read into [`DvlSample`]s.
//!
//! Accepted inputs (see `docs/formats.md`):
//! - JSON lines (the TCP stream on port 16171 captured with `nc`, JSON forwarded over UDP, or a
//!   `record-dvl` log), json_v1 to json_v3.x, LF or CRLF line ends;
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
pub mod bag;
pub mod detect;
pub mod json;
pub mod record;
pub mod report;
pub mod serial;
mod summary;

use std::collections::{BTreeMap, HashMap};
use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use nalgebra::{Matrix3, Vector3};
use serde::Serialize;

use crate::error::{Error, Result};
use crate::time::{Epoch, RawTime};
use crate::types::DvlSample;

pub use detect::detect_format;
pub use record::{RecordOptions, RecordStats, record_tcp};
pub use report::{Parsed, Reject, VelocityReport};

/// The container or encoding of a DVL log.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum DvlFormat {
    /// One JSON object per line (TCP stream, UDP forward, `record-dvl` output).
    JsonLines,
    /// Serial protocol sentences (`wrz`, `wrx`, ...), one per line, CRC-8 checked.
    Serial,
    /// A ROS1 bag (`#ROSBAG V2.0`).
    RosBag,
}

impl DvlFormat {
    /// The name used on the command line and in summaries.
    pub fn name(self) -> &'static str {
        match self {
            DvlFormat::JsonLines => "json",
            DvlFormat::Serial => "serial",
            DvlFormat::RosBag => "rosbag",
        }
    }
}

impl fmt::Display for DvlFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for DvlFormat {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "json" | "jsonl" | "json-lines" | "tcp" | "udp" => Ok(DvlFormat::JsonLines),
            "serial" | "wrz" => Ok(DvlFormat::Serial),
            "bag" | "rosbag" | "ros1" => Ok(DvlFormat::RosBag),
            _ => Err(format!(
                "unknown DVL log format '{s}' (expected json, serial or rosbag)"
            )),
        }
    }
}

/// Which time stamp of a report becomes the sample time.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum DvlTimeSource {
    /// `time_of_validity`: mid-ping, on the DVL clock (json_v3+, `wrz`, `wrs`). The default.
    #[default]
    Validity,
    /// `time_of_transmission`: when the report left the DVL, on the DVL clock.
    Transmission,
    /// The host's receive time: the bag record time (or the `/dvl/data` header stamp) of a
    /// ROS1 bag, or the `host_time_us` that `record-dvl` adds to each line.
    Host,
}

impl DvlTimeSource {
    /// The name used on the command line and in summaries.
    pub fn name(self) -> &'static str {
        match self {
            DvlTimeSource::Validity => "validity",
            DvlTimeSource::Transmission => "transmission",
            DvlTimeSource::Host => "host",
        }
    }
}

impl fmt::Display for DvlTimeSource {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for DvlTimeSource {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "validity" | "time_of_validity" | "tov" => Ok(DvlTimeSource::Validity),
            "transmission" | "time_of_transmission" | "tot" => Ok(DvlTimeSource::Transmission),
            "host" | "receive" | "bag" => Ok(DvlTimeSource::Host),
            _ => Err(format!(
                "unknown DVL time source '{s}' (expected validity, transmission or host)"
            )),
        }
    }
}

/// How to read a DVL log.
#[derive(Clone, Debug, Default)]
pub struct DvlReadOptions {
    /// Force a format; `None` detects it from the content.
    pub format: Option<DvlFormat>,
    /// The time stamp to use for each sample.
    pub time_source: DvlTimeSource,
    /// Stop at the first malformed line with an error naming `file:line`.
    pub strict: bool,
    /// Bag topic to read; `None`: `/dvl/json_data` if present, else the driver's `DVL` topic.
    pub topic: Option<String>,
    /// Epoch of the sample times; `None`: the whole second of the earliest sample.
    pub epoch: Option<Epoch>,
    /// Also hand on the reports the DVL marked invalid (with `valid: false`), for callers that
    /// count them themselves. They are never velocities to fit.
    pub include_invalid: bool,
}

/// How many rejected lines are kept with their reason in [`DvlLogStats::rejected`].
pub const MAX_LISTED: usize = 20;

/// A line (or bag message) that could not be used.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RejectedLine {
    /// 1-based line number (for bags: 1-based message number on the topic read).
    pub line: usize,
    /// Short category (`bad checksum`, `not valid JSON`, ...), the key of
    /// [`DvlLogStats::rejected_by_reason`].
    pub reason: String,
    /// What exactly was wrong.
    pub detail: String,
}

/// A time stamp that does not increase.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TimeProblem {
    /// 1-based line (or message) number of the later report.
    pub line: usize,
    /// Its time minus the previous sample's time, seconds (`<= 0`).
    pub step_s: f64,
}

/// Everything counted while reading a DVL log.
#[derive(Clone, Debug, Default, Serialize)]
pub struct DvlLogStats {
    /// The file read.
    pub path: PathBuf,
    /// The format read (detected or forced).
    pub format: Option<DvlFormat>,
    /// Per-report format labels (`json_v3`, `json_v3.1`, `serial wrz`, `rosbag /dvl/data`, ...)
    /// with the number of reports of each.
    pub formats_seen: BTreeMap<String, usize>,
    /// For bags: the topic read and its message type.
    pub topic: Option<String>,
    /// The time source asked for.
    pub time_source: DvlTimeSource,
    /// What the sample times really are (e.g. `time_of_validity (DVL clock)`, or a time line
    /// rebuilt from `time` increments for logs without absolute times).
    pub time_source_used: String,
    /// Non-empty lines (or bag messages on the topic) examined.
    pub lines: usize,
    /// Every well-formed bottom-track velocity report, invalid ones and duplicates included.
    pub velocity_reports: usize,
    /// Of those, the ones with `velocity_valid` (duplicates included).
    pub valid: usize,
    /// Of those, the ones without (`velocity_valid` false, `n` in serial); never used.
    pub invalid: usize,
    /// Velocity reports that repeat an earlier report exactly; used once.
    pub duplicates: usize,
    /// Water-tracking velocity reports (`velocity_water`, `wrs`); counted, not used.
    pub water_velocity_reports: usize,
    /// Well-formed reports of other types (dead reckoning, transducer reports, replies, ...).
    pub other_reports: usize,
    /// `other_reports` by type.
    pub other_by_type: BTreeMap<String, usize>,
    /// Lines that could not be used.
    pub rejected_lines: usize,
    /// `rejected_lines` by reason.
    pub rejected_by_reason: BTreeMap<String, usize>,
    /// The first [`MAX_LISTED`] rejected lines.
    pub rejected: Vec<RejectedLine>,
    /// Samples (valid, unique, in file order) whose time is earlier than the previous one's.
    pub time_backwards: usize,
    /// Samples whose time equals the previous one's.
    pub time_repeats: usize,
    /// The first [`MAX_LISTED`] of those.
    pub time_problems: Vec<TimeProblem>,
    /// Things a user should know (rebuilt time line, fallback time source, damaged bag, ...).
    pub warnings: Vec<String>,
    /// First and last sample time, seconds relative to the epoch.
    pub first_time_s: Option<f64>,
    pub last_time_s: Option<f64>,
}

impl DvlLogStats {
    /// Mean sample rate of the samples handed on, Hz (`None` with fewer than two samples or a
    /// zero span).
    pub fn rate_hz(&self, n_samples: usize) -> Option<f64> {
        match (self.first_time_s, self.last_time_s) {
            (Some(a), Some(b)) if n_samples >= 2 && b > a => Some((n_samples - 1) as f64 / (b - a)),
            _ => None,
        }
    }

    fn reject(&mut self, path: &Path, strict: bool, line: usize, r: Reject) -> Result<()> {
        if strict {
            return Err(Error::parse(
                path,
                line,
                format!("{}: {}", r.reason, r.detail),
            ));
        }
        self.rejected_lines += 1;
        *self
            .rejected_by_reason
            .entry(r.reason.to_string())
            .or_default() += 1;
        if self.rejected.len() < MAX_LISTED {
            self.rejected.push(RejectedLine {
                line,
                reason: r.reason.to_string(),
                detail: r.detail,
            });
        }
        Ok(())
    }
}

/// A DVL log read into samples.
#[derive(Clone, Debug)]
pub struct DvlLog {
    /// The epoch sample times are relative to.
    pub epoch: Epoch,
    /// Valid, deduplicated samples in time order.
    pub samples: Vec<DvlSample>,
    /// The 1-based source line (bag: message number) of each sample.
    pub lines: Vec<usize>,
    /// Everything counted on the way.
    pub stats: DvlLogStats,
}

/// Reads a DVL log of any accepted format into valid, deduplicated, time-ordered samples.
///
/// Errors: the file cannot be read; its format cannot be recognised; it holds no usable
/// velocity report; the time source asked for is absent; or, in strict mode, the first
/// malformed line (named `file:line`).
pub fn read_dvl_log(path: &Path, opts: &DvlReadOptions) -> Result<DvlLog> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    if detect::is_mcap(&bytes) {
        return Err(Error::Input(format!(
            "{}: ROS2 (MCAP) logs are not read yet; export /dvl/json_data as JSON lines",
            path.display()
        )));
    }
    let format = match opts.format {
        Some(f) => f,
        None => detect_format(&bytes).ok_or_else(|| {
            Error::Input(format!(
                "{}: not a recognised DVL log (JSON lines, serial sentences or ROS1 bag); \
                 use --dvl-format to force one",
                path.display()
            ))
        })?,
    };
    let mut stats = DvlLogStats {
        path: path.to_path_buf(),
        format: Some(format),
        time_source: opts.time_source,
        ..Default::default()
    };
    let mut acc = Accumulator::default();
    match format {
        DvlFormat::JsonLines | DvlFormat::Serial => {
            for (line, content) in text_lines(&bytes) {
                let parsed = if format == DvlFormat::JsonLines {
                    json::parse_line(content)
                } else {
                    serial::parse_line(content)
                };
                acc.push(path, opts.strict, &mut stats, line, parsed)?;
            }
        }
        DvlFormat::RosBag => {
            bag::read_bag(path, opts, &mut stats, &mut |stats, line, parsed| {
                acc.push(path, opts.strict, stats, line, parsed)
            })?;
        }
    }
    acc.finish(path, opts, stats)
}

/// Reads DVL samples from in-memory text (JSON lines or serial sentences), as [`read_dvl_log`]
/// does for a file; `name` stands for the file in messages. Bags need a file.
pub fn read_dvl_text(name: &Path, bytes: &[u8], opts: &DvlReadOptions) -> Result<DvlLog> {
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
    for (line, content) in text_lines(bytes) {
        let parsed = if format == DvlFormat::JsonLines {
            json::parse_line(content)
        } else {
            serial::parse_line(content)
        };
        acc.push(name, opts.strict, &mut stats, line, parsed)?;
    }
    acc.finish(name, opts, stats)
}

/// The non-blank lines of a byte buffer with their 1-based numbers, `\r` line ends removed.
pub fn text_lines(bytes: &[u8]) -> impl Iterator<Item = (usize, &[u8])> {
    bytes
        .split(|&b| b == b'\n')
        .enumerate()
        .filter_map(|(i, l)| {
            let l = l.strip_suffix(b"\r").unwrap_or(l);
            (!l.iter().all(|b| b.is_ascii_whitespace())).then_some((i + 1, l))
        })
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
            Ok(Parsed::Velocity(r)) => {
                stats.velocity_reports += 1;
                bump(&mut stats.formats_seen, &r.label);
                if r.valid {
                    stats.valid += 1;
                } else {
                    stats.invalid += 1;
                }
                let bucket = self.seen.entry(r.key).or_default();
                if bucket.iter().any(|&i| self.reports[i].1.same_report(&r)) {
                    stats.duplicates += 1;
                } else {
                    bucket.push(self.reports.len());
                    self.reports.push((line, r));
                }
            }
            Ok(Parsed::WaterVelocity { label }) => {
                stats.water_velocity_reports += 1;
                bump(&mut stats.formats_seen, &label);
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
            return Err(Error::parse(
                path,
                self.last_line.max(1),
                format!(
                    "no velocity reports in the log ({} lines, {} rejected, {} of other types)",
                    stats.lines,
                    stats.rejected_lines,
                    stats.other_reports + stats.water_velocity_reports
                ),
            ));
        }
        let times = choose_times(path, opts.time_source, &self.reports, &mut stats)?;
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
        // Time order as found in the file.
        for w in 1..samples.len() {
            let step = samples[w].1.t - samples[w - 1].1.t;
            if step <= 0.0 {
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
        samples.sort_by(|a, b| a.1.t.total_cmp(&b.1.t));
        stats.first_time_s = samples.first().map(|s| s.1.t);
        stats.last_time_s = samples.last().map(|s| s.1.t);
        let (lines, samples) = samples.into_iter().unzip();
        Ok(DvlLog {
            epoch,
            samples,
            lines,
            stats,
        })
    }
}

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
    for (i, (_, r)) in reports.iter().enumerate() {
        match r.time_ms {
            Some(dt) if dt >= 0.0 => {
                if i > 0 {
                    t_ms += dt;
                }
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
    stats.time_source_used =
        "rebuilt from `time` increments (no absolute time in this format)".to_string();
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
    Ok(out)
}
