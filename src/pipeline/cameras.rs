//! Camera calibration from board images, a folder's or a bag's: scan or plan, detect, calibrate,
//! detect again with the fitted lenses, calibrate again, and write the camchain and the report.
//!
//! Without a camera model the detector fits each tag side as a straight line in the distorted
//! image, where a side is slightly bent; the corners then lean towards the image centre, more so
//! far from it, and the focal length comes out short. The second pass refines the corners in the
//! undistorted coordinates of the first fit, which removes that lean (on rendered sequences it
//! takes the error of the fitted lens from 0.3 px to below 0.1 px).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::camcal::{CamCalOptions, CamCalResult, FrameTags, calibrate_cameras};
use crate::error::{Error, Result};
use crate::io::bag::frames::BagFrames;
use crate::io::bag::open::OpenBag;
use crate::io::camchain::camchain_yaml;
use crate::io::frames::FrameSource;
use crate::io::images::{ScanStats, StereoFrame, camera_count, image_sizes, scan_images};
use crate::io::target::read_board;
use crate::io::write_atomic;
use crate::report::{CamCalReportInput, render_camcal_html};
use crate::types::board::Board;
use crate::types::camera::Camchain;
use crate::vision::frames::{DetectStats, detect_source_tags};

use super::vision::{VisionOptions, detector_settings};

/// What to do when a camera calibration made from a DVL recording is weak: a recording made for
/// the DVL rotates less than one made for the cameras.
pub const SEPARATE_CAMERA_RECORDING: &str = "record the board for the cameras separately (moved \
     over the whole image and tilted up to 45 degrees), calibrate it with `dvlcal \
     calibrate-cameras`, and pass the camchain with --camchain";

/// Settings of [`calibrate_cameras_from_images`].
#[derive(Clone, Debug, PartialEq)]
pub struct CameraCalOptions {
    /// Threads, decimation, pairing tolerance and the progress bar (the PnP fields are unused).
    pub vision: VisionOptions,
    /// The model and the estimator's thresholds.
    pub camcal: CamCalOptions,
    /// Detect again with the fitted cameras and calibrate again (the corners of the second pass
    /// are refined in undistorted coordinates).
    pub second_pass: bool,
}

impl Default for CameraCalOptions {
    fn default() -> Self {
        CameraCalOptions {
            vision: VisionOptions::default(),
            camcal: CamCalOptions::default(),
            second_pass: true,
        }
    }
}

/// What a camera calibration run found.
#[derive(Clone, Debug)]
pub struct CameraCalRun {
    /// The image folder or bag.
    pub images: PathBuf,
    /// The board file.
    pub target: PathBuf,
    /// The calibration (of the last pass).
    pub result: CamCalResult,
    /// The folder scan (pairing, warnings).
    pub scan: ScanStats,
    /// Detection counts of the last pass.
    pub detect: DetectStats,
    /// Detection passes run (1 or 2).
    pub passes: usize,
    /// Image size per camera.
    pub sizes: Vec<(u32, u32)>,
    /// Wall time of detection (all passes), s.
    pub seconds_detect: f64,
    /// Wall time of the adjustment (all passes), s.
    pub seconds_fit: f64,
}

fn frame_tags(
    frames: &[StereoFrame],
    dets: Vec<Vec<Vec<crate::vision::detect::TagDetection>>>,
) -> Vec<FrameTags> {
    frames
        .iter()
        .zip(dets)
        .map(|(f, d)| FrameTags {
            name: f
                .images
                .iter()
                .flatten()
                .next()
                .map_or_else(|| f.t_ns.to_string(), |r| r.short_name()),
            t_ns: f.t_ns,
            dets: d,
        })
        .collect()
}

/// Calibrates the cameras whose images `images` holds (`cam0`, `cam1`, ... folders, or EuRoC's
/// layout) from the board `target`.
pub fn calibrate_cameras_from_images(
    images: &Path,
    target: &Path,
    opts: &CameraCalOptions,
) -> Result<CameraCalRun> {
    opts.vision.validate()?;
    let board = read_board(target)?;
    let cams = camera_count(images);
    if cams == 0 {
        return Err(Error::dataset(
            images,
            "no cam0 folder (images go in DIR/cam0/<t_ns>.png, DIR/cam1/..., or EuRoC's mav0/camN)",
        ));
    }
    let tol_ns = (opts.vision.pair_tolerance_ms * 1e6).round() as i64;
    let (frames, scan) = scan_images(images, cams, tol_ns)?;
    let sizes = image_sizes(&frames, cams)?;
    calibrate_cameras_from_frames(
        images,
        target,
        &board,
        FrameSource::Files(&frames),
        scan,
        sizes,
        opts,
    )
}

/// Calibrates the cameras of a bag's image topics from the board `target`, as
/// [`calibrate_cameras_from_images`] does for a folder (each detection pass streams the bag
/// once). The chain's `rostopic`s are the bag's image topics.
pub fn calibrate_cameras_from_bag(
    ob: &OpenBag,
    plan: &BagFrames,
    target: &Path,
    opts: &CameraCalOptions,
) -> Result<CameraCalRun> {
    opts.vision.validate()?;
    let board = read_board(target)?;
    let mut run = calibrate_cameras_from_frames(
        ob.path(),
        target,
        &board,
        FrameSource::Bag {
            path: ob.path(),
            plan,
        },
        plan.scan.clone(),
        plan.sizes.clone(),
        opts,
    )?;
    for (t, topic) in run.result.chain.topics.iter_mut().zip(&plan.topics) {
        *t = Some(topic.name.clone());
    }
    Ok(run)
}

/// The calibration of [`calibrate_cameras_from_images`] on frames from any source (a folder,
/// a bag), whose images are read once per detection pass. `name` is the images' folder or bag,
/// `sizes` the image size of each camera.
fn calibrate_cameras_from_frames(
    name: &Path,
    target: &Path,
    board: &Board,
    src: FrameSource<'_>,
    scan: ScanStats,
    sizes: Vec<(u32, u32)>,
    opts: &CameraCalOptions,
) -> Result<CameraCalRun> {
    let frames = src.frames();
    let det = detector_settings(board, &opts.vision);
    let pool = crate::parallel::worker_pool(opts.vision.threads)?;
    let mut seconds_detect = 0.0;
    let mut seconds_fit = 0.0;

    let start = Instant::now();
    let (dets, mut detect) =
        pool.install(|| detect_source_tags(src, &sizes, None, &det, opts.vision.progress))?;
    seconds_detect += start.elapsed().as_secs_f64();
    let start = Instant::now();
    let mut result =
        pool.install(|| calibrate_cameras(board, &frame_tags(frames, dets), &sizes, &opts.camcal))?;
    seconds_fit += start.elapsed().as_secs_f64();
    let mut passes = 1;
    if opts.second_pass {
        let start = Instant::now();
        let (dets, d2) = pool.install(|| {
            detect_source_tags(src, &sizes, Some(&result.chain), &det, opts.vision.progress)
        })?;
        seconds_detect += start.elapsed().as_secs_f64();
        let start = Instant::now();
        let second = pool
            .install(|| calibrate_cameras(board, &frame_tags(frames, dets), &sizes, &opts.camcal));
        seconds_fit += start.elapsed().as_secs_f64();
        // The second pass is the better one when it works; when it does not, the first stands
        // and says why.
        match second {
            Ok(r) => {
                result = r;
                detect = d2;
                passes = 2;
            }
            Err(e) => result.warnings.push(format!(
                "the second pass (corners refined with the fitted lenses) failed ({e}); this is \
                 the first pass's result"
            )),
        }
    }
    for (i, t) in result.chain.topics.iter_mut().enumerate() {
        *t = Some(format!("/cam{i}/image_raw"));
    }
    Ok(CameraCalRun {
        images: name.to_path_buf(),
        target: target.to_path_buf(),
        result,
        scan,
        detect,
        passes,
        sizes,
        seconds_detect,
        seconds_fit,
    })
}

impl CameraCalRun {
    /// The camchain in Kalibr's format, with each parameter's standard deviation under keys of
    /// its own (`intrinsics_std`, `distortion_coeffs_std`, `T_cn_cnm1_std`: rotation rad and
    /// translation m) that Kalibr's readers ignore, and the fit's figures as comments.
    pub fn camchain_yaml(&self) -> String {
        let r = &self.result;
        let mut out = String::new();
        let _ = writeln!(
            out,
            "# dvlcal calibrate-cameras {}: {} model, {} cameras, reprojection RMS {:.3} px, corner \
             noise {:.3} px",
            env!("CARGO_PKG_VERSION"),
            r.model.name(),
            r.chain.cams.len(),
            r.rms_px,
            r.sigma_px
        );
        let _ = writeln!(
            out,
            "# images {}, target {}",
            self.images.display(),
            self.target.display()
        );
        let list = |v: &[f64]| {
            v.iter()
                .map(|x| format!("{x:.3e}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let base = camchain_yaml(&r.chain);
        let mut cam = None::<usize>;
        let flush = |out: &mut String, cam: Option<usize>| {
            let Some(i) = cam else { return };
            let Some(s) = r.std.get(i) else { return };
            let _ = writeln!(out, "  intrinsics_std: [{}]", list(&s.intrinsics));
            let _ = writeln!(out, "  distortion_coeffs_std: [{}]", list(&s.distortion));
            if let (Some(rot), Some(tr)) = (s.rotation_rad, s.translation_m) {
                let _ = writeln!(
                    out,
                    "  T_cn_cnm1_std: {{rotation_rad: [{}], translation_m: [{}]}}",
                    list(&rot),
                    list(&tr)
                );
            }
        };
        for line in base.lines() {
            if let Some(n) = line
                .strip_prefix("cam")
                .and_then(|l| l.strip_suffix(':'))
                .and_then(|n| n.parse::<usize>().ok())
            {
                flush(&mut out, cam);
                cam = Some(n);
            }
            out.push_str(line);
            out.push('\n');
        }
        flush(&mut out, cam);
        out
    }

    /// A plain summary for a terminal.
    pub fn summary(&self) -> String {
        let r = &self.result;
        let mut s = String::new();
        let used = r.frames.iter().filter(|f| f.dropped.is_none()).count();
        let _ = writeln!(
            s,
            "camera calibration ({}): {} frames, {used} used; {} corners used, {} rejected; {} \
             tags at the image border left out; {} detection pass{} ({:.1} s), adjustment {:.2} s",
            r.model.name(),
            r.frames.len(),
            r.corners_used,
            r.corners_rejected,
            r.tags_at_border,
            self.passes,
            if self.passes == 1 { "" } else { "es" },
            self.seconds_detect,
            self.seconds_fit
        );
        if self.detect.unreadable + self.detect.wrong_size > 0 {
            let _ = writeln!(
                s,
                "  {} images unreadable, {} of the wrong size (skipped)",
                self.detect.unreadable, self.detect.wrong_size
            );
        }
        for p in self.detect.problems.iter().take(5) {
            let _ = writeln!(s, "  skipped: {p}");
        }
        for w in &self.scan.warnings {
            let _ = writeln!(s, "  warning: {w}");
        }
        for (i, (c, sd)) in r.chain.cams.iter().zip(&r.std).enumerate() {
            let _ = writeln!(
                s,
                "cam{i}: fu {:.2} +- {:.2}  fv {:.2} +- {:.2}  pu {:.2} +- {:.2}  pv {:.2} +- {:.2} px; \
                 {} [{}]; RMS {:.3} px over {} views",
                c.fu,
                sd.intrinsics[0],
                c.fv,
                sd.intrinsics[1],
                c.pu,
                sd.intrinsics[2],
                c.pv,
                sd.intrinsics[3],
                c.distortion.kalibr_name(),
                c.distortion
                    .coeffs()
                    .iter()
                    .zip(&sd.distortion)
                    .map(|(v, e)| format!("{v:.5} +- {e:.5}"))
                    .collect::<Vec<_>>()
                    .join(", "),
                r.rms_px_per_cam.get(i).copied().unwrap_or(f64::NAN),
                r.views_used.get(i).copied().unwrap_or(0)
            );
            if let (Some(b), Some(rot)) = (sd.baseline_m, sd.rotation_rad) {
                let t = r.chain.t_cn_c0[i] * r.chain.t_cn_c0[i - 1].inverse();
                let angle = crate::lie::so3::log(&t.rot).norm();
                let _ = writeln!(
                    s,
                    "  T_cn_cnm1: baseline {:.2} +- {:.2} mm, translation [{:.2}, {:.2}, {:.2}] mm, \
                     rotation {:.3} deg (std {:.3} deg)",
                    1e3 * t.trans.norm(),
                    1e3 * b,
                    1e3 * t.trans.x,
                    1e3 * t.trans.y,
                    1e3 * t.trans.z,
                    angle.to_degrees(),
                    rot.iter().fold(0.0f64, |a, v| a.max(*v)).to_degrees()
                );
            }
        }
        let dropped: Vec<&str> = r
            .frames
            .iter()
            .filter(|f| f.dropped.is_some() && f.rms_px.iter().any(Option::is_some))
            .map(|f| f.name.as_str())
            .collect();
        if !dropped.is_empty() {
            let _ = writeln!(s, "outlier frames dropped: {}", dropped.join(", "));
        }
        for w in &r.warnings {
            let _ = writeln!(s, "warning: {w}");
        }
        if r.chain.cams.len() > 1 {
            let _ = writeln!(s, "note: {}", self.baseline_note());
        }
        s
    }

    /// What a stereo chain calibrated from a board cannot know: the board's printed size. Its
    /// baselines are in the board's units, so a misprinted board scales them by its own error,
    /// and the DVL calibration's stereo check of the board's size, which compares the board with
    /// the baseline, cannot see it.
    pub fn baseline_note(&self) -> String {
        let name = crate::files::file_name_of(&self.target);
        format!(
            "the baselines are measured in units of the board: a board printed at 97 % of the \
             size {name} states gives baselines 3 % short, and no check with these cameras can \
             see it (the DVL calibration's stereo measure of the board compares the board with \
             these baselines); measure a printed tag against tagSize with a ruler"
        )
    }

    /// Whether the calibration has weak points (warnings): then a separate camera recording is
    /// the better source of the camchain.
    pub fn is_weak(&self) -> bool {
        !self.result.warnings.is_empty()
    }

    /// One line on the fit, for a result that used this chain: model, cameras, reprojection
    /// RMS, frames used and detection passes.
    pub fn one_line(&self) -> String {
        let r = &self.result;
        format!(
            "{} model, {} camera{}, reprojection RMS {:.3} px, {} of {} frames used, {} detection \
             pass{}",
            r.model.name(),
            r.chain.cams.len(),
            if r.chain.cams.len() == 1 { "" } else { "s" },
            r.rms_px,
            r.frames.iter().filter(|f| f.dropped.is_none()).count(),
            r.frames.len(),
            self.passes,
            if self.passes == 1 { "" } else { "es" }
        )
    }

    /// Writes the camchain to `path` (its folder is created).
    pub fn write_camchain(&self, path: &Path) -> Result<()> {
        create_parent(path)?;
        write_atomic(path, self.camchain_yaml().as_bytes())
    }

    /// Writes the HTML report to `path` (its folder is created); `camchain` is where the camchain
    /// was written, `command` the command line.
    pub fn write_report(
        &self,
        path: &Path,
        camchain: &Path,
        command: Option<String>,
    ) -> Result<()> {
        create_parent(path)?;
        let input = CamCalReportInput {
            images: self.images.display().to_string(),
            target: self.target.display().to_string(),
            camchain_yaml: self.camchain_yaml(),
            camchain_path: Some(camchain.display().to_string()),
            command,
        };
        let html = render_camcal_html(&self.result, &input)?;
        write_atomic(path, html.as_bytes())
    }

    /// The chain as the DVL calibration reads it.
    pub fn chain(&self) -> &Camchain {
        &self.result.chain
    }
}

fn create_parent(path: &Path) -> Result<()> {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => {
            std::fs::create_dir_all(d).map_err(|e| Error::io(d, e))
        }
        _ => Ok(()),
    }
}
