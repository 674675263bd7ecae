//! What a report is made from: the calibration outcome, the poses, the DVL log's counts, the
//! image statistics of a run and the IMU calibrated beside the DVL.

use crate::calib::CalibrationOutcome;
use crate::calib::diagnostics::ImuVerdicts;
use crate::calib::imu::ImuEstimate;
use crate::io::dvl::DvlLogStats;
use crate::time::Epoch;
use crate::types::PoseMeasurement;
use crate::vision::frames::{FrameResult, FrameStatus};
use crate::vision::pnp::CornerResidual;

/// One image frame of a `--images` run.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameStat {
    /// Camera time, seconds relative to the dataset epoch.
    pub t: f64,
    /// Whether the frame got a pose.
    pub posed: bool,
    /// Tags detected over all of the frame's images.
    pub tags_detected: usize,
    /// Tag observations used by the pose (0 without a pose).
    pub tags_used: usize,
    /// Reprojection RMS of the pose, pixels.
    pub rms_px: Option<f64>,
    /// Reprojection RMS of each camera's corners, pixels (empty without a pose; `None` for a
    /// camera without used corners).
    pub rms_px_per_cam: Vec<Option<f64>>,
    /// An evenly drawn sample of the pose's corner residuals (see
    /// [`crate::vision::pnp::FramePose::corner_sample`]).
    pub corners: Vec<CornerResidual>,
    /// The width of the sharpest edges of the frame's images, px (their mean over the cameras;
    /// see [`crate::vision::sharpness`]); `None` when not measured.
    pub edge_width_px: Option<f64>,
    /// Why the frame got no pose (`None` for a posed frame).
    pub dropped: Option<FrameDrop>,
}

/// Why a frame got no pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FrameDrop {
    /// None of its images could be read, or all had the wrong size.
    Unreadable,
    /// Its images are blurred (motion or focus): their sharpest edges are clearly wider than
    /// the posed frames' ([`BLUR_FACTOR`]), or than [`BLURRED_EDGE_PX`] when no frame got a pose.
    Blurred,
    /// No tag was found in its images (the board out of view, too far, or too dark).
    NoTags,
    /// Tags were found, but too few of the board's corners for a pose.
    TooFewCorners,
    /// The pose could not be solved (degenerate geometry, a corner behind a camera).
    NoSolution,
}

/// An unposed frame is blurred when its edges are this many times as wide as the posed frames'
/// median (and at least [`BLUR_MARGIN_PX`] wider).
pub const BLUR_FACTOR: f64 = 1.5;

/// ... see [`BLUR_FACTOR`].
pub const BLUR_MARGIN_PX: f64 = 0.75;

/// Edge width beyond which an unposed frame is blurred when no frame got a pose to compare
/// with, px.
pub const BLURRED_EDGE_PX: f64 = 2.5;

/// The median edge width of the posed frames, px.
pub fn posed_edge_width_px(frames: &[FrameStat]) -> Option<f64> {
    let mut w: Vec<f64> = frames
        .iter()
        .filter(|f| f.posed)
        .filter_map(|f| f.edge_width_px)
        .filter(|w| w.is_finite())
        .collect();
    if w.is_empty() {
        return None;
    }
    w.sort_by(f64::total_cmp);
    Some(w[w.len() / 2])
}

/// Per-frame statistics of the detection pipeline's results, on the epoch of the poses, each
/// unposed frame with the reason it got no pose.
pub fn frame_stats(results: &[FrameResult], epoch: &Epoch) -> Vec<FrameStat> {
    let mut stats: Vec<FrameStat> = results
        .iter()
        .map(|r| FrameStat {
            t: epoch.rel(crate::io::images::raw_time(r.frame.t_ns)),
            posed: r.status == FrameStatus::Posed && r.pose.is_some(),
            tags_detected: r.tags_detected.iter().sum(),
            tags_used: r.pose.as_ref().map_or(0, |p| p.tags_used),
            rms_px: r.pose.as_ref().map(|p| p.rms_px),
            rms_px_per_cam: r
                .pose
                .as_ref()
                .map(|p| p.rms_px_per_cam.clone())
                .unwrap_or_default(),
            corners: r
                .pose
                .as_ref()
                .map(|p| p.corner_sample.clone())
                .unwrap_or_default(),
            edge_width_px: mean(r.edge_width_px.iter().flatten().copied()),
            dropped: None,
        })
        .collect();
    let posed = posed_edge_width_px(&stats);
    for (f, r) in stats.iter_mut().zip(results) {
        if f.posed {
            continue;
        }
        let blurred = match (f.edge_width_px, posed) {
            (Some(w), Some(m)) => w > (BLUR_FACTOR * m).max(m + BLUR_MARGIN_PX),
            (Some(w), None) => w > BLURRED_EDGE_PX,
            (None, _) => false,
        };
        f.dropped = Some(match r.status {
            FrameStatus::NoImage => FrameDrop::Unreadable,
            _ if blurred => FrameDrop::Blurred,
            _ if f.tags_detected == 0 => FrameDrop::NoTags,
            FrameStatus::NoSolution => FrameDrop::NoSolution,
            // A frame marked posed without a pose has none to use either.
            FrameStatus::TooFewCorners | FrameStatus::Posed => FrameDrop::TooFewCorners,
        });
    }
    stats
}

fn mean(x: impl Iterator<Item = f64>) -> Option<f64> {
    let (n, s) = x.fold((0usize, 0.0), |(n, s), v| (n + 1, s + v));
    (n > 0).then(|| s / n as f64)
}

/// Everything the report shows.
#[derive(Clone, Debug)]
pub struct ReportInput<'a> {
    /// Page title.
    pub title: &'a str,
    /// What was calibrated, in words (e.g. the input file names).
    pub dataset: &'a str,
    /// The calibration run reported on.
    pub outcome: &'a CalibrationOutcome,
    /// The camera poses the calibration used.
    pub poses: &'a [PoseMeasurement],
    /// The DVL log's counts, when read from a file.
    pub dvl_stats: Option<&'a DvlLogStats>,
    /// Per-frame detection statistics, for runs from images.
    pub frames: Option<&'a [FrameStat]>,
    /// Name of the result file and its text.
    pub result_name: Option<&'a str>,
    /// The result file's YAML text.
    pub result_yaml: Option<&'a str>,
    /// Wall time of the calibration, seconds.
    pub elapsed_s: Option<f64>,
    /// Image size (width, height) of each camera, pixels, for runs from images.
    pub image_sizes: Option<&'a [(u32, u32)]>,
    /// The IMU calibrated against the camera in the same run, when there is one.
    pub imu: Option<ImuReportInput<'a>>,
}

/// An IMU calibrated against the camera, as the report shows it.
#[derive(Clone, Copy, Debug)]
pub struct ImuReportInput<'a> {
    /// The estimate: `T_cam_imu`, the clock offset, gravity, biases, covariance, noise factors.
    pub estimate: &'a ImuEstimate,
    /// Its verdicts and the motion they were made from.
    pub verdicts: &'a ImuVerdicts,
}

impl<'a> ReportInput<'a> {
    /// A report of `outcome` with nothing else known.
    pub fn new(outcome: &'a CalibrationOutcome, poses: &'a [PoseMeasurement]) -> ReportInput<'a> {
        ReportInput {
            title: "DVL calibration report",
            dataset: "",
            outcome,
            poses,
            dvl_stats: None,
            frames: None,
            result_name: None,
            result_yaml: None,
            elapsed_s: None,
            image_sizes: None,
            imu: None,
        }
    }
}
