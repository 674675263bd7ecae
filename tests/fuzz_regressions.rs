//! The fuzz corpora and the inputs that once broke a parser, replayed on the stable compiler.
//! The ros1_bag and ros2_bag inputs are bags written to a temporary file, as the fuzz targets
//! do; the ros_msg inputs are single serialised messages.
//!
//! Every file under `fuzz/corpus/<target>/` and `fuzz/regressions/<target>/` goes through the
//! same library calls as the fuzz target of that name (`fuzz/fuzz_targets/<target>.rs`): each
//! call must return, `Ok` or `Err`, without a panic. Each regression input also has its own
//! expected outcome below, so a fix cannot quietly turn into a different failure.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use dvlcal::io::calib_yaml::{parse_calib_yaml, parse_calibration_guess};
use dvlcal::io::camchain::parse_camchain;
use dvlcal::io::dvl::{DvlFormat, DvlReadOptions, read_dvl_text};
use dvlcal::io::target::parse_board;
use dvlcal::io::times::parse_times;
use dvlcal::io::tum::parse_tum;
use dvlcal::io::twist_csv::parse_twist_csv;
use dvlcal::time::Epoch;

/// The fuzz targets, as named in `fuzz/Cargo.toml`.
const TARGETS: [&str; 10] = [
    "dvl_log",
    "ros1_bag",
    "ros2_bag",
    "ros_msg",
    "tum",
    "camchain",
    "board",
    "calib_yaml",
    "twist_csv",
    "times",
];

/// The epoch the fuzz targets give the readers that need one.
const EPOCH: Epoch = Epoch { sec: 1_700_000_000 };

/// What one library call returned: `Ok` with a short summary, or the error's message.
type Outcome = Result<String, String>;

fn outcome<T>(r: dvlcal::Result<T>, summary: impl FnOnce(&T) -> String) -> Outcome {
    r.as_ref().map(summary).map_err(|e| e.to_string())
}

/// A DVL read's summary; sample times that are not finite numbers are flagged, since no input
/// should produce them.
fn dvl_summary(log: &dvlcal::io::dvl::DvlLog) -> String {
    let n = log.samples.len();
    if log.samples.iter().all(|s| s.t.is_finite()) {
        format!("{n} samples")
    } else {
        format!("{n} samples, NON-FINITE times")
    }
}

/// The calls of fuzz target `target` on `data`, in the target's order. Text targets skip input
/// that is not UTF-8, as the targets do.
fn run(target: &str, data: &[u8]) -> Vec<Outcome> {
    if target == "dvl_log" {
        let name = Path::new("fuzz.log");
        let mut out = vec![outcome(
            read_dvl_text(name, data, &DvlReadOptions::default()),
            dvl_summary,
        )];
        for format in [DvlFormat::JsonLines, DvlFormat::Serial] {
            let opts = DvlReadOptions {
                format: Some(format),
                ..DvlReadOptions::default()
            };
            out.push(outcome(read_dvl_text(name, data, &opts), dvl_summary));
        }
        return out;
    }
    if target == "ros1_bag" {
        return ros1_bag(data);
    }
    if target == "ros2_bag" {
        return ros2_bag(data);
    }
    if target == "ros_msg" {
        return ros_msg(data);
    }
    let Ok(text) = std::str::from_utf8(data) else {
        return vec![];
    };
    match target {
        "tum" => {
            let name = Path::new("fuzz.tum");
            vec![
                outcome(parse_tum(text, name, None), |p| {
                    format!("{} poses", p.poses.len())
                }),
                outcome(parse_tum(text, name, Some(EPOCH)), |p| {
                    format!("{} poses", p.poses.len())
                }),
            ]
        }
        "camchain" => vec![outcome(
            parse_camchain(text, Path::new("fuzz-camchain.yaml")),
            |c| format!("{} cameras", c.cams.len()),
        )],
        "board" => vec![outcome(
            parse_board(text, Path::new("fuzz-board.yaml")),
            |b| format!("{} tags", b.tags.len()),
        )],
        "calib_yaml" => {
            let name = Path::new("fuzz-calibration.yaml");
            vec![
                outcome(parse_calib_yaml(text, name), |_| "result file".into()),
                outcome(parse_calibration_guess(text, name), |_| "guess".into()),
            ]
        }
        "twist_csv" => vec![outcome(
            parse_twist_csv(text, Path::new("fuzz-twist.csv"), EPOCH),
            |r| format!("{} rows", r.len()),
        )],
        "times" => vec![outcome(
            parse_times(text, Path::new("fuzz-times.txt"), EPOCH),
            |t| format!("{} times", t.len()),
        )],
        other => panic!("no fuzz target {other}"),
    }
}

/// The ros1_bag target: the bytes follow the bag magic (unless they start with `#`, then they
/// are the whole file); the bag is opened, every message is read, and the DVL reader runs on it.
fn ros1_bag(data: &[u8]) -> Vec<Outcome> {
    use dvlcal::io::bag::ros1::Ros1Bag;
    let mut bytes = if data.first() == Some(&b'#') {
        Vec::new()
    } else {
        b"#ROSBAG V2.0\n".to_vec()
    };
    bytes.extend_from_slice(data);
    let dir = std::env::temp_dir().join(format!("dvlcal-fuzz-replay-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temporary folder");
    let id = std::thread::current().id();
    let path = dir.join(format!("{id:?}.bag").replace(['(', ')'], ""));
    std::fs::write(&path, &bytes).expect("write the bag");
    let opened = Ros1Bag::open(&path).and_then(|b| {
        b.messages(&|_| true, &mut |_| Ok(()))
            .map(|s| format!("{} messages", s.messages))
    });
    let out = vec![
        opened.map_err(|e| e.to_string()),
        outcome(
            dvlcal::io::dvl::read_dvl_log(&path, &DvlReadOptions::default()),
            dvl_summary,
        ),
    ];
    let _ = std::fs::remove_file(&path);
    out
}

/// A scratch file of this process and thread for a bag input, with extension `ext`.
fn scratch_file(ext: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("dvlcal-fuzz-replay-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temporary folder");
    let id = std::thread::current().id();
    dir.join(format!("{id:?}.{ext}").replace(['(', ')'], ""))
}

/// The ros2_bag target: the bytes follow the MCAP magic (unless they start with 0x89, then
/// they are the whole file); the bag is opened through `Bag`, every message is read, then the
/// first topic's alone.
fn ros2_bag(data: &[u8]) -> Vec<Outcome> {
    use dvlcal::io::bag::{Bag, MCAP_MAGIC};
    let mut bytes = if data.first() == Some(&0x89) {
        Vec::new()
    } else {
        MCAP_MAGIC.to_vec()
    };
    bytes.extend_from_slice(data);
    let path = scratch_file("mcap");
    std::fs::write(&path, &bytes).expect("write the bag");
    let out = match Bag::open(&path) {
        Err(e) => vec![Err(e.to_string())],
        Ok(bag) => {
            let all = bag
                .messages(&|_| true, &mut |_| Ok(()))
                .map(|s| format!("{} messages", s.messages));
            let first = bag
                .messages(&|t| t == 0, &mut |_| Ok(()))
                .map(|s| format!("{} messages", s.messages));
            vec![
                all.map_err(|e| e.to_string()),
                first.map_err(|e| e.to_string()),
            ]
        }
    };
    let _ = std::fs::remove_file(&path);
    out
}

/// The ros_msg target: the bytes as every message type, in both serialisations, the header
/// alone, the camera model of a CameraInfo, and both image messages converted to grey.
fn ros_msg(data: &[u8]) -> Vec<Outcome> {
    use dvlcal::io::bag::Serialization;
    use dvlcal::io::bag::cdr::*;
    use dvlcal::io::bag::image::message_to_gray;
    fn d<M: CdrMessage>(data: &[u8], ser: Serialization) -> Outcome {
        outcome(decode::<M>(data, ser), |_| M::TYPE_NAME.to_string())
    }
    let mut out = Vec::new();
    for ser in [Serialization::Cdr, Serialization::Ros1] {
        out.push(outcome(decode_header(data, ser), |h| {
            format!("header {}", h.stamp.as_nanos())
        }));
        out.extend([
            d::<Time>(data, ser),
            d::<Header>(data, ser),
            d::<StringMsg>(data, ser),
            d::<Vector3>(data, ser),
            d::<Point>(data, ser),
            d::<Quaternion>(data, ser),
            d::<Pose>(data, ser),
            d::<PoseStamped>(data, ser),
            d::<PoseWithCovariance>(data, ser),
            d::<PoseWithCovarianceStamped>(data, ser),
            d::<Twist>(data, ser),
            d::<TwistWithCovariance>(data, ser),
            d::<TwistWithCovarianceStamped>(data, ser),
            d::<Transform>(data, ser),
            d::<TransformStamped>(data, ser),
            d::<TfMessage>(data, ser),
            d::<Odometry>(data, ser),
            d::<Dvl>(data, ser),
            d::<Image>(data, ser),
            d::<CompressedImage>(data, ser),
            d::<RegionOfInterest>(data, ser),
        ]);
        out.push(
            decode::<CameraInfo>(data, ser)
                .and_then(|c| c.model())
                .map(|m| format!("camera {}x{}", m.width, m.height))
                .map_err(|e| e.to_string()),
        );
        for t in ["sensor_msgs/msg/Image", "sensor_msgs/CompressedImage"] {
            out.push(outcome(message_to_gray(data, ser, t), |g| {
                format!("{}x{} grey", g.width(), g.height())
            }));
        }
    }
    out
}

fn fuzz_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz")
}

/// The files of `fuzz/<kind>/<target>/`, sorted (none when the folder does not exist).
fn files(kind: &str, target: &str) -> Vec<PathBuf> {
    let dir = fuzz_dir().join(kind).join(target);
    let Ok(entries) = std::fs::read_dir(&dir) else {
        return vec![];
    };
    let mut out: Vec<PathBuf> = entries
        .map(|e| e.expect("readable folder entry").path())
        .filter(|p| p.is_file())
        .collect();
    out.sort();
    out
}

/// Runs `data` through the target's calls, turning a panic into a failure that names the file.
fn run_file(target: &str, file: &Path) -> Vec<Outcome> {
    let data = std::fs::read(file).expect("readable fuzz input");
    std::panic::catch_unwind(|| run(target, &data))
        .unwrap_or_else(|_| panic!("{target}: {} panicked", file.display()))
}

#[test]
fn every_corpus_input_returns() {
    let mut counts = BTreeMap::new();
    for target in TARGETS {
        let inputs = files("corpus", target);
        assert!(
            !inputs.is_empty(),
            "fuzz/corpus/{target} is empty: the test would pass without testing anything"
        );
        for file in &inputs {
            for o in run_file(target, file) {
                assert!(
                    !o.as_ref().is_ok_and(|s| s.contains("NON-FINITE")),
                    "{}: {o:?}",
                    file.display()
                );
            }
        }
        counts.insert(target, inputs.len());
    }
    println!("corpus inputs per target: {counts:?}");
}

/// Asserts that every outcome is an error whose message contains each of `parts`.
fn all_err(out: &[Outcome], parts: &[&str]) {
    assert!(!out.is_empty(), "no call was made");
    for o in out {
        match o {
            Ok(s) => panic!("expected an error with {parts:?}, got Ok ({s})"),
            Err(msg) => {
                for p in parts {
                    assert!(msg.contains(p), "error '{msg}' lacks '{p}'");
                }
            }
        }
    }
}

/// The expected outcome of each regression input, keyed by `target/file`.
fn check_regression(key: &str, out: &[Outcome]) {
    match key {
        // Whole seconds beyond i64 in scientific notation used to saturate, and the epoch
        // subtraction then overflowed.
        "times/negative_sci_overflow" => all_err(
            out,
            &[
                "fuzz-times.txt:6:",
                "'-3.2e95'",
                "is not a number of seconds",
            ],
        ),
        "tum/huge_negative_time_overflow" => {
            assert_eq!(out.len(), 2);
            all_err(
                out,
                &[
                    "fuzz.tum:3:",
                    "-92233720368547758071e9",
                    "not a number of seconds",
                ],
            );
        }
        // A time stamp near -2^63 s is a valid i64; subtracting the epoch overflowed. Now the
        // row is read and the file fails later, on its own damage.
        "twist_csv/time_overflow" => all_err(out, &["fuzz-twist.csv:3:", "expected 19 fields"]),
        // 40000 sentence starts without a '*': each start rescanned the rest of the line.
        "dvl_log/serial_starts_without_star" => {
            // Detected as serial, forced JSON, forced serial: no velocity in any.
            all_err(out, &["fuzz.log:", "no velocity reports"]);
            assert!(
                out[0].as_ref().unwrap_err().contains("truncated sentence"),
                "{:?}",
                out[0]
            );
        }
        // The first candidate start fails its checksum, the second is the intact sentence.
        "dvl_log/serial_sentence_behind_false_start" => {
            assert_eq!(out[0], Ok("1 samples".to_string()));
            assert_eq!(out[2], Ok("1 samples".to_string()));
            assert!(out[1].is_err(), "{:?}", out[1]);
        }
        // json_v2 increments adding up to infinity gave NaN sample times; those reports are
        // now dropped with a warning.
        "dvl_log/time_increments_overflow" => {
            assert_eq!(out[0], Ok("1 samples".to_string()));
            assert_eq!(out[1], Ok("1 samples".to_string()));
            assert!(out[2].is_err(), "{:?}", out[2]);
        }
        // One camera per line: finding each camera's line searched the whole file again.
        "camchain/many_cameras_last_bad" => all_err(
            out,
            &[
                "fuzz-camchain.yaml:1500:",
                "cam1499: camera_model 'omni' is not supported",
            ],
        ),
        // first_id + index overflowed u32 while the grid was built.
        "board/grid_first_id_overflow" => all_err(
            out,
            &[
                "fuzz-board.yaml:",
                "tag id 4294967295 does not exist in tag36h11",
            ],
        ),
        "board/kalibr_grid_too_many_ids" => all_err(
            out,
            &[
                "fuzz-board.yaml:",
                "tag id 587 does not exist in tag36h11 (587 codes)",
            ],
        ),
        // 2001 listed tags: the duplicate check compared each tag with all before it.
        "board/many_tags_last_duplicate" => all_err(out, &["tag id 7 listed twice"]),
        other => {
            panic!("fuzz/regressions/{other} has no expected outcome in tests/fuzz_regressions.rs")
        }
    }
}

#[test]
fn every_regression_input_behaves_as_fixed() {
    let mut n = 0;
    for target in TARGETS {
        for file in files("regressions", target) {
            let out = run_file(target, &file);
            let name = file.file_name().expect("file name").to_string_lossy();
            check_regression(&format!("{target}/{name}"), &out);
            n += 1;
        }
    }
    assert!(n > 0, "no regression inputs found under fuzz/regressions");
}
