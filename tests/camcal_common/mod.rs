//! Helpers shared by the camera calibration tests: a stereo calibration sequence rendered and
//! detected, as a person waving a board in front of the rig would record it.
#![allow(dead_code)]

use rayon::prelude::*;

use dvlcal::camcal::FrameTags;
use dvlcal::sim::camcal_views::calibration_views;
use dvlcal::sim::image_dataset::{ImageSimSettings, render_frame};
use dvlcal::vision::board::Board;
use dvlcal::vision::camera::Camchain;
use dvlcal::vision::detect::{Detector, DetectorSettings};

/// `n` stereo frames of `board` seen by `chain` from [`calibration_views`] poses, rendered with the
/// default image settings (blur, noise, vignetting, exposure jitter) and detected without
/// knowledge of the cameras (as for a camera that is yet to be calibrated). Frames are rendered
/// and detected in parallel; the result does not depend on the number of threads. Also returns
/// each camera's image size.
pub fn rendered_views(
    chain: &Camchain,
    board: &Board,
    n: usize,
    seed: u64,
) -> (Vec<FrameTags>, Vec<(u32, u32)>) {
    let poses = calibration_views(chain, board, n, seed);
    let settings = ImageSimSettings {
        seed,
        ..ImageSimSettings::default()
    };
    let detector = DetectorSettings {
        family: board.family,
        ..DetectorSettings::default()
    };
    let frames = poses
        .par_iter()
        .enumerate()
        .map_init(
            || Detector::new(&detector).expect("detector"),
            |det, (k, t)| {
                let images = render_frame(board, chain, t, &settings, k as u64);
                FrameTags {
                    name: format!("view{k:03}"),
                    t_ns: k as i64 * 100_000_000,
                    dets: images
                        .iter()
                        .map(|img| det.detect_with_camera(img, None))
                        .collect(),
                }
            },
        )
        .collect();
    let sizes = chain.cams.iter().map(|c| (c.width, c.height)).collect();
    (frames, sizes)
}
