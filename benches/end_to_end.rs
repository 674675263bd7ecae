//! Accuracy of the whole image pipeline over many seeds: a simulated recording (board-view
//! motion) rendered as 752x480 stereo images, AprilTag detection, stereo PnP with covariances,
//! then UIC, compared with the truth.
//!
//! `cargo bench --bench end_to_end [-- SEEDS DURATION_S [poses]]` (default 12 seeds of 30 s;
//! `poses` or `poses:SIGMA` skips the images and calibrates from the simulator's noisy poses
//! (default 2 mm / 2 mrad), to separate the vision's share of the errors from the motion's). Prints a
//! table: per parameter the RMSE over the seeds, the mean reported standard deviation, and the RMS
//! of error / std (1 for honest uncertainties), each with a 95 % percentile-bootstrap interval;
//! and the mean NEES of the 8 parameters (expectation 8).

use std::path::PathBuf;
use std::time::Instant;

use nalgebra::SMatrix;

use dvlcal::calib::model::{NPARAM, difference};
use dvlcal::calib::{CalibOptions, calibrate};
use dvlcal::pipeline::{
    ImageRequest, SimulateRequest, VisionOptions, poses_from_images, write_simulated_dataset,
};
use dvlcal::rng::Rng;
use dvlcal::sim::dataset::{MotionKind, SimConfig, simulate};
use dvlcal::sim::image_dataset::{
    DEFAULT_BOARD_DISTANCE_M, FrameSpec, ImageSimSettings, board_facing, default_board,
    default_stereo_camchain,
};

const NAMES: [&str; NPARAM] = [
    "rot x (deg)",
    "rot y (deg)",
    "rot z (deg)",
    "lever x (mm)",
    "lever y (mm)",
    "lever z (mm)",
    "scale (1e-3)",
    "offset (ms)",
];
const UNITS: [f64; NPARAM] = [
    57.29577951308232,
    57.29577951308232,
    57.29577951308232,
    1e3,
    1e3,
    1e3,
    1e3,
    1e3,
];

struct Run {
    err: SMatrix<f64, NPARAM, 1>,
    std: SMatrix<f64, NPARAM, 1>,
    nees: f64,
    frames: usize,
    posed: usize,
    render_s: f64,
    detect_s: f64,
    calib_s: f64,
}

fn one(seed: u64, duration: f64, dir: &std::path::Path, images: bool, pose_sigma: f64) -> Run {
    let cfg = SimConfig {
        seed,
        duration_s: duration,
        motion: MotionKind::BoardView,
        pose_sigma_pos_m: pose_sigma,
        pose_sigma_rot_rad: pose_sigma,
        ..SimConfig::default()
    };
    if !images {
        // The same motion with the simulator's own pose noise (default 2 mm, 2 mrad), no images: tells
        // the vision's share of the errors from the motion's.
        let ds = simulate(&cfg).expect("simulation");
        let start = Instant::now();
        let o = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("calibrate");
        return summarise(
            &o,
            &ds.truth,
            ds.poses.len(),
            ds.poses.len(),
            0.0,
            0.0,
            start,
        );
    }
    // The recording as `dvlcal simulate --images` writes it, and its poses as `dvlcal calibrate`
    // gets them.
    let _ = std::fs::remove_dir_all(dir);
    let req = SimulateRequest {
        config: cfg,
        images: Some(ImageRequest {
            board: default_board(),
            chain: default_stereo_camchain(),
            board_distance_m: DEFAULT_BOARD_DISTANCE_M,
            settings: ImageSimSettings {
                seed,
                ..ImageSimSettings::default()
            },
        }),
        note: format!("end_to_end bench, seed {seed}"),
    };
    let start = Instant::now();
    let rec = write_simulated_dataset(dir, &req, &|_, _| {}).expect("render");
    let render_s = start.elapsed().as_secs_f64();
    let ds = rec.dataset;

    let start = Instant::now();
    let run = poses_from_images(
        dir,
        &dir.join("camchain.yaml"),
        &dir.join("target.yaml"),
        &VisionOptions::default(),
    )
    .expect("detect");
    let detect_s = start.elapsed().as_secs_f64();
    // The DVL samples are the simulation's own, on its epoch; the poses' epoch is the first
    // frame's whole second, the same one.
    assert_eq!(run.epoch, ds.epoch, "pose and DVL epochs differ");
    if std::env::var_os("DVLCAL_POSE_DIAG").is_some() {
        let board = default_board();
        let t_world_board = board_facing(&ds.truth_poses[0].pose, &board, DEFAULT_BOARD_DISTANCE_M);
        let frames: Vec<FrameSpec> = ds
            .true_poses_in(&t_world_board.inverse())
            .iter()
            .map(|p| FrameSpec {
                t_ns: ds.unix_ns(p.t),
                t_board_cam0: p.pose,
            })
            .collect();
        pose_diagnostics(&run.results, &frames);
    }
    let start = Instant::now();
    let o = calibrate(&run.poses, &ds.dvl, &CalibOptions::default()).expect("calibrate");
    summarise(
        &o,
        &ds.truth,
        run.results.len(),
        run.poses.len(),
        render_s,
        detect_s,
        start,
    )
}

/// The PnP poses against the rendered truth: mean NEES, mean error (bias) per component, and the
/// lag-1 autocorrelation of the whitened errors (0 for errors independent between frames).
fn pose_diagnostics(results: &[dvlcal::vision::frames::FrameResult], frames: &[FrameSpec]) {
    let mut ws: Vec<nalgebra::Vector6<f64>> = Vec::new();
    let mut es: Vec<nalgebra::Vector6<f64>> = Vec::new();
    for (r, f) in results.iter().zip(frames) {
        let Some(p) = &r.pose else { continue };
        let e = (f.t_board_cam0.inverse() * p.t_board_cam0).log();
        let Some(l) = p.cov.cholesky() else { continue };
        ws.push(l.l().solve_lower_triangular(&e).unwrap_or_default());
        es.push(e);
    }
    let n = ws.len() as f64;
    let nees = ws.iter().map(|w| w.norm_squared()).sum::<f64>() / n;
    let mean_e = es.iter().sum::<nalgebra::Vector6<f64>>() / n;
    let rms_e = (es
        .iter()
        .map(|e| e.component_mul(e))
        .sum::<nalgebra::Vector6<f64>>()
        / n)
        .map(f64::sqrt);
    let mut ac = nalgebra::Vector6::zeros();
    for k in 0..6 {
        let (mut num, mut den) = (0.0, 0.0);
        for i in 0..ws.len() {
            den += ws[i][k] * ws[i][k];
            if i + 1 < ws.len() {
                num += ws[i][k] * ws[i + 1][k];
            }
        }
        ac[k] = num / den;
    }
    eprintln!(
        "  poses: mean NEES {nees:.2}; mean error [{:.2e} {:.2e} {:.2e} | {:.2e} {:.2e} {:.2e}], RMS [{:.2e} {:.2e} {:.2e} | {:.2e} {:.2e} {:.2e}]; lag-1 autocorrelation of whitened errors [{:.2} {:.2} {:.2} {:.2} {:.2} {:.2}]",
        mean_e[0],
        mean_e[1],
        mean_e[2],
        mean_e[3],
        mean_e[4],
        mean_e[5],
        rms_e[0],
        rms_e[1],
        rms_e[2],
        rms_e[3],
        rms_e[4],
        rms_e[5],
        ac[0],
        ac[1],
        ac[2],
        ac[3],
        ac[4],
        ac[5]
    );
}

fn summarise(
    o: &dvlcal::calib::CalibrationOutcome,
    truth: &dvlcal::types::CalibrationParams,
    frames: usize,
    posed: usize,
    render_s: f64,
    detect_s: f64,
    start: Instant,
) -> Run {
    let calib_s = start.elapsed().as_secs_f64();
    let truth = *truth;
    let err = difference(&o.params, &truth);
    let std = SMatrix::<f64, NPARAM, 1>::from_fn(|k, _| o.covariance[(k, k)].max(0.0).sqrt());
    let nees = o
        .covariance
        .try_inverse()
        .map(|inv| (err.transpose() * inv * err)[(0, 0)])
        .unwrap_or(f64::NAN);
    Run {
        err,
        std,
        nees,
        frames,
        posed,
        render_s,
        detect_s,
        calib_s,
    }
}

/// 95 % percentile-bootstrap interval of `stat` over `xs`.
fn bootstrap(xs: &[f64], stat: &dyn Fn(&[f64]) -> f64) -> (f64, f64) {
    let mut rng = Rng::new(12345);
    let n = xs.len();
    let mut s: Vec<f64> = (0..2000)
        .map(|_| {
            let sample: Vec<f64> = (0..n)
                .map(|_| xs[((rng.uniform() * n as f64) as usize).min(n - 1)])
                .collect();
            stat(&sample)
        })
        .collect();
    s.sort_by(f64::total_cmp);
    (s[49], s[1949])
}

fn rms(xs: &[f64]) -> f64 {
    (xs.iter().map(|x| x * x).sum::<f64>() / xs.len() as f64).sqrt()
}

fn mean(xs: &[f64]) -> f64 {
    xs.iter().sum::<f64>() / xs.len() as f64
}

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let seeds: u64 = args.first().and_then(|s| s.parse().ok()).unwrap_or(12);
    let duration: f64 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(30.0);
    // Third argument: `poses` or `poses:SIGMA` (pose noise, metres and radians; default 0.002).
    let mode = args.get(2).map(String::as_str).unwrap_or("images");
    let images = !mode.starts_with("poses");
    let pose_sigma: f64 = mode
        .strip_prefix("poses:")
        .and_then(|s| s.parse().ok())
        .unwrap_or(0.002);
    let dir: PathBuf =
        std::env::temp_dir().join(format!("dvlcal-e2e-bench-{}", std::process::id()));
    let mut runs = Vec::new();
    for seed in 0..seeds {
        let r = one(seed, duration, &dir, images, pose_sigma);
        eprintln!(
            "seed {seed}: {}/{} frames posed; NEES {:.2}; render {:.1} s, detect {:.1} s, calibrate {:.2} s",
            r.posed, r.frames, r.nees, r.render_s, r.detect_s, r.calib_s
        );
        runs.push(r);
    }
    let _ = std::fs::remove_dir_all(&dir);
    println!(
        "\n{seeds} seeds x {duration} s (board-view motion, {}, DVL 10 Hz, 1 cm/s)\n",
        if images {
            "752x480 stereo images at 10 Hz"
        } else {
            "poses at 10 Hz with the given noise, no images"
        }
    );
    println!("| parameter | RMSE | mean reported std | RMS of error/std |");
    println!("|---|---|---|---|");
    for k in 0..NPARAM {
        let e: Vec<f64> = runs.iter().map(|r| r.err[k] * UNITS[k]).collect();
        let s: Vec<f64> = runs.iter().map(|r| r.std[k] * UNITS[k]).collect();
        let z: Vec<f64> = runs.iter().map(|r| r.err[k] / r.std[k]).collect();
        let (e0, e1) = bootstrap(&e, &rms);
        let (z0, z1) = bootstrap(&z, &rms);
        println!(
            "| {} | {:.3} [{:.3}, {:.3}] | {:.3} | {:.2} [{:.2}, {:.2}] |",
            NAMES[k],
            rms(&e),
            e0,
            e1,
            mean(&s),
            rms(&z),
            z0,
            z1
        );
    }
    let nees: Vec<f64> = runs.iter().map(|r| r.nees).collect();
    let (n0, n1) = bootstrap(&nees, &mean);
    println!(
        "\nmean NEES {:.2} [{:.2}, {:.2}] (expectation 8); per-seed timings: render {:.1} s, detect {:.1} s, calibrate {:.2} s (means)",
        mean(&nees),
        n0,
        n1,
        mean(&runs.iter().map(|r| r.render_s).collect::<Vec<_>>()),
        mean(&runs.iter().map(|r| r.detect_s).collect::<Vec<_>>()),
        mean(&runs.iter().map(|r| r.calib_s).collect::<Vec<_>>()),
    );
}
