//! Input that is not what it claims to be, or that is easy to misread, is named for what it is:
//! a file that is not the bag its name promises (its magic bytes), a ROS 2 bag whose
//! metadata.yaml names the other storage, a DVL log with CR-only line ends or nothing in it, a
//! Kalibr checkerboard target, an A50 capture taken by polling; and `bag-info` / `dvl-info`
//! print rates and positions that mean what they say.

mod tmp_common;

use std::path::{Path, PathBuf};

use dvlcal::io::bag::info::bag_info;
use dvlcal::io::bag::roles::BagOptions;
use dvlcal::io::bag::{Bag, MCAP_MAGIC, Storage};
use dvlcal::io::dvl::{DvlReadOptions, read_dvl_log, read_dvl_text};
use dvlcal::io::target::parse_board;
use tmp_common::{TmpDir, dvlcal, s};

fn bag_fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/bags")
        .join(name)
}

fn text(o: &std::process::Output) -> (String, String) {
    (
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

// ---------------------------------------------------------------------------------------------
// A file that is not the bag its name promises.

#[test]
fn a_file_named_mcap_that_is_not_one_is_named_by_its_magic_bytes() {
    let tmp = TmpDir::new("named-magic");
    let not = tmp.path("notes.mcap");
    std::fs::write(&not, "hello, this is a text file\n").unwrap();
    let e = Bag::open(&not).unwrap_err().to_string();
    assert!(
        e.contains("notes.mcap: not an MCAP file: magic bytes 68 65 6c 6c 6f 2c 20 74")
            && e.contains("89 4d 43 41 50 30 0d 0a"),
        "{e}"
    );
    // Cut inside the magic: said so, with how many bytes there are.
    let cut = tmp.path("cut.mcap");
    std::fs::write(&cut, &MCAP_MAGIC[..4]).unwrap();
    let e = Bag::open(&cut).unwrap_err().to_string();
    assert!(
        e.contains("cut.mcap: not an MCAP file")
            && e.contains("ends after 4 bytes, inside the magic"),
        "{e}"
    );
    // The same for the other storages' names.
    let db = tmp.path("run.db3");
    std::fs::write(&db, "PK\x03\x04 a zip").unwrap();
    let e = Bag::open(&db).unwrap_err().to_string();
    assert!(
        e.contains("run.db3: not an sqlite3 database: magic bytes 50 4b 03 04"),
        "{e}"
    );
    // Through the program, as a bag and as a DVL log: the same words, exit code 1.
    for cmd in ["bag-info", "dvl-info"] {
        let o = dvlcal(&[cmd, s(&not)]);
        let (_, err) = text(&o);
        assert_eq!(o.status.code(), Some(1), "{cmd}: {err}");
        assert!(
            err.contains("not an MCAP file: magic bytes 68 65"),
            "{cmd}: {err}"
        );
    }
    let o = dvlcal(&["dvl-info", s(&cut)]);
    let (_, err) = text(&o);
    assert!(err.contains("inside the magic"), "{err}");
}

/// A copy of the fixture bag folder `name` whose metadata.yaml has `edit` applied.
fn bag_copy(tmp: &TmpDir, name: &str, edit: &dyn Fn(&str) -> String) -> PathBuf {
    let src = bag_fixture(name);
    let dst = tmp.path(name);
    std::fs::create_dir_all(&dst).unwrap();
    for e in std::fs::read_dir(&src).unwrap() {
        let e = e.unwrap();
        let to = dst.join(e.file_name());
        if e.file_name() == "metadata.yaml" {
            std::fs::write(&to, edit(&std::fs::read_to_string(e.path()).unwrap())).unwrap();
        } else {
            std::fs::copy(e.path(), &to).unwrap();
        }
    }
    dst
}

fn message_count(bag: &Bag) -> u64 {
    bag.messages(&|_| true, &mut |_| Ok(())).unwrap().messages
}

#[test]
fn a_metadata_yaml_naming_the_other_storage_is_read_by_the_magic_with_a_note() {
    let tmp = TmpDir::new("named-storage");
    for (name, said, is, kind) in [
        ("mcap_zstd", "mcap", "sqlite3", Storage::Mcap),
        ("sqlite", "sqlite3", "mcap", Storage::Sqlite3),
    ] {
        let good = Bag::open(&bag_fixture(name)).unwrap();
        assert!(good.notes().is_empty(), "{:?}", good.notes());
        let dir = bag_copy(&tmp, name, &|m| {
            m.replace(
                &format!("storage_identifier: {said}"),
                &format!("storage_identifier: {is}"),
            )
        });
        let bag = Bag::open(&dir).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(bag.storage(), kind, "{name}");
        assert_eq!(message_count(&bag), message_count(&good), "{name}");
        assert_eq!(bag.notes().len(), 1, "{name}: {:?}", bag.notes());
        let note = &bag.notes()[0];
        assert!(
            note.contains("metadata.yaml: storage_identifier is")
                && note.contains(&format!("\"{is}\""))
                && note.contains(kind.file_kind())
                && note.contains(&format!("read as {said}")),
            "{name}: {note}"
        );
        // bag-info shows it as a note (not as damage), dvl-info as a warning.
        let o = dvlcal(&["bag-info", s(&dir)]);
        let (out, err) = text(&o);
        assert!(o.status.success(), "{err}");
        assert!(
            out.lines()
                .any(|l| l.starts_with("note:") && l.contains("storage_identifier is")),
            "{out}"
        );
        assert!(!out.contains("damage:"), "{out}");
        let o = dvlcal(&["dvl-info", s(&dir)]);
        let (out, err) = text(&o);
        assert!(o.status.success(), "{err}");
        assert!(
            out.contains("warning: bag:") && out.contains("storage_identifier is"),
            "{out}"
        );
    }
}

#[test]
fn a_listed_file_of_neither_storage_is_named_with_the_metadata_that_lists_it() {
    let tmp = TmpDir::new("named-listed");
    let dir = bag_copy(&tmp, "mcap_zstd", &|m| m.to_string());
    std::fs::write(dir.join("mcap_zstd.mcap"), "#!/bin/sh\necho not a bag\n").unwrap();
    let e = Bag::open(&dir).unwrap_err().to_string();
    assert!(
        e.contains("mcap_zstd.mcap: not an MCAP file: magic bytes 23 21 2f 62")
            && e.contains("metadata.yaml lists it, storage_identifier \"mcap\""),
        "{e}"
    );
    // Files of both storages under one metadata.yaml: both named.
    let dir = bag_copy(&tmp, "split_mcap", &|m| m.to_string());
    std::fs::copy(
        bag_fixture("bare.db3"),
        dir.join("split_mcap_1.mcap"), // an sqlite3 database under an MCAP name
    )
    .unwrap();
    let e = Bag::open(&dir).unwrap_err().to_string();
    assert!(
        e.contains("two storages")
            && e.contains("split_mcap_0.mcap is an MCAP file")
            && e.contains("split_mcap_1.mcap is an sqlite3 database"),
        "{e}"
    );
}

// ---------------------------------------------------------------------------------------------
// DVL logs: CR-only line ends, nothing in them.

/// A json_v3 velocity report at `k * 100 ms` after a fixed Unix time.
fn v3_line(k: usize) -> String {
    let tov = 1_700_000_000_000_000i64 + k as i64 * 100_000;
    format!(
        "{{\"time\":100.0,\"vx\":{:.4},\"vy\":0.01,\"vz\":-0.02,\"fom\":0.002,\
         \"covariance\":[[1e-6,0,0],[0,1e-6,0],[0,0,1e-6]],\"altitude\":1.5,\"transducers\":[],\
         \"velocity_valid\":true,\"status\":0,\"format\":\"json_v3\",\"type\":\"velocity\",\
         \"time_of_validity\":{tov},\"time_of_transmission\":{}}}",
        0.1 + 0.001 * k as f64,
        tov + 30_000
    )
}

#[test]
fn a_log_with_cr_only_line_ends_is_read_line_by_line_and_said_so() {
    let lines: Vec<String> = (0..50).map(v3_line).collect();
    let lf = lines.join("\n") + "\n";
    let cr = lines.join("\r") + "\r";
    let opts = DvlReadOptions::default();
    let a = read_dvl_text(Path::new("lf.jsonl"), lf.as_bytes(), &opts).unwrap();
    let b = read_dvl_text(Path::new("mac.jsonl"), cr.as_bytes(), &opts).unwrap();
    assert_eq!(b.samples.len(), 50);
    assert_eq!(b.stats.lines, 50);
    assert_eq!(b.stats.rejected_lines, 0);
    assert_eq!(
        a.samples.iter().map(|s| s.t).collect::<Vec<_>>(),
        b.samples.iter().map(|s| s.t).collect::<Vec<_>>()
    );
    assert!(
        !a.stats.warnings.iter().any(|w| w.contains("CR alone")),
        "{:?}",
        a.stats.warnings
    );
    assert!(
        b.stats
            .warnings
            .iter()
            .any(|w| w.contains("mac.jsonl") && w.contains("CR alone")),
        "{:?}",
        b.stats.warnings
    );
    // Line numbers count CR-ended lines: a broken line 7 is named as line 7.
    let mut broken = lines.clone();
    broken[6] = "{\"time\":100.0,\"vx\":".into();
    let e = read_dvl_text(
        Path::new("mac.jsonl"),
        (broken.join("\r") + "\r").as_bytes(),
        &DvlReadOptions {
            strict: true,
            ..Default::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.starts_with("mac.jsonl:7:"), "{e}");
    // Through the program.
    let tmp = TmpDir::new("named-cr");
    let p = tmp.path("mac.jsonl");
    std::fs::write(&p, &cr).unwrap();
    let o = dvlcal(&["dvl-info", s(&p)]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    assert!(out.contains("samples used      50"), "{out}");
    assert!(out.contains("CR alone"), "{out}");
}

#[test]
fn an_empty_log_is_called_empty() {
    let tmp = TmpDir::new("named-empty");
    let empty = tmp.path("empty.jsonl");
    std::fs::write(&empty, "").unwrap();
    let blank = tmp.path("blank.log");
    std::fs::write(&blank, " \n\n\t\r\n  \n").unwrap();
    for (p, words) in [
        (&empty, "empty.jsonl: the DVL log is empty (0 bytes)"),
        (
            &blank,
            "blank.log: the DVL log holds only blanks and line ends (9 bytes",
        ),
    ] {
        let e = read_dvl_log(p, &DvlReadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains(words), "{e}");
        // Forcing a format does not turn it into a parse error.
        for format in ["json", "serial"] {
            let o = dvlcal(&["dvl-info", "--dvl-format", format, s(p)]);
            let (_, err) = text(&o);
            assert_eq!(o.status.code(), Some(1), "{err}");
            assert!(err.contains(words), "{format}: {err}");
        }
    }
    let e = read_dvl_text(Path::new("mem"), b"", &DvlReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("mem: the DVL log is empty"), "{e}");
}

// ---------------------------------------------------------------------------------------------
// Targets.

#[test]
fn a_kalibr_checkerboard_target_is_named_as_such_with_its_line() {
    let yaml = "# my board\ntarget_type: 'checkerboard'\ntargetCols: 6\ntargetRows: 7\n\
                rowSpacingMeters: 0.06\ncolSpacingMeters: 0.06\n";
    let e = parse_board(yaml, Path::new("target.yaml"))
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("target.yaml:2: target_type 'checkerboard': a Kalibr checkerboard target")
            && e.contains("AprilTags only")
            && e.contains("aprilgrid"),
        "{e}"
    );
    assert!(!e.contains("missing field"), "{e}");
    let yaml = "target_type: 'circlegrid'\ntargetCols: 6\ntargetRows: 7\nspacingMeters: 0.02\n\
                asymmetricGrid: False\n";
    let e = parse_board(yaml, Path::new("t.yaml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("t.yaml:1:") && e.contains("circle grid"), "{e}");
    // The program says the same, with exit code 1.
    let tmp = TmpDir::new("named-target");
    let t = tmp.path("checker.yaml");
    std::fs::write(
        &t,
        "target_type: 'checkerboard'\ntargetCols: 6\ntargetRows: 7\n\
         rowSpacingMeters: 0.06\ncolSpacingMeters: 0.06\n",
    )
    .unwrap();
    let o = dvlcal(&["board", "--target", s(&t), "--out", s(&tmp.path("b.svg"))]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("checker.yaml:1:") && err.contains("Kalibr checkerboard"),
        "{err}"
    );
    assert!(!tmp.path("b.svg").exists());
}

// ---------------------------------------------------------------------------------------------
// A capture taken by polling.

/// A small deterministic generator (64-bit LCG), uniform in [0, 1).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// One json_v1 report as the A50 writes it (four transducers, no absolute time), `k`-th of
/// the stream, `dt_ms` after the one before it; with `tov_us`, a json_v3 report instead.
fn a50_line(k: usize, dt_ms: f64, tov_us: Option<i64>) -> String {
    let x = k as f64;
    let beams: Vec<String> = (0..4)
        .map(|id| {
            format!(
                "{{\"id\":{id},\"velocity\":{:.9},\"distance\":{:.9},\"rssi\":{:.6},\
                 \"nsd\":{:.6},\"beam_valid\":true}}",
                1e-4 * ((x + id as f64) * 0.7).sin(),
                0.06 + 0.01 * id as f64,
                50.0 - id as f64,
                26.0 + 0.1 * ((x * 1.3).cos())
            )
        })
        .collect();
    let tail = match tov_us {
        None => "\"format\":\"json_v1\"".to_string(),
        Some(t) => format!(
            "\"format\":\"json_v3\",\"type\":\"velocity\",\"time_of_validity\":{t},\
             \"time_of_transmission\":{}",
            t + 40_000
        ),
    };
    format!(
        "{{\"time\":{dt_ms},\"vx\":{:.12},\"vy\":{:.12},\"vz\":{:.12},\"fom\":0.0009,\
         \"altitude\":0.054,\"transducers\":[{}],\"velocity_valid\":true,\"status\":0,{tail}}}",
        1e-3 * (x * 0.37).sin(),
        1e-3 * (x * 0.23).cos(),
        4e-4 * (x * 0.11).sin(),
        beams.join(",")
    )
}

/// A still A50 log taken as the public capture `out_still_60s.txt` was (see
/// tests/fixtures/polled_a50/README.md): the DVL reports every 40-108 ms; a driver refreshes
/// its latest report at irregular times, about once a second; a loop writes that latest report 11.2 times a
/// second for `capture_s`. Returns the lines and the sum of the DVL's `time` increments over
/// the whole capture.
fn polled_capture(capture_s: f64, with_tov: bool) -> (Vec<String>, f64) {
    let mut rng = Lcg(36);
    // The DVL's stream: report k at t[k], with its increment.
    let (mut t, mut stream) = (0.0f64, Vec::new());
    while t < capture_s + 2.0 {
        let dt_ms = 40.0 + 68.0 * rng.next();
        t += dt_ms * 1e-3;
        stream.push((t, dt_ms));
    }
    let t0 = 1_622_000_000_000_000i64;
    // The driver's refreshes: each takes the latest report at that moment.
    let (mut next_refresh, mut current) = (0.3, 0usize);
    let mut lines = Vec::new();
    let mut i = 0usize;
    loop {
        let read_at = i as f64 / 11.2;
        if read_at > capture_s {
            break;
        }
        while next_refresh <= read_at {
            current = stream
                .partition_point(|s| s.0 <= next_refresh)
                .saturating_sub(1);
            // Irregular, 1.1 s on average (the real capture's runs are 1 to 60 reads long).
            next_refresh += 0.1 - 1.0 * (1.0 - rng.next()).ln();
        }
        let (tk, dt) = stream[current];
        let tov = with_tov.then(|| t0 + (tk * 1e6) as i64);
        lines.push(a50_line(current, dt, tov));
        i += 1;
    }
    (lines, t)
}

#[test]
fn a_polled_capture_is_recognised_and_explained() {
    let capture_s = 60.0;
    let (lines, _) = polled_capture(capture_s, false);
    let log = read_dvl_text(
        Path::new("out_still_60s.txt"),
        (lines.join("\n") + "\n").as_bytes(),
        &DvlReadOptions::default(),
    )
    .unwrap();
    let p = log.stats.polled.clone().expect("recognised as polled");
    // The counts are those of the file.
    let mut distinct = 1;
    let mut repeats = 0;
    for w in lines.windows(2) {
        if w[0] == w[1] {
            repeats += 1;
        } else {
            distinct += 1;
        }
    }
    assert_eq!(
        (p.reports, p.repeats, p.distinct),
        (lines.len(), repeats, distinct)
    );
    assert!(p.repeats * 10 > p.reports * 8, "{p:?}"); // like the real one's 621 of 674
    assert!(p.times_rebuilt && p.unusable());
    // The rebuilt time line spans the increments of the distinct reports, a few seconds.
    let span = p.increments_s.unwrap();
    let rebuilt = log.stats.last_time_s.unwrap() - log.stats.first_time_s.unwrap();
    assert!((span - rebuilt).abs() < 1e-6, "{span} vs {rebuilt}");
    assert!(span < capture_s / 8.0, "{span}");
    // The capture's least length is a true lower bound, and says the squeeze is large.
    let least = p.min_capture_s.unwrap();
    let squeeze = p.min_squeeze().unwrap();
    assert!(least <= capture_s && squeeze <= capture_s / span, "{p:?}");
    assert!(squeeze > 3.0, "{p:?}");
    let w = log
        .stats
        .warnings
        .iter()
        .find(|w| w.contains("polled capture"))
        .expect("a warning");
    for words in [
        format!("{repeats} of {} velocity reports repeat", lines.len()),
        format!("{distinct} distinct reports"),
        format!("add up to {span:.2} s"),
        format!("squeezed at least {squeeze:.1}x"),
        "cannot be calibrated as it is".to_string(),
        "dvlcal record-dvl".to_string(),
        "time_of_validity".to_string(),
    ] {
        assert!(w.contains(&words), "{words:?} not in {w}");
    }
    // In dvl-info's JSON too.
    let v = log.summary_json();
    assert_eq!(v["polled_capture"]["repeats"], repeats);
}

#[test]
fn a_polled_capture_with_dvl_times_keeps_them_and_a_stream_is_not_polled() {
    // The same capture with time_of_validity: the repeats are dropped, the times kept.
    let (lines, _) = polled_capture(30.0, true);
    let log = read_dvl_text(
        Path::new("polled_v3.jsonl"),
        lines.join("\n").as_bytes(),
        &DvlReadOptions::default(),
    )
    .unwrap();
    let p = log.stats.polled.clone().expect("recognised as polled");
    assert!(!p.times_rebuilt && !p.unusable() && p.min_squeeze().is_none());
    assert_eq!(log.samples.len(), p.distinct);
    let span = log.stats.last_time_s.unwrap() - log.stats.first_time_s.unwrap();
    assert!(span > 25.0, "{span}");
    assert!(
        log.stats
            .warnings
            .iter()
            .any(|w| w.contains("polled capture") && w.contains("keep their own times")),
        "{:?}",
        log.stats.warnings
    );
    // A stream: each report once. Forwarded twice: exactly half repeat. Neither is polled.
    let stream: Vec<String> = (0..300).map(|k| a50_line(k, 60.0, None)).collect();
    let twice: Vec<String> = stream.iter().flat_map(|l| [l.clone(), l.clone()]).collect();
    for (name, lines) in [("stream", &stream), ("twice", &twice)] {
        let log = read_dvl_text(
            Path::new(name),
            lines.join("\n").as_bytes(),
            &DvlReadOptions::default(),
        )
        .unwrap();
        assert!(log.stats.polled.is_none(), "{name}");
        assert_eq!(log.samples.len(), 300, "{name}");
        assert!(
            !log.stats.warnings.iter().any(|w| w.contains("polled")),
            "{name}"
        );
    }
}

#[test]
fn calibrate_refuses_a_polled_capture_without_dvl_times() {
    let tmp = TmpDir::new("named-polled");
    let (lines, _) = polled_capture(60.0, false);
    let dvl = tmp.path("out_still_60s.txt");
    std::fs::write(&dvl, lines.join("\n") + "\n").unwrap();
    // Camera poses: a slow circle over 60 s at 10 Hz.
    let mut tum = String::new();
    for k in 0..=600 {
        let t = k as f64 * 0.1;
        let a = 0.1 * t;
        let (h, c) = ((a / 2.0).sin(), (a / 2.0).cos());
        tum.push_str(&format!(
            "{t:.3} {:.6} {:.6} 0.0 0.0 0.0 {h:.9} {c:.9}\n",
            a.cos(),
            a.sin()
        ));
    }
    let poses = tmp.path("poses.tum");
    std::fs::write(&poses, tum).unwrap();
    let out = tmp.path("calib.yaml");
    let o = dvlcal(&[
        "calibrate",
        "--poses",
        s(&poses),
        "--dvl",
        s(&dvl),
        "--out",
        s(&out),
        "--no-progress",
    ]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    // The error itself, not only a warning on the way to another failure.
    let error = err
        .lines()
        .find(|l| l.starts_with("error:"))
        .unwrap_or_else(|| panic!("no error in {err}"));
    assert!(
        error.contains("out_still_60s.txt: a polled capture")
            && error.contains("cannot be calibrated as it is"),
        "{err}"
    );
    assert!(!out.exists());
}

// ---------------------------------------------------------------------------------------------
// bag-info and dvl-info on bags.

fn lp(b: &mut Vec<u8>, x: &str) {
    b.extend_from_slice(&(x.len() as u32).to_le_bytes());
    b.extend_from_slice(x.as_bytes());
}

fn record(b: &mut Vec<u8>, op: u8, content: &[u8]) {
    b.push(op);
    b.extend_from_slice(&(content.len() as u64).to_le_bytes());
    b.extend_from_slice(content);
}

/// A std_msgs/String message in CDR.
fn cdr_string(x: &str) -> Vec<u8> {
    let mut b = vec![0, 1, 0, 0];
    b.extend_from_slice(&(x.len() as u32 + 1).to_le_bytes());
    b.extend_from_slice(x.as_bytes());
    b.push(0);
    b
}

/// An unchunked MCAP file: `topics` (name, type) declared in that order, then `messages`
/// (topic index, record time ns, data) in order, a footer without summary.
fn mcap(topics: &[(&str, &str)], messages: &[(usize, u64, Vec<u8>)]) -> Vec<u8> {
    let mut b = MCAP_MAGIC.to_vec();
    let mut h = Vec::new();
    lp(&mut h, "ros2");
    lp(&mut h, "test");
    record(&mut b, 0x01, &h);
    for (i, (name, ty)) in topics.iter().enumerate() {
        let id = i as u16 + 1;
        let mut sc = id.to_le_bytes().to_vec();
        lp(&mut sc, ty);
        lp(&mut sc, "ros2msg");
        lp(&mut sc, "");
        record(&mut b, 0x03, &sc);
        let mut ch = id.to_le_bytes().to_vec();
        ch.extend_from_slice(&id.to_le_bytes());
        lp(&mut ch, name);
        lp(&mut ch, "cdr");
        ch.extend_from_slice(&0u32.to_le_bytes());
        record(&mut b, 0x04, &ch);
    }
    for (seq, (topic, t, data)) in messages.iter().enumerate() {
        let mut m = (*topic as u16 + 1).to_le_bytes().to_vec();
        m.extend_from_slice(&(seq as u32).to_le_bytes());
        m.extend_from_slice(&t.to_le_bytes());
        m.extend_from_slice(&t.to_le_bytes());
        m.extend_from_slice(data);
        record(&mut b, 0x05, &m);
    }
    record(&mut b, 0x0F, &[0; 4]);
    record(&mut b, 0x02, &[0; 20]);
    b.extend_from_slice(MCAP_MAGIC);
    b
}

#[test]
fn bag_info_sorts_topics_and_gives_rates_only_where_they_mean_something() {
    let t0 = 1_700_000_000_000_000_000u64;
    let s1 = "std_msgs/msg/String";
    // Declared out of order. /zeta: 4 messages within 59 us (what gave 50,632 Hz); /mid: 5
    // messages over 0.4 s; /alpha: 21 messages over 2 s at 10 Hz.
    let topics = [("/zeta", s1), ("/mid", s1), ("/alpha", s1)];
    let mut msgs = Vec::new();
    for k in 0..4u64 {
        msgs.push((0, t0 + k * 19_700, cdr_string("z")));
    }
    for k in 0..21u64 {
        msgs.push((2, t0 + k * 100_000_000, cdr_string("a")));
        if k < 5 {
            msgs.push((1, t0 + 50_000 + k * 100_000_000, cdr_string("m")));
        }
    }
    msgs.sort_by_key(|m| m.1);
    let tmp = TmpDir::new("named-baginfo");
    let path = tmp.path("rates.mcap");
    std::fs::write(&path, mcap(&topics, &msgs)).unwrap();
    let info = bag_info(&path, &BagOptions::default()).unwrap();
    let names: Vec<&str> = info.topics.iter().map(|t| t.topic.name.as_str()).collect();
    assert_eq!(names, ["/alpha", "/mid", "/zeta"]);
    let rate = |n: &str| {
        info.topics
            .iter()
            .find(|t| t.topic.name == n)
            .unwrap()
            .rate_hz()
    };
    assert!((rate("/alpha").unwrap() - 10.0).abs() < 1e-9);
    assert_eq!(rate("/mid"), None);
    assert_eq!(rate("/zeta"), None);
    let page = info.render();
    let row = |n: &str| {
        page.lines()
            .find(|l| l.starts_with(n))
            .unwrap_or_else(|| panic!("{n} in {page}"))
            .split_whitespace()
            .map(str::to_string)
            .collect::<Vec<_>>()
    };
    // name, type, messages, rate, span, role
    assert_eq!(row("/alpha")[2..5], ["21", "10.00", "2.00"]);
    assert_eq!(row("/zeta")[2..5], ["4", "-", "0.00"]);
    assert_eq!(row("/mid")[2..5], ["5", "-", "0.40"]);
    assert!(
        !page.contains("50632") && !page.contains("50,632"),
        "{page}"
    );
    assert!(
        page.contains(
            "note: rate \"-\": 2 topic(s) with fewer than 5 messages or a span under 1 s"
        ),
        "{page}"
    );
    // The program prints the same listing.
    let o = dvlcal(&["bag-info", s(&path)]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    let order: Vec<usize> = ["/alpha", "/mid", "/zeta"]
        .iter()
        .map(|n| {
            out.find(&format!("\n{n} "))
                .unwrap_or_else(|| panic!("{out}"))
        })
        .collect();
    assert!(order.windows(2).all(|w| w[0] < w[1]), "{out}");
}

#[test]
fn dvl_info_on_a_bag_counts_messages_of_its_topic_not_lines() {
    let t0 = 1_700_000_000_000_000_000u64;
    let topics = [("/dvl/json_data", "std_msgs/msg/String")];
    let mut msgs: Vec<(usize, u64, Vec<u8>)> = (0..30)
        .map(|k| (0, t0 + k as u64 * 100_000_000, cdr_string(&v3_line(k))))
        .collect();
    msgs[11].2 = cdr_string("{\"time\":100.0,\"vx\":"); // message 12: cut JSON
    let tmp = TmpDir::new("named-dvlbag");
    let path = tmp.path("dvl.mcap");
    std::fs::write(&path, mcap(&topics, &msgs)).unwrap();
    let o = dvlcal(&["dvl-info", s(&path)]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    let at = format!("{}: message 12 of /dvl/json_data: truncated JSON", s(&path));
    assert!(out.contains(&at), "{out}");
    assert!(!out.contains(&format!("{}:12", s(&path))), "{out}");
    assert!(out.contains("  messages          30"), "{out}");
    assert!(out.contains("  rejected messages 1"), "{out}");
    assert!(!out.contains("rejected lines"), "{out}");
    // JSON: the position says the same.
    let o = dvlcal(&["dvl-info", "--json", s(&path)]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(
        v["rejected"][0]["at"],
        format!("{}: message 12 of /dvl/json_data", s(&path))
    );
    // Strict: the error names the message.
    let o = dvlcal(&["dvl-info", "--strict", s(&path)]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("message 12 of /dvl/json_data: truncated JSON") && !err.contains(":12:"),
        "{err}"
    );
    // A text log still says lines.
    let log = tmp.path("dvl.jsonl");
    let mut lines: Vec<String> = (0..30).map(v3_line).collect();
    lines[11] = "{\"time\":100.0,\"vx\":".into();
    std::fs::write(&log, lines.join("\n")).unwrap();
    let o = dvlcal(&["dvl-info", s(&log)]);
    let (out, _) = text(&o);
    assert!(
        out.contains(&format!("{}:12: truncated JSON", s(&log))) && out.contains("  lines "),
        "{out}"
    );
}
