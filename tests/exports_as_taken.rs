//! Outputs a user takes as they are: the ready-made boards print on their paper at exact scale,
//! the URDF export is a robot ROS's own parser reads, an export never shows a value the data did
//! not measure without saying so, and `compare-calib` does not pass a failed estimate.

use std::path::{Path, PathBuf};
use std::process::Command;

use dvlcal::io::calib_yaml::{Observability, read_calib_yaml};

#[path = "tmp_common/mod.rs"]
mod tmp_common;
use tmp_common::{TmpDir, dvlcal, s};

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

fn text(o: &[u8]) -> String {
    String::from_utf8_lossy(o).into_owned()
}

/// The value of `name="..."` in an element's text (SVG, XML).
fn attr(el: &str, name: &str) -> Option<String> {
    let key = format!(" {name}=\"");
    let start = el.find(&key)? + key.len();
    let end = el[start..].find('"')? + start;
    Some(el[start..end].to_owned())
}

// ---------------------------------------------------------------------------------------------
// Exports

/// `check_urdf` of Debian's liburdfdom-tools on `urdf`: its output, after asserting it parsed.
fn check_urdf(urdf: &Path) -> String {
    let r = Command::new("check_urdf")
        .arg(urdf)
        .output()
        .unwrap_or_else(|e| {
            panic!(
                "check_urdf is needed to test the URDF export against ROS's parser: install \
             Debian's liburdfdom-tools (make test-deps): {e}"
            )
        });
    let out = text(&r.stdout);
    assert!(
        r.status.success(),
        "check_urdf refused {}: {out}{}",
        urdf.display(),
        text(&r.stderr)
    );
    out
}

/// The URDF export is a whole robot: ROS's parser reads it as is, with the camera as the root
/// link and the DVL its one child, joined at the calibrated lever arm.
#[test]
fn the_urdf_export_is_a_robot_that_ros_parses() {
    let tmp = TmpDir::new("urdf-robot");
    let out = tmp.path("cal.yaml");
    let r = dvlcal(&[
        "calibrate",
        s(&repo("sample_data/poses")),
        "--out",
        s(&out),
        "--frames",
        "camera_link,dvl_link",
    ]);
    assert!(r.status.success(), "{}", text(&r.stderr));
    let urdf = tmp.path("cal-urdf.xml");
    let parsed = check_urdf(&urdf);
    assert!(
        parsed.contains("root Link: camera_link has 1 child(ren)"),
        "{parsed}"
    );
    assert!(parsed.contains("child(1):  dvl_link"), "{parsed}");
    let xml = std::fs::read_to_string(&urdf).unwrap();
    assert!(xml.starts_with("<?xml"), "{xml}");
    assert_eq!(xml.matches("<link name=").count(), 2, "{xml}");
    // The joint carries the result's lever arm.
    let arm = read_calib_yaml(&out).unwrap().lever_arm_cam_m;
    let origin = xml.lines().find(|l| l.contains("<origin")).unwrap();
    let xyz: Vec<f64> = attr(origin, "xyz")
        .unwrap()
        .split(' ')
        .map(|v| v.parse().unwrap())
        .collect();
    assert!(
        (0..3).all(|k| (xyz[k] - arm[k]).abs() < 1e-11),
        "{origin} {arm:?}"
    );
}

/// A dataset whose DVL reports cover only the calm first half of `dvlcal simulate`'s default
/// motion: the camera hardly rotates while the DVL measures, so the lever arm is not observed.
fn calm_dataset(tmp: &TmpDir, name: &str, calm: bool) -> PathBuf {
    let d = tmp.path(name);
    let r = dvlcal(&["simulate", "--out", s(&d), "--seed", "3"]);
    assert!(r.status.success(), "{}", text(&r.stderr));
    if calm {
        let log = std::fs::read_to_string(d.join("dvl.jsonl")).unwrap();
        let lines: Vec<&str> = log.lines().collect();
        let half = lines[..lines.len() / 2].join("\n") + "\n";
        std::fs::write(d.join("dvl.jsonl"), half).unwrap();
    }
    d
}

struct Exports {
    tf: String,
    urdf: String,
    kalibr: String,
}

fn exports(out: &Path) -> Exports {
    let read = |suffix: &str| {
        let stem = out.file_stem().unwrap().to_str().unwrap();
        std::fs::read_to_string(out.with_file_name(format!("{stem}-{suffix}")))
            .unwrap_or_else(|e| panic!("{suffix}: {e}"))
    };
    Exports {
        tf: read("tf.txt"),
        urdf: read("urdf.xml"),
        kalibr: read("camchain-imucam.yaml"),
    }
}

/// The comment lines of each export (tf, URDF, Kalibr) whose text starts with `what` and holds
/// `state`.
fn notes<'a>(e: &'a Exports, what: &str, state: &str) -> [Vec<&'a str>; 3] {
    let find = |t: &'a str, open: &str, close: &str| -> Vec<&'a str> {
        t.lines()
            .filter(|l| {
                let body = l.trim_start();
                body.ends_with(close)
                    && body
                        .strip_prefix(open)
                        .is_some_and(|b| b.trim_start().starts_with(what))
                    && l.contains(state)
            })
            .collect()
    };
    [
        find(&e.tf, "#", ""),
        find(&e.urdf, "<!--", "-->"),
        find(&e.kalibr, "#", ""),
    ]
}

/// The comment lines of an export that say a value is not measured, not estimated or poorly
/// determined.
fn caveats(t: &str) -> usize {
    t.lines()
        .filter(|l| {
            let b = l.trim_start();
            (b.starts_with('#') || b.starts_with("<!--"))
                && [": NOT MEASURED", ": NOT ESTIMATED", ": POORLY DETERMINED"]
                    .iter()
                    .any(|k| b.contains(k))
        })
        .count()
}

/// A lever arm the motion did not observe is held at the default prior (zero); each export
/// says, in a comment beside the numbers, that it was not measured, and still reads in its
/// tool. The same recording with its rotations says nothing of the kind.
#[test]
fn a_lever_arm_held_at_the_prior_is_marked_not_measured_in_every_export() {
    let tmp = TmpDir::new("prior-exports");
    for calm in [true, false] {
        let data = calm_dataset(&tmp, if calm { "calm" } else { "full" }, calm);
        let out = tmp.path(if calm { "calm.yaml" } else { "full.yaml" });
        let r = dvlcal(&["calibrate", s(&data), "--out", s(&out)]);
        assert!(r.status.success(), "{}", text(&r.stderr));
        let f = read_calib_yaml(&out).unwrap();
        let lever = f.observability.as_ref().unwrap().lever_arm;
        let e = exports(&out);
        let [tf, urdf, kalibr] = notes(&e, "lever arm", "NOT MEASURED");
        if !calm {
            assert_ne!(lever, Observability::Prior);
            for t in [&e.tf, &e.urdf, &e.kalibr] {
                assert!(!t.contains("NOT MEASURED"), "{t}");
            }
            continue;
        }
        assert_eq!(lever, Observability::Prior);
        assert_eq!(f.lever_arm_cam_m, [0.0; 3]);
        // tf: before the commands that carry the zeros.
        assert_eq!(tf.len(), 1, "{}", e.tf);
        let at = |t: &str, l: &str| t.find(l).unwrap();
        assert!(at(&e.tf, tf[0]) < at(&e.tf, "rosrun"), "{}", e.tf);
        assert!(tf[0].contains("prior"), "{}", tf[0]);
        // URDF: in the joint, above the origin, and ROS's parser still reads the file.
        assert_eq!(urdf.len(), 1, "{}", e.urdf);
        assert!(at(&e.urdf, urdf[0]) < at(&e.urdf, "<origin"), "{}", e.urdf);
        check_urdf(&out.with_file_name("calm-urdf.xml"));
        // Kalibr: in the header, and a pointer beside the camera's transform; still YAML with
        // the cameras alone at the top level.
        assert_eq!(kalibr.len(), 1, "{}", e.kalibr);
        assert!(at(&e.kalibr, kalibr[0]) < at(&e.kalibr, "\n  T_cam_imu:"));
        assert!(
            e.kalibr
                .contains("  # not all of the values below were measured")
        );
        let v: serde_yaml::Value = serde_yaml::from_str(&e.kalibr).unwrap();
        let top: Vec<&str> = v
            .as_mapping()
            .unwrap()
            .keys()
            .filter_map(|k| k.as_str())
            .collect();
        assert_eq!(top, ["cam0"]);
        // The rotation, clock and scale were measured: no note for them.
        for t in [&e.tf, &e.urdf, &e.kalibr] {
            assert_eq!(caveats(t), 1, "{t}");
        }
    }
}

/// Parameters held at the value given (`--method fixed --init`) are marked as not estimated in
/// each export, the clock offset and scale included; a failed calibration exported with
/// `--force` says it failed, with the reasons, at the top of each.
#[test]
fn held_parameters_and_a_forced_failure_are_said_in_every_export() {
    let tmp = TmpDir::new("held-exports");
    let data = repo("sample_data/poses");
    let truth_path = data.join("truth/calibration.yaml");
    let out = tmp.path("fixed.yaml");
    let r = dvlcal(&[
        "calibrate",
        s(&data),
        "--method",
        "fixed",
        "--init",
        s(&truth_path),
        "--out",
        s(&out),
    ]);
    assert!(r.status.success(), "{}", text(&r.stdout));
    let e = exports(&out);
    for what in [
        "rotation",
        "lever arm",
        "clock offset",
        "DVL velocity scale",
    ] {
        let [tf, urdf, kalibr] = notes(&e, what, "NOT ESTIMATED: held at the value given");
        assert_eq!(
            (tf.len(), urdf.len(), kalibr.len()),
            (1, 1, 1),
            "{what}:\n{}\n{}\n{}",
            e.tf,
            e.urdf,
            e.kalibr
        );
    }
    assert!(!e.tf.contains("FAILED"));
    check_urdf(&out.with_file_name("fixed-urdf.xml"));

    // A clock 530 ms off, held: the run fails; with --force the exports are written and say so.
    let truth = std::fs::read_to_string(&truth_path).unwrap();
    let guess = tmp.path("guess.yaml");
    std::fs::write(
        &guess,
        truth.replace("time_offset_s: 0.07\n", "time_offset_s: 0.6\n"),
    )
    .unwrap();
    let out = tmp.path("forced.yaml");
    let r = dvlcal(&[
        "calibrate",
        s(&data),
        "--method",
        "fixed",
        "--init",
        s(&guess),
        "--out",
        s(&out),
        "--force",
    ]);
    assert!(!r.status.success(), "{}", text(&r.stdout));
    let f = read_calib_yaml(&out).unwrap();
    assert!(!f.failure.is_empty());
    let e = exports(&out);
    let [tf, urdf, kalibr] = notes(&e, "THIS CALIBRATION FAILED", "--force");
    assert_eq!((tf.len(), kalibr.len()), (1, 1), "{}\n{}", e.tf, e.kalibr);
    // XML comments may not hold "--": the URDF spells the option "- -force".
    assert!(urdf.is_empty());
    let [_, urdf, _] = notes(&e, "THIS CALIBRATION FAILED", "- -force");
    assert_eq!(urdf.len(), 1, "{}", e.urdf);
    // The first reason of the result file, in words, in each.
    let first: String = f.failure[0].split_whitespace().collect::<Vec<_>>()[..6].join(" ");
    for (t, first) in [
        (&e.tf, first.clone()),
        (&e.urdf, first.replace("--", "- -")),
        (&e.kalibr, first.clone()),
    ] {
        assert!(t.contains(&first), "{first}\n{t}");
    }
    check_urdf(&out.with_file_name("forced-urdf.xml"));
}

// ---------------------------------------------------------------------------------------------
// compare-calib

/// An estimate equal to the truth with honest standard deviations passes; the same file marked
/// `status: failed` is reported as failed, with the reason it records, and exits non-zero.
#[test]
fn compare_calib_does_not_pass_a_failed_estimate() {
    let tmp = TmpDir::new("compare-failed");
    let truth = repo("sample_data/poses/truth/calibration.yaml");
    let body = std::fs::read_to_string(&truth).unwrap();
    let std = "std:\n  rotation_deg: [0.1, 0.1, 0.1]\n  lever_arm_m: [0.01, 0.01, 0.01]\n  \
               time_offset_s: 0.002\n  velocity_scale: 0.002\n";
    let ok = tmp.path("ok.yaml");
    std::fs::write(&ok, format!("{body}{std}")).unwrap();
    let r = dvlcal(&["compare-calib", "--estimate", s(&ok), "--truth", s(&truth)]);
    assert!(r.status.success(), "{}", text(&r.stderr));
    assert!(
        text(&r.stdout).contains("within 3 std"),
        "{}",
        text(&r.stdout)
    );

    let reason = "the DVL's velocities do not fit the camera's motion (normalized cost 41.2)";
    let failed = tmp.path("failed.yaml");
    std::fs::write(
        &failed,
        format!("status: failed\nfailure:\n  - \"{reason}\"\n{body}{std}"),
    )
    .unwrap();
    let r = dvlcal(&[
        "compare-calib",
        "--estimate",
        s(&failed),
        "--truth",
        s(&truth),
    ]);
    let (out, err) = (text(&r.stdout), text(&r.stderr));
    assert_eq!(r.status.code(), Some(1), "{out}{err}");
    assert!(!out.contains("within 3 std"), "{out}");
    assert!(
        out.lines().nth(1).unwrap_or_default().contains("FAILED") && out.contains(reason),
        "{out}"
    );
    assert!(
        err.contains("failed.yaml is a failed calibration (status: failed)")
            && err.contains(reason),
        "{err}"
    );

    // A failed file without reasons says it records none.
    std::fs::write(&failed, format!("status: failed\n{body}{std}")).unwrap();
    let r = dvlcal(&[
        "compare-calib",
        "--estimate",
        s(&failed),
        "--truth",
        s(&truth),
    ]);
    assert!(!r.status.success());
    assert!(
        text(&r.stderr).contains("records no reason"),
        "{}",
        text(&r.stderr)
    );
}
