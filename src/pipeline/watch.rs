//! Following a recording while it is written (`dvlcal watch`): each update stages the records
//! complete so far, calibrates them as `calibrate` would, and says how far each parameter is
//! from its target and what motion would bring the weak ones there
//! ([`crate::calib::advice`]).
//!
//! The dataset folder is staged into a private folder on every update: a text file (a pose
//! file, the DVL log, the IMU's CSV) up to its last complete line, so that a line a buffered
//! writer has cut in two is left for the next update, and every other file (images, YAML) as a
//! hard link (a copy where links are not possible). Images are detected once: their detections
//! are kept across updates ([`DetectionCache`]), so an update decodes only the new ones. Files whose names start with `.` or end in
//! `.tmp` or `.part` are skipped: writers that rename their files into place write them under
//! such names first.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::{Instant, SystemTime};

use serde::Serialize;

use super::calibration::calibrate_dataset;
use super::dataset::{Dataset, dataset_files_checked};
use super::exports::state;
use super::vision::VisionOptions;
use crate::calib::CalibOptions;
use crate::calib::advice::{Recording, advise, group_std};
use crate::calib::outcome::Verdict;
use crate::error::{Error, Result};
use crate::io::calib_yaml::Observability;
use crate::io::dataset::DatasetOverrides;
use crate::io::dvl::DvlReadOptions;
use crate::vision::detect::DetectionCache;

/// The extensions of the files staged up to their last complete line.
const LINE_FILES: [&str; 6] = ["txt", "csv", "jsonl", "json", "log", "tum"];

/// How the updates read and calibrate the data.
#[derive(Clone, Debug, Default)]
pub struct WatchOptions {
    /// The calibration's options (its verdict limits are the targets).
    pub calib: CalibOptions,
    /// The image pipeline's options.
    pub vision: VisionOptions,
    /// How the DVL log is read.
    pub read: DvlReadOptions,
    /// Files named on the command line instead of the folder's.
    pub overrides: DatasetOverrides,
    /// Worker threads (`None`: all cores).
    pub threads: Option<usize>,
}

/// One parameter group's state in an update.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ParameterState {
    /// The group's largest standard deviation (deg for the rotation, m, s, unitless), `null`
    /// before the first calibration.
    pub std: Option<f64>,
    /// The target it must meet (the verdict's limit).
    pub target: f64,
    /// `ok`, `weak`, `prior` or `fixed`, as the result file's `observability` says; `null`
    /// before the first calibration.
    pub verdict: Option<Observability>,
}

/// The counts of data an update used.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct WatchCounts {
    /// Camera poses (from the pose file, or solved from the images so far).
    pub poses: usize,
    /// DVL reports read.
    pub dvl_reports: usize,
    /// DVL reports the calibration used.
    pub dvl_used: usize,
    /// DVL reports with no camera pose near them (the board out of view).
    pub dvl_without_pose: usize,
    /// Seconds of camera data.
    pub span_s: f64,
}

/// What one update found: the JSON object `dvlcal watch --json` prints per update.
#[derive(Clone, Debug, Serialize)]
pub struct WatchUpdate {
    /// 1 for the first update.
    pub update: usize,
    /// Whether every parameter meets its target and the calibration passed its checks.
    pub done: bool,
    /// What to do next, most useful first; empty when done.
    pub advice: Vec<String>,
    /// `rotation` (deg), `lever_arm` (m), `time_offset` (s), `velocity_scale`.
    pub parameters: BTreeMap<&'static str, ParameterState>,
    /// The data used.
    pub counts: WatchCounts,
    /// `ok` or `failed` (the calibration's status), or `not yet` when the data so far could not
    /// be calibrated.
    pub status: String,
    /// Why the data so far could not be calibrated, or why the calibration failed.
    pub reason: Option<String>,
    /// Seconds this update took (staging, reading and calibrating).
    pub update_s: f64,
}

/// A folder followed while it is written.
pub struct Watcher {
    source: PathBuf,
    staging: PathBuf,
    last: Option<Vec<(PathBuf, u64, Option<SystemTime>)>>,
    updates: usize,
    /// The images' detections, so that each image is detected once over all updates.
    cache: DetectionCache,
}

fn skipped(name: &str) -> bool {
    name.starts_with('.') || name.ends_with(".tmp") || name.ends_with(".part")
}

/// The files under `dir` (recursively, skipped names left out), in no particular order.
fn files_under(dir: &Path, out: &mut Vec<PathBuf>) -> Result<()> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    for entry in entries {
        let entry = entry.map_err(|e| Error::io(dir, e))?;
        let name = entry.file_name();
        if skipped(&name.to_string_lossy()) {
            continue;
        }
        let path = entry.path();
        if path.is_dir() {
            files_under(&path, out)?;
        } else {
            out.push(path);
        }
    }
    Ok(())
}

impl Watcher {
    /// Follows the dataset folder `source`, staging into a new private folder.
    pub fn new(source: &Path) -> Result<Watcher> {
        if !source.is_dir() {
            return Err(Error::dataset(
                source,
                "dvlcal watch follows a dataset folder while it is written; this is not a folder",
            ));
        }
        let staging = std::env::temp_dir().join(format!(
            "dvlcal-watch-{}-{}",
            std::process::id(),
            SystemTime::now()
                .duration_since(SystemTime::UNIX_EPOCH)
                .map_or(0, |d| d.as_nanos())
        ));
        Ok(Watcher {
            source: source.to_path_buf(),
            staging,
            last: None,
            updates: 0,
            cache: DetectionCache::default(),
        })
    }

    /// Whether the folder's files changed (in number, size or time) since the last call.
    pub fn changed(&mut self) -> Result<bool> {
        let mut files = Vec::new();
        files_under(&self.source, &mut files)?;
        files.sort();
        let sig: Vec<_> = files
            .into_iter()
            .map(|p| {
                let m = std::fs::metadata(&p).ok();
                let len = m.as_ref().map_or(0, |m| m.len());
                let time = m.and_then(|m| m.modified().ok());
                (p, len, time)
            })
            .collect();
        let changed = self.last.as_ref() != Some(&sig);
        self.last = Some(sig);
        Ok(changed)
    }

    /// Copies the records complete so far of the files [`Watcher::changed`] last listed into
    /// the staging folder (emptied first).
    fn stage(&self) -> Result<()> {
        if self.staging.exists() {
            std::fs::remove_dir_all(&self.staging).map_err(|e| Error::io(&self.staging, e))?;
        }
        for (src, _, _) in self.last.iter().flatten() {
            let rel = src.strip_prefix(&self.source).unwrap_or(src);
            let dst = self.staging.join(rel);
            if let Some(dir) = dst.parent() {
                std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
            }
            let by_line = src
                .extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| LINE_FILES.contains(&e.to_ascii_lowercase().as_str()));
            if by_line {
                let bytes = std::fs::read(src).map_err(|e| Error::io(src, e))?;
                let end = bytes.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
                std::fs::write(&dst, &bytes[..end]).map_err(|e| Error::io(&dst, e))?;
            } else if std::fs::hard_link(src, &dst).is_err() {
                std::fs::copy(src, &dst).map_err(|e| Error::io(src, e))?;
            }
        }
        Ok(())
    }

    /// Stages what the folder held at the last [`Watcher::changed`] and calibrates it; a recording too short to calibrate
    /// gives an update with status `not yet` and the reason (never an error: the data may
    /// still come). An error is returned only when the folder cannot be read or staged.
    pub fn update(&mut self, opts: &WatchOptions) -> Result<WatchUpdate> {
        let clock = Instant::now();
        self.updates += 1;
        self.stage()?;
        let limits = &opts.calib.weak;
        let targets = [
            ("rotation", limits.rotation_deg),
            ("lever_arm", limits.lever_arm_m),
            ("time_offset", limits.time_offset_s),
            ("velocity_scale", limits.velocity_scale),
        ];
        let mut u = WatchUpdate {
            update: self.updates,
            done: false,
            advice: Vec::new(),
            parameters: targets
                .iter()
                .map(|&(name, target)| {
                    (
                        name,
                        ParameterState {
                            std: None,
                            target,
                            verdict: None,
                        },
                    )
                })
                .collect(),
            counts: WatchCounts::default(),
            status: "not yet".into(),
            reason: None,
            update_s: 0.0,
        };
        let vision = VisionOptions {
            cache: Some(self.cache.clone()),
            ..opts.vision.clone()
        };
        let data = dataset_files_checked(Some(&self.staging), &opts.overrides)
            .and_then(|files| Dataset::load(files, &vision, &opts.read, &mut |_| {}));
        let data = match data {
            Ok(d) => d,
            Err(e) => return Ok(self.not_yet(u, &e, clock)),
        };
        u.counts.poses = data.poses.len();
        u.counts.dvl_reports = data.log.as_ref().map_or(0, |l| l.samples.len());
        u.counts.span_s = match (data.poses.first(), data.poses.last()) {
            (Some(a), Some(b)) => b.t - a.t,
            _ => 0.0,
        };
        let run = match calibrate_dataset(&data, &opts.calib, opts.threads) {
            Ok(r) => r,
            Err(e) => return Ok(self.not_yet(u, &e, clock)),
        };
        let o = &run.outcome;
        u.counts.dvl_used = o.counts.dvl_used;
        u.counts.dvl_without_pose = o.counts.dvl_in_pose_gaps;
        let groups = group_std(&o.covariance, limits);
        let verdicts: [&Verdict; 4] = [
            &o.verdicts.rotation,
            &o.verdicts.lever_arm,
            &o.verdicts.time_offset,
            &o.verdicts.velocity_scale,
        ];
        for (((name, _), g), v) in targets.iter().zip(groups).zip(verdicts) {
            u.parameters.insert(
                name,
                ParameterState {
                    std: Some(g.std),
                    target: g.target,
                    verdict: Some(state(v)),
                },
            );
        }
        let failed = !o.status.is_ok();
        u.status = if failed { "failed" } else { "ok" }.into();
        if let crate::calib::outcome::Status::Failed(reasons) = &o.status {
            u.reason = Some(reasons.join("; "));
        }
        let all_ok = verdicts.iter().all(|v| v.ok);
        u.done = all_ok && !failed;
        if !u.done {
            let rec = Recording {
                dvl_rate_hz: if u.counts.span_s > 0.0 {
                    o.counts.dvl_used as f64 / u.counts.span_s
                } else {
                    1.0
                },
                dvl_sigma: (o.residual_rms.norm() / 3f64.sqrt()).max(1e-3),
                speed_mps: rms_speed(&data),
            };
            u.advice = advise(&o.params, &o.covariance, limits, &rec)
                .iter()
                .map(|a| a.sentence())
                .collect();
            if failed && u.advice.is_empty() {
                u.advice.push(format!(
                    "keep recording: the calibration fails its checks ({})",
                    u.reason.as_deref().unwrap_or_default()
                ));
            }
        }
        let dvl = o.counts.dvl_samples.max(1) as f64;
        let blind = o.counts.dvl_in_pose_gaps as f64 / dvl;
        if blind > 0.2 {
            u.advice.push(format!(
                "the camera had no pose for {:.0} % of the DVL's reports (the board out of \
                 view): stay nearer the board",
                100.0 * blind
            ));
        }
        u.update_s = clock.elapsed().as_secs_f64();
        Ok(u)
    }

    /// `u` for data that cannot be calibrated yet: the reason `e` (in the source folder's
    /// paths) and the advice to keep recording.
    fn not_yet(&self, mut u: WatchUpdate, e: &Error, clock: Instant) -> WatchUpdate {
        let reason = self.in_source_words(&e.to_string());
        u.advice.push(format!(
            "keep recording: the data so far cannot be calibrated ({reason})"
        ));
        u.reason = Some(reason);
        u.update_s = clock.elapsed().as_secs_f64();
        u
    }

    /// `text` with the staging folder's paths written as the source folder's.
    fn in_source_words(&self, text: &str) -> String {
        text.replace(
            &self.staging.display().to_string(),
            &self.source.display().to_string(),
        )
    }
}

impl Drop for Watcher {
    fn drop(&mut self) {
        // The staging folder is this run's own; leaving it behind would only waste space.
        let _ = std::fs::remove_dir_all(&self.staging);
    }
}

/// The camera's RMS speed over the poses (m/s), from their differences.
fn rms_speed(data: &Dataset) -> f64 {
    let v: Vec<f64> = data
        .poses
        .windows(2)
        .filter(|w| w[1].t > w[0].t)
        .map(|w| (w[1].pose.trans - w[0].pose.trans).norm() / (w[1].t - w[0].t))
        .collect();
    if v.is_empty() {
        return 0.0;
    }
    (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
}

impl WatchUpdate {
    /// The update as a compact text view for a terminal: the data, a bar per parameter towards
    /// its target, then the advice.
    pub fn text(&self) -> String {
        use std::fmt::Write as _;
        let mut s = String::new();
        let c = &self.counts;
        let _ = writeln!(
            s,
            "update {}: {} poses over {:.0} s, {} of {} DVL reports used ({:.1} s){}",
            self.update,
            c.poses,
            c.span_s,
            c.dvl_used,
            c.dvl_reports,
            self.update_s,
            if self.done { ": DONE" } else { "" }
        );
        for (name, p) in &self.parameters {
            let (scale, unit) = match *name {
                "rotation" => (1.0, "deg"),
                "lever_arm" => (1e3, "mm"),
                "time_offset" => (1e3, "ms"),
                _ => (1.0, ""),
            };
            // Full bar at the target; empty at 10 times it or worse (log scale between).
            let filled = p.std.map_or(0, |sd| {
                let r = (sd / p.target).max(1.0).log10();
                ((1.0 - r.min(1.0)) * 20.0).round() as usize
            });
            let std = p
                .std
                .map_or("-".to_owned(), |sd| format!("{:.3}", sd * scale));
            let _ = writeln!(
                s,
                "  {name:<15} [{}{}] {std} {unit} (target {:.3}) {}",
                "#".repeat(filled),
                ".".repeat(20 - filled),
                p.target * scale,
                p.verdict.map_or("-", Observability::words)
            );
        }
        for a in &self.advice {
            let _ = writeln!(s, "  -> {a}");
        }
        s
    }
}
