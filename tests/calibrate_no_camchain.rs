//! `dvlcal calibrate DIR` on a dataset folder with images, a board and a DVL log but no camchain:
//! the cameras are calibrated from the same images first, the camchain is written beside the
//! result, the weak camera calibration is called out, and the DVL calibration still lands near
//! the simulation's truth.

mod tmp_common;
mod truth_common;
use tmp_common::TmpDir;

use std::path::{Path, PathBuf};
use std::process::Command;

use dvlcal::io::camchain::read_camchain;
use dvlcal::io::dataset::{DatasetOverrides, discover};
use dvlcal::pipeline::dataset_files;
use dvlcal::types::camera::Camchain;

const STEREO: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/sample_data/stereo");

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let p = e.unwrap().path();
        let dest = to.join(p.file_name().unwrap());
        if p.is_dir() {
            copy_dir(&p, &dest);
        } else {
            std::fs::copy(&p, &dest).unwrap();
        }
    }
}

/// The rendered stereo dataset without its camchain (and without its truth).
fn dataset_without_camchain(root: &Path) -> PathBuf {
    let d = root.join("data");
    let src = Path::new(STEREO);
    copy_dir(&src.join("cam0"), &d.join("cam0"));
    copy_dir(&src.join("cam1"), &d.join("cam1"));
    for f in ["target.yaml", "dvl.jsonl"] {
        std::fs::copy(src.join(f), d.join(f)).unwrap();
    }
    d
}

#[test]
fn calibrate_without_camchain_calibrates_the_cameras_first_and_stays_near_the_truth() {
    let tmp = TmpDir::new("no-camchain");
    let data = dataset_without_camchain(&tmp.0);
    let out = tmp.0.join("out");
    let result = out.join("calibration.yaml");
    let report = out.join("report.html");
    let start = std::time::Instant::now();
    let r = Command::new(env!("CARGO_BIN_EXE_dvlcal"))
        .args([
            "calibrate",
            data.to_str().unwrap(),
            "--out",
            result.to_str().unwrap(),
            "--report",
            report.to_str().unwrap(),
            "--no-progress",
        ])
        .output()
        .expect("run dvlcal");
    let seconds = start.elapsed().as_secs_f64();
    let stdout = String::from_utf8_lossy(&r.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&r.stderr).into_owned();
    let all = format!("{stdout}\n{stderr}");
    assert!(r.status.success(), "{all}");
    eprintln!("dvlcal calibrate without a camchain: {seconds:.1} s");

    // It says so, and shows the camera calibration.
    assert!(
        stdout.contains("no camchain: calibrating the cameras from the same images first"),
        "{all}"
    );
    assert!(
        stdout.contains("camera calibration (pinhole-radtan)"),
        "{all}"
    );
    // The board of this recording stays near the image centre: the camera calibration warns
    // about coverage, and the program recommends a separate camera recording.
    assert!(stdout.contains("board corners fell in"), "{all}");
    assert!(
        stderr.contains("the camera calibration from this recording is weak")
            && stderr.contains("dvlcal calibrate-cameras")
            && stderr.contains("--camchain"),
        "{all}"
    );

    // The camchain beside the result, close to the truth the images were rendered with.
    let camchain = out.join("camchain.yaml");
    assert!(stdout.contains("camchain.yaml"), "{all}");
    let fitted = read_camchain(&camchain).expect("the written camchain loads");
    let truth = read_camchain(&Path::new(STEREO).join("camchain.yaml")).unwrap();
    assert_eq!(fitted.cams.len(), 2);
    let mut figures = String::new();
    for (i, (f, t)) in fitted.cams.iter().zip(&truth.cams).enumerate() {
        for (name, a, b) in [("fu", f.fu, t.fu), ("fv", f.fv, t.fv)] {
            let rel = (a - b) / b;
            figures.push_str(&format!(
                "cam{i} {name} {a:.2} truth {b:.2} ({:+.2} %)\n",
                100.0 * rel
            ));
            assert!(rel.abs() < 0.01, "cam{i} {name}: {a} vs {b}");
        }
    }
    let baseline = |c: &Camchain| c.t_cn_c0[1].trans.norm();
    let db = baseline(&fitted) - baseline(&truth);
    figures.push_str(&format!(
        "baseline {:.2} mm truth {:.2} mm ({:+.2} mm)\n",
        1e3 * baseline(&fitted),
        1e3 * baseline(&truth),
        1e3 * db
    ));
    eprintln!("{figures}");
    assert!(db.abs() < 0.002, "{figures}");

    // The camera report beside the DVL report.
    assert!(out.join("report-cameras.html").is_file(), "{all}");
    assert!(report.is_file());

    // The result records where its camchain came from, and warns.
    let text = std::fs::read_to_string(&result).unwrap();
    assert!(
        text.contains("camchain_source: calibrated from the same images"),
        "{text}"
    );
    assert!(text.contains("dvlcal calibrate-cameras"), "{text}");

    // The DVL calibration against the simulation's truth. With the camchain calibrated here,
    // the focal lengths come out some 0.7 % long (the board never tilts far from the image
    // plane, so focal length and distance trade off); the poses' scale follows, and the
    // velocity scale and the lever arm along the optical axis move by a few of their standard
    // deviations. The bounds are the end-to-end test's 3.5 sigma, widened to 6 sigma for that
    // bias.
    let a = truth_common::against_truth(Path::new(STEREO), &result);
    truth_common::assert_within(&a, 6.0);
    let (d, table) = (a.err, a.table);
    // And in absolute terms: rotation within 0.5 deg, lever arm within 1.5 cm, scale within
    // 1 %, clock offset within 3 ms.
    assert!(
        d[..3].iter().all(|e| e.abs() < 0.5f64.to_radians()),
        "{table}"
    );
    assert!(d[3..6].iter().all(|e| e.abs() < 0.015), "{table}");
    assert!(d[6].abs() < 0.01, "{table}");
    assert!(d[7].abs() < 0.003, "{table}");
}

#[test]
fn a_result_named_camchain_yaml_is_refused_before_the_run() {
    let tmp = TmpDir::new("no-camchain-refuse");
    let d = tmp.0.join("data");
    std::fs::create_dir_all(d.join("cam0")).unwrap();
    for f in ["target.yaml", "dvl.jsonl"] {
        std::fs::copy(Path::new(STEREO).join(f), d.join(f)).unwrap();
    }
    let out = tmp.0.join("camchain.yaml");
    let r = Command::new(env!("CARGO_BIN_EXE_dvlcal"))
        .args([
            "calibrate",
            d.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--no-progress",
        ])
        .output()
        .expect("run dvlcal");
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success());
    assert!(stderr.contains("name the result otherwise"), "{stderr}");
    assert!(!out.exists());
}

#[test]
fn images_with_a_board_and_no_camchain_are_a_dataset() {
    let tmp = TmpDir::new("no-camchain-discover");
    let d = tmp.0.join("data");
    std::fs::create_dir_all(d.join("cam0")).unwrap();
    for f in ["target.yaml", "dvl.jsonl"] {
        std::fs::copy(Path::new(STEREO).join(f), d.join(f)).unwrap();
    }

    // A folder: camchain None, no error.
    let f = discover(&d, &DatasetOverrides::default()).expect("discover");
    assert_eq!(f.images.as_deref(), Some(d.as_path()));
    assert_eq!(f.target.as_deref(), Some(d.join("target.yaml").as_path()));
    assert_eq!(f.dvl.as_deref(), Some(d.join("dvl.jsonl").as_path()));
    assert!(f.camchain.is_none());
    assert!(f.calibrates_cameras());
    let f = dataset_files(Some(&d), &DatasetOverrides::default()).expect("dataset_files");
    assert!(f.camchain.is_none() && f.calibrates_cameras());

    // Files named one by one: --images and --target without --camchain.
    let given = DatasetOverrides {
        images: Some(d.clone()),
        target: Some(d.join("target.yaml")),
        dvl: Some(d.join("dvl.jsonl")),
        ..Default::default()
    };
    let f = dataset_files(None, &given).expect("dataset_files without a folder");
    assert!(f.camchain.is_none() && f.calibrates_cameras());

    // A camchain makes it an ordinary dataset.
    std::fs::copy(
        Path::new(STEREO).join("camchain.yaml"),
        d.join("camchain.yaml"),
    )
    .unwrap();
    let f = discover(&d, &DatasetOverrides::default()).unwrap();
    assert!(f.camchain.is_some() && !f.calibrates_cameras());
    std::fs::remove_file(d.join("camchain.yaml")).unwrap();

    // Images without a board stay an error, in both forms.
    std::fs::remove_file(d.join("target.yaml")).unwrap();
    let e = discover(&d, &DatasetOverrides::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("images but no board"), "{e}");
    let e = dataset_files(
        None,
        &DatasetOverrides {
            target: None,
            ..given
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("--images needs --target"), "{e}");
}
