//! Camera poses from stereo images, a folder's or a bag's: scan or plan, detect, solve (one
//! path for both), and the per-frame table.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use super::chain_order::check_chain_order;
use crate::error::{Error, Result};
use crate::io::bag::frames::BagFrames;
use crate::io::bag::open::OpenBag;
use crate::io::calib_yaml::{CalibrationFile, CalibrationInfo};
use crate::io::camchain::read_camchain;
use crate::io::frames::FrameSource;
pub use crate::io::frames_csv::frames_csv_path;
use crate::io::frames_csv::{FrameRow, format_frames_csv};
use crate::io::images::{Layout, ScanStats, raw_time, scan_images};
use crate::io::target::read_board;
use crate::io::tum::as_read_back;
use crate::time::Epoch;
use crate::types::PoseMeasurement;
use crate::types::board::{Board, TagPrint};
use crate::types::camera::Camchain;
use crate::vision::detect::{DetectionCache, DetectorSettings};
use crate::vision::focal::{FocalScale, focal_scales};
use crate::vision::frames::{DetectStats, FrameResult, detect_source};
use crate::vision::pnp::PnpOptions;
use crate::vision::scale::{BoardSize, estimate_board_scale, frame_scales};

/// Detection and PnP settings (the options `dvlcal detect` and `dvlcal calibrate` share).
#[derive(Clone, Debug, PartialEq)]
pub struct VisionOptions {
    /// Worker threads, one image pair per thread at a time (`--threads`; `None`: all cores).
    pub threads: Option<usize>,
    /// Decimation of the image for quad detection; corners are refined at full resolution
    /// (`--decimate`).
    pub decimate: f32,
    /// Largest time difference between paired cam0 / cam1 images, ms (`--pair-tolerance-ms`).
    pub pair_tolerance_ms: f64,
    /// Frames with fewer board corners (all cameras) get no pose (`--min-corners`).
    pub min_corners: usize,
    /// Corner noise (px) for the pose covariances; `None`: estimated per frame from the
    /// residuals (`--pixel-sigma`).
    pub pixel_sigma: Option<f64>,
    /// Show a progress bar on a terminal.
    pub progress: bool,
    /// Detections of earlier runs over the same image files (`dvlcal watch`), used and added to
    /// (`None`: every image is detected).
    pub cache: Option<DetectionCache>,
}

impl Default for VisionOptions {
    fn default() -> Self {
        VisionOptions {
            threads: None,
            decimate: 2.0,
            pair_tolerance_ms: 2.0,
            min_corners: 8,
            pixel_sigma: None,
            progress: false,
            cache: None,
        }
    }
}

impl VisionOptions {
    /// Checks the values the pipeline owns (the detector checks its own, `--decimate`, and the
    /// worker pool `--threads`); the error names the option.
    pub fn validate(&self) -> Result<()> {
        if !(self.pair_tolerance_ms.is_finite() && self.pair_tolerance_ms >= 0.0) {
            return Err(Error::option(
                "--pair-tolerance-ms",
                "must be a non-negative number",
            ));
        }
        if self.min_corners < 4 {
            return Err(Error::option("--min-corners", "must be at least 4"));
        }
        if let Some(s) = self.pixel_sigma
            && !(s.is_finite() && s > 0.0)
        {
            return Err(Error::option("--pixel-sigma", "must be positive"));
        }
        Ok(())
    }
}

/// Largest reprojection RMS of the posed frames, px, for the poses to be used: beyond it the
/// camera model, the board or their units are wrong, and the poses would be too.
pub const MAX_REPROJECTION_RMS_PX: f64 = 3.0;

/// Everything a run of the image pipeline produced.
#[derive(Debug)]
pub struct VisionRun {
    /// The image folder or bag.
    pub images: PathBuf,
    /// The camera chain the poses were solved with.
    pub chain: Camchain,
    /// The board file.
    pub target: PathBuf,
    /// The board's printed size as the stereo pair measured it; when it differs from the file's
    /// ([`crate::vision::scale::BoardScale::significant`]) the poses were solved with the board
    /// scaled to the measured size (`applied`).
    pub board_size: BoardSize,
    /// Per camera, its focal length as the frames measure it ([`crate::vision::focal`]; `None`
    /// for a camera too few frames measured, and for a chain calibrated from the same images).
    pub focal: Vec<Option<FocalScale>>,
    /// The epoch of the pose times: the whole second of the first frame.
    pub epoch: Epoch,
    /// One per posed frame, in time order, with covariances (`T_board_cam0` on the camera
    /// clock).
    pub poses: Vec<PoseMeasurement>,
    /// One per frame, posed or not.
    pub results: Vec<FrameResult>,
    /// What the folder scan found (with its warnings).
    pub scan: ScanStats,
    /// Detection and PnP counts (with the images that could not be used).
    pub stats: DetectStats,
    /// Wall time of detection and PnP, s.
    pub seconds: f64,
    /// When the poses reproject badly and the camera chain read in another order (`T_cn_cnm1`
    /// inverted, cam0 and cam1 swapped) fits the same frames far better: the sentence that says
    /// so ([`super::chain_order`]).
    pub chain_order: Option<String>,
}

/// Scans `images`, detects the board's tags and solves every frame on a pool of
/// `opts.threads` workers. Skipped images and frames are counted in the run; a run in which no
/// frame got a pose is returned too (to report on), and [`VisionRun::require_poses`] turns it into
/// an error.
pub fn poses_from_images(
    images: &Path,
    camchain: &Path,
    target: &Path,
    opts: &VisionOptions,
) -> Result<VisionRun> {
    opts.validate()?;
    let chain = read_camchain(camchain)?;
    poses_from_images_with_chain(images, chain, target, opts)
}

/// [`poses_from_images`] with the camera chain given as a value (one fitted in the same run, for
/// example by [`super::calibrate_cameras_from_images`]) instead of a file.
pub fn poses_from_images_with_chain(
    images: &Path,
    chain: Camchain,
    target: &Path,
    opts: &VisionOptions,
) -> Result<VisionRun> {
    opts.validate()?;
    let board = read_board(target)?;
    let tol_ns = (opts.pair_tolerance_ms * 1e6).round() as i64;
    let (frames, scan) = scan_images(images, chain.cams.len(), tol_ns)?;
    solve_poses(
        images,
        FrameSource::Files(&frames),
        scan,
        &[],
        chain,
        (target, &board),
        opts,
    )
}

/// Camera poses from a bag's images, as [`poses_from_images_with_chain`] does for a folder:
/// the frames planned from the header stamps ([`crate::io::bag::frames::plan_frames`]), the
/// images streamed, detected and solved on `opts.threads` workers.
pub fn poses_from_bag(
    ob: &OpenBag,
    plan: &BagFrames,
    chain: Camchain,
    target: &Path,
    opts: &VisionOptions,
) -> Result<VisionRun> {
    opts.validate()?;
    let board = read_board(target)?;
    if chain.cams.len() < plan.topics.len() {
        return Err(Error::Input(format!(
            "{}: {} image topics, the camera chain has {} cameras",
            ob.path().display(),
            plan.topics.len(),
            chain.cams.len()
        )));
    }
    for (c, (&(w, h), cam)) in plan.sizes.iter().zip(&chain.cams).enumerate() {
        if (w, h) != (0, 0) && (w, h) != (cam.width, cam.height) {
            return Err(Error::Input(format!(
                "{}: {} images are {w}x{h}, cam{c} of the camera chain is {}x{}",
                ob.path().display(),
                plan.topics[c].name,
                cam.width,
                cam.height
            )));
        }
    }
    solve_poses(
        ob.path(),
        FrameSource::Bag {
            path: ob.path(),
            plan,
        },
        plan.scan.clone(),
        &plan.unreadable,
        chain,
        (target, &board),
        opts,
    )
}

/// The poses of the frames of `src` (a folder or a bag, `name`): detection and stereo PnP on a
/// pool of `opts.threads` workers. `unreadable` names the images the planning could not read;
/// they head the run's problems. `target` is the board's file and the board it holds.
///
/// With two or more cameras the frames measure the board's printed size
/// ([`crate::vision::scale`]); when it differs from the file's, the frames are read, detected
/// and solved again with the board scaled to the measured size (a second pass, which only a
/// misprinted board costs).
fn solve_poses(
    name: &Path,
    src: FrameSource<'_>,
    scan: ScanStats,
    unreadable: &[String],
    chain: Camchain,
    target: (&Path, &Board),
    opts: &VisionOptions,
) -> Result<VisionRun> {
    let (target, board) = target;
    let mut det = detector_settings(board, opts);
    if let FrameSource::Bag { path, .. } = src {
        det.cache_bag = Some(path.to_path_buf());
    }
    let pnp = PnpOptions {
        min_corners: opts.min_corners,
        sigma_px: opts.pixel_sigma,
        ..PnpOptions::default()
    };
    let pool = crate::parallel::worker_pool(opts.threads)?;
    let start = Instant::now();
    let (mut results, mut stats) =
        pool.install(|| detect_source(src, board, &chain, &det, &pnp, opts.progress))?;
    let mut board_size = if chain.cams.len() < 2 {
        BoardSize::OneCamera
    } else {
        match estimate_board_scale(&frame_scales(&results)) {
            Some(b) => BoardSize::Measured(b),
            None => BoardSize::TooFewStereoFrames,
        }
    };
    if let BoardSize::Measured(b) = &mut board_size
        && b.significant()
    {
        let scaled = board.scaled(b.scale);
        (results, stats) =
            pool.install(|| detect_source(src, &scaled, &chain, &det, &pnp, opts.progress))?;
        b.applied = true;
    }
    // Stereo that reprojects badly: is the chain the other way round? (A diagnosis only: its
    // own failure leaves the error as it is.)
    let poor = stats.rms_px.is_nan() || stats.rms_px > MAX_REPROJECTION_RMS_PX;
    let chain_order = if chain.cams.len() >= 2 && poor {
        pool.install(|| check_chain_order(src, board, &chain, &det, &pnp))
            .ok()
            .flatten()
            .and_then(|c| c.hint(MAX_REPROJECTION_RMS_PX))
    } else {
        None
    };
    let focal = focal_scales(&results, chain.cams.len());
    stats.problems.splice(0..0, unreadable.iter().cloned());
    let seconds = start.elapsed().as_secs_f64();
    let epoch = Epoch::at(raw_time(src.frames().first().map_or(0, |f| f.t_ns)));
    let poses = posed_frames(&results, &epoch);
    Ok(VisionRun {
        images: name.to_path_buf(),
        chain,
        target: target.to_path_buf(),
        board_size,
        focal,
        epoch,
        poses,
        results,
        scan,
        stats,
        seconds,
        chain_order,
    })
}

/// The detector settings of the image pipeline for `board`: one thread per detector (the frames
/// run in parallel), the decimation of `opts`, the board's ids (the Kalibr second pass stops
/// once they are all found) and whether it is a Kalibr print (its brightened pass then runs
/// first, libapriltag's own detection only for ids it leaves unfound).
pub fn detector_settings(board: &Board, opts: &VisionOptions) -> DetectorSettings {
    DetectorSettings {
        family: board.family,
        decimate: opts.decimate,
        threads: 1,
        board_ids: Some(board.tags.iter().map(|t| t.id).collect()),
        kalibr_print: board.print == TagPrint::Kalibr,
        cache: opts.cache.clone(),
        ..DetectorSettings::default()
    }
}

/// The poses of the posed frames, with their times relative to `epoch`.
pub fn posed_frames(results: &[FrameResult], epoch: &Epoch) -> Vec<PoseMeasurement> {
    results
        .iter()
        .filter_map(|r| {
            r.pose.as_ref().map(|p| PoseMeasurement {
                t: epoch.rel(raw_time(r.frame.t_ns)),
                pose: p.t_board_cam0,
                cov: Some(p.cov),
            })
        })
        .collect()
}

/// Records in the result file the warnings of the image folder's (or bag's) scan of `run`:
/// cameras of the chain without images, camera folders the chain does not use, images without
/// a partner, file names read in another unit.
pub(crate) fn note_image_scan(file: &mut CalibrationFile, run: Option<&VisionRun>) {
    if let Some(run) = run.filter(|r| !r.scan.warnings.is_empty()) {
        let info = file.info.get_or_insert_with(CalibrationInfo::default);
        info.warnings.extend(run.scan.warnings.iter().cloned());
    }
}

impl VisionRun {
    /// The poses as a TUM file of them reads back ([`as_read_back`]): what the calibration
    /// takes, so that calibrating from images and from `dvlcal detect`'s TUM file and frames
    /// table give the same digits. (`poses` keeps the solver's rotations, which the TUM file is
    /// written from.)
    pub fn poses_as_read_back(&self) -> Vec<PoseMeasurement> {
        self.poses
            .iter()
            .map(|p| PoseMeasurement {
                pose: as_read_back(&p.pose),
                ..p.clone()
            })
            .collect()
    }

    /// An error naming the folder when no frame got a pose.
    pub fn require_poses(&self) -> Result<()> {
        if self.poses.is_empty() {
            return Err(Error::dataset(
                &self.images,
                format!("no frame gave a pose ({} frames)", self.stats.frames),
            ));
        }
        if self.stats.rms_px.is_nan() || self.stats.rms_px > MAX_REPROJECTION_RMS_PX {
            let why = match &self.chain_order {
                Some(order) => order.clone(),
                None => "check the intrinsics and distortion (of this resolution?), the tag size \
                         and spacing (metres?), and that the board file is the board in the \
                         images"
                    .into(),
            };
            return Err(Error::dataset(
                &self.images,
                format!(
                    "the poses reproject the board's corners with {:.1} px RMS (a good camera \
                     model and board give well under 1 px; at most {MAX_REPROJECTION_RMS_PX} px is \
                     accepted): {why}",
                    self.stats.rms_px,
                ),
            ));
        }
        Ok(())
    }

    /// Four lines on what was read, detected and skipped, and the board's size.
    pub fn summary(&self) -> String {
        let sc = &self.scan;
        let st = &self.stats;
        let layout = match sc.layout {
            Layout::Kalibr => "camN/<t_ns> layout",
            Layout::Euroc => "EuRoC layout",
            Layout::Bag => "bag image topics",
        };
        let per_cam: Vec<String> = sc
            .images
            .iter()
            .enumerate()
            .map(|(c, n)| format!("cam{c} {n}"))
            .collect();
        let mut s = String::new();
        let _ = writeln!(
            s,
            "images {} ({layout}): {} images; {} frames, {} with every camera, {} cam0 alone, \
             {} unpaired images of other cameras dropped, {} other files ignored",
            self.images.display(),
            per_cam.join(", "),
            st.frames,
            sc.complete,
            sc.unpaired_cam0,
            sc.unpaired_other,
            sc.ignored
        );
        let _ = writeln!(
            s,
            "poses {} of {} frames; {:.1} tags detected per frame, {} used, {} rejected as outliers, \
             {} not on the board; reprojection RMS {:.3} px; {:.2} s ({:.1} frames/s)",
            st.poses,
            st.frames,
            st.tags_per_frame(),
            st.tags_used,
            st.tags_rejected,
            st.tags_unknown,
            st.rms_px,
            self.seconds,
            st.frames as f64 / self.seconds.max(1e-9)
        );
        let _ = writeln!(
            s,
            "skipped frames: {} too few corners, {} no solution, {} no usable image \
             ({} unreadable images, {} of the wrong size)",
            st.too_few_corners, st.no_solution, st.no_image, st.unreadable, st.wrong_size
        );
        let _ = writeln!(s, "board size: {}", self.board_size_words());
        s
    }

    /// [`BoardSize::words`] with the board file's name.
    pub fn board_size_words(&self) -> String {
        let name = crate::files::file_name_of(&self.target);
        self.board_size.words(&name)
    }

    /// The per-frame table written beside a TUM file of the poses: one row per pose, same order
    /// (see [`crate::io::frames_csv`] and `docs/formats.md`).
    pub fn frames_csv(&self) -> String {
        let rows: Vec<FrameRow> = self
            .results
            .iter()
            .filter_map(|r| {
                r.pose.as_ref().map(|p| FrameRow {
                    t: self.epoch.rel(raw_time(r.frame.t_ns)),
                    tags: p.tags_used,
                    corners: p.corners_used,
                    rms_px: p.rms_px,
                    rejected: p.tags_rejected,
                    sigma_px: p.sigma_px,
                    cov: p.cov,
                })
            })
            .collect();
        format_frames_csv(&self.epoch, &rows)
    }
}
