//! Image datasets with known truth: what a stereo camera sees of a board along a simulated motion.
//!
//! # Frames
//!
//! - `world`: the frame of the simulated camera poses `T_world_cam0` (the motion's frame).
//! - `board`: the board's own frame (Kalibr's, see [`crate::types::board`]); it is fixed in the
//!   world at `T_world_board`.
//! - `cam0`, `cam1`: the cameras; `T_c1_c0` comes from the camchain (`Camchain::t_cn_c0[1]`).
//!
//! Camera `n` sees the board at `T_cn_board = T_cn_c0 T_world_cam0^-1 T_world_board`, and the pose a
//! board-based pose estimator should recover from the images is
//! `T_board_cam0 = T_world_board^-1 T_world_cam0`.
//!
//! # Images
//!
//! Each stereo frame `k` draws from its own stream of the seed (so the frames can be rendered in
//! any order, in parallel, and still come out bit-identical): first one exposure gain per camera,
//! `exposure (1 + u)` with `u` uniform in `[-exposure_jitter, exposure_jitter]`, then the
//! renderer's noise of cam0, then of cam1.

use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use image::GrayImage;
use nalgebra::{Matrix3, Vector3};

use crate::error::{Error, Result};
use crate::lie::{Se3, so3};
use crate::rng::Rng;
use crate::sim::render::{RenderSettings, render};
use crate::types::board::{Board, TagFamily};
use crate::types::camera::{Camchain, Camera, Distortion};

/// First stream number of the per-frame image streams (frame `k` uses `IMAGE_STREAM_BASE + k`);
/// far from the motion and dataset noise streams.
pub const IMAGE_STREAM_BASE: u64 = 1 << 32;

/// Default distance from the starting camera to the board centre, metres.
pub const DEFAULT_BOARD_DISTANCE_M: f64 = 1.8;

/// A stereo pair like the common 752x480 global-shutter rigs: radial-tangential distortion,
/// 0.11 m baseline (cam1 to the right of cam0), a few milliradians of relative rotation.
pub fn default_stereo_camchain() -> Camchain {
    let cam0 = Camera {
        fu: 458.0,
        fv: 457.0,
        pu: 367.5,
        pv: 248.5,
        distortion: Distortion::RadTan {
            k1: -0.28,
            k2: 0.074,
            p1: 2.0e-4,
            p2: 1.8e-5,
        },
        width: 752,
        height: 480,
    };
    let cam1 = Camera {
        fu: 457.5,
        fv: 456.2,
        pu: 379.0,
        pv: 255.2,
        distortion: Distortion::RadTan {
            k1: -0.284,
            k2: 0.076,
            p1: -1.0e-4,
            p2: -8.0e-5,
        },
        width: 752,
        height: 480,
    };
    // cam0's origin lies 0.11 m to the left of cam1 (negative x in cam1).
    let t_c1_c0 = Se3::new(
        so3::exp(&Vector3::new(0.002, -0.003, 0.001)),
        Vector3::new(-0.11, 0.0004, -0.0008),
    );
    Camchain {
        cams: vec![cam0, cam1],
        t_cn_c0: vec![Se3::identity(), t_c1_c0],
        topics: vec![
            Some("/cam0/image_raw".into()),
            Some("/cam1/image_raw".into()),
        ],
    }
}

/// The default board: Kalibr's 6x6 tag36h11 aprilgrid geometry (88 mm tags, spacing 0.3; about
/// 0.66 m square), as `calib_boards/kalibr_aprilgrid_6x6.yaml` describes it.
pub fn default_board() -> Board {
    Board::grid(TagFamily::Tag36h11, 6, 6, 0.088, 0.3, 0)
}

/// The centre of the board's tags (mean of all tag corners), board frame.
pub fn board_centre(board: &Board) -> Vector3<f64> {
    let n = board.tags.len() * 4;
    if n == 0 {
        return Vector3::zeros();
    }
    let sum: Vector3<f64> = board.tags.iter().flat_map(|t| t.corners.iter()).sum();
    sum / n as f64
}

/// `T_world_board` of a board facing the camera at `t_world_cam`: its centre on the optical axis
/// at `distance_m`, its z axis pointing back at the camera, its x axis along the camera's x and its
/// y axis along the camera's -y (so that the tags appear upright).
pub fn board_facing(t_world_cam: &Se3, board: &Board, distance_m: f64) -> Se3 {
    let r_cam_board = Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0));
    let t_cam_board = Se3::new(
        r_cam_board,
        Vector3::new(0.0, 0.0, distance_m) - r_cam_board * board_centre(board),
    );
    t_world_cam * &t_cam_board
}

/// `T_cn_board` for every camera of the chain, given `T_board_cam0`.
pub fn board_in_cameras(chain: &Camchain, t_board_cam0: &Se3) -> Vec<Se3> {
    let t_c0_board = t_board_cam0.inverse();
    chain.t_cn_c0.iter().map(|t| t * &t_c0_board).collect()
}

/// How the images of a dataset are formed.
#[derive(Clone, Debug)]
pub struct ImageSimSettings {
    /// Blur, noise, vignetting, supersampling and the mean exposure.
    pub render: RenderSettings,
    /// Relative half-width of the per-image exposure change (0.1: gains within +-10 %).
    pub exposure_jitter: f64,
    /// Seed of the per-frame streams (use the dataset's seed).
    pub seed: u64,
    /// Worker threads rendering frames (0: one per available core).
    pub threads: usize,
    /// Write JPEG files of this quality (1..=100) instead of PNG, for compact datasets.
    pub jpeg_quality: Option<u8>,
}

impl Default for ImageSimSettings {
    fn default() -> Self {
        ImageSimSettings {
            render: RenderSettings::default(),
            exposure_jitter: 0.1,
            seed: 1,
            threads: 0,
            jpeg_quality: None,
        }
    }
}

/// Renders stereo frame number `frame` (which selects its random stream) of every camera of
/// `chain`, with the board at `T_board_cam0`.
pub fn render_frame(
    board: &Board,
    chain: &Camchain,
    t_board_cam0: &Se3,
    s: &ImageSimSettings,
    frame: u64,
) -> Vec<GrayImage> {
    let mut rng = Rng::stream(s.seed, IMAGE_STREAM_BASE.wrapping_add(frame));
    let j = s.exposure_jitter.abs();
    let gains: Vec<f64> = chain
        .cams
        .iter()
        .map(|_| s.render.exposure * (1.0 + rng.uniform_in(-j, j)))
        .collect();
    chain
        .cams
        .iter()
        .zip(board_in_cameras(chain, t_board_cam0))
        .zip(gains)
        .map(|((cam, t_cam_board), gain)| {
            let settings = RenderSettings {
                exposure: gain,
                ..s.render.clone()
            };
            render(board, cam, &t_cam_board, &settings, &mut rng)
        })
        .collect()
}

/// One stereo frame to render: absolute time stamp (file name) and the truth pose.
#[derive(Clone, Copy, Debug)]
pub struct FrameSpec {
    /// Absolute time, nanoseconds (Unix time for simulated datasets).
    pub t_ns: i64,
    /// `T_board_cam0`.
    pub t_board_cam0: Se3,
}

/// What [`write_image_dataset`] did.
#[derive(Clone, Debug, Default)]
pub struct ImageSimStats {
    /// Stereo frames rendered.
    pub frames: usize,
    /// Images written (frames times cameras).
    pub images: usize,
    /// Per camera: frames in which every tag corner projects into the image.
    pub board_fully_visible: Vec<usize>,
    /// Wall-clock time spent rendering and writing, seconds.
    pub seconds: f64,
}

/// Whether every tag corner of the board projects into `cam`'s image at `T_cam_board`.
pub fn board_fully_visible(board: &Board, cam: &Camera, t_cam_board: &Se3) -> bool {
    board.tags.iter().flat_map(|t| t.corners.iter()).all(|c| {
        cam.project(&t_cam_board.transform_point(c))
            .is_some_and(|px| cam.in_image(&px))
    })
}

/// Writes `dir/<t_ns>.png`, or `.jpg` with a quality.
fn save_image(
    img: &image::GrayImage,
    dir: &Path,
    t_ns: i64,
    jpeg_quality: Option<u8>,
) -> (std::path::PathBuf, std::result::Result<(), String>) {
    match jpeg_quality {
        None => {
            let path = dir.join(format!("{t_ns}.png"));
            let r = img
                .save_with_format(&path, image::ImageFormat::Png)
                .map_err(|e| e.to_string());
            (path, r)
        }
        Some(q) => {
            let path = dir.join(format!("{t_ns}.jpg"));
            let r = std::fs::File::create(&path)
                .map_err(|e| e.to_string())
                .and_then(|f| {
                    let mut w = std::io::BufWriter::new(f);
                    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut w, q.clamp(1, 100))
                        .encode_image(img)
                        .map_err(|e| e.to_string())?;
                    std::io::Write::flush(&mut w).map_err(|e| e.to_string())
                });
            (path, r)
        }
    }
}

/// Renders every frame of `frames` into `dir/camN/<t_ns>.png` (or `.jpg`) (the folders are created), in
/// parallel over frames; the files do not depend on the number of threads. `progress(done,
/// total)` is called from the worker threads after each frame.
pub fn write_image_dataset(
    dir: &Path,
    board: &Board,
    chain: &Camchain,
    frames: &[FrameSpec],
    s: &ImageSimSettings,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<ImageSimStats> {
    let start = std::time::Instant::now();
    let cam_dirs: Vec<PathBuf> = (0..chain.cams.len())
        .map(|i| dir.join(format!("cam{i}")))
        .collect();
    for d in &cam_dirs {
        std::fs::create_dir_all(d).map_err(|e| Error::io(d, e))?;
    }
    let threads = if s.threads == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        s.threads.min(crate::parallel::thread_limit())
    }
    .clamp(1, frames.len().max(1));
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let failed = AtomicBool::new(false);
    let first_error: Mutex<Option<(usize, Error)>> = Mutex::new(None);
    let visible: Mutex<Vec<usize>> = Mutex::new(vec![0; chain.cams.len()]);
    std::thread::scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|| {
                loop {
                    if failed.load(Ordering::Relaxed) {
                        break;
                    }
                    let k = next.fetch_add(1, Ordering::Relaxed);
                    let Some(f) = frames.get(k) else { break };
                    let images = render_frame(board, chain, &f.t_board_cam0, s, k as u64);
                    let seen: Vec<bool> = chain
                        .cams
                        .iter()
                        .zip(board_in_cameras(chain, &f.t_board_cam0))
                        .map(|(cam, t)| board_fully_visible(board, cam, &t))
                        .collect();
                    for (img, d) in images.iter().zip(&cam_dirs) {
                        let (path, saved) = save_image(img, d, f.t_ns, s.jpeg_quality);
                        if let Err(e) = saved {
                            failed.store(true, Ordering::Relaxed);
                            let err = Error::Input(format!("{}: {e}", path.display()));
                            if let Ok(mut slot) = first_error.lock() {
                                if slot.as_ref().is_none_or(|(j, _)| k < *j) {
                                    *slot = Some((k, err));
                                }
                            }
                            return;
                        }
                    }
                    if let Ok(mut v) = visible.lock() {
                        for (n, seen_n) in v.iter_mut().zip(&seen) {
                            *n += usize::from(*seen_n);
                        }
                    }
                    let n = done.fetch_add(1, Ordering::Relaxed) + 1;
                    progress(n, frames.len());
                }
            });
        }
    });
    if let Some((_, e)) = first_error.into_inner().ok().flatten() {
        return Err(e);
    }
    Ok(ImageSimStats {
        frames: frames.len(),
        images: frames.len() * chain.cams.len(),
        board_fully_visible: visible.into_inner().unwrap_or_default(),
        seconds: start.elapsed().as_secs_f64(),
    })
}
