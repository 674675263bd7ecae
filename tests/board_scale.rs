//! The board's printed size measured by the stereo pair: the rendered recording of
//! `sample_data/stereo` given with a board file that states the board 1/0.97 and 1/1.03 times its
//! true size (so the true print is 97 % and 103 % of the file), and as it is (100 %).

mod tmp_common;
mod truth_common;
use tmp_common::{TmpDir, dvlcal, s};

use std::path::{Path, PathBuf};

use dvlcal::io::calib_yaml::read_calib_yaml;
use dvlcal::vision::pnp::FrameScale;
use dvlcal::vision::scale::{BoardScale, estimate_board_scale};

const STEREO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/sample_data/stereo");
/// The tag size `sample_data/stereo` was rendered with, m.
const TAG_SIZE_M: f64 = 0.088;

/// A dataset folder with the images, DVL log, camchain and truth of `sample_data/stereo` and a
/// board file stating the tag size `tag_size_m`; `cams`: the cameras of the camchain (1 or 2).
fn dataset(tmp: &TmpDir, tag_size_m: f64, cams: usize) -> PathBuf {
    let d = tmp.path("data");
    std::fs::create_dir_all(&d).unwrap();
    let src = Path::new(STEREO);
    for part in ["cam0", "cam1", "dvl.jsonl", "truth"] {
        std::os::unix::fs::symlink(src.join(part), d.join(part)).unwrap();
    }
    let chain = std::fs::read_to_string(src.join("camchain.yaml")).unwrap();
    let chain = if cams == 1 {
        chain.split("\ncam1:").next().unwrap().to_owned() + "\n"
    } else {
        chain
    };
    std::fs::write(d.join("camchain.yaml"), chain).unwrap();
    std::fs::write(
        d.join("target.yaml"),
        format!(
            "family: tag36h11\nrows: 6\ncols: 6\ntag_size: {tag_size_m}\nspacing: 0.3\n\
             first_id: 0\n"
        ),
    )
    .unwrap();
    d
}

/// Calibrates `dir` into `out`; returns what the program printed.
fn calibrate(dir: &Path, out: &Path) -> String {
    let r = dvlcal(&[
        "calibrate",
        s(dir),
        "--out",
        s(out),
        "--threads",
        "2",
        "--no-progress",
    ]);
    let stdout = String::from_utf8_lossy(&r.stdout).into_owned();
    assert!(
        r.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&r.stderr)
    );
    stdout
}

/// The board scale, its std and whether it was applied, from a result file.
fn board_scale(out: &Path) -> (f64, f64, bool) {
    let f = read_calib_yaml(out).unwrap();
    let g = f.info.expect("info").figures;
    (
        g.board_scale.expect("board_scale"),
        g.board_scale_std.expect("board_scale_std"),
        g.board_scale_applied.expect("board_scale_applied"),
    )
}

/// A board printed at `print` times the size its file states: measured within 3 std (under
/// 0.3 %), said so, and the calibration made with the measured size within 3 std of the truth.
fn misprinted(print: f64, tag: &str) {
    let tmp = TmpDir::new(tag);
    let dir = dataset(&tmp, TAG_SIZE_M / print, 2);
    let out = tmp.path("calibration.yaml");
    let stdout = calibrate(&dir, &out);
    let (scale, std, applied) = board_scale(&out);
    eprintln!("print {print}: board_scale {scale:.6} +- {std:.6}");
    assert!((scale - print).abs() < 3.0 * std, "{scale} +- {std}");
    assert!(std < 0.003, "{std}");
    assert!(applied);
    // The std (0.02 %) is shown with two decimals.
    let said = format!(
        "the board measures {:.2} +- {:.2} % of target.yaml",
        100.0 * scale,
        100.0 * std
    );
    assert!(said.starts_with(&format!("the board measures {:.1}", 100.0 * print)));
    assert!(stdout.contains(&format!("warning: {said}")), "{stdout}");
    let a = truth_common::against_truth(&dir, &out);
    truth_common::assert_within(&a, 3.0);
}

#[test]
fn board_printed_at_97_percent_is_measured_and_calibrated_at_its_size() {
    misprinted(0.97, "board-97");
}

#[test]
fn board_printed_at_103_percent_is_measured_and_calibrated_at_its_size() {
    misprinted(1.03, "board-103");
}

#[test]
fn board_printed_as_stated_is_left_as_it_is() {
    let tmp = TmpDir::new("board-100");
    let out = tmp.path("calibration.yaml");
    let stdout = calibrate(Path::new(STEREO), &out);
    let (scale, std, applied) = board_scale(&out);
    eprintln!("print 1: board_scale {scale:.6} +- {std:.6}");
    assert!((scale - 1.0).abs() < 3.0 * std, "{scale} +- {std}");
    assert!(std < 0.003, "{std}");
    assert!(!applied);
    assert!(!stdout.contains("warning: the board measures"), "{stdout}");
    assert!(
        stdout.contains("board size: the board measures 100.0"),
        "{stdout}"
    );
}

#[test]
fn one_camera_cannot_tell_the_board_from_the_velocity_scale() {
    let tmp = TmpDir::new("board-mono");
    let dir = dataset(&tmp, TAG_SIZE_M, 1);
    let out = tmp.path("calibration.yaml");
    let stdout = calibrate(&dir, &out);
    let words = "with one camera the board's printed size and the DVL's velocity scale cannot be \
                 told apart";
    assert!(stdout.contains(words), "{stdout}");
    let info = read_calib_yaml(&out).unwrap().info.expect("info");
    assert!(
        info.notes.iter().any(|n| n.contains(words)),
        "{:?}",
        info.notes
    );
    assert_eq!(info.figures.board_scale, None);
}

fn fit(scale: f64, std: f64) -> FrameScale {
    FrameScale { scale, std }
}

#[test]
fn frames_combine_by_weight_with_the_spread_as_std_and_outliers_out() {
    // Alternating 0.969 and 0.971 at equal weight: mean 0.97, std the frames' spread over
    // sqrt(n) (n = 20) with the detector's floor, and one frame at 1.2 left out.
    let mut v: Vec<FrameScale> = (0..20)
        .map(|i| fit(if i % 2 == 0 { 0.969 } else { 0.971 }, 0.001))
        .collect();
    v.push(fit(1.2, 0.001));
    let b = estimate_board_scale(&v).expect("scale");
    assert_eq!((b.frames, b.rejected), (20, 1));
    assert!((b.scale - 0.97).abs() < 1e-12, "{b:?}");
    let spread = (20.0 * 1e-6 / 19.0f64).sqrt() / 20f64.sqrt();
    let sd = spread.hypot(dvlcal::vision::scale::SYSTEMATIC_STD);
    assert!((b.std - sd).abs() < 1e-12, "{b:?} {sd}");
    assert!(b.significant());
    assert_eq!(
        b.measures("target.yaml"),
        "the board measures 97.00 +- 0.03 % of target.yaml"
    );
    assert!(estimate_board_scale(&[fit(1.0, 0.001); 4]).is_none());
}

#[test]
fn small_or_uncertain_scales_are_not_applied() {
    let at = |scale: f64, std: f64| BoardScale {
        scale,
        std,
        frames: 10,
        rejected: 0,
        applied: false,
    };
    assert!(!at(1.0015, 1e-5).significant()); // under 0.2 %
    assert!(!at(0.99, 0.004).significant()); // under 3 std
    assert!(at(1.03, 0.001).significant());
    assert!(at(0.97, 0.001).significant());
}
