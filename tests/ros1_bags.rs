//! ROS 1 bags written by an independent writer (the Python `rosbags` package, see
//! tests/fixtures/ros1/make_bags.py) and real A50 bags, whole and damaged: cut at random points,
//! never indexed, with zeroed stretches and flipped bytes. Every damaged bag must give exactly
//! the messages it still holds, say what was lost, and never panic or hang.

mod dvl_common;

use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Duration;

use dvl_common::*;
use dvlcal::io::bag::ros1::Ros1Bag;
use dvlcal::io::dvl::{DvlLog, DvlReadOptions, read_dvl_log, read_dvl_text};
use dvlcal::rng::Rng;
use dvlcal::time::RawTime;

const FIXTURES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/ros1");
/// Messages per fixture bag, and the record time of the first (s); one message per 0.2 s.
const N: usize = 200;
const T0: i64 = 1_656_000_000;

fn fixture(name: &str) -> PathBuf {
    Path::new(FIXTURES).join(name)
}

fn opts() -> DvlReadOptions {
    DvlReadOptions::default()
}

/// Reads a log in another thread: a reader that loops forever fails the test instead of
/// hanging it.
fn read_within(path: &Path, secs: u64) -> dvlcal::error::Result<DvlLog> {
    let (tx, rx) = mpsc::channel();
    let p = path.to_path_buf();
    std::thread::spawn(move || {
        let _ = tx.send(read_dvl_log(&p, &DvlReadOptions::default()));
    });
    rx.recv_timeout(Duration::from_secs(secs))
        .unwrap_or_else(|_| panic!("{}: no answer within {secs} s", path.display()))
}

/// The JSON lines the bags were made from, and where each one's text lies in `bag` (found by
/// searching the bytes, in order: independent of the reader under test).
fn lines_in(bag: &[u8], lines: &[String]) -> Vec<(usize, usize)> {
    let mut at = 0usize;
    lines
        .iter()
        .map(|l| {
            let k = bag[at..]
                .windows(l.len())
                .position(|w| w == l.as_bytes())
                .unwrap_or_else(|| panic!("line not in the bag: {l}"));
            let start = at + k;
            at = start + l.len();
            (start, at)
        })
        .collect()
}

/// A message record of format 2.0 starts 50 bytes before its std_msgs/String text: header
/// length (4), the fields conn (13), op (8) and time (17), data length (4), string length (4).
const RECORD_BEFORE_TEXT: usize = 50;

/// The velocity reports in `lines` (read as a JSON-lines log); 0 when there are none.
fn reports_in(lines: &[&String]) -> usize {
    let text: String = lines.iter().map(|l| format!("{l}\n")).collect();
    read_dvl_text(Path::new("expected.jsonl"), text.as_bytes(), &opts())
        .map(|l| l.stats.velocity_reports)
        .unwrap_or(0)
}

fn jsonl(name: &str, n: usize) -> Vec<String> {
    std::fs::read_to_string(real(name, "jsonl"))
        .unwrap()
        .lines()
        .take(n)
        .map(str::to_string)
        .collect()
}

#[test]
fn bags_of_an_independent_writer_read_as_their_json_lines() {
    let lines = jsonl("dvl_circle", N);
    let refs: Vec<&String> = lines.iter().collect();
    let text: String = lines.iter().map(|l| format!("{l}\n")).collect();
    let reference = read_dvl_text(Path::new("ref.jsonl"), text.as_bytes(), &opts()).unwrap();
    let by_time = DvlReadOptions {
        time_source: dvlcal::io::dvl::DvlTimeSource::Host,
        ..opts()
    };
    for name in [
        "json_none.bag",
        "json_bz2.bag",
        "json_lz4.bag",
        "json_active.bag",
    ] {
        let p = fixture(name);
        let bag = Ros1Bag::open(&p).unwrap();
        let topics: Vec<String> = bag.connections().map(|c| c.topic.clone()).collect();
        assert_eq!(topics, ["/dvl/json_data", "/chatter"], "{name}");
        assert!(
            bag.connections().all(|c| c.msg_type == "std_msgs/String"),
            "{name}"
        );
        let log = read_dvl_log(&p, &opts()).unwrap();
        assert_eq!(log.stats.velocity_reports, reports_in(&refs), "{name}");
        assert_eq!(log.samples.len(), reference.samples.len(), "{name}");
        for (a, b) in log.samples.iter().zip(&reference.samples) {
            assert_eq!(a.v, b.v, "{name}");
            assert_eq!(a.cov, b.cov, "{name}");
        }
        // Host times are the record times the writer was given: message k at T0 + 0.2 k.
        let host = read_dvl_log(&p, &by_time).unwrap();
        assert_eq!(host.samples.len(), reference.samples.len(), "{name}");
        for (s, &line) in host.samples.iter().zip(&host.lines) {
            let ns = (line as i64 - 1) * 200_000_000;
            let expected = host.epoch.rel(RawTime {
                sec: T0 + ns / 1_000_000_000,
                frac: (ns % 1_000_000_000) as f64 * 1e-9,
            });
            assert!(
                (s.t - expected).abs() < 1e-6,
                "{name}: {} vs {expected}",
                s.t
            );
        }
        let damage: Vec<&String> = log
            .stats
            .warnings
            .iter()
            .filter(|w| w.starts_with("bag:"))
            .collect();
        if name == "json_active.bag" {
            assert!(!bag.indexed());
            assert!(
                damage
                    .iter()
                    .any(|w| w.contains("no index") && w.contains("rosbag reindex")),
                "{damage:?}"
            );
        } else {
            assert!(bag.indexed(), "{name}");
            assert!(damage.is_empty(), "{name}: {damage:?}");
        }
    }
}

/// Cuts `bag` at `cuts` points and checks each gives exactly the velocity reports of the
/// messages wholly before the cut, with the loss said.
fn check_cuts(label: &str, bag: &[u8], lines: &[String], cuts: usize, seed: u64) {
    let spans = lines_in(bag, lines);
    let dir = temp_dir(&format!("cut-{label}"));
    let mut rng = Rng::new(seed);
    let first = spans[0].0;
    for k in 0..cuts {
        let cut = first + (rng.uniform() * (bag.len() - first) as f64) as usize;
        let p = dir.join(format!("{label}-{k}.bag"));
        std::fs::write(&p, &bag[..cut]).unwrap();
        let whole: Vec<&String> = lines
            .iter()
            .zip(&spans)
            .filter(|(_, s)| s.1 <= cut)
            .map(|(l, _)| l)
            .collect();
        let expected = reports_in(&whole);
        match read_within(&p, 30) {
            Ok(log) => {
                assert_eq!(log.stats.velocity_reports, expected, "{label} cut at {cut}");
                if cut < bag.len() {
                    assert!(
                        log.stats.warnings.iter().any(|w| w.starts_with("bag:")),
                        "{label} cut at {cut}: no damage said: {:?}",
                        log.stats.warnings
                    );
                }
            }
            Err(e) => {
                let e = e.to_string();
                assert_eq!(expected, 0, "{label} cut at {cut}: {e}");
                assert!(e.contains(&p.display().to_string()), "{e}");
            }
        }
        std::fs::remove_file(&p).unwrap();
    }
}

#[test]
fn bags_cut_short_give_every_whole_message_before_the_cut() {
    let real_bag = std::fs::read(real("dvl_circle", "bag")).unwrap();
    let all = jsonl("dvl_circle", usize::MAX);
    check_cuts("real", &real_bag, &all, 60, 11);
    let fixture_bag = std::fs::read(fixture("json_none.bag")).unwrap();
    check_cuts("fixture", &fixture_bag, &jsonl("dvl_circle", N), 40, 12);
    let active = std::fs::read(fixture("json_active.bag")).unwrap();
    check_cuts("active", &active, &jsonl("dvl_circle", N), 20, 13);
}

#[test]
fn compressed_bags_cut_short_never_panic_and_say_so() {
    let dir = temp_dir("cut-compressed");
    let full = reports_in(&jsonl("dvl_circle", N).iter().collect::<Vec<_>>());
    let mut rng = Rng::new(5);
    for name in ["json_bz2.bag", "json_lz4.bag"] {
        let bag = std::fs::read(fixture(name)).unwrap();
        for k in 0..20 {
            let cut = 13 + (rng.uniform() * (bag.len() - 13) as f64) as usize;
            let p = dir.join(format!("{k}-{name}"));
            std::fs::write(&p, &bag[..cut]).unwrap();
            match read_within(&p, 30) {
                Ok(log) => {
                    // A cut in the index section at the end loses no message, but is said.
                    assert!(log.stats.velocity_reports <= full, "{name} cut at {cut}");
                    assert!(
                        log.stats.warnings.iter().any(|w| w.starts_with("bag:")),
                        "{name} cut at {cut}"
                    );
                }
                Err(e) => assert!(e.to_string().contains(&p.display().to_string()), "{e}"),
            }
        }
    }
}

#[test]
fn zeroed_stretches_lose_only_the_messages_they_cover() {
    let dir = temp_dir("zeroed");
    let mut rng = Rng::new(21);
    for (label, bag, lines) in [
        (
            "real",
            std::fs::read(real("dvl_circle", "bag")).unwrap(),
            jsonl("dvl_circle", usize::MAX),
        ),
        (
            "fixture",
            std::fs::read(fixture("json_none.bag")).unwrap(),
            jsonl("dvl_circle", N),
        ),
    ] {
        let spans = lines_in(&bag, &lines);
        for k in 0..30 {
            let len = 1 + (rng.uniform() * 4096.0) as usize;
            let z = 13 + (rng.uniform() * (bag.len() - 13 - len) as f64) as usize;
            let mut damaged = bag.clone();
            damaged[z..z + len].fill(0);
            let p = dir.join(format!("{label}-{k}.bag"));
            std::fs::write(&p, &damaged).unwrap();
            let kept: Vec<&String> = lines
                .iter()
                .zip(&spans)
                .filter(|(_, s)| s.1 <= z || s.0 - RECORD_BEFORE_TEXT >= z + len)
                .map(|(l, _)| l)
                .collect();
            let expected = reports_in(&kept);
            let log = read_within(&p, 30)
                .unwrap_or_else(|e| panic!("{label}: zeros at {z}..{}: {e}", z + len));
            assert_eq!(
                log.stats.velocity_reports,
                expected,
                "{label}: zeros at {z}..{}: {:?}",
                z + len,
                log.stats.warnings
            );
            if kept.len() < lines.len() {
                // Zeros inside one message's text leave the bag's framing whole: that message
                // is a rejected line; anything more is bag damage.
                assert!(
                    log.stats.rejected_lines > 0
                        || log.stats.warnings.iter().any(|w| w.starts_with("bag:")),
                    "{label}: zeros at {z}: {:?}",
                    log.stats.warnings
                );
            }
        }
    }
}

#[test]
fn flipped_bytes_never_hide_the_damage() {
    let bag = std::fs::read(real("dvl_circle", "bag")).unwrap();
    let full = read_dvl_log(&real("dvl_circle", "bag"), &opts()).unwrap();
    let dir = temp_dir("flips");
    let mut rng = Rng::new(77);
    for k in 0..120 {
        let mut damaged = bag.clone();
        let flips = 1 + (rng.uniform() * 8.0) as usize;
        for _ in 0..flips {
            let at = (rng.uniform() * bag.len() as f64) as usize;
            damaged[at] ^= 1 << ((rng.uniform() * 8.0) as u32 % 8);
        }
        let p = dir.join(format!("{k}.bag"));
        std::fs::write(&p, &damaged).unwrap();
        match read_within(&p, 30) {
            Ok(log) => {
                let lost = log.stats.velocity_reports < full.stats.velocity_reports;
                let said = log.stats.rejected_lines > 0
                    || log.stats.warnings.iter().any(|w| w.starts_with("bag:"));
                assert!(!lost || said, "run {k}: reports lost without a word");
            }
            Err(e) => {
                let e = e.to_string();
                assert!(e.contains(&p.display().to_string()), "{e}");
                // An empty result keeps the damage that explains it.
                if e.contains("no velocity reports") {
                    assert!(e.contains("bag:") || e.contains("rejected"), "{e}");
                }
            }
        }
    }
}

#[test]
fn a_damaged_bag_is_an_error_under_strict() {
    let bag = std::fs::read(fixture("json_active.bag")).unwrap();
    let dir = temp_dir("strict-bag");
    let p = dir.join("active.bag");
    std::fs::write(&p, &bag).unwrap();
    let strict = DvlReadOptions {
        strict: true,
        ..opts()
    };
    let e = read_dvl_log(&p, &strict).unwrap_err().to_string();
    assert!(e.contains("active.bag") && e.contains("no index"), "{e}");
    // Not a bag at all: named as such.
    std::fs::write(&p, b"#ROSBAG V1.2\nold").unwrap();
    let e = Ros1Bag::open(&p).unwrap_err().to_string();
    assert!(e.contains("not a ROS 1 bag"), "{e}");
    // Only the magic: no chunk, an error naming the file.
    std::fs::write(&p, b"#ROSBAG V2.0\n").unwrap();
    let e = read_dvl_log(&p, &opts()).unwrap_err().to_string();
    assert!(
        e.contains("active.bag") && e.contains("no readable chunk"),
        "{e}"
    );
}
