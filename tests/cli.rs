//! End-to-end tests of the `dvlcal` binary: simulate, fit-trajectory, eval-twist, and the
//! errors bad input files get.

use std::path::{Path, PathBuf};
use std::process::Output;

const HEADER: &str =
    "t,vx,vy,vz,wx,wy,wz,std_vx,std_vy,std_vz,std_wx,std_wy,std_wz,dvx,dvy,dvz,dwx,dwy,dwz";

#[path = "tmp_common/mod.rs"]
mod tmp_common;
use tmp_common::{TmpDir as TempDir, dvlcal, s};

fn assert_ok(out: &Output) {
    assert!(
        out.status.success(),
        "dvlcal failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Simulates a 10 s sinusoid dataset into `dir`.
fn simulate(dir: &TempDir) -> PathBuf {
    let d = dir.path("sim");
    assert_ok(&dvlcal(&[
        "simulate",
        "--out",
        s(&d),
        "--seed",
        "3",
        "--duration",
        "10",
        "--motion",
        "sinusoid",
    ]));
    d
}

fn data_rows(csv: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(csv).expect("read csv");
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some(HEADER));
    lines.map(str::to_owned).collect()
}

#[test]
fn simulate_fit_and_eval_round_trip() {
    let dir = TempDir::new("ok");
    let sim = simulate(&dir);
    let poses = sim.join("poses.txt");
    let n_poses = std::fs::read_to_string(&poses)
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .count();
    assert_eq!(n_poses, 101);

    // At the pose times.
    let out = dir.path("twist.csv");
    assert_ok(&dvlcal(&[
        "fit-trajectory",
        "--poses",
        s(&poses),
        "--out",
        s(&out),
    ]));
    let rows = data_rows(&out);
    assert_eq!(rows.len(), n_poses);
    assert!(rows.iter().all(|r| r.split(',').count() == 19));

    // At requested times (absolute, as in the files).
    let times = dir.path("times.txt");
    std::fs::write(
        &times,
        "# times\n1700000000.05\n1700000003.333333333\n\n1700000009.999\n1700000000.0\n",
    )
    .unwrap();
    let out2 = dir.path("twist_at.csv");
    assert_ok(&dvlcal(&[
        "fit-trajectory",
        "--poses",
        s(&poses),
        "--out",
        s(&out2),
        "--at",
        s(&times),
    ]));
    let rows = data_rows(&out2);
    assert_eq!(rows.len(), 4);
    assert!(rows[1].starts_with("1700000003.333333333,"), "{}", rows[1]);

    // Twist errors against the simulation's truth are small: the lively motion at 10 Hz with
    // 2 mm / 2 mrad noise gives RMS norm errors of about 0.03 m/s and 0.06 rad/s.
    let ev = dvlcal(&[
        "eval-twist",
        "--estimate",
        s(&out),
        "--truth",
        s(&sim.join("truth").join("twist.csv")),
    ]);
    assert_ok(&ev);
    let text = String::from_utf8_lossy(&ev.stdout).to_string();
    let norm = |key: &str| -> f64 {
        let line = text.lines().find(|l| l.starts_with(key)).expect(key);
        let i = line.find("(norm ").expect("norm") + 6;
        line[i..]
            .trim_end_matches(')')
            .trim()
            .parse()
            .expect("number")
    };
    let (ev_v, ev_w) = (norm("RMS error v"), norm("RMS error w"));
    assert!(ev_v < 0.06, "RMS v error {ev_v}\n{text}");
    assert!(ev_w < 0.12, "RMS w error {ev_w}\n{text}");
}

/// Runs fit-trajectory on a TUM file with `content` and checks that it fails, naming `file:line`.
fn fails_at(dir: &TempDir, name: &str, content: &str, line: usize) {
    let p = dir.path(name);
    std::fs::write(&p, content).unwrap();
    let out = dvlcal(&[
        "fit-trajectory",
        "--poses",
        s(&p),
        "--out",
        s(&dir.path("o.csv")),
    ]);
    expect_failure(&out, &format!("{}:{line}:", p.display()));
}

fn expect_failure(out: &Output, needle: &str) {
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "expected failure for {needle}");
    assert!(err.contains(needle), "stderr lacks '{needle}': {err}");
    assert!(!err.contains("panicked"), "panic: {err}");
}

const GOOD: [&str; 4] = [
    "1700000000.0 0 0 0 0 0 0 1",
    "1700000000.1 0.01 0 0 0 0 0 1",
    "1700000000.2 0.02 0 0 0 0 0 1",
    "1700000000.3 0.03 0 0 0 0 0 1",
];

fn tum(lines: &[&str]) -> String {
    let mut s = String::from("# timestamp tx ty tz qx qy qz qw\n");
    for l in lines {
        s.push_str(l);
        s.push('\n');
    }
    s
}

#[test]
fn bad_pose_files_name_file_and_line() {
    let dir = TempDir::new("bad");
    // Line numbers count the comment header as line 1.
    let mut l = GOOD.to_vec();
    l[1] = "1700000000.1 0.01 0 0 0 0 1";
    fails_at(&dir, "malformed.txt", &tum(&l), 3);
    let mut l = GOOD.to_vec();
    l[2] = "1700000000.2 NaN 0 0 0 0 0 1";
    fails_at(&dir, "nan.txt", &tum(&l), 4);
    let mut l = GOOD.to_vec();
    l[2] = "1700000000.2 0.02 0 0 0 0 0 nan";
    fails_at(&dir, "nan_q.txt", &tum(&l), 4);
    let mut l = GOOD.to_vec();
    l[3] = "1700000000.15 0.03 0 0 0 0 0 1";
    fails_at(&dir, "backwards.txt", &tum(&l), 5);
    let mut l = GOOD.to_vec();
    l[2] = "1700000000.1 0.02 0 0 0 0 0 1";
    fails_at(&dir, "duplicate.txt", &tum(&l), 4);
    let mut l = GOOD.to_vec();
    l[1] = "1700000000.1 0.01 0 0 0 0 0 1.1";
    fails_at(&dir, "quaternion.txt", &tum(&l), 3);
    let mut l = GOOD.to_vec();
    l[0] = "17000000x0.0 0 0 0 0 0 0 1";
    fails_at(&dir, "bad_time.txt", &tum(&l), 2);
    fails_at(&dir, "empty.txt", "", 1);
    fails_at(&dir, "comments.txt", "# nothing\n# here\n", 2);

    // Too few poses to fit: the message names the file.
    let p = dir.path("two.txt");
    std::fs::write(&p, tum(&GOOD[..2])).unwrap();
    let out = dvlcal(&[
        "fit-trajectory",
        "--poses",
        s(&p),
        "--out",
        s(&dir.path("o.csv")),
    ]);
    expect_failure(&out, s(&p));

    // A missing file.
    let p = dir.path("missing.txt");
    let out = dvlcal(&[
        "fit-trajectory",
        "--poses",
        s(&p),
        "--out",
        s(&dir.path("o.csv")),
    ]);
    expect_failure(&out, s(&p));
}

#[test]
fn bad_time_files_name_file_and_line() {
    let dir = TempDir::new("times");
    let poses = dir.path("poses.txt");
    std::fs::write(&poses, tum(&GOOD)).unwrap();
    let run = |name: &str, content: &str, line: usize| {
        let p = dir.path(name);
        std::fs::write(&p, content).unwrap();
        let out = dvlcal(&[
            "fit-trajectory",
            "--poses",
            s(&poses),
            "--out",
            s(&dir.path("o.csv")),
            "--at",
            s(&p),
        ]);
        expect_failure(&out, &format!("{}:{line}:", p.display()));
    };
    run(
        "after.txt",
        "1700000000.1\n1700000000.2\n1700000000.31\n",
        3,
    );
    run("before.txt", "# t\n1699999999.99\n", 2);
    run("nan.txt", "1700000000.1\nnan\n", 2);
    run("two_fields.txt", "1700000000.1 1700000000.2\n", 1);
    let missing = dir.path("none.txt");
    let out = dvlcal(&[
        "fit-trajectory",
        "--poses",
        s(&poses),
        "--out",
        s(&dir.path("o.csv")),
        "--at",
        s(&missing),
    ]);
    expect_failure(&out, s(&missing));
}

#[test]
fn robustness_options_refuse_bad_values_by_name() {
    for (option, value) in [
        ("--loss", "tukey"),
        ("--default-lever-arm-sigma", "-1"),
        ("--default-lever-arm-sigma", "0"),
        ("--default-lever-arm-sigma", "abc"),
    ] {
        let out = dvlcal(&["calibrate", "/nonexistent", option, value]);
        assert!(!out.status.success(), "{option} {value}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(option), "{option} {value}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
}
