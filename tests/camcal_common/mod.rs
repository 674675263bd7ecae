//! Helpers shared by the camera calibration tests: a stereo calibration sequence rendered and
//! detected, as a person waving a board in front of the rig would record it.
#![allow(dead_code)]

use rayon::prelude::*;

use dvlcal::camcal::FrameTags;
use dvlcal::sim::camcal_views::calibration_views;
use dvlcal::sim::image_dataset::{ImageSimSettings, render_frame};
use dvlcal::types::board::Board;
use dvlcal::types::camera::Camchain;
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

/// The images of `n` [`calibration_views`] frames (one image per camera), rendered in parallel with
/// the default image settings.
pub fn render_views(
    chain: &Camchain,
    board: &Board,
    n: usize,
    seed: u64,
) -> Vec<Vec<image::GrayImage>> {
    let poses = calibration_views(chain, board, n, seed);
    let settings = ImageSimSettings {
        seed,
        ..ImageSimSettings::default()
    };
    poses
        .par_iter()
        .enumerate()
        .map(|(k, t)| render_frame(board, chain, t, &settings, k as u64))
        .collect()
}

/// The tags of rendered frames, detected in parallel; with `cams`, corners are refined with those
/// camera models (the second pass of a camera calibration).
pub fn detect_views(
    images: &[Vec<image::GrayImage>],
    board: &Board,
    cams: Option<&Camchain>,
) -> Vec<FrameTags> {
    let detector = DetectorSettings {
        family: board.family,
        ..DetectorSettings::default()
    };
    images
        .par_iter()
        .enumerate()
        .map_init(
            || Detector::new(&detector).expect("detector"),
            |det, (k, imgs)| FrameTags {
                name: format!("view{k:03}"),
                t_ns: k as i64 * 100_000_000,
                dets: imgs
                    .iter()
                    .enumerate()
                    .map(|(c, img)| det.detect_with_camera(img, cams.map(|ch| &ch.cams[c])))
                    .collect(),
            },
        )
        .collect()
}

/// A fisheye stereo pair like TUM-VI's (512x512, equidistant, about 190 px focal length, 10 cm
/// baseline).
pub fn fisheye_chain() -> Camchain {
    use dvlcal::lie::{Se3, so3};
    use dvlcal::types::camera::{Camera, Distortion};
    use nalgebra::Vector3;
    let cam = |fu: f64, pu: f64, pv: f64, k: [f64; 4]| Camera {
        fu,
        fv: fu + 0.3,
        pu,
        pv,
        distortion: Distortion::Equidistant {
            k1: k[0],
            k2: k[1],
            k3: k[2],
            k4: k[3],
        },
        width: 512,
        height: 512,
    };
    Camchain {
        cams: vec![
            cam(
                190.98,
                254.93,
                256.90,
                [0.00348, 0.000716, -0.00205, 0.000203],
            ),
            cam(
                190.44,
                252.60,
                254.92,
                [0.00340, 0.001766, -0.00266, 0.000329],
            ),
        ],
        t_cn_c0: vec![
            Se3::identity(),
            Se3::new(
                so3::exp(&Vector3::new(0.004, -0.012, 0.002)),
                Vector3::new(-0.1010, -0.0019, -0.0010),
            ),
        ],
        topics: vec![None, None],
    }
}
