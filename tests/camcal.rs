//! Camera calibration (`dvlcal::camcal`) on rendered calibration sequences with known cameras,
//! against OpenCV's calibrateCamera + stereoCalibrate on the same frames, and the
//! `calibrate-cameras` command end to end.

mod camcal_common;
mod tmp_common;

use camcal_common::{detect_views, fisheye_chain, render_views};
use dvlcal::camcal::{CamCalOptions, CameraModel, calibrate_cameras};
use dvlcal::eval::camera::{
    baseline_error, extrinsic_error, opencv_stereo_reference, ray_pixel_error,
};
use dvlcal::io::camchain::read_camchain;
use dvlcal::io::target::read_board;
use dvlcal::sim::image_dataset::{default_board, default_stereo_camchain};
use dvlcal::types::camera::Camchain;

/// Ray error RMS per camera (px) and baseline error (mm) of an estimate against the truth.
fn errors(truth: &Camchain, est: &Camchain) -> (Vec<f64>, f64, f64) {
    let rays = truth
        .cams
        .iter()
        .zip(&est.cams)
        .map(|(t, e)| ray_pixel_error(t, e, 8.0).expect("ray error").rms_px)
        .collect();
    let b = 1e3 * baseline_error(&truth.t_cn_c0[1], &est.t_cn_c0[1]).abs();
    let (dt, _) = extrinsic_error(&truth.t_cn_c0[1], &est.t_cn_c0[1]);
    (rays, b, 1e3 * dt)
}

#[test]
fn radtan_stereo_at_least_as_good_as_opencv_on_the_same_frames() {
    let truth = default_stereo_camchain();
    let board = default_board();
    let sizes: Vec<(u32, u32)> = truth.cams.iter().map(|c| (c.width, c.height)).collect();
    for seed in [11u64, 12] {
        let images = render_views(&truth, &board, 36, seed);
        let first = detect_views(&images, &board, None);
        let reference = opencv_stereo_reference(&board, &first, &sizes).expect("OpenCV reference");
        let one = calibrate_cameras(&board, &first, &sizes, &CamCalOptions::default())
            .expect("first pass");
        let second = detect_views(&images, &board, Some(&one.chain));
        let two = calibrate_cameras(&board, &second, &sizes, &CamCalOptions::default())
            .expect("second pass");
        let (r_cv, b_cv, t_cv) = errors(&truth, &reference);
        let (r_one, b_one, t_one) = errors(&truth, &one.chain);
        let (r_two, b_two, t_two) = errors(&truth, &two.chain);
        eprintln!(
            "seed {seed}: ray RMS px OpenCV {r_cv:.3?} dvlcal 1 pass {r_one:.3?} 2 passes {r_two:.3?}; \
             baseline error mm {b_cv:.3} {b_one:.3} {b_two:.3}; translation error mm {t_cv:.3} {t_one:.3} {t_two:.3}"
        );
        for c in 0..2 {
            // Same corners: the joint adjustment is no worse than OpenCV's (5 % slack for the
            // different outlier handling).
            assert!(
                r_one[c] <= 1.05 * r_cv[c] + 0.01,
                "seed {seed} cam{c}: {} vs OpenCV {}",
                r_one[c],
                r_cv[c]
            );
            // Corners refined with the fitted lens: well below a tenth of a pixel.
            assert!(
                r_two[c] < 0.12,
                "seed {seed} cam{c}: two passes {}",
                r_two[c]
            );
            assert!(r_two[c] <= r_cv[c], "seed {seed} cam{c}");
        }
        assert!(
            t_two < 0.5 && b_two < 0.3,
            "seed {seed}: translation {t_two} mm, baseline {b_two} mm"
        );
        assert!(
            t_two <= t_cv.max(0.2),
            "seed {seed}: {t_two} vs OpenCV {t_cv}"
        );
    }
}

#[test]
fn fisheye_stereo_with_the_equidistant_model() {
    let truth = fisheye_chain();
    let board = default_board();
    let sizes: Vec<(u32, u32)> = truth.cams.iter().map(|c| (c.width, c.height)).collect();
    let images = render_views(&truth, &board, 36, 21);
    let opts = CamCalOptions {
        model: CameraModel::PinholeEqui,
        ..CamCalOptions::default()
    };
    let one = calibrate_cameras(&board, &detect_views(&images, &board, None), &sizes, &opts)
        .expect("first pass");
    let two = calibrate_cameras(
        &board,
        &detect_views(&images, &board, Some(&one.chain)),
        &sizes,
        &opts,
    )
    .expect("second pass");
    let (r, b, t) = errors(&truth, &two.chain);
    eprintln!(
        "fisheye: ray RMS px {r:.3?}, baseline error {b:.3} mm, translation error {t:.3} mm; fit RMS {:.3} px",
        two.rms_px
    );
    assert!(r.iter().all(|v| *v < 0.3), "{r:?}");
    eprintln!(
        "fisheye coverage {:?}",
        two.coverage
            .iter()
            .map(|c| (c.covered_fraction, c.radial_reach))
            .collect::<Vec<_>>()
    );
    assert!(b < 0.5 && t < 1.0, "baseline {b} mm, translation {t} mm");
    assert!(matches!(
        two.chain.cams[0].distortion,
        dvlcal::types::camera::Distortion::Equidistant { .. }
    ));
}

/// A calibration sequence of a Kalibr-printed aprilgrid written as a dataset folder, calibrated by
/// the `calibrate-cameras` command: the camchain it writes is read back and compared with the
/// truth, and the report holds its sections.
#[test]
fn calibrate_cameras_command_on_a_kalibr_printed_board() {
    use dvlcal::sim::camcal_views::calibration_views;
    use dvlcal::sim::image_dataset::{FrameSpec, ImageSimSettings, write_image_dataset};
    use dvlcal::types::board::TagPrint;
    let tmp = tmp_common::TmpDir::new("calibrate-cameras");
    let target = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("calib_boards/kalibr_aprilgrid_6x6.yaml");
    let board = read_board(&target).expect("board");
    assert_eq!(board.print, TagPrint::Kalibr);
    let truth = default_stereo_camchain();
    let frames: Vec<FrameSpec> = calibration_views(&truth, &board, 30, 4)
        .into_iter()
        .enumerate()
        .map(|(k, t)| FrameSpec {
            t_ns: 1_700_000_000_000_000_000 + k as i64 * 200_000_000,
            t_board_cam0: t,
        })
        .collect();
    let images = tmp.0.join("images");
    let settings = ImageSimSettings {
        seed: 4,
        ..ImageSimSettings::default()
    };
    write_image_dataset(&images, &board, &truth, &frames, &settings, &|_, _| {}).expect("render");
    let out = tmp.0.join("out/camchain.yaml");
    let report = tmp.0.join("out/cameras.html");
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_dvlcal"))
        .args(["calibrate-cameras", "--images"])
        .arg(&images)
        .arg("--target")
        .arg(&target)
        .arg("--out")
        .arg(&out)
        .arg("--report")
        .arg(&report)
        .output()
        .expect("run dvlcal");
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&run.stderr)
    );
    assert!(stdout.contains("2 detection passes"), "{stdout}");
    let chain = read_camchain(&out).expect("the written camchain reads back");
    let (rays, b, t) = errors(&truth, &chain);
    eprintln!(
        "Kalibr board, command: ray RMS {rays:.3?} px, baseline error {b:.3} mm, translation {t:.3} mm"
    );
    assert!(rays.iter().all(|r| *r < 0.15), "{rays:?}");
    assert!(b < 0.3 && t < 0.5);
    let text = std::fs::read_to_string(&out).expect("camchain text");
    assert!(text.contains("intrinsics_std") && text.contains("T_cn_cnm1_std"));
    let html = std::fs::read_to_string(&report).expect("report");
    for id in dvlcal::report::CAMCAL_SECTION_IDS {
        assert!(html.contains(&format!("id=\"{id}\"")), "section {id}");
    }
    for id in dvlcal::report::camcal_plot_ids(2) {
        assert!(html.contains(&format!("id=\"{id}\"")), "plot {id}");
    }
}

#[test]
fn calibrate_cameras_refuses_what_it_cannot_use() {
    let tmp = tmp_common::TmpDir::new("calibrate-cameras-bad");
    let target = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("calib_boards/kalibr_aprilgrid_6x6.yaml");
    let run = |args: &[&std::ffi::OsStr]| {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_dvlcal"))
            .arg("calibrate-cameras")
            .args(args)
            .output()
            .expect("run dvlcal");
        (
            o.status.success(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        )
    };
    let out = tmp.0.join("c.yaml");
    // No cam0 folder.
    let (ok, err) = run(&[
        "--images".as_ref(),
        tmp.0.as_os_str(),
        "--target".as_ref(),
        target.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert!(!ok && err.contains("cam0"), "{err}");
    // Images without a board: too few views, named by camera.
    let cam0 = tmp.0.join("cam0");
    std::fs::create_dir_all(&cam0).expect("mkdir");
    for k in 0..6 {
        image::GrayImage::from_pixel(64, 48, image::Luma([128u8]))
            .save(cam0.join(format!("{}.png", 1_000_000_000 + k * 100_000_000)))
            .expect("png");
    }
    let (ok, err) = run(&[
        "--images".as_ref(),
        tmp.0.as_os_str(),
        "--target".as_ref(),
        target.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert!(
        !ok && err.contains("cam0") && err.contains("0 frames"),
        "{err}"
    );
    assert!(!out.exists(), "nothing is written for a failed calibration");
    // An unknown model.
    let (ok, err) = run(&[
        "--images".as_ref(),
        tmp.0.as_os_str(),
        "--target".as_ref(),
        target.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
        "--model".as_ref(),
        "omni-radtan".as_ref(),
    ]);
    assert!(!ok && err.contains("pinhole-equi"), "{err}");
}
