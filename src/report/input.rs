//! What a report is made from: the calibration outcome, the poses, the DVL log's counts and the
//! image statistics of a run.

use crate::calib::CalibrationOutcome;
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
}

/// Per-frame statistics of the detection pipeline's results, on the epoch of the poses.
pub fn frame_stats(results: &[FrameResult], epoch: &Epoch) -> Vec<FrameStat> {
    results
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
        })
        .collect()
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
        }
    }
}
