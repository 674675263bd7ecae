//! What a DVL log is read into: the formats, the read options, the samples with their source
//! lines, and the counts gathered on the way.

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;

use serde::Serialize;

use super::polled::PolledCapture;
use super::report::Reject;
use crate::error::{Error, Result};
use crate::time::Epoch;
use crate::types::DvlSample;

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

/// How a DVL clock jumped between two consecutive reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum ClockStepKind {
    /// The time went back (an NTP correction, a clock set by hand).
    Back,
    /// The time went forward by more than the reports' own `time` increments allow.
    Forward,
    /// The time restarted near the Unix epoch (the DVL rebooted without a time source).
    Restart,
}

impl ClockStepKind {
    /// Words for messages.
    pub fn words(self) -> &'static str {
        match self {
            ClockStepKind::Back => "steps back",
            ClockStepKind::Forward => "steps forward",
            ClockStepKind::Restart => "restarts (a reboot)",
        }
    }
}

/// A discontinuity of the DVL clock: where one clock segment ends and the next begins.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ClockStep {
    /// 1-based line (bag: message number) of the first report after the step.
    pub line: usize,
    /// The line of the report before it.
    pub previous_line: usize,
    /// The time of the report after the step minus the one before, seconds.
    pub step_s: f64,
    /// What kind of jump it is.
    pub kind: ClockStepKind,
}

/// A stretch of a DVL log whose clock runs without a step.
#[derive(Clone, Debug, PartialEq)]
pub struct ClockSegment {
    /// Its samples in [`DvlLog::samples`] (time-ordered within the segment).
    pub samples: std::ops::Range<usize>,
    /// The first and last source line of its reports (file order).
    pub lines: (usize, usize),
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
    /// For bags: the name of the topic read, whose messages the line numbers count.
    pub bag_topic: Option<String>,
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
    /// The speed of sound the DVL assumed, m/s, from the last configuration reply in the log
    /// (JSON `get_config`, serial `wrc`) or given by the user.
    pub sound_speed_mps: Option<f64>,
    /// Where `sound_speed_mps` came from (`file:line` of the reply, or the option).
    pub sound_speed_source: Option<String>,
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
    /// Steps and restarts of the DVL clock, in file order (each starts a new clock segment).
    pub clock_steps: Vec<ClockStep>,
    /// Set when the log was captured by polling the latest report rather than recorded from
    /// the DVL's stream ([`PolledCapture`]).
    pub polled: Option<PolledCapture>,
    /// Things a user should know (rebuilt time line, fallback time source, damaged bag, ...).
    pub warnings: Vec<String>,
    /// First and last sample time, seconds relative to the epoch.
    pub first_time_s: Option<f64>,
    /// Last sample time, s relative to the epoch.
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

    /// What a line number counts: `line` in a text log, `message` (of the topic read) in a
    /// bag.
    pub fn unit(&self) -> &'static str {
        if self.bag_topic.is_some() {
            "message"
        } else {
            "line"
        }
    }

    /// Where line `n` is, for messages: `file:n` in a text log, `file: message n of /topic`
    /// in a bag.
    pub fn at(&self, n: usize) -> String {
        match &self.bag_topic {
            Some(t) => format!("{}: message {n} of {t}", self.path.display()),
            None => format!("{}:{n}", self.path.display()),
        }
    }

    /// Where lines `a` to `b` are: `file:a..b`, or `file: messages a..b of /topic`.
    pub fn at_range(&self, a: usize, b: usize) -> String {
        match &self.bag_topic {
            Some(t) => format!("{}: messages {a}..{b} of {t}", self.path.display()),
            None => format!("{}:{a}..{b}", self.path.display()),
        }
    }

    /// An error at line (bag: message) `n`, named as [`DvlLogStats::at`] does.
    pub(super) fn error_at(&self, n: usize, msg: String) -> Error {
        match self.bag_topic {
            Some(_) => Error::Input(format!("{}: {msg}", self.at(n))),
            None => Error::parse(&self.path, n, msg),
        }
    }

    pub(super) fn reject(
        &mut self,
        path: &Path,
        strict: bool,
        line: usize,
        r: Reject,
    ) -> Result<()> {
        if strict {
            return Err(match self.bag_topic {
                Some(_) => self.error_at(line, format!("{}: {}", r.reason, r.detail)),
                None => Error::parse(path, line, format!("{}: {}", r.reason, r.detail)),
            });
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
    /// The clock segments, in file order: one unless the clock stepped ([`ClockStep`]). The
    /// samples are time-ordered within each segment, the segments follow one another.
    pub clock_segments: Vec<ClockSegment>,
    /// Everything counted on the way.
    pub stats: DvlLogStats,
}

/// The shortest stretch without a valid report that counts as a gap, whatever the rate.
pub const GAP_MIN_S: f64 = 0.5;
/// A gap is also at least this many typical report intervals (three or more reports missing).
pub const GAP_MIN_INTERVALS: f64 = 4.0;

/// A stretch of a DVL log without a valid velocity report.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DvlGap {
    /// Time of the last valid report before the gap, seconds relative to the log's epoch.
    pub start_s: f64,
    /// Time of the first valid report after it.
    pub end_s: f64,
    /// Source lines (bag: message numbers) of those two reports.
    pub lines: (usize, usize),
}

impl DvlLog {
    /// The shortest stretch without a valid report that counts as a gap in this log:
    /// [`GAP_MIN_INTERVALS`] median report intervals, and at least [`GAP_MIN_S`].
    pub fn gap_threshold_s(&self) -> f64 {
        let mut dt: Vec<f64> = self.samples.windows(2).map(|s| s[1].t - s[0].t).collect();
        dt.sort_by(f64::total_cmp);
        let median = dt.get(dt.len() / 2).copied().unwrap_or(0.0);
        (GAP_MIN_INTERVALS * median).max(GAP_MIN_S)
    }

    /// The stretches of at least `min_s` seconds between consecutive valid reports, in time
    /// order (invalid reports inside them do not end them).
    pub fn gaps(&self, min_s: f64) -> Vec<DvlGap> {
        self.samples
            .windows(2)
            .zip(self.lines.windows(2))
            .filter(|(s, _)| s[1].t - s[0].t >= min_s)
            .map(|(s, l)| DvlGap {
                start_s: s[0].t,
                end_s: s[1].t,
                lines: (l[0], l[1]),
            })
            .collect()
    }
}

/// Whether a text's lines end with CR alone (classic Mac OS): it holds a CR and no LF.
pub fn cr_only(bytes: &[u8]) -> bool {
    !bytes.contains(&b'\n') && bytes.contains(&b'\r')
}

/// The non-blank lines of a byte buffer with their 1-based numbers, `\r` line ends removed.
/// Lines end with LF or CRLF, or with CR alone in a text without any LF ([`cr_only`]).
pub fn text_lines(bytes: &[u8]) -> impl Iterator<Item = (usize, &[u8])> {
    let end = if cr_only(bytes) { b'\r' } else { b'\n' };
    bytes
        .split(move |&b| b == end)
        .enumerate()
        .filter_map(|(i, l)| {
            let l = l.strip_suffix(b"\r").unwrap_or(l);
            (!l.iter().all(|b| b.is_ascii_whitespace())).then_some((i + 1, l))
        })
}
