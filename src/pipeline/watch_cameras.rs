//! The camera model of a watched recording that has images but no camchain
//! ([`super::watch`]). `calibrate` calibrates the cameras from all the images before it solves
//! their poses; an update that did so at every update would repeat a bundle adjustment over a
//! growing set of images, and detect every image again with each new model (the detections are
//! kept per model). So the watch keeps the camera calibration it made and solves the later
//! updates' poses with it ([`super::Dataset::load_reusing_cameras`]), and calibrates again only
//! when the images it could use have grown enough to be worth it:
//!
//! - the first calibration is made by the first update whose images can be calibrated (as
//!   `calibrate` would calibrate them; until then the updates say `not yet`);
//! - it is made again when the frames with a board pose number at least [`GROWTH`] times those
//!   the kept model was calibrated with, or [`GROWTH_WEAK`] times when that calibration was
//!   weak ([`CameraCalRun::is_weak`]: its warnings, such as the board covering little of the
//!   image, may go with more views), and in both cases at least [`MIN_NEW_FRAMES`] more.
//!
//! So a recording of `n` frames is calibrated some `log(n / n0) / log(1.5)` times over the
//! watch instead of once per update. The final result is not made from the kept model: once the
//! watch is over, `calibrate` runs on the finished recording and calibrates the cameras from
//! all its images.

use serde::Serialize;

use super::cameras::CameraCalRun;
use super::dataset::Dataset;

/// The growth of the frames with a board pose over those of the kept calibration that makes an
/// update calibrate the cameras again.
pub const GROWTH: f64 = 1.5;

/// [`GROWTH`] when the kept calibration is weak.
pub const GROWTH_WEAK: f64 = 1.25;

/// The fewest new frames with a board pose that make an update calibrate the cameras again.
pub const MIN_NEW_FRAMES: usize = 10;

/// Where an update's camera model came from (`cameras.model` in `dvlcal watch --json`).
#[derive(Clone, Copy, Debug, Serialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum CameraModelSource {
    /// This update calibrated the cameras from the images so far.
    Calibrated,
    /// This update solved the poses with the model an earlier update calibrated.
    Reused,
}

/// The camera model an update solved the poses with, when the recording has images but no
/// camchain (`cameras` in `dvlcal watch --json`; `null` with a camchain or a pose file).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct CameraModel {
    /// Calibrated by this update, or reused from an earlier one.
    pub model: CameraModelSource,
    /// The update that calibrated it.
    pub calibrated_in_update: usize,
    /// The frames with a board pose when it was calibrated.
    pub calibrated_frames: usize,
    /// Whether that calibration is weak (it has warnings).
    pub weak: bool,
    /// The frames with a board pose in this update.
    pub frames: usize,
    /// Why this update, due to calibrate the cameras again, kept the earlier model: that
    /// calibration failed (the next update tries again).
    pub recalibration_failed: Option<String>,
}

/// The camera calibration a watch keeps between its updates.
#[derive(Debug)]
struct Kept {
    run: CameraCalRun,
    /// The frames with a board pose when it was made.
    frames: usize,
    /// The update that made it.
    update: usize,
}

/// The camera model of a watch: the calibration kept and the count of those made.
#[derive(Debug, Default)]
pub(super) struct WatchCameras {
    kept: Option<Kept>,
    calibrations: usize,
}

/// The frames of `data` with a board pose (0 without images).
fn posed_frames(data: &Dataset) -> usize {
    data.vision.as_ref().map_or(0, |v| v.poses.len())
}

impl WatchCameras {
    /// The calibration to solve the next update's poses with, once one was made.
    pub(super) fn model(&self) -> Option<&CameraCalRun> {
        self.kept.as_ref().map(|k| &k.run)
    }

    /// Camera calibrations made so far by the updates.
    pub(super) fn calibrations(&self) -> usize {
        self.calibrations
    }

    /// Whether `data`, loaded with the kept model, has enough more frames with a board pose
    /// to calibrate the cameras again (the rule in the module's documentation).
    pub(super) fn outgrown(&self, data: &Dataset) -> bool {
        let Some(k) = self.kept.as_ref().filter(|_| data.cameras_reused) else {
            return false;
        };
        let now = posed_frames(data);
        let growth = if k.run.is_weak() { GROWTH_WEAK } else { GROWTH };
        now >= k.frames + MIN_NEW_FRAMES && now as f64 >= growth * k.frames as f64
    }

    /// Takes in the camera model `data` (update `update`) was solved with: a calibration made
    /// by this update is kept for the next ones. `failed` is why a calibration due this update
    /// failed. `None` when `data` has no camera calibration (a camchain, a pose file).
    pub(super) fn record(
        &mut self,
        data: &Dataset,
        update: usize,
        failed: Option<String>,
    ) -> Option<CameraModel> {
        let run = data.cameras.as_ref()?;
        let frames = posed_frames(data);
        let model = if data.cameras_reused {
            CameraModelSource::Reused
        } else {
            self.calibrations += 1;
            self.kept = Some(Kept {
                run: run.clone(),
                frames,
                update,
            });
            CameraModelSource::Calibrated
        };
        let (calibrated_in_update, calibrated_frames) = self
            .kept
            .as_ref()
            .map_or((update, frames), |k| (k.update, k.frames));
        Some(CameraModel {
            model,
            calibrated_in_update,
            calibrated_frames,
            weak: run.is_weak(),
            frames,
            recalibration_failed: failed,
        })
    }
}

impl CameraModel {
    /// The model in one line, for the update's text view.
    pub fn words(&self) -> String {
        let weak = if self.weak { ", weak" } else { "" };
        let mut s = match self.model {
            CameraModelSource::Calibrated => format!(
                "cameras calibrated from the {} frames with a board pose{weak}",
                self.calibrated_frames
            ),
            CameraModelSource::Reused => format!(
                "cameras as calibrated in update {} from {} frames{weak}, reused for {} frames",
                self.calibrated_in_update, self.calibrated_frames, self.frames
            ),
        };
        if let Some(why) = &self.recalibration_failed {
            s.push_str(&format!(" (calibrating them again failed: {why})"));
        }
        s
    }
}
