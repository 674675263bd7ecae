//! A DVL clock that steps back, forward, or restarts mid-log: the step is found and named by
//! file:line, the log is split into clock segments with an offset each, and the extrinsics and
//! scale come out as without the step.

mod tmp_common;
mod truth_common;

use std::path::{Path, PathBuf};

use dvlcal::io::calib_yaml::ResultStatus;
use dvlcal::io::dvl::{ClockStepKind, DvlReadOptions, read_dvl_log};
use tmp_common::{TmpDir, dvlcal, s};
use truth_common::against_truth;

const SAMPLE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/sample_data/poses");
/// The first report (1-based line) on the stepped clock.
const STEP_LINE: usize = 351;
const TRUE_OFFSET_S: f64 = 0.07;

/// A copy of the poses sample whose DVL log's clock is changed by `change(line, time_us) -> new
/// time_us` (1-based line), both stamps alike; the `time` increments are kept, as the DVL reports
/// them whatever its clock does.
fn stepped(tmp: &TmpDir, name: &str, change: impl Fn(usize, i64) -> i64) -> PathBuf {
    let dir = tmp.0.join(name);
    std::fs::create_dir_all(dir.join("truth")).unwrap();
    for f in ["poses.txt", "truth/calibration.yaml"] {
        std::fs::copy(Path::new(SAMPLE).join(f), dir.join(f)).unwrap();
    }
    let log = std::fs::read_to_string(Path::new(SAMPLE).join("dvl.jsonl")).unwrap();
    let mut out = String::new();
    for (i, line) in log.lines().enumerate() {
        let mut v: serde_json::Value = serde_json::from_str(line).unwrap();
        for key in ["time_of_validity", "time_of_transmission"] {
            let t = v[key].as_i64().unwrap();
            v[key] = serde_json::Value::from(change(i + 1, t));
        }
        out.push_str(&v.to_string());
        out.push('\n');
    }
    std::fs::write(dir.join("dvl.jsonl"), out).unwrap();
    dir
}

/// `changed` from `STEP_LINE` on, `t` before.
fn after(line: usize, t: i64, changed: i64) -> i64 {
    if line >= STEP_LINE { changed } else { t }
}

/// Calibrates `dir` and checks the result against the truth: every parameter within 3 std (the
/// offset of the first segment), the second segment's offset `expected_second` within 3 std.
fn calibrates_with_two_segments(dir: &Path, kind: ClockStepKind, expected_second: f64) {
    let log = read_dvl_log(&dir.join("dvl.jsonl"), &DvlReadOptions::default()).unwrap();
    assert_eq!(
        log.stats.clock_steps.len(),
        1,
        "{:?}",
        log.stats.clock_steps
    );
    let step = &log.stats.clock_steps[0];
    assert_eq!(
        (step.line, step.previous_line, step.kind),
        (STEP_LINE, STEP_LINE - 1, kind)
    );
    assert_eq!(log.clock_segments.len(), 2);
    assert_eq!(log.clock_segments[1].lines.0, STEP_LINE);

    let out_yaml = dir.join("out/calibration.yaml");
    let out = dvlcal(&["calibrate", s(dir), "--out", s(&out_yaml)]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stdout}\n{stderr}");
    // Named by file and line.
    let named = format!("dvl.jsonl:{STEP_LINE}: the DVL clock {}", kind.words());
    assert!(
        stdout.contains(&named) || stderr.contains(&named),
        "{stdout}\n{stderr}"
    );
    assert!(
        stdout.contains("clock segments calibrated together"),
        "{stdout}"
    );

    let t = against_truth(dir, &out_yaml);
    eprintln!("{}", t.table);
    assert_eq!(t.file.status, Some(ResultStatus::Ok));
    truth_common::assert_within(&t, 3.0);
    let segs = t
        .file
        .info
        .as_ref()
        .and_then(|i| i.figures.clock_segments.clone())
        .expect("clock_segments in the result");
    assert_eq!(segs.len(), 2);
    assert_eq!(segs[1].lines[0], STEP_LINE);
    let (o1, s1) = (
        segs[0].time_offset_s.unwrap(),
        segs[0].time_offset_std_s.unwrap(),
    );
    let (o2, s2) = (
        segs[1].time_offset_s.unwrap(),
        segs[1].time_offset_std_s.unwrap(),
    );
    assert!((o1 - TRUE_OFFSET_S).abs() < 3.0 * s1, "{o1} +- {s1}");
    assert!((o2 - expected_second).abs() < 3.0 * s2, "{o2} +- {s2}");
    assert!(s1 < 0.01 && s2 < 0.01, "{s1} {s2}");
}

#[test]
fn a_dvl_clock_stepping_back_10_s_is_split_at_its_line() {
    let tmp = TmpDir::new("clock-step-back");
    let dir = stepped(&tmp, "back", |l, t| after(l, t, t - 10_000_000));
    // The DVL clock reads 10 s less: t_cam = t_dvl + 10.07 s there.
    calibrates_with_two_segments(&dir, ClockStepKind::Back, TRUE_OFFSET_S + 10.0);
}

#[test]
fn a_dvl_clock_stepping_forward_10_s_is_split_at_its_line() {
    let tmp = TmpDir::new("clock-step-forward");
    let dir = stepped(&tmp, "forward", |l, t| after(l, t, t + 10_000_000));
    calibrates_with_two_segments(&dir, ClockStepKind::Forward, TRUE_OFFSET_S - 10.0);
}

#[test]
fn a_dvl_reboot_restarting_its_clock_near_zero_is_split_at_its_line() {
    let tmp = TmpDir::new("clock-restart");
    // After the reboot the clock counts from 5 s after the Unix epoch.
    let first_after = 1_700_000_000_000_197 + 35_000_000;
    let dir = stepped(&tmp, "restart", move |l, t| {
        after(l, t, t - first_after + 5_000_000)
    });
    let shift = (first_after - 5_000_000) as f64 * 1e-6;
    calibrates_with_two_segments(&dir, ClockStepKind::Restart, TRUE_OFFSET_S + shift);
}

#[test]
fn a_short_segment_is_left_out_with_a_warning() {
    let tmp = TmpDir::new("clock-short");
    // A step back at line 351, and another 2 s later: the middle segment is too short.
    let dir = stepped(&tmp, "short", |l, t| {
        if l >= STEP_LINE + 20 {
            t - 20_000_000
        } else {
            after(l, t, t - 10_000_000)
        }
    });
    let out_yaml = dir.join("out/calibration.yaml");
    let r = dvlcal(&["calibrate", s(&dir), "--out", s(&out_yaml)]);
    let stdout = String::from_utf8_lossy(&r.stdout);
    assert!(r.status.success(), "{stdout}");
    assert!(stdout.contains("is left out: too short"), "{stdout}");
    let t = against_truth(&dir, &out_yaml);
    let segs = t
        .file
        .info
        .as_ref()
        .and_then(|i| i.figures.clock_segments.clone())
        .unwrap();
    assert_eq!(segs.len(), 3);
    assert!(segs[1].left_out.is_some() && segs[1].time_offset_s.is_none());
    assert!(segs[0].time_offset_s.is_some() && segs[2].time_offset_s.is_some());
}

#[test]
fn a_steady_clock_with_a_pause_is_one_segment() {
    // Reports missing for 10 s (the `time` increment says so) are a pause, not a step.
    let tmp = TmpDir::new("clock-pause");
    let dir = tmp.0.join("pause");
    std::fs::create_dir_all(&dir).unwrap();
    let log = std::fs::read_to_string(Path::new(SAMPLE).join("dvl.jsonl")).unwrap();
    let mut out = String::new();
    for (i, line) in log.lines().enumerate() {
        let mut v: serde_json::Value = serde_json::from_str(line).unwrap();
        if (STEP_LINE..STEP_LINE + 100).contains(&(i + 1)) {
            continue;
        }
        if i + 1 == STEP_LINE + 100 {
            v["time"] = serde_json::Value::from(10_100.0);
        }
        out.push_str(&v.to_string());
        out.push('\n');
    }
    std::fs::write(dir.join("dvl.jsonl"), out).unwrap();
    let log = read_dvl_log(&dir.join("dvl.jsonl"), &DvlReadOptions::default()).unwrap();
    assert!(
        log.stats.clock_steps.is_empty(),
        "{:?}",
        log.stats.clock_steps
    );
    assert_eq!(log.clock_segments.len(), 1);
    // The sample itself has one segment too.
    let log = read_dvl_log(
        &Path::new(SAMPLE).join("dvl.jsonl"),
        &DvlReadOptions::default(),
    )
    .unwrap();
    assert_eq!(log.clock_segments.len(), 1);
    assert_eq!(log.clock_segments[0].samples, 0..log.samples.len());
}

#[test]
fn the_real_a50_logs_and_bags_have_a_steady_clock() {
    // The A50's own recordings (JSON and the driver's bags): jitter of the `time` increments
    // against `time_of_validity` of up to 0.1 s, and no step.
    let dir = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../shared/data/a50-ros-driver"
    ));
    let mut read = 0;
    for name in [
        "dvl",
        "dvl_circle",
        "dvl_fast_rectangle",
        "dvl_slow_rectangle",
    ] {
        for ext in ["jsonl", "bag"] {
            let path = dir.join(format!("{name}.{ext}"));
            let log = read_dvl_log(&path, &DvlReadOptions::default()).unwrap();
            assert!(log.samples.len() > 300, "{}", path.display());
            assert!(
                log.stats.clock_steps.is_empty(),
                "{}: {:?}",
                path.display(),
                log.stats.clock_steps
            );
            assert_eq!(log.clock_segments.len(), 1, "{}", path.display());
            read += 1;
        }
    }
    assert_eq!(read, 8);
}

/// A copy of the poses sample whose camera clock steps by `step_s` from pose line `from` on
/// (1-based, the header being line 1).
fn camera_stepped(tmp: &TmpDir, name: &str, from: usize, step_s: f64) -> PathBuf {
    let dir = tmp.0.join(name);
    std::fs::create_dir_all(dir.join("truth")).unwrap();
    for f in ["dvl.jsonl", "truth/calibration.yaml"] {
        std::fs::copy(Path::new(SAMPLE).join(f), dir.join(f)).unwrap();
    }
    let text = std::fs::read_to_string(Path::new(SAMPLE).join("poses.txt")).unwrap();
    let mut out = String::new();
    for (i, line) in text.lines().enumerate() {
        let mut fields: Vec<String> = line.split(' ').map(str::to_owned).collect();
        if i + 1 >= from && !line.starts_with('#') {
            // Whole nanoseconds: the stamp keeps its nine decimals.
            let (sec, frac) = fields[0].split_once('.').unwrap();
            let ns: i128 = sec.parse::<i128>().unwrap() * 1_000_000_000
                + frac.parse::<i128>().unwrap()
                + (step_s * 1e9).round() as i128;
            fields[0] = format!(
                "{}.{:09}",
                ns.div_euclid(1_000_000_000),
                ns.rem_euclid(1_000_000_000)
            );
        }
        out.push_str(&fields.join(" "));
        out.push('\n');
    }
    std::fs::write(dir.join("poses.txt"), out).unwrap();
    dir
}

#[test]
fn a_camera_clock_stepping_back_is_split_at_its_line_and_each_segment_keeps_its_offset() {
    let tmp = TmpDir::new("camera-clock-step");
    // From line 352 (pose 351, 35 s into the minute) the camera clock reads 10 s earlier.
    let dir = camera_stepped(&tmp, "back", 352, -10.0);
    let out_yaml = dir.join("out/calibration.yaml");
    let out = dvlcal(&["calibrate", s(&dir), "--out", s(&out_yaml)]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stdout}\n{stderr}");
    let named = "poses.txt:352: the camera clock steps back by 10.000 s after line 351";
    assert!(
        stdout.contains(named) || stderr.contains(named),
        "{stdout}\n{stderr}"
    );
    let t = against_truth(&dir, &out_yaml);
    assert_eq!(t.file.status, Some(ResultStatus::Ok));
    truth_common::assert_within(&t, 3.0);
    let segs = t
        .file
        .info
        .as_ref()
        .and_then(|i| i.figures.clock_segments.clone())
        .expect("clock_segments in the result");
    assert_eq!(segs.len(), 2, "{segs:?}");
    assert_eq!(segs[0].camera_lines, Some([2, 351]));
    assert_eq!(segs[1].camera_lines.map(|l| l[0]), Some(352));
    // On its own camera clock the second segment's offset is 10 s smaller.
    for (seg, expected) in segs.iter().zip([TRUE_OFFSET_S, TRUE_OFFSET_S - 10.0]) {
        let (o, sd) = (seg.time_offset_s.unwrap(), seg.time_offset_std_s.unwrap());
        assert!(
            (o - expected).abs() < 3.0 * sd && sd < 0.01,
            "{o} +- {sd} vs {expected}"
        );
    }
    // One drift needs one clock: refused, naming the option and the segments.
    let out = dvlcal(&[
        "calibrate",
        s(&dir),
        "--clock-drift",
        "--out",
        s(&dir.join("drift.yaml")),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("--clock-drift with a clock that steps")
            && stderr.contains("camera clock segment"),
        "{stderr}"
    );
    // A stamp repeated, or a step back under a second, is still an error naming the line.
    let dir = camera_stepped(&tmp, "shuffled", 352, -0.15);
    let out = dvlcal(&["calibrate", s(&dir), "--out", s(&dir.join("out.yaml"))]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("poses.txt:352") && stderr.contains("out of order"),
        "{stderr}"
    );
}
