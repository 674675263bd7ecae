//! Image datasets of `dvlcal simulate --images`: the board-view motion keeps the board in view, and
//! the written images, camchain and target are complete and usable.

use std::path::{Path, PathBuf};
use std::process::Command;

use dvlcal::io::camchain::read_camchain;
use dvlcal::io::image::load_gray;
use dvlcal::io::images::scan_images;
use dvlcal::io::target::read_board;
use dvlcal::lie::Se3;
use dvlcal::sim::dataset::{MotionKind, SimConfig, simulate};
use dvlcal::sim::image_dataset::{
    DEFAULT_BOARD_DISTANCE_M, board_centre, board_facing, board_fully_visible, board_in_cameras,
    default_board, default_stereo_camchain,
};
use dvlcal::vision::detect::{Detector, DetectorSettings};
use dvlcal::vision::frames::detect_poses;
use dvlcal::vision::pnp::PnpOptions;

struct TempDir(PathBuf);

impl TempDir {
    fn new(name: &str) -> TempDir {
        let p =
            std::env::temp_dir().join(format!("dvlcal_vision_sim_{}_{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).unwrap();
        TempDir(p)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[test]
fn board_view_motion_keeps_the_board_in_view() {
    let cfg = SimConfig {
        motion: MotionKind::BoardView,
        duration_s: 60.0,
        ..SimConfig::default()
    };
    let ds = simulate(&cfg).unwrap();
    let board = default_board();
    let chain = default_stereo_camchain();
    let t_world_board = board_facing(&ds.truth_poses[0].pose, &board, DEFAULT_BOARD_DISTANCE_M);
    let centre = board_centre(&board);
    let margin = 60.0;
    let (mut w_calm, mut w_max, mut d_min, mut d_max) = (0.0f64, 0.0f64, f64::MAX, 0.0f64);
    for (p, s) in ds.poses.iter().zip(&ds.truth_poses) {
        let t_board_cam0 = t_world_board.inverse() * s.pose;
        for (i, (cam, t_cam_board)) in chain
            .cams
            .iter()
            .zip(board_in_cameras(&chain, &t_board_cam0))
            .enumerate()
        {
            let c = t_cam_board.transform_point(&centre);
            d_min = d_min.min(c.norm());
            d_max = d_max.max(c.norm());
            let px = cam.project(&c).expect("board centre behind the camera");
            assert!(
                px.x > margin
                    && px.y > margin
                    && px.x < cam.width as f64 - margin
                    && px.y < cam.height as f64 - margin,
                "t = {} s, cam{i}: board centre at {px:?}",
                p.t
            );
            assert!(
                board_fully_visible(&board, cam, &t_cam_board),
                "t = {} s, cam{i}",
                p.t
            );
        }
        let w = s.twist.fixed_rows::<3>(3).norm();
        if p.t < 0.5 * cfg.duration_s {
            w_calm = w_calm.max(w);
        }
        w_max = w_max.max(w);
    }
    assert!(w_calm < 1e-9, "rotation in the calm part: {w_calm}");
    assert!((1.0..3.0).contains(&w_max), "peak rotation rate {w_max}");
    assert!(
        d_min > 1.5 && d_max < 2.5,
        "board distance {d_min}..{d_max}"
    );
}

fn dvlcal(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_dvlcal"))
        .args(args)
        .output()
        .expect("running dvlcal")
}

fn png_times(dir: &Path) -> Vec<i64> {
    let mut t: Vec<i64> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let name = e.unwrap().file_name().into_string().unwrap();
            let stem = name
                .strip_suffix(".png")
                .unwrap_or_else(|| panic!("not a PNG: {name}"));
            stem.parse()
                .unwrap_or_else(|_| panic!("not a time stamp: {name}"))
        })
        .collect();
    t.sort();
    t
}

/// `(t_ns, pose)` rows of a TUM file written by dvlcal (nine decimals).
fn read_tum(path: &Path) -> Vec<(i64, Se3)> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            let (sec, frac) = f[0].split_once('.').unwrap();
            let t_ns = sec.parse::<i64>().unwrap() * 1_000_000_000 + frac.parse::<i64>().unwrap();
            let v: Vec<f64> = f[1..].iter().map(|x| x.parse().unwrap()).collect();
            let pose = Se3::from_quaternion_xyzw(
                &[v[3], v[4], v[5], v[6]],
                nalgebra::Vector3::new(v[0], v[1], v[2]),
            );
            (t_ns, pose)
        })
        .collect()
}

#[test]
fn simulate_images_writes_a_usable_dataset() {
    let tmp = TempDir::new("images");
    let out = tmp.0.join("ds");
    let o = out.to_str().unwrap();
    let res = dvlcal(&[
        "simulate",
        "--out",
        o,
        "--images",
        "--duration",
        "3",
        "--camera-rate",
        "2",
        "--supersample",
        "2",
    ]);
    assert!(
        res.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&res.stdout),
        String::from_utf8_lossy(&res.stderr)
    );
    for f in [
        "dvl.jsonl",
        "camchain.yaml",
        "target.yaml",
        "truth/poses.txt",
        "truth/poses_noisy.txt",
        "truth/calibration.yaml",
        "truth/poses_board.txt",
        "truth/board_in_world.txt",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    // With images the camera data are the images: no pose file competes with them.
    assert!(!out.join("poses.txt").exists());
    let t0 = png_times(&out.join("cam0"));
    let t1 = png_times(&out.join("cam1"));
    let expected: Vec<i64> = (0..7)
        .map(|k| 1_700_000_000_000_000_000 + k * 500_000_000)
        .collect();
    assert_eq!(t0, expected);
    assert_eq!(t1, expected);

    let chain = read_camchain(&out.join("camchain.yaml")).unwrap();
    let want = default_stereo_camchain();
    assert_eq!(chain.cams, want.cams);
    for (a, b) in chain.t_cn_c0.iter().zip(&want.t_cn_c0) {
        assert!((a.to_matrix() - b.to_matrix()).abs().max() < 1e-12);
    }
    let board = read_board(&out.join("target.yaml")).unwrap();
    assert_eq!(board.tags, default_board().tags);

    let first = out.join("cam0").join(format!("{}.png", t0[0]));
    let img = load_gray(&first).unwrap();
    assert_eq!(img.dimensions(), (752, 480));
    let mut det = Detector::new(&DetectorSettings::default()).unwrap();
    let dets = det.detect(&img);
    assert!(
        dets.len() >= 30,
        "{} of 36 tags detected in {}",
        dets.len(),
        first.display()
    );

    // The detection pipeline recovers the truth poses (frames agree end to end).
    let (frames, _) = scan_images(&out, 2, 2_000_000).unwrap();
    assert_eq!(frames.len(), 7);
    let (posed, _) = detect_poses(
        &frames,
        &board,
        &chain,
        &DetectorSettings::default(),
        &PnpOptions::default(),
        false,
    );
    let truth = read_tum(&out.join("truth").join("poses_board.txt"));
    for ((frame, pose), (t_ns, want)) in posed.iter().zip(&truth) {
        assert_eq!(frame.t_ns, *t_ns);
        let got = pose.as_ref().expect("frame without a pose").t_board_cam0;
        let d = (want.inverse() * got).log();
        let (dt, dr) = (d.fixed_rows::<3>(0).norm(), d.fixed_rows::<3>(3).norm());
        assert!(
            dt < 0.02 && dr < 0.01,
            "t_ns {t_ns}: error {dt} m, {dr} rad"
        );
    }

    // The truth pose of the first frame: the board 1.8 m straight ahead, upright.
    let line = std::fs::read_to_string(out.join("truth").join("poses_board.txt")).unwrap();
    let v: Vec<f64> = line
        .lines()
        .find(|l| !l.starts_with('#'))
        .unwrap()
        .split_whitespace()
        .map(|x| x.parse().unwrap())
        .collect();
    let c = board_centre(&board);
    let expected = [
        1_700_000_000.0,
        c.x,
        c.y,
        DEFAULT_BOARD_DISTANCE_M,
        1.0,
        0.0,
        0.0,
        0.0,
    ];
    for (a, b) in v.iter().zip(expected) {
        assert!((a - b).abs() < 1e-9, "{v:?}");
    }
}
