//! File formats: round trips, exact time stamps, and errors that name file and line.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use dvlcal::io::calib_yaml::{
    CalibrationFile, CalibrationInfo, CalibrationStd, Observability, ObservabilityFlags,
    read_calib_yaml, write_calib_yaml,
};
use dvlcal::io::dvl::a50::{
    A50Transducer, A50VelocityReport, parse_velocity_report, velocity_report_line, write_a50_jsonl,
};
use dvlcal::io::dvl::{DvlLog, DvlReadOptions, read_dvl_log};
use dvlcal::io::times::read_times;
use dvlcal::io::tum::{read_tum, write_tum};
use dvlcal::io::twist_csv::{TWIST_CSV_HEADER, TwistRow, read_twist_csv, write_twist_csv};
use dvlcal::io::write_atomic;
use dvlcal::lie::Se3;
use dvlcal::time::Epoch;
use dvlcal::types::{CalibrationParams, PoseMeasurement};

/// Every velocity report of an A50 log, valid and invalid, read strictly (the first malformed
/// line is an error).
fn read_a50_velocities(path: &Path, epoch: Option<Epoch>) -> dvlcal::Result<DvlLog> {
    let opts = DvlReadOptions {
        strict: true,
        epoch,
        include_invalid: true,
        ..DvlReadOptions::default()
    };
    read_dvl_log(path, &opts)
}
use nalgebra::{Vector3, Vector6};

const REAL_LOG: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../shared/data/a50-ros-driver/dvl.jsonl"
);

/// A fresh directory under the system temporary directory.
fn temp_dir(tag: &str) -> PathBuf {
    static N: AtomicU64 = AtomicU64::new(0);
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or(0);
    let dir = std::env::temp_dir().join(format!(
        "dvlcal-io-{tag}-{}-{}-{nanos}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn write_file(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Asserts an error message names `name` and line `line` as `name:line:`.
fn assert_err_at(err: dvlcal::Error, name: &str, line: usize) {
    let msg = err.to_string();
    assert!(
        msg.contains(&format!("{name}:{line}:")),
        "expected {name}:{line} in '{msg}'"
    );
}

fn sample_poses() -> Vec<PoseMeasurement> {
    (0..20)
        .map(|k| {
            let s = k as f64;
            let xi = Vector6::new(0.1 * s, -0.2 * s, 0.3, 0.01 * s, 0.7, -0.02 * s);
            PoseMeasurement {
                t: 0.123456789 + 0.05 * s,
                pose: Se3::exp(&xi),
                cov: None,
            }
        })
        .collect()
}

#[test]
fn atomic_write_replaces_and_leaves_no_temporary() {
    let dir = temp_dir("atomic");
    let p = dir.join("out.txt");
    write_atomic(&p, b"first").unwrap();
    write_atomic(&p, b"second").unwrap();
    assert_eq!(std::fs::read(&p).unwrap(), b"second");
    let names: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
    assert_eq!(names.len(), 1, "temporary files left behind");
    // A target that cannot be written (a directory in its place) fails and is left as it was.
    let sub = dir.join("sub");
    std::fs::create_dir(&sub).unwrap();
    std::fs::write(sub.join("keep"), b"x").unwrap();
    let err = write_atomic(&sub, b"data").unwrap_err();
    assert!(err.to_string().contains("sub"), "{err}");
    assert!(sub.join("keep").exists());
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 2);
}

#[test]
fn tum_round_trip() {
    let dir = temp_dir("tum");
    let p = dir.join("poses.txt");
    let epoch = Epoch { sec: 1_718_000_000 };
    let poses = sample_poses();
    write_tum(&p, epoch, &poses).unwrap();
    let back = read_tum(&p, None).unwrap();
    assert_eq!(back.epoch, epoch);
    assert_eq!(back.poses.len(), poses.len());
    // Line 1 is the comment header.
    assert_eq!(back.lines, (2..2 + poses.len()).collect::<Vec<_>>());
    for (a, b) in poses.iter().zip(&back.poses) {
        assert!((a.t - b.t).abs() < 1e-9);
        assert!((a.pose.trans - b.pose.trans).norm() == 0.0);
        assert!((a.pose.rot - b.pose.rot).abs().max() < 1e-14);
        assert!(b.cov.is_none());
    }
}

#[test]
fn tum_keeps_unix_time_digits() {
    let dir = temp_dir("tumtime");
    let p = write_file(
        &dir,
        "unix.txt",
        "1718000000.123456789 1 2 3 0 0 0 1\n1718000001.000000001 1 2 3 0 0 0 1\n",
    );
    let r = read_tum(&p, None).unwrap();
    assert_eq!(r.epoch, Epoch { sec: 1_718_000_000 });
    assert!((r.poses[0].t - 0.123456789).abs() < 1e-15);
    let out = dir.join("out.txt");
    write_tum(&out, r.epoch, &r.poses).unwrap();
    let text = std::fs::read_to_string(&out).unwrap();
    let stamps: Vec<&str> = text
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| l.split(' ').next().unwrap())
        .collect();
    assert_eq!(stamps, ["1718000000.123456789", "1718000001.000000001"]);
}

#[test]
fn tum_accepts_comments_commas_crlf_and_normalises() {
    let dir = temp_dir("tumfmt");
    let p = write_file(
        &dir,
        "mixed.txt",
        "# header\r\n\r\n10.5,1,2,3,0,0,0,1.0005\r\n  11.0 4 5 6 0 0 0.7071068 0.7071068 # note\r\n",
    );
    let r = read_tum(&p, Some(Epoch { sec: 10 })).unwrap();
    assert_eq!(r.lines, [3, 4]);
    assert_eq!(r.poses[0].t, 0.5);
    assert!(
        (r.poses[0].pose.rot - nalgebra::Matrix3::identity())
            .abs()
            .max()
            < 1e-12
    );
    assert_eq!(r.poses[1].pose.trans, Vector3::new(4.0, 5.0, 6.0));
}

#[test]
fn tum_bad_input_names_file_and_line() {
    let dir = temp_dir("tumbad");
    let good = "1.0 0 0 0 0 0 0 1\n";
    let cases: [(&str, String, usize); 9] = [
        (
            "malformed.txt",
            format!("# c\n{good}2.0 0 0 x 0 0 0 1\n"),
            3,
        ),
        ("badtime.txt", format!("{good}2.0.0 0 0 0 0 0 0 1\n"), 2),
        ("nan.txt", format!("{good}\n2.0 0 NaN 0 0 0 0 1\n"), 3),
        ("inf.txt", format!("{good}2.0 0 0 0 0 0 0 inf\n"), 2),
        ("fields.txt", format!("{good}2.0 0 0 0 0 0 1\n"), 2),
        (
            "order.txt",
            format!("{good}3.0 0 0 0 0 0 0 1\n2.5 0 0 0 0 0 0 1\n"),
            3,
        ),
        ("dup.txt", format!("{good}{good}"), 2),
        ("quat.txt", format!("{good}2.0 0 0 0 0 0 0 1.01\n"), 2),
        ("empty.txt", "# nothing here\n\n".to_string(), 2),
    ];
    for (name, text, line) in cases {
        let p = write_file(&dir, name, &text);
        let err = read_tum(&p, None).unwrap_err();
        assert_err_at(err, name, line);
    }
    // The ordering errors say which line they follow.
    let p = write_file(&dir, "dup2.txt", &format!("# c\n{good}{good}"));
    let msg = read_tum(&p, None).unwrap_err().to_string();
    assert!(
        msg.contains("dup2.txt:3:") && msg.contains("line 2"),
        "{msg}"
    );
    // A missing file names the file.
    let missing = dir.join("missing.txt");
    let msg = read_tum(&missing, None).unwrap_err().to_string();
    assert!(msg.contains("missing.txt"), "{msg}");
}

#[test]
fn times_read_with_lines_and_errors() {
    let dir = temp_dir("times");
    let p = write_file(
        &dir,
        "times.txt",
        "# eval times\n1718000000.5\r\n\n1717999999.25\n1718000002\n",
    );
    let epoch = Epoch { sec: 1_718_000_000 };
    let t = read_times(&p, epoch).unwrap();
    assert_eq!(t, vec![(2, 0.5), (4, -0.75), (5, 2.0)]);
    for (name, text, line) in [
        ("t_nan.txt", "1\nnan\n", 2),
        ("t_word.txt", "1\n2\nabc\n", 3),
        ("t_two.txt", "1 2\n", 1),
        ("t_inf.txt", "\ninf\n", 2),
    ] {
        let p = write_file(&dir, name, text);
        assert_err_at(read_times(&p, epoch).unwrap_err(), name, line);
    }
}

fn sample_rows() -> Vec<TwistRow> {
    (0..10)
        .map(|k| {
            let s = k as f64;
            let v = |a: f64| Vector3::new(a, -a / 3.0, 1e-12 * a);
            TwistRow {
                t: 0.000000001 + s / 7.0,
                v: v(s + 0.1),
                w: v(0.3 * s),
                std_v: v(1e-3),
                std_w: v(2e-4),
                dv: v(-s),
                dw: v(s * 1e5),
            }
        })
        .collect()
}

#[test]
fn twist_csv_round_trip_and_errors() {
    let dir = temp_dir("twist");
    let p = dir.join("twist.csv");
    let epoch = Epoch { sec: 1_718_000_000 };
    let rows = sample_rows();
    write_twist_csv(&p, epoch, &rows).unwrap();
    let text = std::fs::read_to_string(&p).unwrap();
    assert_eq!(text.lines().next().unwrap(), TWIST_CSV_HEADER);
    assert!(
        text.lines()
            .nth(1)
            .unwrap()
            .starts_with("1718000000.000000001,")
    );
    let back = read_twist_csv(&p, epoch).unwrap();
    assert_eq!(back.len(), rows.len());
    for (a, b) in rows.iter().zip(&back) {
        assert!((a.t - b.t).abs() < 1e-9);
        assert_eq!(
            (a.v, a.w, a.std_v, a.std_w, a.dv, a.dw),
            (b.v, b.w, b.std_v, b.std_w, b.dv, b.dw)
        );
    }

    let row = text.lines().nth(1).unwrap();
    let bad_header = write_file(&dir, "hdr.csv", &format!("t,vx\n{row}\n"));
    assert_err_at(
        read_twist_csv(&bad_header, epoch).unwrap_err(),
        "hdr.csv",
        1,
    );
    let short = write_file(
        &dir,
        "short.csv",
        &format!(
            "{TWIST_CSV_HEADER}\n{row}\n{}\n",
            &row[..row.rfind(',').unwrap()]
        ),
    );
    assert_err_at(read_twist_csv(&short, epoch).unwrap_err(), "short.csv", 3);
    let mut fields: Vec<&str> = row.split(',').collect();
    fields[3] = "NaN";
    let nan = write_file(
        &dir,
        "nan.csv",
        &format!("{TWIST_CSV_HEADER}\r\n\r\n{}\r\n", fields.join(",")),
    );
    let msg = read_twist_csv(&nan, epoch).unwrap_err().to_string();
    assert!(msg.contains("nan.csv:3:") && msg.contains("vz"), "{msg}");
}

fn sample_report(k: i64) -> A50VelocityReport {
    let beam = |id: i64| A50Transducer {
        id,
        velocity: 0.01 * id as f64 - 0.02,
        distance: 0.1062000021338462 + 0.01 * id as f64,
        rssi: -26.294679641723633,
        nsd: -87.89620971679688,
        beam_valid: id != 2 || k % 2 == 0,
    };
    A50VelocityReport {
        time: 77.88848876953125,
        vx: 0.0056208535097539425 * k as f64,
        vy: -0.06387434154748917,
        vz: 1.5e-7,
        fom: 0.001417846535332501,
        covariance: [
            [
                1.456108861930261e-6,
                6.3190796595336e-8,
                -2.4175271562398848e-8,
            ],
            [
                6.3190796595336e-8,
                1.9791643808275694e-6,
                -2.081109187201946e-7,
            ],
            [
                -2.4175271562398848e-8,
                -2.081109187201946e-7,
                1.502408082387774e-7,
            ],
        ],
        altitude: if k == 3 { -1.0 } else { 0.10219412297010422 },
        transducers: [beam(0), beam(1), beam(2), beam(3)],
        velocity_valid: k != 3,
        status: 0,
        format: "json_v3.1".to_string(),
        report_type: "velocity".to_string(),
        time_of_validity: 1_718_000_000_123_456 + 80_000 * k,
        time_of_transmission: 1_718_000_000_223_456 + 80_000 * k,
    }
}

#[test]
fn a50_report_line_parses_back_to_the_same_sample() {
    let dir = temp_dir("a50");
    let reports: Vec<_> = (0..5).map(sample_report).collect();
    let line = velocity_report_line(&reports[1]);
    assert!(!line.contains('\n'));
    assert!(line.starts_with("{\"time\":77.88848876953125,\"vx\":"));
    assert!(line.contains("\"vz\":1.502408082387774e-7") || line.contains("\"vz\":1.5e-7"));
    assert!(line.ends_with(
        "\"format\":\"json_v3.1\",\"type\":\"velocity\",\"time_of_validity\":1718000000203456,\"time_of_transmission\":1718000000303456}"
    ));
    let parsed = parse_velocity_report(&line).unwrap();
    assert_eq!(parsed, reports[1]);

    let p = dir.join("dvl.jsonl");
    write_a50_jsonl(&p, &reports).unwrap();
    let bytes = std::fs::read(&p).unwrap();
    assert_eq!(bytes.iter().filter(|&&b| b == b'\n').count(), 5);
    assert_eq!(
        bytes.windows(2).filter(|w| w == b"\r\n").count(),
        5,
        "lines end with CRLF"
    );
    let log = read_a50_velocities(&p, None).unwrap();
    assert_eq!(log.epoch, Epoch { sec: 1_718_000_000 });
    assert_eq!(log.lines, [1, 2, 3, 4, 5]);
    assert_eq!(
        (log.stats.other_reports + log.stats.water_velocity_reports),
        0
    );
    for (r, s) in reports.iter().zip(&log.samples) {
        assert!((s.t - (r.time_of_validity - 1_718_000_000_000_000) as f64 * 1e-6).abs() < 1e-12);
        assert_eq!(s.v, Vector3::new(r.vx, r.vy, r.vz));
        assert_eq!(s.valid, r.velocity_valid);
        let cov = s.cov.unwrap();
        for i in 0..3 {
            for j in 0..3 {
                assert_eq!(cov[(i, j)], r.covariance[i][j]);
            }
        }
    }
}

#[test]
fn a50_real_log_counts_and_exact_reproduction() {
    let path = Path::new(REAL_LOG);
    let log = read_a50_velocities(path, None).unwrap();
    assert_eq!(log.samples.len(), 1423);
    assert_eq!(log.samples.iter().filter(|s| s.valid).count(), 1295);
    assert_eq!(
        (log.stats.other_reports + log.stats.water_velocity_reports),
        0
    );
    assert_eq!(log.epoch, Epoch { sec: 1_550_140_933 });
    assert!(log.samples.iter().all(|s| s.cov.is_some()));
    let span = log.samples.last().unwrap().t - log.samples[0].t;
    assert!((span - 154.8).abs() < 0.1, "span {span}");
}

#[test]
fn a50_real_logs_reproduced_byte_for_byte() {
    for (name, total, valid) in [
        ("dvl", 1423, 1295),
        ("dvl_circle", 378, 303),
        ("dvl_fast_rectangle", 396, 363),
        ("dvl_slow_rectangle", 457, 407),
    ] {
        let path = PathBuf::from(format!(
            "{}/../shared/data/a50-ros-driver/{name}.jsonl",
            env!("CARGO_MANIFEST_DIR")
        ));
        let log = read_a50_velocities(&path, None).unwrap();
        assert_eq!(log.samples.len(), total, "{name}");
        assert_eq!(
            log.samples.iter().filter(|s| s.valid).count(),
            valid,
            "{name}"
        );
        let text = std::fs::read_to_string(&path).unwrap();
        for (i, line) in text.lines().enumerate() {
            let r = parse_velocity_report(line).unwrap();
            assert_eq!(velocity_report_line(&r), line, "{name}:{}", i + 1);
        }
    }
}

#[test]
fn a50_reader_errors_and_other_reports() {
    let dir = temp_dir("a50bad");
    let good = velocity_report_line(&sample_report(0));
    let dead_reckoning = r#"{"ts":49056.809,"x":12.43,"y":64.1,"z":1.54,"std":0.2,"roll":0.1,"pitch":0.2,"yaw":94.3,"type":"position_local","status":0,"format":"json_v3.1"}"#;
    let p = write_file(
        &dir,
        "mixed.jsonl",
        &format!("{dead_reckoning}\r\n{good}\r\n\r\n"),
    );
    let log = read_a50_velocities(&p, Some(Epoch { sec: 1_718_000_000 })).unwrap();
    assert_eq!(
        (
            log.samples.len(),
            (log.stats.other_reports + log.stats.water_velocity_reports),
            log.lines.clone()
        ),
        (1, 1, vec![2])
    );

    let missing = good.replace("\"vy\":", "\"vy_\":");
    let p = write_file(&dir, "missing.jsonl", &format!("{good}\n{missing}\n"));
    let msg = read_a50_velocities(&p, None).unwrap_err().to_string();
    assert!(
        msg.contains("missing.jsonl:2:") && msg.contains("vy"),
        "{msg}"
    );
    let p = write_file(
        &dir,
        "broken.jsonl",
        &format!("{good}\n{good}\n{}\n", &good[..40]),
    );
    assert_err_at(
        read_a50_velocities(&p, None).unwrap_err(),
        "broken.jsonl",
        3,
    );
    let p = write_file(&dir, "none.jsonl", &format!("{dead_reckoning}\n"));
    assert_err_at(read_a50_velocities(&p, None).unwrap_err(), "none.jsonl", 1);
}

fn sample_params() -> CalibrationParams {
    CalibrationParams {
        t_cam_dvl: Se3::exp(&Vector6::new(0.12, -0.05, 0.31, 0.3, -1.2, 2.0)),
        time_offset_s: -0.0375,
        velocity_scale: 1.0123,
    }
}

#[test]
fn calib_yaml_round_trip() {
    let dir = temp_dir("calib");
    let p = dir.join("calib.yaml");
    let params = sample_params();
    let mut file = CalibrationFile::from_params(&params);
    write_calib_yaml(&p, &file).unwrap();
    let back = read_calib_yaml(&p).unwrap();
    assert_eq!(back, file);
    let bp = back.to_params().unwrap();
    assert!((bp.t_cam_dvl.rot - params.t_cam_dvl.rot).abs().max() < 1e-14);
    assert_eq!(bp.t_cam_dvl.trans, params.t_cam_dvl.trans);
    assert_eq!(bp.time_offset_s, params.time_offset_s);
    assert_eq!(bp.velocity_scale, params.velocity_scale);

    // With every optional section, key order as documented.
    file.std = Some(CalibrationStd {
        rotation_deg: Some([0.1, 0.2, 0.3]),
        lever_arm_m: Some([0.001, 0.002, 0.003]),
        time_offset_s: Some(0.0004),
        velocity_scale: None,
        clock_drift_ppm: None,
        imu: None,
    });
    file.observability = Some(ObservabilityFlags {
        rotation: Observability::Ok,
        lever_arm: Observability::Weak,
        time_offset: Observability::Prior,
        velocity_scale: Observability::Fixed,
        imu: None,
    });
    let mut info = CalibrationInfo {
        method: Some("continuous-time batch".to_string()),
        iterations: Some(12),
        warnings: vec!["little rotation about z".to_string()],
        notes: vec![],
        ..Default::default()
    };
    info.figures.poses = Some(1200);
    info.figures.dvl_normalized_cost = Some(0.0123);
    file.info = Some(info);
    write_calib_yaml(&p, &file).unwrap();
    let text = std::fs::read_to_string(&p).unwrap();
    let keys: Vec<&str> = text
        .lines()
        .filter(|l| !l.starts_with(['#', ' ', '-']))
        .map(|l| l.split(':').next().unwrap())
        .collect();
    assert_eq!(
        keys,
        [
            "T_cam_dvl",
            "T_dvl_cam",
            "quaternion_cam_dvl_xyzw",
            "lever_arm_cam_m",
            "time_offset_s",
            "velocity_scale",
            "std",
            "observability",
            "info"
        ]
    );
    assert!(text.contains("lever_arm: weak"), "{text}");
    assert!(text.contains("time_offset: prior"), "{text}");
    assert!(text.contains("velocity_scale: fixed"), "{text}");
    // A held parameter has no standard deviation, not a zero one.
    assert!(text.contains("  velocity_scale: null"), "{text}");
    assert_eq!(read_calib_yaml(&p).unwrap(), file);
}

/// The run's figures are written as keys of `info` in alphabetical order, as a map of YAML values
/// writes them (lists of mappings, NaN, keys present only when given), and read back with the
/// keys a file holds that are none of them kept as read.
#[test]
fn calib_yaml_figures_write_as_a_sorted_map() {
    use dvlcal::io::calib_yaml::{RunFigures, WorstResidual};
    use serde_yaml::{Mapping, Value};
    let figures = RunFigures {
        poses: Some(1200),
        loss: Some("cauchy".into()),
        dvl_residual_rms_mps: Some([0.01, 0.02, 0.5]),
        halves_difference_in_std: Some(vec![0.5, f64::NAN, -1.25e-7]),
        dvl_residuals_correlated: Some(true),
        dvl_worst_residuals: Some(vec![WorstResidual {
            t_s: 12.5,
            variances_out: 30.0,
            weight: 0.125,
        }]),
        ..RunFigures::default()
    };
    let info = CalibrationInfo {
        method: Some("uic".into()),
        figures,
        ..CalibrationInfo::default()
    };
    let mut worst = Mapping::new();
    worst.insert("t_s".into(), 12.5.into());
    worst.insert("variances_out".into(), 30.0.into());
    worst.insert("weight".into(), 0.125.into());
    let mut map = std::collections::BTreeMap::<String, Value>::new();
    map.insert("method".into(), "uic".into());
    map.insert("poses".into(), 1200usize.into());
    map.insert("loss".into(), "cauchy".into());
    map.insert("dvl_residual_rms_mps".into(), vec![0.01, 0.02, 0.5].into());
    map.insert(
        "halves_difference_in_std".into(),
        vec![0.5, f64::NAN, -1.25e-7].into(),
    );
    map.insert("dvl_residuals_correlated".into(), true.into());
    map.insert(
        "dvl_worst_residuals".into(),
        vec![Value::Mapping(worst)].into(),
    );
    // `method` first, then the figures sorted: what a sorted map of values gives here.
    let text = serde_yaml::to_string(&info).unwrap();
    let mut expected = String::from("method: uic\n");
    map.remove("method");
    expected.push_str(&serde_yaml::to_string(&map).unwrap());
    assert_eq!(text, expected);
    assert!(text.contains(".nan"), "{text}");
    // Read back: the figures, and a key of another version kept as it was.
    let mut back: CalibrationInfo =
        serde_yaml::from_str(&format!("{text}old_key: [1, 2]\n")).unwrap();
    assert_eq!(back.figures.poses, Some(1200));
    assert_eq!(
        back.figures.dvl_worst_residuals,
        info.figures.dvl_worst_residuals
    );
    assert!(back.figures.other.contains_key("old_key"), "{back:?}");
    back.figures.other.clear();
    back.figures.halves_difference_in_std = None;
    let mut want = info.clone();
    want.figures.halves_difference_in_std = None;
    assert_eq!(back, want);
    // A figure of another type than this version's is kept as read, not refused.
    let odd: CalibrationInfo = serde_yaml::from_str("poses: many\n").unwrap();
    assert_eq!(odd.figures.poses, None);
    assert!(odd.figures.other.contains_key("poses"));
}

/// A result of `--method fixed` as earlier versions wrote it: zero standard deviations and
/// `ok` for what was held. It still reads, and a comparison counts the zero-std parameters as
/// held rather than measured.
#[test]
fn calib_yaml_of_earlier_versions_still_reads() {
    let text = "\
status: ok
T_cam_dvl:
  - [1.0, 0.0, 0.0, 0.05]
  - [0.0, 1.0, 0.0, 0.25]
  - [0.0, 0.0, 1.0, -0.1]
  - [0.0, 0.0, 0.0, 1.0]
T_dvl_cam:
  - [1.0, 0.0, 0.0, -0.05]
  - [0.0, 1.0, 0.0, -0.25]
  - [0.0, 0.0, 1.0, 0.1]
  - [0.0, 0.0, 0.0, 1.0]
quaternion_cam_dvl_xyzw: [0.0, 0.0, 0.0, 1.0]
lever_arm_cam_m: [0.05, 0.25, -0.1]
time_offset_s: 0.6
velocity_scale: 1.01
std:
  rotation_deg: [0.0, 0.0, 0.0]
  lever_arm_m: [0.0, 0.0, 0.0]
  time_offset_s: 0.0021
  velocity_scale: 0.0004
observability:
  rotation: ok
  lever_arm: ok
  time_offset: ok
  velocity_scale: ok
info:
  method: fixed extrinsics, estimated clock offset
";
    let f = dvlcal::io::calib_yaml::parse_calib_yaml(text, std::path::Path::new("old.yaml"))
        .expect("an earlier version's file reads");
    let st = f.std.clone().expect("std section");
    assert_eq!(st.rotation_deg, Some([0.0; 3]));
    assert_eq!(st.time_offset_s, Some(0.0021));
    assert_eq!(
        f.observability.as_ref().map(|o| o.lever_arm),
        Some(Observability::Ok)
    );
    let mut truth = f.to_params().unwrap();
    truth.time_offset_s = 0.07;
    let ce = dvlcal::eval::calibration_error(&f, &truth).unwrap();
    assert!((0..6).all(|k| ce.held(k)), "{:?}", ce.state);
    assert!(!ce.held(6) && !ce.held(7), "{:?}", ce.state);
    assert!((ce.error[7] - 0.53).abs() < 1e-12, "{}", ce.error[7]);
}

#[test]
fn calib_yaml_rejects_bad_files() {
    let dir = temp_dir("calibbad");
    let good = CalibrationFile::from_params(&sample_params());

    // Non-rigid rotation block.
    let mut sheared = good.clone();
    sheared.t_cam_dvl[0][1] += 0.01;
    let err = sheared.to_params().unwrap_err().to_string();
    assert!(err.contains("T_cam_dvl") && err.contains("rigid"), "{err}");
    let p = dir.join("sheared.yaml");
    write_calib_yaml(&p, &sheared).unwrap();
    let err = read_calib_yaml(&p).unwrap_err().to_string();
    assert!(
        err.contains("sheared.yaml") && err.contains("rigid"),
        "{err}"
    );

    // Bad last row.
    let mut last = good.clone();
    last.t_cam_dvl[3][0] = 0.5;
    assert!(
        last.to_params()
            .unwrap_err()
            .to_string()
            .contains("last row")
    );
    // Inverse, quaternion and lever arm must agree with T_cam_dvl.
    let mut inv = good.clone();
    inv.t_dvl_cam[0][3] += 0.01;
    assert!(
        inv.to_params()
            .unwrap_err()
            .to_string()
            .contains("T_dvl_cam")
    );
    let mut q = good.clone();
    q.quaternion_cam_dvl_xyzw = [0.0, 0.0, 0.0, 1.0];
    assert!(
        q.to_params()
            .unwrap_err()
            .to_string()
            .contains("quaternion")
    );
    let mut arm = good.clone();
    arm.lever_arm_cam_m[2] += 0.1;
    assert!(
        arm.to_params()
            .unwrap_err()
            .to_string()
            .contains("lever_arm")
    );

    // YAML errors name the file and the line.
    let p = write_file(
        &dir,
        "broken.yaml",
        "T_cam_dvl:\n  - [1, 0, 0, 0]\n  bad: [\n",
    );
    let err = read_calib_yaml(&p).unwrap_err().to_string();
    assert!(err.contains("broken.yaml:"), "{err}");
    let p = write_file(&dir, "partial.yaml", "time_offset_s: 0.1\n");
    let err = read_calib_yaml(&p).unwrap_err().to_string();
    assert!(
        err.contains("partial.yaml") && err.contains("T_cam_dvl"),
        "{err}"
    );
}
