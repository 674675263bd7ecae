//! A short rendered stereo sequence of an AprilTag board with known poses, written in the
//! kalibr_bagcreater layout (DIR/cam0/<t_ns>.png, DIR/cam1/...), with its camchain and target.
//! Shared by tests/vision_pipeline.rs, tests/vision_render.rs, tests/vision_kalibr.rs and
//! benches/detect.rs.

#![allow(dead_code)]

use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Vector3, Vector6};

use dvlcal::io::camchain::camchain_yaml;
use dvlcal::lie::{Se3, so3};
use dvlcal::rng::Rng;
use dvlcal::sim::render::{RenderSettings, render};
use dvlcal::types::board::{Board, TagFamily};
use dvlcal::types::camera::{Camchain, Camera, Distortion};

/// First frame time, ns (an EuRoC-like Unix time with a sub-microsecond part).
pub const T0_NS: i64 = 1_403_636_579_763_555_584;
/// Frame period, ns (10 Hz).
pub const DT_NS: i64 = 100_000_000;

pub fn camera() -> Camera {
    Camera {
        fu: 458.654,
        fv: 457.296,
        pu: 367.215,
        pv: 248.375,
        distortion: Distortion::RadTan {
            k1: -0.28340811,
            k2: 0.07395907,
            p1: 0.00019359,
            p2: 1.76187114e-05,
        },
        width: 752,
        height: 480,
    }
}

/// Stereo pair, cam1 11 cm to the right of cam0.
pub fn chain() -> Camchain {
    let r = so3::exp(&Vector3::new(0.003, -0.008, 0.002));
    Camchain {
        cams: vec![camera(), camera()],
        t_cn_c0: vec![
            Se3::identity(),
            Se3::new(r, r * Vector3::new(-0.11, 0.0, 0.0)),
        ],
        topics: vec![
            Some("/cam0/image_raw".into()),
            Some("/cam1/image_raw".into()),
        ],
    }
}

/// 6 x 6 tag36h11 grid of 8.8 cm tags, Kalibr spacing 0.3.
pub fn board() -> Board {
    Board::grid(TagFamily::Tag36h11, 6, 6, 0.088, 0.3, 0)
}

pub const TARGET_YAML: &str =
    "target_type: 'aprilgrid'\ntagCols: 6\ntagRows: 6\ntagSize: 0.088\ntagSpacing: 0.3\n";

/// `T_board_cam0` of frame `k`: the camera 0.9..1.3 m from the board, swinging around it.
pub fn pose(k: usize) -> Se3 {
    let s = k as f64;
    let r0 = Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0);
    let tilt = so3::exp(&Vector3::new(
        0.25 * (0.7 * s).sin(),
        0.3 * (0.5 * s + 1.0).sin(),
        0.2 * (0.3 * s).cos(),
    ));
    let r = r0 * tilt;
    let centre = Vector3::new(
        0.33 + 0.05 * (0.9 * s).sin(),
        0.33 + 0.04 * (1.3 * s).cos(),
        0.0,
    );
    let dist = 1.1 + 0.2 * (0.4 * s).sin();
    Se3::new(r, centre - r * Vector3::new(0.0, 0.0, dist))
}

/// Renders `n` stereo frames into `dir` (created), with the camchain and target YAML beside the
/// image folders. Returns the true `T_board_cam0` per frame and the frame times (ns).
pub fn write_sequence(
    dir: &Path,
    n: usize,
    settings: &RenderSettings,
    seed: u64,
) -> (Vec<Se3>, Vec<i64>) {
    write_sequence_of(dir, n, settings, seed, &board())
}

/// [`write_sequence`] of another printing of the same board geometry (tags drawn as
/// libapriltag draws them, or as Kalibr prints them).
pub fn write_sequence_of(
    dir: &Path,
    n: usize,
    settings: &RenderSettings,
    seed: u64,
    board: &Board,
) -> (Vec<Se3>, Vec<i64>) {
    let chain = chain();
    let mut rng = Rng::new(seed);
    let mut poses = Vec::new();
    let mut times = Vec::new();
    for c in 0..2 {
        std::fs::create_dir_all(dir.join(format!("cam{c}"))).unwrap();
    }
    for k in 0..n {
        let t_b_c0 = pose(k);
        let t_ns = T0_NS + k as i64 * DT_NS;
        for c in 0..2 {
            let t_cn_b = chain.t_cn_c0[c] * t_b_c0.inverse();
            let img = render(board, &chain.cams[c], &t_cn_b, settings, &mut rng);
            img.save(image_path(dir, c, t_ns)).unwrap();
        }
        poses.push(t_b_c0);
        times.push(t_ns);
    }
    std::fs::write(dir.join("camchain.yaml"), camchain_yaml(&chain)).unwrap();
    std::fs::write(dir.join("target.yaml"), TARGET_YAML).unwrap();
    (poses, times)
}

pub fn image_path(dir: &Path, cam: usize, t_ns: i64) -> PathBuf {
    dir.join(format!("cam{cam}")).join(format!("{t_ns}.png"))
}

/// A fresh, empty folder under the system's temporary folder.
pub fn fresh_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("dvlcal-vision-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The board upright in front of the camera at `dist` m, centred, turned by `tilt` (rotation
/// vector, board frame).
pub fn facing(board: &Board, dist: f64, tilt: Vector3<f64>) -> Se3 {
    let (mut lo, mut hi) = (Vector3::repeat(f64::MAX), Vector3::repeat(f64::MIN));
    for t in &board.tags {
        for c in &t.corners {
            lo = lo.inf(c);
            hi = hi.sup(c);
        }
    }
    let centre = (lo + hi) / 2.0;
    let upright = Se3::new(
        Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0)),
        Vector3::new(0.0, 0.0, dist),
    );
    let turn = Se3::exp(&Vector6::new(0.0, 0.0, 0.0, tilt.x, tilt.y, tilt.z));
    upright * turn * Se3::new(Matrix3::identity(), -centre)
}
