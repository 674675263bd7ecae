//! Logs captured by polling: a program that reads the latest velocity report in a loop (a
//! driver's last value, a web page refreshed) writes each report again at every read until a
//! new one arrives, and misses the reports that come and go between two reads. Such a log is
//! recognised by its runs of one report repeated line after line; the DVL's own stream never
//! repeats a report.
//!
//! Where the reports carry the DVL's time (`time_of_validity`), the repeats are dropped like any
//! duplicate and the rest keep their times, only sparser. Where they do not (json_v1/json_v2,
//! `wrx`), the time line is rebuilt from each report's `time` increment, which counts from the
//! report just before it in the DVL's stream, most often one the poll missed: that time line
//! is squeezed, and matches no camera clock.

use serde::Serialize;

use super::report::VelocityReport;

/// Fewest repeats that make a polled capture (a few duplicates come from forwarding).
pub const POLLED_MIN_REPEATS: usize = 10;

/// What marks a log as captured by polling, and what it cost.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PolledCapture {
    /// Velocity reports read (lines), repeats included.
    pub reports: usize,
    /// Reports that repeat the report just before them.
    pub repeats: usize,
    /// Runs of one report: the distinct reports in the order they came.
    pub distinct: usize,
    /// The longest run, in lines.
    pub longest_run: usize,
    /// The `time` increments of the distinct reports after the first, summed: the time line
    /// rebuilt from them spans this long, seconds (`None` without increments).
    pub increments_s: Option<f64>,
    /// If the reads came at a steady rate, the capture lasted at least this long, seconds:
    /// each report was current at least as long as its successor's increment says, so no read
    /// rate is faster than (run + 1) / increment of any run (`None` without increments).
    pub min_capture_s: Option<f64>,
    /// Whether the sample times were rebuilt from the `time` increments (no DVL time).
    pub times_rebuilt: bool,
}

impl PolledCapture {
    /// The capture of `runs` (index into `reports` and length of each run of one report, in
    /// file order), if it was taken by polling: more than half of its velocity reports repeat
    /// the one just before (a stream forwarded twice repeats exactly half) and at least
    /// [`POLLED_MIN_REPEATS`] do.
    pub fn find(
        runs: &[(usize, usize)],
        reports: &[(usize, VelocityReport)],
        times_rebuilt: bool,
    ) -> Option<PolledCapture> {
        let total: usize = runs.iter().map(|r| r.1).sum();
        let repeats = total - runs.len();
        if repeats < POLLED_MIN_REPEATS || 2 * repeats <= total {
            return None;
        }
        let increment = |k: usize| {
            runs.get(k)
                .and_then(|r| reports.get(r.0))
                .and_then(|r| r.1.time_ms)
                .filter(|t| t.is_finite() && *t > 0.0)
                .map(|t| t * 1e-3)
        };
        let increments: Option<Vec<f64>> = (1..runs.len()).map(increment).collect();
        let (increments_s, min_capture_s) = match increments {
            Some(dt) if !dt.is_empty() => {
                let max_rate = runs
                    .iter()
                    .zip(&dt)
                    .map(|(r, dt)| (r.1 + 1) as f64 / dt)
                    .fold(f64::INFINITY, f64::min);
                (
                    Some(dt.iter().sum()),
                    Some(total.saturating_sub(1) as f64 / max_rate),
                )
            }
            _ => (None, None),
        };
        Some(PolledCapture {
            reports: total,
            repeats,
            distinct: runs.len(),
            longest_run: runs.iter().map(|r| r.1).max().unwrap_or(0),
            increments_s,
            min_capture_s,
            times_rebuilt,
        })
    }

    /// The rebuilt time line is squeezed at least this many times (`None` when the times are
    /// the DVL's own, or without increments).
    pub fn min_squeeze(&self) -> Option<f64> {
        match (self.times_rebuilt, self.increments_s, self.min_capture_s) {
            (true, Some(span), Some(capture)) if span > 0.0 => Some(capture / span),
            _ => None,
        }
    }

    /// Whether the log cannot be calibrated as it is: its times are rebuilt from increments
    /// that skip the reports the polling missed.
    pub fn unusable(&self) -> bool {
        self.times_rebuilt
    }

    /// What the log is, what that costs and what to record instead, for a warning.
    pub fn explain(&self) -> String {
        let mut s = format!(
            "a polled capture, not the DVL's stream: {} of {} velocity reports repeat the one \
             just before ({} distinct reports, each written up to {} times in a row), as when a \
             program reads the latest report in a loop; the DVL sends each report once, and the \
             reports that came between two reads are missing",
            self.repeats, self.reports, self.distinct, self.longest_run
        );
        if self.times_rebuilt {
            match (self.increments_s, self.min_capture_s, self.min_squeeze()) {
                (Some(span), Some(capture), Some(squeeze)) => s.push_str(&format!(
                    ". The reports carry no DVL time, and their `time` increments (each counted \
                     from the report just before it in the DVL's stream, mostly one the reads \
                     missed) add up to {span:.2} s, while a capture read at a steady rate with \
                     these repeats lasted at least {capture:.1} s: the time line rebuilt from \
                     the increments is squeezed at least {squeeze:.1}x"
                )),
                _ => s.push_str(
                    ". The reports carry no DVL time, and their `time` increments count from \
                     reports the reads missed: the time line rebuilt from them is squeezed",
                ),
            }
            s.push_str(
                ". It cannot be calibrated as it is: its times match no camera clock. Record \
                 the DVL's TCP stream itself instead (`dvlcal record-dvl --tcp HOST:16171`, or \
                 `nc HOST 16171 > dvl.jsonl`), with reports that carry time_of_validity \
                 (json_v3 or later)",
            );
        } else {
            s.push_str(
                ". The repeats were dropped as duplicates and the distinct reports keep their \
                 own times, but they are sparse: record the DVL's TCP stream itself \
                 (`dvlcal record-dvl --tcp HOST:16171`) for every report",
            );
        }
        s
    }
}
