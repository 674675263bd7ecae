//! One dataset (camera trajectory, DVL log and IMU stream) read into memory: from a dataset
//! folder, from files named one by one, or both (named files win). The DVL log may be missing
//! when an IMU stream and its noise file are there: a camera + IMU calibration
//! ([`super::imu_only`]).

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::io::bag::camera_info::camera_from_info;
use crate::io::bag::frames::plan_frames;
use crate::io::bag::is_bag;
use crate::io::bag::open::OpenBag;
use crate::io::bag::poses::read_bag_poses;
use crate::io::calib_yaml::CalibrationFile;
use crate::io::camchain::read_camchain;
use crate::io::dataset::{DatasetFiles, DatasetOverrides, discover};
use crate::io::dvl::{DvlLog, DvlReadOptions, read_dvl_log};
use crate::io::frames_csv::{frames_csv_path, read_tum_with_covariances};
use crate::io::images::camera_count;
use crate::io::imu::noise::{ImuNoiseFile, read_imu_noise};
use crate::io::imu::{ImuLog, read_imu_csv};
use crate::io::tum::{CameraClockStep, CameraSegment};
use crate::types::PoseMeasurement;
use crate::types::camera::Camchain;
use crate::vision::scale::BoardSize;

use super::cameras::{
    CameraCalOptions, CameraCalRun, calibrate_cameras_from_bag, calibrate_cameras_from_images,
};
use super::vision::{
    VisionOptions, VisionRun, poses_from_bag, poses_from_images, poses_from_images_with_chain,
};

/// The files of a dataset: found in `dir` with `given` taking precedence, or, without a folder,
/// exactly the files `given` names (a DVL log, and poses or images with a target and, optionally,
/// a camchain: without one the cameras are calibrated from the images when the dataset is
/// loaded).
pub fn dataset_files(dir: Option<&Path>, given: &DatasetOverrides) -> Result<DatasetFiles> {
    if let Some(d) = dir {
        if crate::io::bag::is_bag(d) {
            return Ok(DatasetFiles::from_bag(d, given));
        }
        return discover(d, given);
    }
    if let Some(b) = &given.bag {
        return Ok(DatasetFiles::from_bag(b, given));
    }
    if given.dvl.is_none() && given.imu.is_none() {
        return Err(Error::Input(
            "give a dataset folder, or --dvl LOG (or --imu FILE --imu-noise FILE) with --poses \
             FILE or --images DIR"
                .into(),
        ));
    }
    match (&given.poses, &given.images) {
        (Some(_), _) => {}
        (None, Some(_)) => {
            if given.target.is_none() {
                return Err(Error::Input(
                    "--images needs --target FILE (and --camchain FILE, or the cameras are \
                     calibrated from the same images)"
                        .into(),
                ));
            }
        }
        // DVL + IMU: the IMU from a file, or from the DVL's bag.
        (None, None) if given.imu.is_some() || given.dvl.as_deref().is_some_and(is_bag) => {}
        (None, None) => {
            return Err(Error::Input(
                "give --poses FILE, or --images DIR --target FILE [--camchain FILE]; or, to \
                 calibrate the DVL against an IMU, --imu FILE --imu-noise FILE"
                    .into(),
            ));
        }
    }
    Ok(DatasetFiles {
        root: PathBuf::from("."),
        images: given.images.clone(),
        camchain: given.camchain.clone(),
        target: given.target.clone(),
        dvl: given.dvl.clone(),
        poses: given.poses.clone(),
        bag: None,
        imu: given.imu.clone(),
        imu_noise: given.imu_noise.clone(),
        bag_options: given.bag_options.clone(),
        ignored: Vec::new(),
    })
}

/// [`dataset_files`], with the camera + IMU mode checked at once: without a DVL log the IMU
/// stream needs its noise file.
pub fn dataset_files_checked(dir: Option<&Path>, given: &DatasetOverrides) -> Result<DatasetFiles> {
    let files = dataset_files(dir, given)?;
    if let (None, Some(imu), None) = (&files.dvl, &files.imu, &files.imu_noise) {
        return Err(Error::dataset(
            &files.root,
            format!(
                "no DVL log, and the IMU stream {} has no noise file: a camera + IMU \
                 calibration needs the IMU's noise (Kalibr's imu.yaml: --imu-noise FILE)",
                imu.display()
            ),
        ));
    }
    Ok(files)
}

/// One line on what a dataset folder holds, then one per ignored file with the reason.
pub fn describe_files(f: &DatasetFiles) -> String {
    let show = |p: &Option<PathBuf>| {
        p.as_ref()
            .map_or("-".to_string(), |p| p.display().to_string())
    };
    let poses = match f.pose_covariances() {
        Some(c) => format!("{} (covariances {})", show(&f.poses), c.display()),
        None => show(&f.poses),
    };
    let mut s = format!(
        "dataset {}: images {}, poses {poses}, bag {}, camchain {}, target {}, DVL log {}\n",
        f.root.display(),
        show(&f.images),
        show(&f.bag),
        show(&f.camchain),
        show(&f.target),
        show(&f.dvl)
    );
    if f.imu.is_some() || f.imu_noise.is_some() {
        s.push_str(&format!(
            "  IMU {}, IMU noise {}\n",
            show(&f.imu),
            show(&f.imu_noise)
        ));
    }
    for (p, why) in &f.ignored {
        s.push_str(&format!("  ignored {}: {why}\n", p.display()));
    }
    s
}

/// What a chain calibrated from the same images (`calibrated`) cannot check: the board's size
/// (its baseline is in the board's units; a scale that was applied stays, the poses were solved
/// with it) and its focal lengths (fitted to these very images).
fn chain_from_same_images(run: &mut VisionRun, calibrated: bool) {
    if !calibrated {
        return;
    }
    if !run.board_size.measured().is_some_and(|b| b.applied) {
        run.board_size = BoardSize::BaselineFromBoard;
    }
    run.focal.iter_mut().for_each(|f| *f = None);
}

/// The dataset's IMU files read and checked, what was found said in `notes`: a file that cannot
/// be used is left out with a note saying why (the camera-IMU calibration then does not run).
fn read_imu_files(
    files: &DatasetFiles,
    epoch: crate::time::Epoch,
    notes: &mut Vec<String>,
) -> Result<(Option<ImuLog>, Option<ImuNoiseFile>)> {
    let from_file = files.imu.as_deref().map(|p| read_imu_csv(p, Some(epoch)));
    let read = match from_file {
        Some(r) => Some(r),
        None => super::imu_bag::imu_from_bag(files, epoch, notes)?,
    };
    let imu = read.and_then(|r| match r {
        Ok(log) => {
            notes.extend(log.summary());
            Some(log)
        }
        Err(e) => {
            notes.push(format!("IMU stream not used: {e}"));
            None
        }
    });
    let noise = files
        .imu_noise
        .as_deref()
        .and_then(|p| match read_imu_noise(p) {
            Ok(n) => {
                notes.push(format!(
                    "{}: IMU noise: gyro {} rad/s/sqrt(Hz), accelerometer {} m/s^2/sqrt(Hz) at \
                     {} Hz",
                    p.display(),
                    n.noise.gyroscope_noise_density,
                    n.noise.accelerometer_noise_density,
                    n.noise.update_rate
                ));
                Some(n)
            }
            Err(e) => {
                notes.push(format!("IMU noise not used: {e}"));
                None
            }
        });
    Ok((imu, noise))
}

/// The DVL log `path` of `files`, read on `epoch` (a bag's DVL topic and time as `files`
/// chooses them); a polled capture without the DVL's time is refused.
fn read_dvl(
    path: &Path,
    files: &DatasetFiles,
    epoch: crate::time::Epoch,
    read: &DvlReadOptions,
) -> Result<DvlLog> {
    let mut read = DvlReadOptions {
        epoch: Some(epoch),
        ..read.clone()
    };
    if crate::io::bag::is_bag(path) {
        if read.topic.is_none() {
            read.topic = files.bag_options.dvl_topic.clone();
        }
        if files.bag_options.time == crate::io::bag::roles::BagTime::Record {
            read.time_source = crate::io::dvl::DvlTimeSource::Host;
        }
    }
    let log = read_dvl_log(path, &read)?;
    // A polled capture without the DVL's time has a squeezed time line: nothing to fit.
    if let Some(p) = log.stats.polled.as_ref().filter(|p| p.unusable()) {
        return Err(Error::Input(format!("{}: {}", path.display(), p.explain())));
    }
    Ok(log)
}

/// The note of a dataset whose poses were solved with the earlier camera calibration `k`.
fn reused_note(k: &CameraCalRun) -> String {
    format!(
        "no camchain: the cameras as calibrated earlier from this recording's images ({}), reused",
        k.one_line()
    )
}

/// The DVL + IMU mode in words ([`super::dvl_imu`]), as the notes and the summary say it.
pub const DVL_IMU_MODE: &str = "DVL + IMU: no camera data given";

/// A dataset read into memory: the camera poses, the DVL log and the IMU stream on one epoch.
#[derive(Debug)]
pub struct Dataset {
    /// Where each part came from.
    pub files: DatasetFiles,
    /// The camera poses `T_world_cam` on the camera clock.
    pub poses: Vec<PoseMeasurement>,
    /// The image pipeline's run, when the poses come from images.
    pub vision: Option<VisionRun>,
    /// The camera calibration run from the same images, when the dataset had images but no
    /// camchain (its chain is the one the poses were solved with).
    pub cameras: Option<CameraCalRun>,
    /// Whether [`Dataset::cameras`] is an earlier calibration passed to
    /// [`Dataset::load_reusing_cameras`] and reused, rather than one made from these images.
    pub cameras_reused: bool,
    /// The DVL log, read on the poses' epoch; `None` in a camera + IMU dataset (no DVL log
    /// given: [`super::imu_only`]).
    pub log: Option<DvlLog>,
    /// The DVL log's file (`None` as `log`).
    pub dvl_path: Option<PathBuf>,
    /// What the camera trajectory came from: the pose file or the image folder.
    pub camera_source: PathBuf,
    /// Things the user should know about the camera data (a bag's zero stamps, the source of
    /// the camera model, ...).
    pub notes: Vec<String>,
    /// The camera frame's name when the data give one (the `header.frame_id` of a bag's cam0
    /// images): the parent frame of the exports unless `--frames` says otherwise.
    pub camera_frame: Option<String>,
    /// The camera clock's steps back in a pose file (found in file order; images and bags are
    /// read in time order, where a step cannot be seen).
    pub camera_clock_steps: Vec<CameraClockStep>,
    /// The IMU stream, read on the poses' epoch and checked, when the folder has one (a stream
    /// that cannot be used is a note, not an error: the DVL's calibration runs without it).
    pub imu: Option<ImuLog>,
    /// The IMU's noise file, when the folder has one.
    pub imu_noise: Option<ImuNoiseFile>,
    /// The camera clock's segments of a pose file (one when it did not step; none for images
    /// and bags): the poses of each later segment follow the one before by a frame's interval.
    pub camera_segments: Vec<CameraSegment>,
    /// The poses dropped as held: repeats of the pose before them while the rig moved
    /// ([`crate::types::held_pose_runs`]).
    pub held_poses: HeldPoses,
}

/// Camera poses dropped as held: the tracker (or the camera) repeated its last pose at new
/// times while the rig moved, so their times are wrong ([`crate::types::held_pose_runs`]).
#[derive(Clone, Debug, Default)]
pub struct HeldPoses {
    /// Holds found.
    pub runs: usize,
    /// Poses they had, dropped.
    pub poses: usize,
    /// What was dropped and where, for the result's warnings (`None` when nothing was).
    pub warning: Option<String>,
}

/// At most this many holds are located in the warning; the rest are counted.
const HELD_SHOWN: usize = 5;

/// `poses` without their held poses, and what was dropped. The holds are located by the pose
/// file's lines when `lines` gives them, else by their time after the first pose. The camera
/// clock's segments (ranges of pose indices) are moved to the kept poses.
fn drop_held_poses(
    poses: Vec<PoseMeasurement>,
    lines: Option<&[usize]>,
    source: &Path,
    segments: &mut [CameraSegment],
) -> (Vec<PoseMeasurement>, HeldPoses) {
    let runs = crate::types::held_pose_runs(&poses);
    if runs.is_empty() {
        return (poses, HeldPoses::default());
    }
    let t0 = poses.first().map_or(0.0, |p| p.t);
    let place = |r: &std::ops::Range<usize>| match lines {
        Some(l) if r.len() == 1 => format!("line {}", l.get(r.start).copied().unwrap_or(0)),
        Some(l) => format!(
            "lines {}-{}",
            l.get(r.start).copied().unwrap_or(0),
            l.get(r.end - 1).copied().unwrap_or(0)
        ),
        None => format!(
            "{} at {:.2} s",
            r.len(),
            poses.get(r.start).map_or(f64::NAN, |p| p.t - t0)
        ),
    };
    let shown: Vec<String> = runs.iter().take(HELD_SHOWN).map(place).collect();
    let more = runs.len().saturating_sub(HELD_SHOWN);
    let count: usize = runs.iter().map(|r| r.len()).sum();
    let warning = format!(
        "{}: {count} camera poses in {} holds repeat the pose before them exactly while the rig \
         moved ({}{}{}): the tracker held its last pose, or the camera repeated a frame, so \
         their times are wrong and the motion would seem to stop and lurch; they were dropped",
        source.display(),
        runs.len(),
        if lines.is_some() {
            ""
        } else {
            "poses after the first: "
        },
        shown.join(", "),
        if more > 0 {
            format!(" and {more} more")
        } else {
            String::new()
        }
    );
    let (kept, index) = crate::types::without_runs(poses, &runs);
    for seg in segments.iter_mut() {
        let (a, b) = (seg.poses.start, seg.poses.end);
        seg.poses = index.partition_point(|&i| i < a)..index.partition_point(|&i| i < b);
    }
    let held = HeldPoses {
        runs: runs.len(),
        poses: count,
        warning: Some(warning),
    };
    (kept, held)
}

impl Dataset {
    /// Reads the camera trajectory (running the image pipeline on images) and the DVL log on
    /// its epoch. `on_vision` sees the image run as soon as detection ends, also when no frame
    /// got a pose (the error follows). Images without a camchain are calibrated first, with
    /// the default camera model (see [`Dataset::load_observed`]).
    pub fn load(
        files: DatasetFiles,
        vision: &VisionOptions,
        read: &DvlReadOptions,
        on_vision: &mut dyn FnMut(&VisionRun),
    ) -> Result<Dataset> {
        Self::load_observed(files, vision, read, &mut |_| {}, on_vision)
    }

    /// [`Dataset::load`], with `on_cameras` seeing the camera calibration as soon as it ends
    /// when the files have images but no camchain ([`DatasetFiles::calibrates_cameras`]). The
    /// cameras are then calibrated from the same images and board with
    /// [`calibrate_cameras_from_images`] (threads, decimation, pairing tolerance and progress
    /// bar from `vision`; the default camera model, two detection passes), and the poses are
    /// solved with the fitted chain. A camera calibration that fails is an error; one with
    /// warnings ([`CameraCalRun::is_weak`]) is used, and kept in [`Dataset::cameras`] for the
    /// caller to report.
    pub fn load_observed(
        files: DatasetFiles,
        vision: &VisionOptions,
        read: &DvlReadOptions,
        on_cameras: &mut dyn FnMut(&CameraCalRun),
        on_vision: &mut dyn FnMut(&VisionRun),
    ) -> Result<Dataset> {
        Self::load_inner(files, vision, read, None, on_cameras, on_vision)
    }

    /// [`Dataset::load`], except that a dataset with images but no camchain has its poses
    /// solved with `cameras`, an earlier calibration of the same cameras (of a recording that
    /// has grown since: `dvlcal watch`), instead of a calibration from its images. `cameras` is
    /// reused when it has as many cameras as the images (and, in a bag, the same image sizes);
    /// when it has not, the cameras are calibrated from the images as [`Dataset::load`] does.
    /// [`Dataset::cameras_reused`] says which happened. Datasets with a camchain or a pose file
    /// load as with [`Dataset::load`].
    pub fn load_reusing_cameras(
        files: DatasetFiles,
        vision: &VisionOptions,
        read: &DvlReadOptions,
        cameras: &CameraCalRun,
    ) -> Result<Dataset> {
        Self::load_inner(files, vision, read, Some(cameras), &mut |_| {}, &mut |_| {})
    }

    /// [`Dataset::load_observed`], reusing `kept` as [`Dataset::load_reusing_cameras`] says.
    fn load_inner(
        files: DatasetFiles,
        vision: &VisionOptions,
        read: &DvlReadOptions,
        kept: Option<&CameraCalRun>,
        on_cameras: &mut dyn FnMut(&CameraCalRun),
        on_vision: &mut dyn FnMut(&VisionRun),
    ) -> Result<Dataset> {
        let mut cameras = None;
        let mut cameras_reused = false;
        let mut notes = Vec::new();
        let mut camera_frame = None;
        let (mut camera_clock_steps, mut camera_segments) = (Vec::new(), Vec::new());
        let mut pose_lines = None;
        let (epoch, poses, run, camera_source) = match (&files.poses, &files.images) {
            (Some(p), _) => {
                let (tum, table) = read_tum_with_covariances(p, None)?;
                notes.push(match table {
                    Some(t) => format!(
                        "pose covariances from {} ({} rows, one per pose)",
                        t.display(),
                        tum.poses.len()
                    ),
                    None => format!(
                        "{} carries no covariances (no {} beside it): the pose noise is \
                         estimated from the trajectory fit",
                        p.display(),
                        frames_csv_path(p).display()
                    ),
                });
                camera_clock_steps = tum.clock_steps;
                camera_segments = tum.segments;
                pose_lines = Some(tum.lines);
                (tum.epoch, tum.poses, None, p.clone())
            }
            (None, Some(dir)) => {
                let Some(target) = &files.target else {
                    return Err(Error::dataset(dir, "images need a target (board YAML)"));
                };
                let mut run = match &files.camchain {
                    Some(chain) => poses_from_images(dir, chain, target, vision)?,
                    None => {
                        let fits = |k: &&CameraCalRun| k.chain().cams.len() == camera_count(dir);
                        let cal = match kept.filter(fits) {
                            Some(k) => {
                                cameras_reused = true;
                                notes.push(reused_note(k));
                                k.clone()
                            }
                            None => {
                                let opts = CameraCalOptions {
                                    vision: vision.clone(),
                                    ..CameraCalOptions::default()
                                };
                                let cal = calibrate_cameras_from_images(dir, target, &opts)
                                    .map_err(|e| {
                                        e.during(
                                            "no camchain: calibrating the cameras from the same \
                                             images",
                                        )
                                    })?;
                                on_cameras(&cal);
                                cal
                            }
                        };
                        let chain = cal.chain().clone();
                        cameras = Some(cal);
                        poses_from_images_with_chain(dir, chain, target, vision)?
                    }
                };
                chain_from_same_images(&mut run, cameras.is_some());
                on_vision(&run);
                run.require_poses()?;
                (run.epoch, run.poses_as_read_back(), Some(run), dir.clone())
            }
            // DVL + IMU: no camera; the epoch is the IMU's first sample.
            (None, None) if files.bag.is_none() && files.dvl.is_some() && files.imu.is_some() => {
                let imu = files.imu.clone().unwrap_or_default();
                notes.push(DVL_IMU_MODE.to_owned());
                (read_imu_csv(&imu, None)?.epoch, Vec::new(), None, imu)
            }
            (None, None) => {
                let dvl_bag = files.dvl.as_ref().filter(|p| is_bag(p));
                let Some(bag) = files.bag.as_ref().or(dvl_bag) else {
                    return Err(Error::dataset(&files.root, "no camera data"));
                };
                let ob = OpenBag::open(bag, &files.bag_options)?;
                notes.extend(ob.roles.notes.iter().cloned());
                let camera_topic = files.bag.is_some()
                    && (!ob.roles.images.is_empty()
                        || ob.roles.pose.is_some()
                        || files.bag_options.pose_topic.is_some());
                if !camera_topic {
                    // DVL + IMU from a bag without camera data: the epoch is the IMU's.
                    let epoch = match &files.imu {
                        Some(p) => Some(read_imu_csv(p, None)?.epoch),
                        None => super::imu_bag::imu_epoch(&ob)?,
                    };
                    let Some(epoch) = epoch else {
                        return Err(Error::dataset(
                            bag,
                            format!(
                                "no camera data (no image or pose topic; topics: {}), and no \
                                 sensor_msgs/Imu topic to calibrate the DVL against: give the \
                                 camera's images or poses",
                                ob.topic_list()
                            ),
                        ));
                    };
                    notes.push(DVL_IMU_MODE.to_owned());
                    (epoch, Vec::new(), None, bag.clone())
                } else if ob.roles.images.is_empty() || files.bag_options.pose_topic.is_some() {
                    // A pose topic named by the user wins over the bag's images.
                    let p = read_bag_poses(&ob)?;
                    notes.push(format!("camera poses from {}", p.source));
                    notes.extend(p.warnings);
                    (p.epoch, p.poses, None, bag.clone())
                } else {
                    let Some(target) = &files.target else {
                        return Err(Error::dataset(
                            bag,
                            "the bag holds images: give the board with --target",
                        ));
                    };
                    let tol_ns = (vision.pair_tolerance_ms * 1e6).round() as i64;
                    let plan = plan_frames(&ob, tol_ns)?;
                    let chain = match &files.camchain {
                        Some(c) => read_camchain(c)?,
                        None => match (
                            plan.sizes.len(),
                            camera_from_info(&ob, 0)?,
                            kept.filter(|k| k.sizes == plan.sizes),
                        ) {
                            (1, Some(cam), _) => {
                                notes.push(
                                    "no camchain: the camera model is the bag's CameraInfo".into(),
                                );
                                Camchain::mono(cam)
                            }
                            (_, _, Some(k)) => {
                                let k = k.clone();
                                cameras_reused = true;
                                notes.push(reused_note(&k));
                                let chain = k.chain().clone();
                                cameras = Some(k);
                                chain
                            }
                            _ => {
                                let opts = CameraCalOptions {
                                    vision: vision.clone(),
                                    ..CameraCalOptions::default()
                                };
                                let cal = calibrate_cameras_from_bag(&ob, &plan, target, &opts)
                                    .map_err(|e| {
                                        e.during(
                                            "no camchain: calibrating the cameras from the bag's \
                                             images",
                                        )
                                    })?;
                                on_cameras(&cal);
                                let chain = cal.chain().clone();
                                cameras = Some(cal);
                                chain
                            }
                        },
                    };
                    camera_frame = plan.frame_ids.first().cloned().flatten();
                    let mut run = poses_from_bag(&ob, &plan, chain, target, vision)?;
                    chain_from_same_images(&mut run, cameras.is_some());
                    on_vision(&run);
                    run.require_poses()?;
                    (run.epoch, run.poses_as_read_back(), Some(run), bag.clone())
                }
            }
        };
        let (poses, held_poses) = drop_held_poses(
            poses,
            pose_lines.as_deref(),
            &camera_source,
            &mut camera_segments,
        );
        notes.extend(held_poses.warning.clone());
        let log = match &files.dvl {
            Some(p) => Some(read_dvl(p, &files, epoch, read)?),
            None => None,
        };
        let (imu, imu_noise) = read_imu_files(&files, epoch, &mut notes)?;
        if log.is_none() && imu.is_none() {
            let why = notes.iter().find(|n| n.starts_with("IMU stream not used"));
            return Err(Error::dataset(
                &files.root,
                format!(
                    "no DVL log, and no IMU stream that could be used{}",
                    why.map_or(String::new(), |w| format!(" ({w})"))
                ),
            ));
        }
        let dvl_path = log.as_ref().and(files.dvl.clone());
        Ok(Dataset {
            imu,
            imu_noise,
            files,
            poses,
            vision: run,
            cameras,
            cameras_reused,
            dvl_path,
            log,
            camera_source,
            notes,
            camera_frame,
            camera_clock_steps,
            camera_segments,
            held_poses,
        })
    }

    /// Records the held poses dropped in a result file: a warning and `info.poses_held_dropped`
    /// (nothing when there were none).
    pub fn note_held_poses(&self, file: &mut CalibrationFile) {
        let Some(w) = &self.held_poses.warning else {
            return;
        };
        let info = file.info.get_or_insert_with(Default::default);
        info.warnings.push(w.clone());
        info.figures.poses_held_dropped = Some(self.held_poses.poses);
    }

    /// The DVL log, or the error of a camera + IMU dataset that has none.
    pub fn dvl(&self) -> Result<&DvlLog> {
        self.log.as_ref().ok_or_else(|| {
            Error::dataset(
                &self.files.root,
                "no DVL log: this dataset is a camera + IMU one (only its IMU can be calibrated)",
            )
        })
    }

    /// The sound speed the DVL was set to as the user gives it (`--dvl-sound-speed`), m/s:
    /// used when the DVL log holds no configuration reply; when it holds one, the log's wins
    /// and the warning returned says so. Nothing without a DVL log or a speed.
    pub fn give_sound_speed(&mut self, given: Option<f64>) -> Option<String> {
        let (st, c) = (&mut self.log.as_mut()?.stats, given?);
        match st.sound_speed_mps {
            None => {
                st.sound_speed_mps = Some(c);
                st.sound_speed_source = Some("--dvl-sound-speed".into());
                None
            }
            Some(logged) => Some(format!(
                "--dvl-sound-speed {c} m/s not used: the DVL log's configuration reply gives the \
                 sound speed it was set to, {logged} m/s{}",
                st.sound_speed_source
                    .as_deref()
                    .map_or(String::new(), |s| format!(" ({s})"))
            )),
        }
    }

    /// The dataset's name in tables: its folder's last component.
    pub fn short_name(&self) -> String {
        self.files
            .root
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| self.files.root.display().to_string())
    }
}
