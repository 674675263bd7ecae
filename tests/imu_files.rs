//! The IMU's files end to end: EuRoC's IMU CSV read from a real EuRoC excerpt (and refused when
//! converted to deg/s or g), the malformed, out-of-order, gappy and saturated streams named by
//! file and line, the noise files (Kalibr's imu.yaml, EuRoC's sensor.yaml), the dataset
//! folder's IMU parts, and `dvlcal simulate --imu` read back against its truth.

use std::path::{Path, PathBuf};

use dvlcal::io::dataset::{DatasetOverrides, discover};
use dvlcal::io::imu::noise::{NoiseFileKind, read_imu_noise, write_kalibr_imu_yaml};
use dvlcal::io::imu::truth::{read_imu_bias_csv, read_imu_truth};
use dvlcal::io::imu::{EUROC_IMU_HEADER, read_imu_csv, write_imu_csv};
use dvlcal::sim::imu::ImuSimConfig;
use dvlcal::time::Epoch;
use dvlcal::types::imu::{ImuNoise, ImuSample, STANDARD_GRAVITY};
use dvlcal::types::imu_units::{DEG_PER_RAD, GyroScale};
use nalgebra::Vector3;

#[path = "tmp_common/mod.rs"]
mod tmp_common;
use tmp_common::{TmpDir, dvlcal, s};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/imu/euroc_v1_01_easy")
        .join(name)
}

/// The real excerpt's data rows, as text.
fn euroc_rows() -> Vec<String> {
    std::fs::read_to_string(fixture("data.csv"))
        .unwrap()
        .lines()
        .skip(1)
        .map(str::to_owned)
        .collect()
}

/// A data row with its six values mapped by `f(column, value)` (columns 1..=6).
fn map_row(row: &str, f: impl Fn(usize, f64) -> f64) -> String {
    let fields: Vec<&str> = row.split(',').collect();
    let mut out = vec![fields[0].to_string()];
    for (k, v) in fields[1..].iter().enumerate() {
        out.push(format!("{:?}", f(k + 1, v.parse().unwrap())));
    }
    out.join(",")
}

/// `rows` under EuRoC's header (or `header`) written to `dir/name`.
fn write_csv(tmp: &TmpDir, name: &str, header: &str, rows: &[String]) -> PathBuf {
    let p = tmp.path(name);
    let mut text = format!("{header}\n");
    for r in rows {
        text.push_str(r);
        text.push('\n');
    }
    std::fs::write(&p, text).unwrap();
    p
}

fn error_of(p: &Path) -> String {
    read_imu_csv(p, None)
        .expect_err("the file must be refused")
        .to_string()
}

#[test]
fn a_real_euroc_stream_reads_with_its_stamps_values_and_units() {
    let log = read_imu_csv(&fixture("data.csv"), None).expect("real EuRoC data is accepted");
    let st = &log.stats;
    assert_eq!(log.samples.len(), 600);
    assert_eq!((st.rows, st.duplicates, st.gaps), (600, 0, 0));
    assert_eq!(st.header_line, Some(1));
    assert_eq!(log.lines[0], 2);
    assert_eq!(log.epoch, Epoch { sec: 1_403_715_279 });
    // The nanoseconds survive: first and last stamps, and EuRoC's own jitter.
    let first = log.samples[0].t;
    let last = log.samples[599].t;
    assert_eq!(log.epoch.format_abs(first, 9), "1403715279.262142976");
    assert_eq!(log.epoch.format_abs(last, 9), "1403715282.257143040");
    assert!((log.samples[1].t - first - 4.999936e-3).abs() < 1e-12);
    assert!((last - first - 2.995000064).abs() < 1e-12);
    // The first row's values, bit for bit as the text gives them.
    let num = |t: &str| t.parse::<f64>().unwrap();
    let s0 = &log.samples[0];
    let gyro = [
        "0.030019663134302467",
        "-0.11379546723003027",
        "0.072605696882964116",
    ];
    let accel = [
        "5.475379583333333",
        "0.40043820833333332",
        "-1.1522813749999998",
    ];
    assert_eq!(s0.gyro, Vector3::from(gyro.map(num)));
    assert_eq!(s0.accel, Vector3::from(accel.map(num)));
    assert_eq!(log.samples[599].gyro.x, num("-0.52010811709431026"));
    // Not refused on units, and the figures that say so.
    assert!((st.rate_hz - 200.0).abs() < 0.01, "{}", st.rate_hz);
    assert!(
        (st.accel_median_norm - 9.7935).abs() < 1e-3,
        "{}",
        st.accel_median_norm
    );
    assert!(
        st.gyro_p99_radps > 0.6 && st.gyro_p99_radps < 0.7,
        "{}",
        st.gyro_p99_radps
    );
    assert_eq!(st.gyro_scale.scale, GyroScale::RadiansPerSecond);
    assert!(st.gyro_scale.pairs >= 5, "{:?}", st.gyro_scale);
    assert!(
        st.gyro_scale.ratio > 0.5 && st.gyro_scale.ratio < 2.0,
        "{:?}",
        st.gyro_scale
    );
    assert_eq!(st.saturated_samples, 0);
    let summary = log.summary().join("\n");
    assert!(summary.contains("600 IMU samples at 200.0 Hz"), "{summary}");
}

#[test]
fn the_real_stream_in_degrees_or_in_g_is_refused_with_the_conversion() {
    let tmp = TmpDir::new("imu-units");
    let rows = euroc_rows();
    // The gyro in deg/s: its rates reach 39 "rad/s".
    let deg: Vec<String> = rows
        .iter()
        .map(|r| map_row(r, |k, v| if k <= 3 { v * DEG_PER_RAD } else { v }))
        .collect();
    let p = write_csv(&tmp, "deg.csv", EUROC_IMU_HEADER, &deg);
    let e = error_of(&p);
    assert!(e.starts_with(&format!("{}:2: ", p.display())), "{e}");
    assert!(e.contains("degrees per second"), "{e}");
    assert!(e.contains("pi/180 = 0.017453293"), "{e}");
    // The accelerometer in g: median norm 0.9987.
    let g: Vec<String> = rows
        .iter()
        .map(|r| map_row(r, |k, v| if k >= 4 { v / STANDARD_GRAVITY } else { v }))
        .collect();
    let p = write_csv(&tmp, "g.csv", EUROC_IMU_HEADER, &g);
    let e = error_of(&p);
    assert!(e.starts_with(&format!("{}:2: ", p.display())), "{e}");
    assert!(e.contains("it looks in g"), "{e}");
    assert!(
        e.contains("median norm of its specific force is 0.99"),
        "{e}"
    );
    assert!(e.contains("by 9.80665"), "{e}");
    // In mg, and with gravity removed.
    let mg: Vec<String> = rows
        .iter()
        .map(|r| {
            map_row(r, |k, v| {
                if k >= 4 {
                    v / STANDARD_GRAVITY * 1e3
                } else {
                    v
                }
            })
        })
        .collect();
    let e = error_of(&write_csv(&tmp, "mg.csv", EUROC_IMU_HEADER, &mg));
    assert!(e.contains("milli-g") && e.contains("by 0.00980665"), "{e}");
    // A header that says deg/s is refused at its line, whatever the numbers.
    let header = EUROC_IMU_HEADER.replace("w_RS_S_y [rad s^-1]", "w_RS_S_y [deg s^-1]");
    let p = write_csv(&tmp, "header.csv", &header, &rows);
    let e = error_of(&p);
    assert!(e.starts_with(&format!("{}:1: ", p.display())), "{e}");
    assert!(e.contains("degrees ('w_rs_s_y [deg s^-1]')"), "{e}");
}

#[test]
fn a_slowly_tilting_gyro_in_degrees_is_told_by_gravity() {
    // Rocking about x at 0.15 rad/s at most: in deg/s below 9, under any rate threshold, but
    // 57 times the rate gravity turns at in the accelerometer.
    let tmp = TmpDir::new("imu-tilt");
    let samples = |scale: f64| -> Vec<ImuSample> {
        (0..4000)
            .map(|k| {
                let t = k as f64 * 0.005;
                let angle = 0.3 * (0.5 * t).sin();
                let rate = 0.15 * (0.5 * t).cos();
                ImuSample {
                    t,
                    gyro: Vector3::new(rate * scale, 0.002, -0.001),
                    accel: Vector3::new(0.05, angle.sin(), angle.cos()) * STANDARD_GRAVITY,
                }
            })
            .collect()
    };
    let epoch = Epoch { sec: 1_700_000_000 };
    let rad = tmp.path("rad.csv");
    write_imu_csv(&rad, epoch, &samples(1.0)).unwrap();
    let log = read_imu_csv(&rad, None).expect("rad/s accepted");
    assert_eq!(log.stats.gyro_scale.scale, GyroScale::RadiansPerSecond);
    assert!((log.stats.gyro_scale.ratio - 1.0).abs() < 0.1);
    let deg = tmp.path("deg.csv");
    write_imu_csv(&deg, epoch, &samples(DEG_PER_RAD)).unwrap();
    let e = error_of(&deg);
    assert!(log.stats.gyro_p99_radps * DEG_PER_RAD < 20.0);
    assert!(e.contains("degrees per second"), "{e}");
    assert!(e.contains("tilts 5"), "{e}");
}

#[test]
fn malformed_lines_and_backward_time_name_the_file_and_line() {
    let tmp = TmpDir::new("imu-malformed");
    let rows = euroc_rows();
    let cases: Vec<(usize, String, &str)> = vec![
        (
            10,
            rows[10].rsplit_once(',').unwrap().0.to_string(),
            "expected 7 fields",
        ),
        (
            20,
            rows[20].replacen(",", ",x", 2).replacen(",x", ",", 1),
            "w_RS_S_y: 'x",
        ),
        (30, rows[30].replacen(",", ",nan,", 1), "expected 7 fields"),
        (
            40,
            map_row(&rows[40], |k, v| if k == 4 { f64::INFINITY } else { v }),
            "a_RS_S_x: 'inf' is not finite",
        ),
        (
            50,
            format!("1403715279.512142976{}", &rows[50][19..]),
            "looks like seconds",
        ),
    ];
    for (k, row, want) in cases {
        let mut r = rows.clone();
        r[k] = row;
        let p = write_csv(&tmp, &format!("bad{k}.csv"), EUROC_IMU_HEADER, &r);
        let e = error_of(&p);
        // Row k is on line k + 2 (the header is line 1).
        assert!(
            e.starts_with(&format!("{}:{}: ", p.display(), k + 2)),
            "{e}"
        );
        assert!(e.contains(want), "{want}: {e}");
    }
    // Two rows swapped: time goes backwards at the second of them, naming the first.
    let mut r = rows.clone();
    r.swap(100, 101);
    let p = write_csv(&tmp, "swapped.csv", EUROC_IMU_HEADER, &r);
    let e = error_of(&p);
    assert!(e.starts_with(&format!("{}:103: ", p.display())), "{e}");
    assert!(e.contains("4999936 ns before the one on line 102"), "{e}");
    assert!(e.contains("time goes backwards"), "{e}");
    // An empty file and a header alone.
    let p = write_csv(&tmp, "empty.csv", EUROC_IMU_HEADER, &[]);
    assert!(error_of(&p).contains("no IMU samples"), "{}", error_of(&p));
}

#[test]
fn a_repeated_stamp_is_skipped_and_counted() {
    let tmp = TmpDir::new("imu-dup");
    let mut rows = euroc_rows();
    // A second sample with the stamp of row 200, other values: skipped, the first kept.
    let stamp = rows[200].split(',').next().unwrap().to_string();
    rows.insert(201, format!("{stamp},0,0,0,0,0,9.8"));
    let p = write_csv(&tmp, "dup.csv", EUROC_IMU_HEADER, &rows);
    let log = read_imu_csv(&p, None).unwrap();
    assert_eq!(
        (log.samples.len(), log.stats.rows, log.stats.duplicates),
        (600, 601, 1)
    );
    assert_eq!(log.stats.duplicate_lines, vec![203]);
    assert_ne!(log.samples[201].gyro, Vector3::zeros());
    let summary = log.summary().join("\n");
    assert!(
        summary.contains("1 repeated time stamps skipped (lines 203)"),
        "{summary}"
    );
}

#[test]
fn a_gap_is_counted_and_the_longest_named_with_its_time_and_lines() {
    let tmp = TmpDir::new("imu-gap");
    let mut rows = euroc_rows();
    // Rows 300..311 lost: 60 ms between rows 299 and 311; rows 100..104 lost: 25 ms.
    rows.drain(300..311);
    rows.drain(100..104);
    let p = write_csv(&tmp, "gap.csv", EUROC_IMU_HEADER, &rows);
    let log = read_imu_csv(&p, None).unwrap();
    let st = &log.stats;
    assert_eq!((log.samples.len(), st.gaps), (585, 2));
    let g = st.longest_gap.clone().expect("a gap");
    assert!((g.duration_s - 0.060000000).abs() < 1e-6, "{g:?}");
    // Row 299 of the excerpt is now on line 297 (header, then 4 rows fewer before it).
    assert_eq!((g.previous_line, g.line), (297, 298));
    assert_eq!(log.epoch.format_abs(g.t_s, 9), "1403715280.757143040");
    let summary = log.summary().join("\n");
    assert!(
        summary.contains(
            "2 gaps longer than 2.5 sample intervals; the longest 0.060 s after \
                          1403715280.757143040"
        ),
        "{summary}"
    );
    assert!(summary.contains("lines 297-298"), "{summary}");
}

#[test]
fn an_axis_held_at_full_scale_is_saturation_named_by_lines() {
    let tmp = TmpDir::new("imu-sat");
    let mut rows = euroc_rows();
    // Accelerometer z pinned at -16 m/s^2 (a 16 m/s^2 range) for five samples; +16 once.
    for r in &mut rows[120..125] {
        *r = map_row(r, |k, v| if k == 6 { -16.0 } else { v });
    }
    rows[300] = map_row(&rows[300], |k, v| if k == 6 { 16.0 } else { v });
    let p = write_csv(&tmp, "sat.csv", EUROC_IMU_HEADER, &rows);
    let log = read_imu_csv(&p, None).unwrap();
    let st = &log.stats;
    assert_eq!((st.saturated_samples, st.saturated_run_count), (5, 1));
    let run = &st.saturated_runs[0];
    assert_eq!(
        (run.axis, run.value, run.lines, run.samples),
        ("accel z", -16.0, (122, 126), 5)
    );
    let summary = log.summary().join("\n");
    assert!(
        summary.contains("5 saturated samples in 1 runs") && summary.contains("lines 122-126"),
        "{summary}"
    );
}

#[test]
fn the_writer_reads_back_to_the_same_stamps_and_values() {
    let tmp = TmpDir::new("imu-write");
    let log = read_imu_csv(&fixture("data.csv"), None).unwrap();
    let out = tmp.path("imu0/data.csv");
    std::fs::create_dir_all(out.parent().unwrap()).unwrap();
    write_imu_csv(&out, log.epoch, &log.samples).unwrap();
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.starts_with(&format!("{EUROC_IMU_HEADER}\n1403715279262142976,")));
    let back = read_imu_csv(&out, Some(log.epoch)).unwrap();
    assert_eq!(back.samples, log.samples);
    // Non-finite values are refused by the writer.
    let mut bad = log.samples.clone();
    bad[3].accel.y = f64::NAN;
    let e = write_imu_csv(&tmp.path("bad.csv"), log.epoch, &bad).unwrap_err();
    assert!(e.to_string().contains("IMU sample 3"), "{e}");
}

#[test]
fn euroc_sensor_yaml_and_kalibr_imu_yaml_read_with_errors_naming_the_key() {
    // The real sensor.yaml, with its %YAML:1.0 line and OpenCV matrix.
    let f = read_imu_noise(&fixture("sensor.yaml")).expect("EuRoC's sensor.yaml");
    assert_eq!(f.kind, NoiseFileKind::EurocSensor);
    assert_eq!(
        f.noise,
        ImuNoise {
            accelerometer_noise_density: 2.0e-3,
            accelerometer_random_walk: 3.0e-3,
            gyroscope_noise_density: 1.6968e-4,
            gyroscope_random_walk: 1.9393e-5,
            update_rate: 200.0,
        }
    );
    let t_bs = f.t_bs.expect("T_BS");
    assert!(
        (t_bs.to_matrix() - nalgebra::Matrix4::identity())
            .abs()
            .max()
            < 1e-15
    );

    // Kalibr's imu.yaml, written and read back exactly.
    let tmp = TmpDir::new("imu-yaml");
    let noise = ImuSimConfig::default_truth().noise;
    let p = tmp.path("imu.yaml");
    write_kalibr_imu_yaml(&p, &noise, "/imu0").unwrap();
    let text = std::fs::read_to_string(&p).unwrap();
    assert!(text.contains("gyroscope_random_walk: 3.8e-5"), "{text}");
    assert!(text.contains("rostopic: /imu0"), "{text}");
    let back = read_imu_noise(&p).unwrap();
    assert_eq!((back.kind, back.noise), (NoiseFileKind::Kalibr, noise));

    // A missing key, a negative density, a rate that is no rate: file, line and key named.
    let edits: [(&str, &str, &str); 3] = [
        (
            "gyroscope_random_walk: 3.8e-5",
            "",
            "key 'gyroscope_random_walk' is missing",
        ),
        (
            "accelerometer_noise_density: 0.004",
            "accelerometer_noise_density: -0.004",
            ":3: key 'accelerometer_noise_density': -0.004 must be positive",
        ),
        (
            "update_rate: 200.0",
            "update_rate: 0",
            "key 'update_rate': 0 Hz",
        ),
    ];
    for (k, (from, to, want)) in edits.iter().enumerate() {
        assert!(text.contains(from), "{from}: {text}");
        let q = tmp.path(&format!("imu{k}.yaml"));
        std::fs::write(&q, text.replace(from, to)).unwrap();
        let e = read_imu_noise(&q).unwrap_err().to_string();
        assert!(e.starts_with(&format!("{}:", q.display())), "{e}");
        assert!(e.contains(want), "{want}: {e}");
    }
}

#[test]
fn a_dataset_folder_finds_its_imu_and_takes_no_other_yaml_for_its_noise() {
    let tmp = TmpDir::new("imu-dataset");
    let sample = Path::new(env!("CARGO_MANIFEST_DIR")).join("sample_data/poses");
    let d = tmp.path("run");
    std::fs::create_dir_all(d.join("imu0")).unwrap();
    for f in ["poses.txt", "dvl.jsonl"] {
        std::fs::copy(sample.join(f), d.join(f)).unwrap();
    }
    std::fs::copy(fixture("data.csv"), d.join("imu0/data.csv")).unwrap();
    write_kalibr_imu_yaml(
        &d.join("imu.yaml"),
        &ImuSimConfig::default_truth().noise,
        "/imu0",
    )
    .unwrap();
    // Other YAMLs: a dvlcal result and one with two of the noise keys only.
    std::fs::copy(
        sample.join("truth/calibration.yaml"),
        d.join("calibration.yaml"),
    )
    .unwrap();
    std::fs::write(
        d.join("partial.yaml"),
        "gyroscope_noise_density: 1e-4\naccelerometer_noise_density: 2e-3\n",
    )
    .unwrap();
    let found = discover(&d, &DatasetOverrides::default()).unwrap();
    assert_eq!(found.imu, Some(d.join("imu0/data.csv")));
    assert_eq!(found.imu_noise, Some(d.join("imu.yaml")));
    assert_eq!(found.poses, Some(d.join("poses.txt")));
    assert_eq!((found.camchain.clone(), found.target.clone()), (None, None));
    let inputs = found.inputs();
    assert!(inputs.contains(&d.join("imu0/data.csv")), "{inputs:?}");
    assert!(inputs.contains(&d.join("imu.yaml")), "{inputs:?}");
    let why = |name: &str| {
        found
            .ignored
            .iter()
            .find(|(p, _)| p.ends_with(name))
            .map(|(_, w)| w.clone())
            .unwrap_or_default()
    };
    assert_eq!(why("calibration.yaml"), "a calibration result");
    assert!(
        why("partial.yaml").contains("without accelerometer_random_walk, gyroscope_random_walk")
    );

    // A second noise file is an error naming both.
    std::fs::copy(d.join("imu.yaml"), d.join("imu_copy.yaml")).unwrap();
    let e = discover(&d, &DatasetOverrides::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("imu.yaml") && e.contains("imu_copy.yaml"), "{e}");
    std::fs::remove_file(d.join("imu_copy.yaml")).unwrap();

    // EuRoC's layout: mav0/imu0/data.csv with its sensor.yaml as the noise.
    std::fs::remove_file(d.join("imu.yaml")).unwrap();
    std::fs::create_dir_all(d.join("mav0/imu0")).unwrap();
    std::fs::rename(d.join("imu0/data.csv"), d.join("mav0/imu0/data.csv")).unwrap();
    std::fs::copy(fixture("sensor.yaml"), d.join("mav0/imu0/sensor.yaml")).unwrap();
    let found = discover(&d, &DatasetOverrides::default()).unwrap();
    assert_eq!(found.imu, Some(d.join("mav0/imu0/data.csv")));
    assert_eq!(found.imu_noise, Some(d.join("mav0/imu0/sensor.yaml")));
}

/// `dvlcal simulate --imu` into `dir` with `extra` arguments; the IMU stream read back against
/// the truth it was written with.
fn simulate_and_check(tmp: &TmpDir, name: &str, extra: &[&str], rate: f64) {
    let d = tmp.path(name);
    let mut args = vec!["simulate", "--out", s(&d), "--seed", "5", "--imu"];
    args.extend_from_slice(extra);
    let r = dvlcal(&args);
    let stdout = String::from_utf8_lossy(&r.stdout);
    assert!(
        r.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&r.stderr)
    );
    let truth = read_imu_truth(&d.join("truth/imu.yaml")).unwrap();
    // On the poses' epoch: the first IMU tick may fall before the camera's first whole second.
    let poses = dvlcal::io::tum::read_tum(&d.join("truth/poses.txt"), None).unwrap();
    let log = read_imu_csv(&d.join("imu0/data.csv"), Some(poses.epoch)).expect("the stream");
    assert!(
        stdout.contains(&format!("wrote {} IMU samples at {rate} Hz", truth.samples)),
        "{stdout}"
    );
    // The sample count and noise of the truth; the stream on the IMU clock covers the camera
    // span (camera time = IMU time + offset, from the poses' epoch).
    assert_eq!(log.samples.len(), truth.samples);
    assert_eq!((log.stats.duplicates, log.stats.gaps), (0, 0));
    assert!((log.stats.rate_hz - rate).abs() < 1e-6 * rate);
    let noise = read_imu_noise(&d.join("imu.yaml")).unwrap();
    let mut want = ImuSimConfig::default_truth();
    want.noise.update_rate = rate;
    assert_eq!(noise.noise, want.noise);
    assert_eq!(truth.noise, want.noise);
    assert_eq!(truth.imu_time_offset_s, want.time_offset_s);
    let dm = truth.t_cam_imu.to_matrix() - want.t_cam_imu.to_matrix();
    assert!(dm.abs().max() < 1e-15, "{dm}");
    assert_eq!(truth.bias_start, want.initial_bias);
    let cam = |t: f64| t + truth.imu_time_offset_s;
    let (t0, t1) = (poses.poses[0].t, poses.poses.last().unwrap().t);
    let start = cam(log.samples[0].t);
    assert!(
        start >= t0 - 1e-9 && start < t0 + 1.0 / rate,
        "{start} vs {t0}"
    );
    let end = cam(log.samples.last().unwrap().t);
    assert!(
        end <= t1 + 1e-9 && end > t1 - 1.0 / rate + 1e-9,
        "{end} vs {t1}"
    );
    // A span whose end falls on an IMU tick ends on it (8 s - 5 ms at 100 Hz does not).
    let ticks = (t1 - truth.imu_time_offset_s) * rate;
    if (ticks - ticks.round()).abs() < 1e-6 {
        assert!((end - t1).abs() < 1e-9, "{end} vs {t1}");
    }
    // One bias row per sample, at the samples' times, starting at the truth's first biases.
    let bias = read_imu_bias_csv(&d.join("truth/imu_bias.csv"), log.epoch).unwrap();
    assert_eq!(bias.len(), truth.samples);
    assert!((bias[0].0 - log.samples[0].t).abs() < 1e-9);
    assert_eq!(bias[0].1, truth.bias_start);
    // Gravity: the median specific force is g within the accelerometer's biases.
    assert!((log.stats.accel_median_norm - STANDARD_GRAVITY).abs() < 0.5);
    // The folder's discovery finds both IMU files.
    let found = discover(&d, &DatasetOverrides::default()).unwrap();
    assert_eq!(
        (found.imu, found.imu_noise),
        (Some(d.join("imu0/data.csv")), Some(d.join("imu.yaml")))
    );
}

#[test]
fn simulate_imu_writes_a_stream_the_reader_reads_back_with_the_truth() {
    let tmp = TmpDir::new("imu-simulate");
    simulate_and_check(
        &tmp,
        "poses",
        &["--duration", "8", "--imu-rate", "100"],
        100.0,
    );
    simulate_and_check(
        &tmp,
        "images",
        &[
            "--images",
            "--duration",
            "2",
            "--supersample",
            "1",
            "--jpeg-quality",
            "60",
        ],
        200.0,
    );
}

#[test]
fn a_bad_imu_rate_is_refused_before_anything_is_written() {
    let tmp = TmpDir::new("imu-rate");
    let d = tmp.path("out");
    let r = dvlcal(&["simulate", "--out", s(&d), "--imu", "--imu-rate", "0"]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success());
    assert!(err.contains("--imu-rate must be a rate in Hz"), "{err}");
    assert!(
        !d.exists(),
        "simulate wrote into {} before refusing",
        d.display()
    );
    // --imu-rate alone is a usage error (it needs --imu).
    let r = dvlcal(&["simulate", "--out", s(&d), "--imu-rate", "100"]);
    assert_eq!(r.status.code(), Some(2));
}

#[test]
fn loading_a_dataset_reads_and_checks_its_imu_and_notes_a_bad_one() {
    use dvlcal::io::dvl::DvlReadOptions;
    use dvlcal::pipeline::{Dataset, VisionOptions, dataset_files};
    let tmp = TmpDir::new("imu-load");
    let d = tmp.path("sim");
    let r = dvlcal(&["simulate", "--out", s(&d), "--duration", "6", "--imu"]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let load = || {
        let files = dataset_files(Some(&d), &DatasetOverrides::default()).unwrap();
        Dataset::load(
            files,
            &VisionOptions::default(),
            &DvlReadOptions::default(),
            &mut |_| {},
        )
        .expect("the dataset loads")
    };
    let data = load();
    let imu = data.imu.as_ref().expect("the IMU stream read");
    // On the poses' epoch: camera time 0 is the epoch, the IMU 5 ms behind.
    assert_eq!(imu.epoch, dvlcal::time::Epoch { sec: 1_700_000_000 });
    let truth = read_imu_truth(&d.join("truth/imu.yaml")).unwrap();
    assert_eq!(imu.samples.len(), truth.samples);
    assert!(
        (imu.samples[0].t + 0.005).abs() < 1e-9,
        "{}",
        imu.samples[0].t
    );
    assert_eq!(
        data.imu_noise.as_ref().map(|n| n.noise.update_rate),
        Some(200.0)
    );
    let notes = data.notes.join("\n");
    let want = format!("{} IMU samples at 200.0 Hz", truth.samples);
    assert!(notes.contains(&want), "{notes}");
    // The same stream in deg/s: left out with the reason, the dataset still loads.
    let rows: Vec<String> = std::fs::read_to_string(d.join("imu0/data.csv"))
        .unwrap()
        .lines()
        .skip(1)
        .map(|r| map_row(r, |k, v| if k <= 3 { v * DEG_PER_RAD } else { v }))
        .collect();
    let mut text = format!("{EUROC_IMU_HEADER}\n");
    text.push_str(&rows.join("\n"));
    std::fs::write(d.join("imu0/data.csv"), text).unwrap();
    let data = load();
    assert!(data.imu.is_none());
    let notes = data.notes.join("\n");
    assert!(
        notes.contains("IMU stream not used: ") && notes.contains("degrees per second"),
        "{notes}"
    );
}
