//! Camera calibration against OpenCV on rendered calibration sequences with known cameras
//! (docs/accuracy.md, "Camera calibration"; timings in docs/performance.md).
//!
//! `cargo bench --bench camcal -- [SEEDS] [VIEWS]` (defaults 12 seeds of 36 stereo views of the
//! 6x6 aprilgrid, the default 752x480 radtan pair). Per seed the same rendered frames are
//! calibrated three ways: OpenCV's calibrateCamera + stereoCalibrate on the corners detected
//! without a camera model (`eval::camera::opencv_stereo_reference`), dvlcal's adjustment on the
//! same corners (one pass), and dvlcal with the corners refined again with the first fit's lenses
//! (two passes, what `calibrate-cameras` does). Printed: the ray error (RMS pixel distance between
//! where the true and the estimated model send the same ray, over the whole image), the baseline
//! and translation errors of `T_c1_c0`, the normalised focal-length error `err / std`, and the
//! time of detection and adjustment.

#[path = "../tests/camcal_common/mod.rs"]
mod camcal_common;

use std::time::Instant;

use camcal_common::{detect_views, render_views};
use dvlcal::camcal::{CamCalOptions, calibrate_cameras};
use dvlcal::eval::camera::{
    baseline_error, extrinsic_error, opencv_stereo_reference, ray_pixel_error,
};
use dvlcal::sim::image_dataset::{default_board, default_stereo_camchain};
use dvlcal::types::camera::Camchain;

struct Row {
    ray: [f64; 3],
    baseline_mm: [f64; 3],
    trans_mm: [f64; 3],
    z: [f64; 4],
    detect_s: f64,
    fit_s: f64,
}

fn ray(truth: &Camchain, est: &Camchain) -> f64 {
    let sq: f64 = truth
        .cams
        .iter()
        .zip(&est.cams)
        .map(|(t, e)| {
            ray_pixel_error(t, e, 8.0)
                .map_or(f64::NAN, |r| r.rms_px)
                .powi(2)
        })
        .sum();
    (sq / truth.cams.len() as f64).sqrt()
}

fn mean_ci(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    let sd = (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0).max(1.0)).sqrt();
    (m, 2.0 * sd / n.sqrt())
}

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-'))
        .collect();
    let seeds: u64 = args.first().and_then(|s| s.parse().ok()).unwrap_or(12);
    let views: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(36);
    let truth = default_stereo_camchain();
    let board = default_board();
    let sizes: Vec<(u32, u32)> = truth.cams.iter().map(|c| (c.width, c.height)).collect();
    println!(
        "camera calibration, {seeds} seeds x {views} stereo views (752x480 radtan pair, 6x6 aprilgrid)"
    );
    println!(
        "seed | ray RMS px: OpenCV, dvlcal 1 pass, 2 passes | baseline err mm | translation err mm | fu err/std | detect s | fit s"
    );
    let mut rows = Vec::new();
    for seed in 1..=seeds {
        let images = render_views(&truth, &board, views, seed);
        let t0 = Instant::now();
        let first = detect_views(&images, &board, None);
        let mut detect_s = t0.elapsed().as_secs_f64();
        let Ok(cv) = opencv_stereo_reference(&board, &first, &sizes) else {
            println!("{seed} | OpenCV failed");
            continue;
        };
        let t0 = Instant::now();
        let Ok(one) = calibrate_cameras(&board, &first, &sizes, &CamCalOptions::default()) else {
            println!("{seed} | dvlcal failed");
            continue;
        };
        let mut fit_s = t0.elapsed().as_secs_f64();
        let t0 = Instant::now();
        let second = detect_views(&images, &board, Some(&one.chain));
        detect_s += t0.elapsed().as_secs_f64();
        let t0 = Instant::now();
        let Ok(two) = calibrate_cameras(&board, &second, &sizes, &CamCalOptions::default()) else {
            println!("{seed} | dvlcal second pass failed");
            continue;
        };
        fit_s += t0.elapsed().as_secs_f64();
        let ests = [&cv, &one.chain, &two.chain];
        let b = ests.map(|e| 1e3 * baseline_error(&truth.t_cn_c0[1], &e.t_cn_c0[1]).abs());
        let t = ests.map(|e| 1e3 * extrinsic_error(&truth.t_cn_c0[1], &e.t_cn_c0[1]).0);
        let r = ests.map(|e| ray(&truth, e));
        let (e, t0c, sd) = (&two.chain.cams[0], &truth.cams[0], &two.std[0]);
        let z = [
            (e.fu - t0c.fu) / sd.intrinsics[0],
            (e.pu - t0c.pu) / sd.intrinsics[2],
            (e.distortion.coeffs()[0] - t0c.distortion.coeffs()[0]) / sd.distortion[0],
            1e-3 * b[2] * baseline_error(&truth.t_cn_c0[1], &two.chain.t_cn_c0[1]).signum()
                / two.std[1].baseline_m.unwrap_or(f64::NAN),
        ];
        let focal_z = z[0];
        println!(
            "{seed} | {:.3} {:.3} {:.3} | {:.3} {:.3} {:.3} | {:.3} {:.3} {:.3} | {focal_z:+.2} | {detect_s:.2} | {fit_s:.2}",
            r[0], r[1], r[2], b[0], b[1], b[2], t[0], t[1], t[2]
        );
        rows.push(Row {
            ray: r,
            baseline_mm: b,
            trans_mm: t,
            z,
            detect_s,
            fit_s,
        });
    }
    if rows.is_empty() {
        return;
    }
    let names = [
        "OpenCV calibrateCamera + stereoCalibrate",
        "dvlcal, 1 pass (same corners)",
        "dvlcal, 2 passes (calibrate-cameras)",
    ];
    println!(
        "\nmethod | ray RMS px (mean +- 2 s.e.) | worst seed | baseline err mm (mean) | translation err mm (mean) | seeds better than OpenCV (ray)"
    );
    for (k, name) in names.iter().enumerate() {
        let ray: Vec<f64> = rows.iter().map(|r| r.ray[k]).collect();
        let (m, ci) = mean_ci(&ray);
        let worst = ray.iter().fold(0.0f64, |a, v| a.max(*v));
        let (bm, _) = mean_ci(&rows.iter().map(|r| r.baseline_mm[k]).collect::<Vec<_>>());
        let (tm, _) = mean_ci(&rows.iter().map(|r| r.trans_mm[k]).collect::<Vec<_>>());
        let better = rows.iter().filter(|r| r.ray[k] < r.ray[0]).count();
        println!(
            "{name} | {m:.3} +- {ci:.3} | {worst:.3} | {bm:.3} | {tm:.3} | {better}/{}",
            rows.len()
        );
    }
    let rms_z: Vec<f64> = (0..4)
        .map(|k| (rows.iter().map(|r| r.z[k] * r.z[k]).sum::<f64>() / rows.len() as f64).sqrt())
        .collect();
    let (d, _) = mean_ci(&rows.iter().map(|r| r.detect_s).collect::<Vec<_>>());
    let (f, _) = mean_ci(&rows.iter().map(|r| r.fit_s).collect::<Vec<_>>());
    println!(
        "\nRMS of err/std, 2 passes (1 when the std are honest): cam0 fu {:.2}, pu {:.2}, k1 {:.2}, baseline {:.2}\nmean time per seed: detection (2 passes, {views} stereo frames) {d:.2} s, adjustment (2 fits) {f:.2} s",
        rms_z[0], rms_z[1], rms_z[2], rms_z[3]
    );
}
