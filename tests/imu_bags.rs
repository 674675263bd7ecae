//! `sensor_msgs/Imu` from every kind of bag dvlcal reads, against fixtures an independent writer
//! made (`scripts/make_imu_bag_fixtures.py`, rosbags 0.11.9; `tests/fixtures/imu_bags/`): the
//! values against the formula the script used, the topic found by its type, two IMU topics, bad
//! messages counted and named, and `bag-info`'s listing.

use std::path::{Path, PathBuf};
use std::process::Command;

use dvlcal::io::bag::Bag;
use dvlcal::io::bag::imu::{ImuBagSummary, read_imu_from_bag};
use dvlcal::io::bag::roles::{BagOptions, BagTime};
use dvlcal::types::imu::ImuSample;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");
/// The script's first header stamp, ns, and its whole second.
const T0_NS: i64 = 1_712_345_678_123_456_789;
const EPOCH_S: i64 = 1_712_345_678;
const STEP_NS: i64 = 5_000_000;
/// Messages on the good bags' Imu topic.
const N: usize = 301;

fn fixture(rel: &str) -> PathBuf {
    Path::new(ROOT).join("tests/fixtures/imu_bags").join(rel)
}

/// The script's gyro of message k (0-based), rad/s.
fn gyro(k: usize) -> [f64; 3] {
    let s = 0.005 * k as f64;
    let pi = std::f64::consts::PI;
    [
        0.3 * (2.0 * pi * 0.5 * s).sin(),
        0.2 * (2.0 * pi * 0.25 * s).cos(),
        -0.1 + 0.001 * k as f64,
    ]
}

/// The script's linear acceleration of message k, m/s^2.
fn accel(k: usize) -> [f64; 3] {
    let s = 0.005 * k as f64;
    let pi = std::f64::consts::PI;
    [
        0.5 * (2.0 * pi * s).sin(),
        -0.25,
        9.80665 + 0.2 * (pi * s).cos(),
    ]
}

/// Seconds from the epoch of a time in ns.
fn rel(t_ns: i64) -> f64 {
    (t_ns - EPOCH_S * 1_000_000_000) as f64 * 1e-9
}

/// The header stamp of message k, seconds from the epoch.
fn stamp(k: usize) -> f64 {
    rel(T0_NS + STEP_NS * k as i64)
}

/// The record time of message k, seconds from the epoch.
fn record(k: usize) -> f64 {
    rel(T0_NS + STEP_NS * k as i64 + 3_000_000 + 500_000 * (k % 3) as i64)
}

fn read(path: &Path, options: &BagOptions) -> (Vec<ImuSample>, ImuBagSummary) {
    let bag = Bag::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    read_imu_from_bag(&bag, options).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn read_err(path: &Path, options: &BagOptions) -> String {
    let bag = Bag::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    match read_imu_from_bag(&bag, options) {
        Ok((s, _)) => panic!("{}: read {} samples", path.display(), s.len()),
        Err(e) => e.to_string(),
    }
}

/// Sample `i` is message `k` of the formula at time `t`.
fn assert_sample(s: &ImuSample, k: usize, t: f64, what: &str) {
    assert!((s.t - t).abs() < 1e-12, "{what}: t {} against {t}", s.t);
    for a in 0..3 {
        assert!(
            (s.gyro[a] - gyro(k)[a]).abs() < 1e-12,
            "{what}: gyro {}",
            s.gyro
        );
        assert!(
            (s.accel[a] - accel(k)[a]).abs() < 1e-12,
            "{what}: accel {}",
            s.accel
        );
    }
}

fn no_problems(sum: &ImuBagSummary) {
    assert_eq!(
        (
            sum.undecodable,
            sum.non_finite,
            sum.backwards,
            sum.repeated,
            sum.zero_stamps
        ),
        (0, 0, 0, 0, 0),
        "{sum:?}"
    );
    assert!(
        sum.problems.is_empty() && sum.warnings.is_empty(),
        "{sum:?}"
    );
}

#[test]
fn every_storage_gives_the_formulas_samples_at_their_header_stamps() {
    for name in [
        "imu.bag",
        "imu_sqlite",
        "imu_sqlite/imu_sqlite.db3",
        "imu.mcap",
    ] {
        let (samples, sum) = read(&fixture(name), &BagOptions::default());
        // Found by its type: the topic's name does not say "imu", the temperature's does.
        assert_eq!(sum.topic, "/vn100/data", "{name}");
        assert_eq!(sum.source, "/vn100/data (sensor_msgs/Imu)", "{name}");
        assert_eq!((sum.messages, sum.samples, samples.len()), (N as u64, N, N));
        assert_eq!(sum.epoch.sec, EPOCH_S, "{name}");
        assert_eq!(sum.time, BagTime::Header);
        no_problems(&sum);
        // Unix-time precision: the first stamp's nanoseconds survive.
        assert!(
            (samples[0].t - 0.123_456_789).abs() < 1e-15,
            "{}",
            samples[0].t
        );
        assert!((samples[N - 1].t - 1.623_456_789).abs() < 1e-12, "{name}");
        assert!((sum.rate_hz.unwrap() - 200.0).abs() < 1e-6, "{sum:?}");
        for (k, s) in samples.iter().enumerate() {
            assert_sample(s, k, stamp(k), &format!("{name} message {}", k + 1));
        }
        // Values written out: message 101 (s = 0.5 s, t = 0.623456789 s).
        let m = &samples[100];
        assert!((m.t - 0.623_456_789).abs() < 1e-12, "{}", m.t);
        let want_gyro = [0.3, 0.2 * std::f64::consts::FRAC_1_SQRT_2, 0.0];
        let want_accel = [0.0, -0.25, 9.80665];
        for a in 0..3 {
            assert!(
                (m.gyro[a] - want_gyro[a]).abs() < 1e-12,
                "{name}: {}",
                m.gyro
            );
            assert!(
                (m.accel[a] - want_accel[a]).abs() < 1e-12,
                "{name}: {}",
                m.accel
            );
        }
    }
}

#[test]
fn record_times_are_used_when_the_options_say_so() {
    let opts = BagOptions {
        time: BagTime::Record,
        ..BagOptions::default()
    };
    for name in ["imu.bag", "imu_sqlite", "imu.mcap"] {
        let (samples, sum) = read(&fixture(name), &opts);
        assert_eq!((samples.len(), sum.time), (N, BagTime::Record), "{name}");
        assert!((samples[0].t - 0.126_456_789).abs() < 1e-15, "{name}");
        for (k, s) in samples.iter().enumerate() {
            assert_sample(s, k, record(k), &format!("{name} record time {}", k + 1));
        }
    }
}

#[test]
fn big_endian_cdr_reads_as_little_endian_does() {
    let path = fixture("big_endian.mcap");
    // Every message's encapsulation header says big-endian (00 00).
    let mut heads = Vec::new();
    Bag::open(&path)
        .unwrap()
        .messages(&|_| true, &mut |m| {
            heads.push(m.data[..4].to_vec());
            Ok(())
        })
        .unwrap();
    assert_eq!(heads.len(), 40);
    assert!(heads.iter().all(|h| h == &[0, 0, 0, 0]), "{heads:?}");
    let (samples, sum) = read(&path, &BagOptions::default());
    assert_eq!((samples.len(), sum.messages), (40, 40));
    no_problems(&sum);
    for (k, s) in samples.iter().enumerate() {
        assert_sample(s, k, stamp(k), &format!("big-endian message {}", k + 1));
    }
}

#[test]
fn two_imu_topics_are_an_error_listing_both_until_one_is_named() {
    let path = fixture("two_imus.mcap");
    let e = read_err(&path, &BagOptions::default());
    assert!(
        e.contains("two_imus.mcap")
            && e.contains("2 sensor_msgs/Imu topics")
            && e.contains("/imu0/data")
            && e.contains("/imu1/data")
            && e.contains("--imu-topic"),
        "{e}"
    );
    let opts = BagOptions {
        imu_topic: Some("/imu1/data".into()),
        ..BagOptions::default()
    };
    let (samples, sum) = read(&path, &opts);
    assert_eq!((sum.topic.as_str(), samples.len()), ("/imu1/data", 20));
    for (k, s) in samples.iter().enumerate() {
        assert!((s.gyro[0] - (gyro(k)[0] + 1.0)).abs() < 1e-12, "{}", s.gyro);
        assert!((s.gyro[1] - gyro(k)[1]).abs() < 1e-12);
        assert!((s.t - stamp(k)).abs() < 1e-12);
    }
    let imu0 = BagOptions {
        imu_topic: Some("/imu0/data".into()),
        ..BagOptions::default()
    };
    let (samples, _) = read(&path, &imu0);
    assert!((samples[3].gyro[0] - gyro(3)[0]).abs() < 1e-12);
}

#[test]
fn a_topic_named_must_exist_and_be_an_imu() {
    let path = fixture("imu.mcap");
    let named = |t: &str| BagOptions {
        imu_topic: Some(t.into()),
        ..BagOptions::default()
    };
    let e = read_err(&path, &named("/imu/temperature"));
    assert!(
        e.contains("--imu-topic /imu/temperature has type sensor_msgs/Temperature"),
        "{e}"
    );
    let e = read_err(&path, &named("/imu/data"));
    assert!(
        e.contains("no such topic") && e.contains("/vn100/data [sensor_msgs/Imu]"),
        "{e}"
    );
    // A bag without any Imu topic.
    let none = Path::new(ROOT).join("tests/fixtures/bags/none.mcap");
    let e = read_err(&none, &BagOptions::default());
    assert!(
        e.contains("none.mcap: no sensor_msgs/Imu topic") && e.contains("/pose"),
        "{e}"
    );
}

/// The damage of `bad_imu.*` (see the script): what is counted, named and kept.
fn check_bad(name: &str) {
    let path = fixture(name);
    let (samples, sum) = read(&path, &BagOptions::default());
    assert_eq!(sum.topic, "/imu/data");
    assert_eq!(sum.messages, 60, "{name}");
    assert_eq!(
        (
            sum.undecodable,
            sum.non_finite,
            sum.backwards,
            sum.repeated,
            sum.zero_stamps
        ),
        (1, 1, 1, 1, 1),
        "{name}: {sum:#?}"
    );
    assert_eq!((samples.len(), sum.samples), (57, 57), "{name}");
    let shown = path.display().to_string();
    let named = |needle: &str| {
        sum.problems
            .iter()
            .find(|p| p.contains(needle))
            .unwrap_or_else(|| panic!("{name}: no {needle} in {:#?}", sum.problems))
            .clone()
    };
    // Each named with the bag, its number on the topic, and what is wrong.
    let cut = named("message 10 of /imu/data");
    assert!(cut.starts_with(&shown) && cut.contains("bytes"), "{cut}");
    let nan = named("message 20 of /imu/data");
    assert!(nan.contains("not finite") && nan.contains("NaN"), "{nan}");
    let back = named("message 30 of /imu/data");
    assert!(
        back.contains("time goes back 0.047500000 s from message 29"),
        "{back}"
    );
    let rep = named("message 40 of /imu/data");
    assert!(
        rep.contains("repeats the time stamp of message 39"),
        "{rep}"
    );
    // The warnings count them, naming the bag and the first message.
    for (needle, first) in [
        (
            "/imu/data: 1 message skipped, not decodable as sensor_msgs/Imu",
            "(first: message 10 of /imu/data: ",
        ),
        (
            "/imu/data: 1 message skipped, an angular velocity or linear acceleration not finite",
            "(first: message 20 of /imu/data: ",
        ),
        (
            "/imu/data: time goes backwards 1 time; the samples were sorted by time",
            "(first: message 30 of /imu/data: ",
        ),
        (
            "/imu/data: 1 sample dropped, repeating an earlier time stamp",
            "(first: message 40 of /imu/data: ",
        ),
        (
            "/imu/data: 1 message with a zero header.stamp, placed at the record time",
            "",
        ),
    ] {
        let w = sum
            .warnings
            .iter()
            .find(|w| w.contains(needle))
            .unwrap_or_else(|| panic!("{name}: no {needle} in {:#?}", sum.warnings));
        assert!(w.starts_with(&shown) && w.contains(first), "{w}");
    }
    // Strictly increasing times after sorting.
    assert!(samples.windows(2).all(|w| w[0].t < w[1].t), "{name}");
    let at = |t: f64| {
        samples
            .iter()
            .find(|s| (s.t - t).abs() < 1e-9)
            .unwrap_or_else(|| panic!("{name}: no sample at {t}"))
    };
    // Message 30 (k = 29) sits where its stamp puts it, 92.5 ms after the first.
    assert_sample(at(stamp(0) + 0.0925), 29, stamp(0) + 0.0925, "message 30");
    // Message 39 (k = 38) kept at its stamp, message 40's copy of it dropped.
    assert_sample(at(stamp(38)), 38, stamp(38), "message 39");
    // Message 45 (k = 44), stamped zero: at its record time.
    assert_sample(at(record(44)), 44, record(44), "message 45");
    // None of the messages skipped: 10 (k = 9), 20 (k = 19).
    assert!(samples.iter().all(|s| (s.t - stamp(9)).abs() > 1e-6));
    assert!(samples.iter().all(|s| (s.t - stamp(19)).abs() > 1e-6));

    // With record times nothing goes back, repeats or is stamped zero.
    let opts = BagOptions {
        time: BagTime::Record,
        ..BagOptions::default()
    };
    let (samples, sum) = read(&path, &opts);
    assert_eq!(
        (
            sum.undecodable,
            sum.non_finite,
            sum.backwards,
            sum.repeated,
            sum.zero_stamps
        ),
        (1, 1, 0, 0, 0),
        "{name}"
    );
    assert_eq!(samples.len(), 58);
}

#[test]
fn bad_messages_are_counted_and_named_in_ros1() {
    check_bad("bad_imu.bag");
}

#[test]
fn bad_messages_are_counted_and_named_in_cdr() {
    check_bad("bad_imu.mcap");
}

fn dvlcal(args: &[&str]) -> (bool, String, String) {
    let r = Command::new(env!("CARGO_BIN_EXE_dvlcal"))
        .args(args)
        .output()
        .expect("run dvlcal");
    (
        r.status.success(),
        String::from_utf8_lossy(&r.stdout).into_owned(),
        String::from_utf8_lossy(&r.stderr).into_owned(),
    )
}

fn line_of(stdout: &str, topic: &str) -> String {
    stdout
        .lines()
        .find(|l| l.starts_with(&format!("{topic} ")))
        .unwrap_or_else(|| panic!("no {topic} in\n{stdout}"))
        .to_string()
}

#[test]
fn bag_info_lists_the_imu_topic_with_its_count_rate_and_role() {
    for name in ["imu.bag", "imu_sqlite", "imu.mcap"] {
        let path = fixture(name);
        let (ok, out, err) = dvlcal(&["bag-info", path.to_str().unwrap()]);
        assert!(ok, "{err}");
        let imu = line_of(&out, "/vn100/data");
        let cols: Vec<&str> = imu.split_whitespace().collect();
        // topic, type, messages, rate Hz, span s, role.
        assert_eq!(
            cols,
            [
                "/vn100/data",
                "sensor_msgs/Imu",
                "301",
                "200.00",
                "1.50",
                "IMU"
            ],
            "{name}: {out}"
        );
        let temp = line_of(&out, "/imu/temperature");
        assert!(temp.trim_end().ends_with(" -"), "{temp}");
    }
    // Two Imu topics: neither gets the part, a note names both; --imu-topic chooses.
    let two = fixture("two_imus.mcap");
    let (ok, out, err) = dvlcal(&["bag-info", two.to_str().unwrap()]);
    assert!(ok, "{err}");
    assert!(
        line_of(&out, "/imu0/data").trim_end().ends_with(" -"),
        "{out}"
    );
    let note = out
        .lines()
        .find(|l| l.starts_with("note:") && l.contains("--imu-topic"))
        .unwrap_or_else(|| panic!("no note in\n{out}"));
    assert!(
        note.contains("/imu0/data") && note.contains("/imu1/data"),
        "{note}"
    );
    let (ok, out, err) = dvlcal(&[
        "bag-info",
        two.to_str().unwrap(),
        "--imu-topic",
        "/imu1/data",
    ]);
    assert!(ok, "{err}");
    assert!(
        line_of(&out, "/imu1/data").trim_end().ends_with(" IMU"),
        "{out}"
    );
    assert!(
        line_of(&out, "/imu0/data").trim_end().ends_with(" -"),
        "{out}"
    );
    // A topic named that is not there: listed anyway, with the reason no part was given.
    let (ok, out, err) = dvlcal(&["bag-info", two.to_str().unwrap(), "--imu-topic", "/nope"]);
    assert!(ok, "{err}");
    assert!(
        out.contains("note: no roles: --imu-topic /nope: no such topic"),
        "{out}"
    );
}

#[test]
fn calibrate_refuses_an_imu_topic_when_no_input_is_a_bag() {
    let poses = Path::new(ROOT).join("sample_data/poses");
    let out = std::env::temp_dir().join(format!("dvlcal-imu-refused-{}.yaml", std::process::id()));
    let r = Command::new(env!("CARGO_BIN_EXE_dvlcal"))
        .args([
            "calibrate",
            poses.to_str().unwrap(),
            "--imu-topic",
            "/imu/data",
            "--out",
            out.to_str().unwrap(),
        ])
        .output()
        .expect("run dvlcal");
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--imu-topic") && err.contains("no input here is a bag"),
        "{err}"
    );
    assert!(!out.exists());
}
