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
//!
//! Images without a camchain are calibrated by an update once they can be, and that camera model
//! is reused by the later updates until the images have grown enough to calibrate them again
//! ([`super::watch_cameras`]).
//!
//! A bag (`NAME.bag.active`, a bare `.mcap`, a ROS 2 bag folder being recorded) is not staged
//! but read in place, to the length it had when the update began ([`super::watch_bag`]).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant, SystemTime};

use serde::Serialize;

use nalgebra::Vector3;

use super::calibration::calibrate_dataset;
use super::cameras::CameraCalRun;
use super::dataset::{Dataset, dataset_files_checked};
use super::exports::state;
use super::vision::VisionOptions;
use super::watch_bag::{FollowedBag, Signature, signature};
use super::watch_cameras::WatchCameras;
pub use super::watch_cameras::{
    CameraModel, CameraModelSource, GROWTH, GROWTH_WEAK, MIN_NEW_FRAMES,
};
use crate::calib::advice::{Recording, advise, group_std};
use crate::calib::fusion::{StretchEstimate, fuse};
use crate::calib::outcome::{CalibrationOutcome, Status};
use crate::calib::segments::calibrate_segments;
use crate::calib::update::ParamMat;
use crate::calib::{CalibOptions, WarmStartUse};
use crate::error::{Error, Result};
use crate::io::calib_yaml::Observability;
use crate::io::dataset::DatasetOverrides;
use crate::io::dvl::DvlReadOptions;
use crate::types::CalibrationParams;
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
    /// The length of the stretches a long recording is calibrated in, seconds (`None`:
    /// [`STRETCH_S`]).
    pub stretch_s: Option<f64>,
}

/// The default length of a stretch, seconds: an update calibrates the last one or two
/// stretches, whatever the recording's length, and adds the earlier ones' results.
pub const STRETCH_S: f64 = 60.0;

/// Seconds of camera data past a stretch's end before the stretch is closed (its DVL reports
/// may follow the poses by a clock offset and the writer's buffering).
const CLOSE_AFTER_S: f64 = 2.0;

/// Seconds of DVL reports taken beyond each end of a stretch (the calibration keeps those that
/// fall inside the camera's span).
const REPORTS_BEYOND_S: f64 = 1.0;

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
    /// Stretches of the recording whose calibrations were combined (1: the recording was
    /// calibrated whole).
    pub stretches: usize,
    /// Stretches left out because their calibration failed or could not be made.
    pub stretches_failed: usize,
    /// Seconds of camera data this update calibrated (the rest had been calibrated by earlier
    /// updates).
    pub solved_s: f64,
    /// Camera calibrations the updates have made so far, this one's included (images without
    /// a camchain: [`WatchUpdate::cameras`] says whether this update made one; 0 otherwise).
    pub camera_calibrations: usize,
}

/// The estimate so far, in the result file's keys.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct WatchEstimate {
    /// The rotation of `T_cam_dvl`, `[x, y, z, w]`.
    pub quaternion_cam_dvl_xyzw: [f64; 4],
    /// The DVL origin in camera coordinates, metres.
    pub lever_arm_cam_m: [f64; 3],
    /// `t_cam = t_dvl + time_offset_s`.
    pub time_offset_s: f64,
    /// The DVL's velocity scale.
    pub velocity_scale: f64,
}

impl WatchEstimate {
    fn of(p: &CalibrationParams) -> WatchEstimate {
        let t = &p.t_cam_dvl;
        WatchEstimate {
            quaternion_cam_dvl_xyzw: t.quaternion_xyzw(),
            lever_arm_cam_m: [t.trans.x, t.trans.y, t.trans.z],
            time_offset_s: p.time_offset_s,
            velocity_scale: p.velocity_scale,
        }
    }
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
    /// The estimate so far (`null` before the first calibration).
    pub estimate: Option<WatchEstimate>,
    /// `rotation` (deg), `lever_arm` (m), `time_offset` (s), `velocity_scale`.
    pub parameters: BTreeMap<&'static str, ParameterState>,
    /// The data used.
    pub counts: WatchCounts,
    /// `ok` or `failed` (the calibration's status), or `not yet` when the data so far could not
    /// be calibrated.
    pub status: String,
    /// Why the data so far could not be calibrated, or why the calibration failed.
    pub reason: Option<String>,
    /// Whether the latest data's calibration started from the last update's solution (its clock
    /// offset searched near the last one's), rather than from the data alone: the last update
    /// passed its checks, and its solution fitted the new data better than the closed form.
    pub started_from_last: bool,
    /// Seconds this update took (staging, reading and calibrating).
    pub update_s: f64,
    /// The camera model the poses were solved with, when the images have no camchain: calibrated
    /// by this update or reused from an earlier one (`null` with a camchain or a pose file, and
    /// before the data could be read).
    pub cameras: Option<CameraModel>,
}

/// A folder, or a bag, followed while it is written.
pub struct Watcher {
    source: PathBuf,
    /// The bag followed, when the source is one (nothing is staged then).
    bag: Option<FollowedBag>,
    staging: PathBuf,
    last: Option<Signature>,
    /// The size and time each staged file had when it was staged.
    staged: BTreeMap<PathBuf, (u64, Option<SystemTime>)>,
    updates: usize,
    /// The closed stretches' calibrations, by index (each solved once).
    closed: BTreeMap<usize, StretchRun>,
    /// The clock offset of the last update, to pick a stretch's DVL reports by.
    offset_guess: f64,
    /// The last update's solution when it passed its checks: the next update's calibrations
    /// start from it ([`CalibOptions::warm_start`]).
    last_solution: Option<CalibrationParams>,
    /// The images' detections, so that each image is detected once over all updates.
    cache: DetectionCache,
    /// The camera calibration of images without a camchain, kept across updates.
    cameras: WatchCameras,
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
    /// Follows the dataset folder `source`, staging into a new private folder; or the bag
    /// `source` (a bag file, there or still to come by its name, or a ROS 2 bag folder or
    /// recording folder: [`FollowedBag`]), read in place.
    pub fn new(source: &Path) -> Result<Watcher> {
        let bag = FollowedBag::of(source);
        if bag.is_none() && !source.is_dir() {
            return Err(Error::dataset(
                source,
                "dvlcal watch follows a dataset folder or a bag (.bag, .bag.active, .mcap, \
                 .db3, a ROS 2 bag folder) while it is written; this is neither",
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
            bag,
            staging,
            last: None,
            staged: BTreeMap::new(),
            updates: 0,
            closed: BTreeMap::new(),
            offset_guess: 0.0,
            last_solution: None,
            cache: DetectionCache::default(),
            cameras: WatchCameras::default(),
        })
    }

    /// Whether the folder's files (or the bag's) changed (in number, size or time) since the
    /// last call.
    pub fn changed(&mut self) -> Result<bool> {
        if let Some(bag) = &mut self.bag {
            return Ok(bag.changed(&mut self.cache));
        }
        let mut files = Vec::new();
        files_under(&self.source, &mut files)?;
        files.sort();
        let sig = signature(files);
        let changed = self.last.as_ref() != Some(&sig);
        self.last = Some(sig);
        Ok(changed)
    }

    /// Brings the staging folder up to the files [`Watcher::changed`] last listed: a file new
    /// or changed since it was staged is staged again (a text file up to its last complete
    /// line, any other as a hard link), a file gone from the folder is removed.
    fn stage(&mut self) -> Result<()> {
        let listed: BTreeMap<&PathBuf, (u64, Option<SystemTime>)> = self
            .last
            .iter()
            .flatten()
            .map(|(p, len, time)| (p, (*len, *time)))
            .collect();
        let gone: Vec<PathBuf> = self
            .staged
            .keys()
            .filter(|p| !listed.contains_key(p))
            .cloned()
            .collect();
        for src in gone {
            self.staged.remove(&src);
            let dst = self.staging_path(&src);
            std::fs::remove_file(&dst).map_err(|e| Error::io(&dst, e))?;
        }
        for (src, sig) in listed {
            if self.staged.get(src) == Some(&sig) {
                continue;
            }
            let dst = self.staging_path(src);
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
            } else {
                if dst.exists() {
                    // Replaced under its name: its detections are those of the old image.
                    self.cache.forget(&dst);
                    std::fs::remove_file(&dst).map_err(|e| Error::io(&dst, e))?;
                }
                if std::fs::hard_link(src, &dst).is_err() {
                    std::fs::copy(src, &dst).map_err(|e| Error::io(src, e))?;
                }
            }
            self.staged.insert(src.clone(), sig);
        }
        Ok(())
    }

    /// The detections of the images seen so far, keyed by their files in the followed folder:
    /// for a calibration of the folder itself, which then detects only the images the updates
    /// have not seen.
    pub fn detections(&self) -> DetectionCache {
        if self.bag.is_some() {
            // Keyed by the bag as it is read now: the bag the final calibration reads.
            return self.cache.clone();
        }
        self.cache.rebased(&self.staging, &self.source)
    }

    /// The bag the final calibration is to read instead of the path followed, with the words
    /// that say why (`NAME.bag.active` renamed `NAME.bag`, a recording folder's storage file
    /// read alone); `None` when it reads the path followed.
    pub fn final_dataset(&self) -> Option<(PathBuf, String)> {
        self.bag.as_ref()?.final_dataset()
    }

    /// What the final calibration takes, once the watch is over: the bag to read instead of
    /// the path followed ([`Watcher::final_dataset`]), the detections of the images seen
    /// ([`Watcher::detections`]), and what to tell the user of them.
    pub fn finish(&self) -> (Option<PathBuf>, DetectionCache, Vec<String>) {
        let (bag, mut notes): (Option<PathBuf>, Vec<String>) = match self.final_dataset() {
            Some((bag, why)) => (Some(bag), vec![why]),
            None => (None, Vec::new()),
        };
        let seen = self.detections();
        if !seen.is_empty() {
            notes.push(format!(
                "the final calibration reuses the tags of {} images",
                seen.len()
            ));
        }
        (bag, seen, notes)
    }

    /// Why the followed recording is over, once it is seen to be (a bag renamed at its end,
    /// a ROS 2 bag's `metadata.yaml` written).
    pub fn ended(&self) -> Option<&str> {
        self.bag.as_ref()?.ended()
    }

    /// Where the folder's file `src` is staged.
    fn staging_path(&self, src: &Path) -> PathBuf {
        self.staging
            .join(src.strip_prefix(&self.source).unwrap_or(src))
    }

    /// Stages what the folder held at the last [`Watcher::changed`] and calibrates it; a recording too short to calibrate
    /// gives an update with status `not yet` and the reason (never an error: the data may
    /// still come). An error is returned only when the folder cannot be read or staged.
    pub fn update(&mut self, opts: &WatchOptions) -> Result<WatchUpdate> {
        let clock = Instant::now();
        self.updates += 1;
        if self.bag.is_none() {
            self.stage()?;
        }
        let mut u = self.blank_update(opts);
        let limits = &opts.calib.weak;
        let targets = targets(limits);
        let (data, recalibration_failed) = self.load_data(opts);
        let data = match data {
            Ok(d) => d,
            Err(e) => return Ok(self.not_yet(u, &e, clock)),
        };
        u.cameras = self
            .cameras
            .record(&data, self.updates, recalibration_failed);
        u.counts.camera_calibrations = self.cameras.calibrations();
        u.counts.poses = data.poses.len();
        u.counts.dvl_reports = data.log.as_ref().map_or(0, |l| l.samples.len());
        u.counts.span_s = match (data.poses.first(), data.poses.last()) {
            (Some(a), Some(b)) => b.t - a.t,
            _ => 0.0,
        };
        let solved = match self.stretch_plan(&data, opts) {
            Some(stretches) => self.solve_stretches(&data, opts, &stretches),
            None => {
                calibrate_dataset(&data, &self.calib_options(opts), opts.threads).and_then(|run| {
                    let run = StretchRun::of(Ok(run.outcome));
                    let est = run
                        .estimate
                        .clone()
                        .ok_or_else(|| Error::Input("the calibration gave no estimate".into()))?;
                    Ok(Solved {
                        params: est.params,
                        covariance: est.covariance,
                        run,
                        stretches: 1,
                        stretches_failed: 0,
                        solved_s: u.counts.span_s,
                    })
                })
            }
        };
        let s = match solved {
            Ok(s) => s,
            Err(e) => return Ok(self.not_yet(u, &e, clock)),
        };
        self.offset_guess = s.params.time_offset_s;
        u.started_from_last = s.run.warm == WarmStartUse::Started;
        u.estimate = Some(WatchEstimate::of(&s.params));
        u.counts.dvl_used = s.run.dvl_used;
        u.counts.dvl_without_pose = s.run.dvl_in_pose_gaps;
        u.counts.stretches = s.stretches;
        u.counts.stretches_failed = s.stretches_failed;
        u.counts.solved_s = s.solved_s;
        let groups = group_std(&s.covariance, limits);
        let mut all_ok = true;
        for (((name, _), g), verdict) in targets.iter().zip(groups).zip(s.run.verdicts) {
            all_ok &= matches!(verdict, Observability::Ok | Observability::Fixed);
            u.parameters.insert(
                name,
                ParameterState {
                    std: Some(g.std),
                    target: g.target,
                    verdict: Some(verdict),
                },
            );
        }
        let failed = s.run.failed.is_some();
        // A solution that failed its checks is not carried on, and neither is the one before it.
        self.last_solution = (!failed).then_some(s.params);
        u.status = if failed { "failed" } else { "ok" }.into();
        u.reason = s.run.failed.clone();
        u.done = all_ok && !failed;
        if !u.done {
            let rec = Recording {
                dvl_rate_hz: if u.counts.span_s > 0.0 {
                    s.run.dvl_used as f64 / u.counts.span_s
                } else {
                    1.0
                },
                dvl_sigma: (s.run.residual_rms.norm() / 3f64.sqrt()).max(1e-3),
                speed_mps: rms_speed(&data),
            };
            u.advice = advise(&s.params, &s.covariance, limits, &rec)
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
        let dvl = s.run.dvl_samples.max(1) as f64;
        let blind = s.run.dvl_in_pose_gaps as f64 / dvl;
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

    /// The data as they are now ([`Watcher::load`]), solved with the camera model kept, if
    /// any, or with one calibrated anew when the images have outgrown it
    /// ([`WatchCameras::outgrown`]); with why that calibration failed, when it did (the data
    /// are then those solved with the model kept).
    fn load_data(&mut self, opts: &WatchOptions) -> (Result<Dataset>, Option<String>) {
        let mut data = self.load(opts, self.cameras.model());
        // A bag renamed while it was read (`NAME.bag.active` at its end): read it again under
        // its new name.
        if data.is_err() && self.bag.as_mut().is_some_and(|b| b.moved(&mut self.cache)) {
            data = self.load(opts, self.cameras.model());
        }
        if !data.as_ref().is_ok_and(|d| self.cameras.outgrown(d)) {
            return (data, None);
        }
        match self.load(opts, None) {
            Ok(fresh) => (Ok(fresh), None),
            Err(e) => (data, Some(self.in_source_words(&e.to_string()))),
        }
    }

    /// The data as they are now: the staging folder, or the bag read in place, its files'
    /// lengths fixed while it is read. Images without a camchain are solved with `cameras`
    /// when it is given, else calibrated first ([`Dataset::load_reusing_cameras`]).
    fn load(&self, opts: &WatchOptions, cameras: Option<&CameraCalRun>) -> Result<Dataset> {
        let (root, fixed) = match &self.bag {
            Some(bag) => {
                let (path, fixed) = bag.snapshot().map_err(Error::Input)?;
                (path, Some(fixed))
            }
            None => (self.staging.clone(), None),
        };
        let vision = VisionOptions {
            cache: Some(self.cache.clone()),
            ..opts.vision.clone()
        };
        let data =
            dataset_files_checked(Some(&root), &opts.overrides).and_then(|files| match cameras {
                Some(c) => Dataset::load_reusing_cameras(files, &vision, &opts.read, c),
                None => Dataset::load(files, &vision, &opts.read, &mut |_| {}),
            });
        drop(fixed);
        data
    }

    /// The update before anything is read: `not yet`, no estimate, the targets of `opts`.
    fn blank_update(&self, opts: &WatchOptions) -> WatchUpdate {
        WatchUpdate {
            update: self.updates,
            done: false,
            advice: Vec::new(),
            estimate: None,
            parameters: targets(&opts.calib.weak)
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
            started_from_last: false,
            update_s: 0.0,
            cameras: None,
        }
    }

    /// `u` for data that cannot be calibrated yet: the reason `e` (in the source folder's
    /// paths) and the advice to keep recording.
    fn not_yet(&self, mut u: WatchUpdate, e: &Error, clock: Instant) -> WatchUpdate {
        let mut reason = self.in_source_words(&e.to_string());
        if let Some(hint) = self.bag.as_ref().and_then(|b| b.hint(&reason)) {
            reason = format!("{reason}: {hint}");
        }
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

/// The parameter groups' names and targets (the verdict limits `limits`), in update order.
fn targets(limits: &crate::calib::options::WeakThresholds) -> [(&'static str, f64); 4] {
    [
        ("rotation", limits.rotation_deg),
        ("lever_arm", limits.lever_arm_m),
        ("time_offset", limits.time_offset_s),
        ("velocity_scale", limits.velocity_scale),
    ]
}

/// When [`Watcher::follow`] updates and when it ends.
#[derive(Clone, Copy, Debug)]
pub struct Pace {
    /// Time between updates (an update that takes longer is followed by the next at once).
    pub interval: Duration,
    /// End when no file has changed for this long after an update.
    pub until_idle: Duration,
    /// End once an update says done.
    pub stop_when_done: bool,
}

impl Watcher {
    /// Follows the folder: every `pace.interval`, when a file changed, an update, given to
    /// `each`; until the folder stays unchanged for `pace.until_idle`, `stop` is set, (with
    /// `pace.stop_when_done`) an update says done, or a followed bag's recording is seen to
    /// end ([`Watcher::ended`]: after one last update of the finished bag).
    pub fn follow(
        &mut self,
        opts: &WatchOptions,
        pace: &Pace,
        stop: &AtomicBool,
        each: &mut dyn FnMut(&WatchUpdate) -> std::result::Result<(), serde_json::Error>,
    ) -> Result<()> {
        let mut last_change = Instant::now();
        while !stop.load(Ordering::SeqCst) {
            let tick = Instant::now();
            if self.changed()? {
                let u = self.update(opts)?;
                // Idle time counts from the end of the update: a long update is not idleness.
                last_change = Instant::now();
                each(&u).map_err(|e| Error::Input(format!("writing an update: {e}")))?;
                if (u.done && pace.stop_when_done) || self.ended().is_some() {
                    break;
                }
            } else if last_change.elapsed() >= pace.until_idle {
                break;
            }
            // Sleep in short steps so that a stop ends the wait at once.
            let until = tick + pace.interval;
            while Instant::now() < until && !stop.load(Ordering::SeqCst) {
                let left = until.saturating_duration_since(Instant::now());
                std::thread::sleep(Duration::from_millis(50).min(left));
            }
        }
        Ok(())
    }
}

/// What an update's calibration gave: the estimate (of the whole recording, or its stretches
/// combined), the verdicts and the counts.
struct Solved {
    params: CalibrationParams,
    covariance: ParamMat,
    /// The verdicts, counts, residuals and failure of the whole (its `estimate` unused).
    run: StretchRun,
    stretches: usize,
    stretches_failed: usize,
    solved_s: f64,
}

/// One stretch's calibration (kept across updates once the stretch is closed).
#[derive(Clone, Debug)]
struct StretchRun {
    /// The estimate, when the calibration gave one (`failed` says whether it can be used).
    estimate: Option<StretchEstimate>,
    verdicts: [Observability; 4],
    dvl_used: usize,
    dvl_samples: usize,
    dvl_in_pose_gaps: usize,
    residual_rms: Vector3<f64>,
    /// Why it failed, when it did.
    failed: Option<String>,
    /// What became of the last update's solution as its start.
    warm: WarmStartUse,
}

/// The verdicts of `o` as the result file states them.
fn states(o: &CalibrationOutcome) -> [Observability; 4] {
    [
        state(&o.verdicts.rotation),
        state(&o.verdicts.lever_arm),
        state(&o.verdicts.time_offset),
        state(&o.verdicts.velocity_scale),
    ]
}

impl StretchRun {
    fn of(run: Result<CalibrationOutcome>) -> StretchRun {
        match run {
            Ok(o) => {
                let failed = match &o.status {
                    Status::Failed(reasons) => Some(reasons.join("; ")),
                    Status::Ok => None,
                };
                StretchRun {
                    estimate: Some(StretchEstimate {
                        params: o.params,
                        covariance: o.covariance,
                        priors: o.priors,
                    }),
                    verdicts: states(&o),
                    dvl_used: o.counts.dvl_used,
                    dvl_samples: o.counts.dvl_samples,
                    dvl_in_pose_gaps: o.counts.dvl_in_pose_gaps,
                    residual_rms: o.residual_rms,
                    failed,
                    warm: o.init.as_ref().map_or(WarmStartUse::None, |i| i.warm),
                }
            }
            Err(e) => StretchRun {
                estimate: None,
                verdicts: [Observability::Weak; 4],
                dvl_used: 0,
                dvl_samples: 0,
                dvl_in_pose_gaps: 0,
                residual_rms: Vector3::zeros(),
                failed: Some(e.to_string()),
                warm: WarmStartUse::None,
            },
        }
    }
}

/// The closed stretches `[start, end]` (seconds on the camera clock) and the open one, when
/// `data` is long enough to be calibrated in stretches (two stretches and the closing margin)
/// and has one clock on each side; `None` when it is to be calibrated whole.
type Stretches = (Vec<(f64, f64)>, (f64, f64));

impl Watcher {
    /// The calibration's options for this update: `opts`' own, started from the last update's
    /// solution when there is one.
    fn calib_options(&self, opts: &WatchOptions) -> CalibOptions {
        CalibOptions {
            warm_start: self.last_solution,
            ..opts.calib.clone()
        }
    }

    fn stretch_plan(&self, data: &Dataset, opts: &WatchOptions) -> Option<Stretches> {
        let len = opts.stretch_s.unwrap_or(STRETCH_S);
        let one_clock = data.camera_segments.len() <= 1
            && data
                .log
                .as_ref()
                .is_some_and(|l| l.clock_segments.len() == 1)
            && !opts.calib.clock_drift;
        let (first, last) = (data.poses.first()?.t, data.poses.last()?.t);
        let n = ((last - first - CLOSE_AFTER_S) / len).floor();
        if !(one_clock && len.is_finite() && len > 0.0 && n >= 2.0) {
            return None;
        }
        let n = n as usize;
        let closed = (0..n - 1)
            .map(|j| (first + j as f64 * len, first + (j + 1) as f64 * len))
            .collect();
        Some((closed, (first + (n - 1) as f64 * len, last)))
    }

    /// Calibrates the stretch `[a, b]` of `data`: its poses, and the DVL reports whose time
    /// on the camera clock (by the last offset found) is within [`REPORTS_BEYOND_S`] of it.
    fn solve_stretch(&self, data: &Dataset, opts: &WatchOptions, (a, b): (f64, f64)) -> StretchRun {
        let run = data.dvl().and_then(|log| {
            let poses: Vec<_> = data
                .poses
                .iter()
                .filter(|p| p.t >= a && p.t <= b)
                .cloned()
                .collect();
            let guess = self.offset_guess;
            let samples: Vec<_> = log
                .samples
                .iter()
                .filter(|s| (a - REPORTS_BEYOND_S..=b + REPORTS_BEYOND_S).contains(&(s.t + guess)))
                .cloned()
                .collect();
            let first = data.poses.first().map_or(a, |p| p.t);
            let name = format!(
                "{} from {:.0} s to {:.0} s",
                log.stats.path.display(),
                a - first,
                b - first
            );
            let pool = crate::parallel::worker_pool(opts.threads)?;
            let calib = self.calib_options(opts);
            pool.install(|| calibrate_segments(&poses, &[&samples], &[name], &calib))
                .map(|(o, _)| o)
        });
        StretchRun::of(run)
    }

    /// Calibrates the open stretch (and the closed ones not calibrated yet) and combines them
    /// ([`crate::calib::fusion`]).
    fn solve_stretches(
        &mut self,
        data: &Dataset,
        opts: &WatchOptions,
        (closed, open): &Stretches,
    ) -> Result<Solved> {
        let mut solved_s = 0.0;
        for (j, &span) in closed.iter().enumerate() {
            if !self.closed.contains_key(&j) {
                let run = self.solve_stretch(data, opts, span);
                self.closed.insert(j, run);
                solved_s += span.1 - span.0;
            }
        }
        let latest = self.solve_stretch(data, opts, *open);
        solved_s += open.1 - open.0;
        let runs: Vec<&StretchRun> = self
            .closed
            .range(..closed.len())
            .map(|(_, r)| r)
            .chain([&latest])
            .collect();
        let ok: Vec<&StretchRun> = runs
            .iter()
            .copied()
            .filter(|r| r.failed.is_none())
            .collect();
        let estimates: Vec<StretchEstimate> =
            ok.iter().filter_map(|r| r.estimate.clone()).collect();
        let Some(reference) = estimates.last() else {
            return Err(Error::Input(format!(
                "no stretch of the recording could be calibrated; the latest: {}",
                latest.failed.as_deref().unwrap_or("?")
            )));
        };
        let base = crate::calib::prior::Priors {
            held_lever_axes: None,
            ..reference.priors
        };
        let fused = fuse(&estimates, reference, &base);
        let (params, covariance) = match &fused {
            Some(f) => (f.params, f.covariance),
            None => (reference.params, reference.covariance),
        };
        let limits = &opts.calib.weak;
        let groups = group_std(&covariance, limits);
        let reference_run = ok.last().copied().unwrap_or(&latest);
        let verdicts = std::array::from_fn(|k| {
            let held = reference_run.verdicts[k] == Observability::Fixed;
            let by_prior = ok.iter().all(|r| r.verdicts[k] == Observability::Prior);
            if held {
                Observability::Fixed
            } else if groups[k].met() {
                Observability::Ok
            } else if by_prior {
                Observability::Prior
            } else {
                Observability::Weak
            }
        });
        let failed = match (&latest.failed, &fused) {
            (Some(why), _) => Some(format!("the last {:.0} s: {why}", open.1 - open.0)),
            (None, None) => Some(
                "the stretches' calibrations could not be combined (a covariance that cannot be \
                 inverted)"
                    .to_owned(),
            ),
            (None, Some(_)) => None,
        };
        Ok(Solved {
            params,
            covariance,
            run: StretchRun {
                estimate: None,
                verdicts,
                dvl_used: ok.iter().map(|r| r.dvl_used).sum(),
                dvl_samples: runs.iter().map(|r| r.dvl_samples).sum(),
                dvl_in_pose_gaps: runs.iter().map(|r| r.dvl_in_pose_gaps).sum(),
                residual_rms: reference_run.residual_rms,
                failed,
                warm: latest.warm,
            },
            stretches: estimates.len(),
            stretches_failed: runs.len() - estimates.len(),
            solved_s,
        })
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
            "update {}: {} poses over {:.0} s, {} of {} DVL reports used{} ({:.1} s){}",
            self.update,
            c.poses,
            c.span_s,
            c.dvl_used,
            c.dvl_reports,
            match (c.stretches, c.stretches_failed) {
                (0 | 1, 0) => String::new(),
                (n, 0) => format!(", {n} stretches combined"),
                (n, f) => format!(", {n} stretches combined ({f} failed, left out)"),
            },
            self.update_s,
            if self.done { ": DONE" } else { "" }
        );
        if let Some(m) = &self.cameras {
            let _ = writeln!(s, "  {}", m.words());
        }
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
