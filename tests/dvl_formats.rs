//! DVL log ingest on the real A50 logs, on JSON and serial renderings of the same reports, and
//! on corrupted copies with known damage.

mod dvl_common;

use std::path::Path;

use dvl_common::*;
use dvlcal::io::dvl::{
    DvlFormat, DvlLog, DvlReadOptions, DvlTimeSource, detect_format, read_dvl_log, read_dvl_text,
};
use dvlcal::time::Epoch;

fn lenient() -> DvlReadOptions {
    DvlReadOptions::default()
}

fn read(path: &Path) -> DvlLog {
    read_dvl_log(path, &lenient()).unwrap_or_else(|e| panic!("{e}"))
}

fn read_bytes(name: &str, bytes: &[u8], opts: &DvlReadOptions) -> DvlLog {
    read_dvl_text(Path::new(name), bytes, opts).unwrap_or_else(|e| panic!("{e}"))
}

/// The lines of a real JSON-lines log, as text.
fn real_lines(name: &str) -> Vec<String> {
    std::fs::read_to_string(real(name, "jsonl"))
        .unwrap()
        .lines()
        .map(String::from)
        .collect()
}

/// The error of a strict read of `bytes` (which must fail), as the user sees it.
fn strict_error(name: &str, bytes: &[u8]) -> String {
    let strict = DvlReadOptions {
        strict: true,
        ..lenient()
    };
    read_dvl_text(Path::new(name), bytes, &strict)
        .unwrap_err()
        .to_string()
}

/// Samples equal bit for bit (time, velocity, covariance).
fn assert_same_samples(a: &DvlLog, b: &DvlLog, what: &str) {
    assert_eq!(a.epoch, b.epoch, "{what}: epoch");
    assert_eq!(a.samples.len(), b.samples.len(), "{what}: count");
    for (k, (x, y)) in a.samples.iter().zip(&b.samples).enumerate() {
        assert_eq!(x.t.to_bits(), y.t.to_bits(), "{what}: t of sample {k}");
        assert_eq!(x.v, y.v, "{what}: v of sample {k}");
        assert_eq!(x.cov, y.cov, "{what}: cov of sample {k}");
        assert_eq!(x.valid, y.valid, "{what}: valid of sample {k}");
    }
}

#[test]
fn real_logs_counts_match_readme_and_bags_agree_with_json_lines() {
    for (name, total, valid, span) in REAL {
        let j = read(&real(name, "jsonl"));
        let b = read(&real(name, "bag"));
        for (log, fmt) in [(&j, DvlFormat::JsonLines), (&b, DvlFormat::RosBag)] {
            let s = &log.stats;
            assert_eq!(s.format, Some(fmt), "{name}");
            assert_eq!(
                (s.velocity_reports, s.valid, s.invalid),
                (total, valid, total - valid),
                "{name} {fmt}"
            );
            assert_eq!((s.duplicates, s.rejected_lines, s.other_reports), (0, 0, 0));
            assert_eq!(log.samples.len(), valid);
            assert!(log.samples.iter().all(|x| x.valid && x.cov.is_some()));
            assert!(log.samples.windows(2).all(|w| w[0].t < w[1].t));
            let got = s.last_time_s.unwrap() - s.first_time_s.unwrap();
            assert!((got - span).abs() < 0.05, "{name}: span {got}");
            assert!(s.time_source_used.contains("time_of_validity"));
            assert!(s.warnings.is_empty(), "{name}: {:?}", s.warnings);
        }
        assert_eq!(
            b.stats.topic.as_deref(),
            Some("/dvl/json_data (std_msgs/String)")
        );
        assert_same_samples(&j, &b, name);
        assert_eq!(j.lines, b.lines, "{name}: message numbers are line numbers");
    }
}

#[test]
fn driver_dvl_topic_gives_the_same_velocities_with_host_times() {
    for (name, total, valid, _) in REAL {
        let j = read(&real(name, "jsonl"));
        let opts = DvlReadOptions {
            topic: Some("/dvl/data".into()),
            ..lenient()
        };
        let d = read_dvl_log(&real(name, "bag"), &opts).unwrap();
        // The driver publishes both topics per report; a recording may stop between the two
        // (dvl_fast_rectangle: the last report is on /dvl/json_data only).
        let missing = total - d.stats.velocity_reports;
        assert!(missing <= 1, "{name}: {missing}");
        assert!(valid - d.stats.valid <= missing);
        assert!(d.stats.time_source_used.contains("header stamp"));
        assert!(d.samples.iter().all(|x| x.cov.is_none()));
        // Same reports in the same order.
        let vj: Vec<_> = j.samples.iter().map(|x| x.v).collect();
        let vd: Vec<_> = d.samples.iter().map(|x| x.v).collect();
        assert_eq!(vj[..vd.len()], vd[..], "{name}");
        // Host times are the bag's recording time (June 2022), not the DVL clock (Feb 2019).
        assert!(d.epoch.sec > 1_654_000_000 && j.epoch.sec < 1_551_000_000);
    }
}

#[test]
fn time_sources() {
    let p = real("dvl_circle", "bag");
    let tot = read_dvl_log(
        &p,
        &DvlReadOptions {
            time_source: DvlTimeSource::Transmission,
            ..lenient()
        },
    )
    .unwrap();
    assert!(tot.stats.time_source_used.contains("time_of_transmission"));
    let host = read_dvl_log(
        &p,
        &DvlReadOptions {
            time_source: DvlTimeSource::Host,
            ..lenient()
        },
    )
    .unwrap();
    assert!(host.stats.time_source_used.contains("bag record time"));
    assert_eq!(host.samples.len(), 303);
    // The reports' own covariances are handed on as read (a noise override is the
    // calibration's, `CalibOptions::dvl_sigma`).
    assert!(host.samples.iter().all(|s| s.cov.is_some()));
    // JSON lines have no host time unless record-dvl wrote them.
    let err = read_dvl_log(
        &real("dvl_circle", "jsonl"),
        &DvlReadOptions {
            time_source: DvlTimeSource::Host,
            ..lenient()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("no host receive times"), "{err}");
    // A given epoch is kept; times keep microsecond precision.
    let e = Epoch { sec: 1_550_142_000 };
    let log = read_dvl_log(
        &real("dvl_circle", "jsonl"),
        &DvlReadOptions {
            epoch: Some(e),
            ..lenient()
        },
    )
    .unwrap();
    assert_eq!(log.epoch, e);
    let first = log.samples[0].t;
    let us = (first * 1e6).round();
    assert!((first * 1e6 - us).abs() < 1e-3, "{first}");
}

#[test]
fn serial_rendering_reads_to_identical_samples() {
    for (name, total, valid, _) in REAL {
        let reports = real_reports(name);
        let json = std::fs::read(real(name, "jsonl")).unwrap();
        let mut serial = String::new();
        for (k, r) in reports.iter().enumerate() {
            // Garbage before the sentence, as on a real serial line, on every 7th line.
            if k % 7 == 3 {
                serial.push_str("\u{1}x*w\u{7f}");
            }
            serial.push_str(&wrz_sentence(r));
        }
        let j = read_bytes("j.jsonl", &json, &lenient());
        let s = read_bytes("s.txt", serial.as_bytes(), &lenient());
        assert_eq!(detect_format(serial.as_bytes()), Some(DvlFormat::Serial));
        assert_eq!(s.stats.format, Some(DvlFormat::Serial));
        assert_eq!((s.stats.velocity_reports, s.stats.valid), (total, valid));
        assert_eq!(s.stats.rejected_lines, 0, "{:?}", s.stats.rejected);
        assert_eq!(s.stats.formats_seen.get("serial wrz"), Some(&total));
        assert_same_samples(&j, &s, name);
    }
}

#[test]
fn json_v1_and_wrx_rebuild_the_same_time_line() {
    let reports = real_reports("dvl_fast_rectangle");
    let v1: String = reports.iter().map(|r| json_v1_line(r) + "\n").collect();
    let wrx: String = reports.iter().map(wrx_sentence).collect();
    let a = read_bytes("v1.jsonl", v1.as_bytes(), &lenient());
    let b = read_bytes("wrx.txt", wrx.as_bytes(), &lenient());
    assert_eq!(a.stats.velocity_reports, 396);
    assert_eq!(a.stats.valid, 363);
    assert!(a.stats.time_source_used.contains("rebuilt"));
    assert!(
        a.stats
            .warnings
            .iter()
            .any(|w| w.contains("arbitrary origin"))
    );
    assert!(a.samples.iter().all(|s| s.cov.is_none()));
    assert_same_samples(&a, &b, "json_v1 vs wrx");
    // The time line is the running sum of `time` (ms) from the first report.
    let mut t = 0.0;
    let mut expect = Vec::new();
    for (k, r) in reports.iter().enumerate() {
        if k > 0 {
            t += r.time;
        }
        if r.velocity_valid {
            expect.push(t * 1e-3);
        }
    }
    for (s, e) in a.samples.iter().zip(&expect) {
        assert!((s.t - e).abs() < 1e-9, "{} vs {e}", s.t);
    }
    // Over 34 s the increments track time_of_validity to within a few ms per report.
    let j = read(&real("dvl_fast_rectangle", "jsonl"));
    let drift = (a.samples.last().unwrap().t - a.samples[0].t)
        - (j.samples.last().unwrap().t - j.samples[0].t);
    assert!(drift.abs() < 1.0, "drift {drift}");
}

#[test]
fn crlf_lf_and_mixed_report_types() {
    let reports = real_reports("dvl_circle");
    let lines = real_lines("dvl_circle");
    let lf = lines.join("\n");
    let crlf = lines.join("\r\n") + "\r\n";
    let a = read_bytes("lf", lf.as_bytes(), &lenient());
    let b = read_bytes("crlf", crlf.as_bytes(), &lenient());
    assert_same_samples(&a, &b, "LF vs CRLF");

    let dr = r#"{"ts":49056.809,"x":12.43,"y":64.1,"z":1.54,"std":0.2,"roll":0.1,"pitch":0.2,"yaw":94.3,"type":"position_local","status":0,"format":"json_v3.1"}"#;
    let water = lines[0].replace("\"type\":\"velocity\"", "\"type\":\"velocity_water\"");
    let mut mixed = String::new();
    for (k, l) in lines.iter().enumerate() {
        mixed.push_str(l);
        mixed.push_str("\r\n");
        if k % 50 == 0 {
            mixed.push_str(dr);
            mixed.push_str("\r\n\r\n");
            mixed.push_str(&water);
            mixed.push_str("\r\n");
        }
    }
    let m = read_bytes("mixed", mixed.as_bytes(), &lenient());
    let n_extra = lines.len().div_ceil(50);
    assert_eq!(m.stats.other_reports, n_extra);
    assert_eq!(m.stats.other_by_type.get("position_local"), Some(&n_extra));
    assert_eq!(m.stats.water_velocity_reports, n_extra);
    assert_eq!(m.stats.velocity_reports, reports.len());
    assert_same_samples(&a, &m, "with other reports");

    // Serial: other sentences are counted, not velocities.
    let mut serial = String::new();
    for r in &reports {
        serial.push_str(&wrz_sentence(r));
    }
    serial.push_str("wru,0,0.070,1.10,-40,-95*9c\r\n");
    serial.push_str(&dvlcal::io::dvl::a50::with_checksum(
        "wrp,49056.809,12.43,64.1,1.54,0.2,0.1,0.2,94.3,0",
    ));
    serial.push_str(&dvlcal::io::dvl::a50::with_checksum("wrt,1.2,1.3,1.4,1.5"));
    serial.push_str(&dvlcal::io::dvl::a50::with_checksum(
        "wrs,0.1,0.2,0.3,y,0.001,1;0;0;0;1;0;0;0;1,1550142242831870,1550142246235337,100.5,0",
    ));
    let s = read_bytes("serial", serial.as_bytes(), &lenient());
    assert_eq!(s.stats.other_reports, 3);
    assert_eq!(s.stats.water_velocity_reports, 1);
    assert_eq!(s.stats.rejected_lines, 0, "{:?}", s.stats.rejected);
    assert_same_samples(&a, &s, "serial with other sentences");
}

/// Real JSON lines with known damage: every count is exact.
#[test]
fn corrupted_json_copy_counts_are_exact() {
    let lines = real_lines("dvl_circle");
    let clean = read(&real("dvl_circle", "jsonl"));
    let mut out: Vec<String> = Vec::new();
    let mut damaged = 0usize; // velocity reports destroyed
    let mut damaged_valid = 0usize;
    let mut rejected = 0usize;
    let mut dups = 0usize;
    let mut dup_valid = 0usize;
    let mut kinds = [0usize; 5];
    for (k, l) in lines.iter().enumerate() {
        let is_valid = l.contains("\"velocity_valid\":true");
        let bad = match k % 40 {
            5 => Some(l[..l.len() / 2].to_string()), // truncated
            11 => Some(l.replacen("\"vx\":", "\"vx\":NaN,\"_\":", 1)), // NaN literal
            17 => Some(l.replacen("\"vy\":", "\"vy\":\"abc\",\"_\":", 1)), // non-numeric
            23 => Some(format!("\u{0}\u{1}garbage{}", &l[3..])), // garbage
            29 => Some(l.replacen("\"vz\":", "\"vq\":", 1)), // missing field
            _ => None,
        };
        match bad {
            Some(b) => {
                out.push(b);
                kinds[[5, 11, 17, 23, 29]
                    .iter()
                    .position(|&x| x == k % 40)
                    .unwrap()] += 1;
                damaged += 1;
                damaged_valid += is_valid as usize;
                rejected += 1;
            }
            None => {
                out.push(l.clone());
                if k % 40 == 33 {
                    // A real capture repeats messages: three more copies.
                    for _ in 0..3 {
                        out.push(l.clone());
                    }
                    dups += 3;
                    dup_valid += 3 * is_valid as usize;
                }
            }
        }
    }
    out.push("[1,2,3]".into());
    out.push("{\"time\":1.0}".into());
    rejected += 2;
    let text = out.join("\r\n");
    let log = read_bytes("bad.jsonl", text.as_bytes(), &lenient());
    let s = &log.stats;
    assert_eq!(s.rejected_lines, rejected);
    assert_eq!(s.duplicates, dups);
    assert_eq!(s.velocity_reports, 378 - damaged + dups);
    assert_eq!(s.valid, 303 - damaged_valid + dup_valid);
    assert_eq!(log.samples.len(), 303 - damaged_valid);
    let by = &s.rejected_by_reason;
    let n = |k: &str| by.get(k).copied().unwrap_or(0);
    assert_eq!(n("truncated JSON"), kinds[0], "{by:?}");
    assert_eq!(n("not valid JSON"), kinds[1] + kinds[3], "{by:?}"); // NaN and garbage
    assert_eq!(n("non-numeric field"), kinds[2]);
    assert_eq!(n("missing field"), kinds[4]);
    assert_eq!(kinds, [10, 10, 10, 9, 9]);
    assert_eq!(n("not a JSON object"), 1);
    assert_eq!(n("unknown report"), 1);
    assert_eq!(s.rejected.len(), 20);
    assert_eq!(s.rejected[0].line, 6);
    assert_eq!(s.rejected[0].reason, "truncated JSON");
    // The samples that survive are exactly the clean ones minus the damaged.
    assert!(
        log.samples
            .iter()
            .all(|x| clean.samples.iter().any(|c| c.t == x.t && c.v == x.v))
    );

    // Strict: the first damaged line is an error naming file:line.
    let err = strict_error("bad.jsonl", text.as_bytes());
    assert!(err.starts_with("bad.jsonl:6: truncated JSON"), "{err}");
}

#[test]
fn a_log_longer_than_a_parse_block_reads_as_line_by_line() {
    // The reader parses blocks of 65536 lines side by side and hands them on in order. The real
    // circle log repeated 200 times (75k+ lines) crosses that boundary: every copy after the
    // first is a duplicate, wherever it falls, and one damaged line past the first block is
    // rejected under its own line number (and is strict mode's error).
    let lines = real_lines("dvl_circle");
    let clean = read(&real("dvl_circle", "jsonl"));
    let copies = 200;
    let mut out: Vec<String> = Vec::new();
    for _ in 0..copies {
        out.extend(lines.iter().cloned());
    }
    assert!(out.len() > 70_000, "{}", out.len());
    let bad = 70_001; // 1-based line number of the damaged line
    out[bad - 1] = out[bad - 1][..20].to_string();
    let text = out.join("\n");
    let log = read_bytes("long.jsonl", text.as_bytes(), &lenient());
    let s = &log.stats;
    assert_eq!(s.rejected_lines, 1);
    assert_eq!(s.rejected[0].line, bad);
    assert_eq!(s.rejected[0].reason, "truncated JSON");
    // The damaged line is a later copy of a report whose first copy was read.
    assert_eq!(s.velocity_reports, 378 * copies - 1);
    assert_eq!(s.duplicates, 378 * (copies - 1) - 1);
    assert_same_samples(&log, &clean, "200 copies");
    let err = strict_error("long.jsonl", text.as_bytes());
    assert!(err.starts_with("long.jsonl:70001: truncated JSON"), "{err}");
}

#[test]
fn corrupted_serial_copy_counts_are_exact() {
    let reports = real_reports("dvl_slow_rectangle");
    let mut out = String::new();
    let mut rejected = 0;
    let mut lost_valid = 0;
    let mut first_bad = None;
    for (k, r) in reports.iter().enumerate() {
        let s = wrz_sentence(r);
        let line_no = out.matches('\n').count() + 1;
        let bad = match k % 25 {
            2 => {
                // One digit changed: the checksum no longer matches.
                let i = s.find('.').unwrap() + 1;
                let d = s.as_bytes()[i];
                let nd = if d == b'9' { '0' } else { (d + 1) as char };
                Some(format!("{}{}{}", &s[..i], nd, &s[i + 1..]))
            }
            9 => Some(s[..s.len() / 2].to_string() + "\r\n"), // truncated
            13 => {
                let body = s.split('*').next().unwrap();
                let mut f: Vec<&str> = body.split(',').collect();
                f[1] = "nan";
                Some(dvlcal::io::dvl::a50::with_checksum(&f.join(",")))
            }
            19 => {
                let body = s.split('*').next().unwrap();
                let mut f: Vec<&str> = body.split(',').collect();
                f.pop();
                Some(dvlcal::io::dvl::a50::with_checksum(&f.join(",")))
            }
            21 => Some("\u{2}\u{3}noise without any sentence\r\n".to_string()),
            _ => None,
        };
        match bad {
            Some(b) => {
                first_bad.get_or_insert(line_no);
                out.push_str(&b);
                rejected += 1;
                if k % 25 != 21 {
                    lost_valid += r.velocity_valid as usize;
                } else {
                    out.push_str(&s);
                }
            }
            None => out.push_str(&s),
        }
    }
    let log = read_bytes("bad.txt", out.as_bytes(), &lenient());
    let by = &log.stats.rejected_by_reason;
    let n = |k: &str| by.get(k).copied().unwrap_or(0);
    assert_eq!(log.stats.rejected_lines, rejected);
    assert_eq!(n("bad checksum"), 19, "{by:?}");
    assert_eq!(n("truncated sentence"), 18);
    assert_eq!(n("non-finite value"), 18);
    assert_eq!(n("wrong field count"), 18);
    assert_eq!(n("not a DVL sentence"), 18);
    assert_eq!(log.samples.len(), 407 - lost_valid);
    let err = strict_error("bad.txt", out.as_bytes());
    assert!(
        err.starts_with(&format!("bad.txt:{}: bad checksum", first_bad.unwrap())),
        "{err}"
    );
}

#[test]
fn time_going_backwards_is_reported_and_sorted() {
    let mut lines = real_lines("dvl_circle");
    // Find two consecutive valid reports and swap them.
    let k = (0..lines.len() - 1)
        .find(|&k| {
            lines[k].contains("\"velocity_valid\":true")
                && lines[k + 1].contains("\"velocity_valid\":true")
        })
        .unwrap();
    lines.swap(k, k + 1);
    // And a different report with a repeated time stamp.
    let rep = lines[k + 5].replacen("\"vx\":", "\"vx\":1.5,\"_\":", 1);
    lines.insert(k + 6, rep);
    let text = lines.join("\n");
    let log = read_bytes("swap.jsonl", text.as_bytes(), &lenient());
    assert_eq!(log.stats.time_backwards, 1);
    assert!(
        log.stats
            .time_problems
            .iter()
            .any(|p| p.line == k + 2 && p.step_s < 0.0)
    );
    assert!(log.samples.windows(2).all(|w| w[0].t <= w[1].t));
    assert_eq!(log.stats.duplicates, 0);
    let clean = read(&real("dvl_circle", "jsonl"));
    assert_eq!(
        log.samples.len(),
        clean.samples.len() + lines[k + 5].contains("\"velocity_valid\":true") as usize
    );
}

#[test]
fn detection_and_unreadable_inputs() {
    let dir = temp_dir("detect");
    let j = std::fs::read(real("dvl", "jsonl")).unwrap();
    assert_eq!(detect_format(&j), Some(DvlFormat::JsonLines));
    let b = std::fs::read(real("dvl", "bag")).unwrap();
    assert_eq!(detect_format(&b), Some(DvlFormat::RosBag));
    assert_eq!(detect_format(b"hello\nworld\n"), None);
    assert_eq!(detect_format(b""), None);
    // An MCAP file (a ROS 2 bag) is a bag; one cut right after its magic is an error naming it.
    let mcap = dir.join("x.mcap");
    std::fs::write(&mcap, b"\x89MCAP0\r\nrest").unwrap();
    assert_eq!(detect_format(b"\x89MCAP0\r\nrest"), Some(DvlFormat::RosBag));
    let e = read_dvl_log(&mcap, &lenient()).unwrap_err().to_string();
    assert!(e.contains("x.mcap"), "{e}");
    // A truncated bag is an error or a warning, never a panic.
    let cut = dir.join("cut.bag");
    std::fs::write(&cut, &b[..b.len() / 2]).unwrap();
    match read_dvl_log(&cut, &lenient()) {
        Ok(log) => assert!(log.stats.velocity_reports < 1423),
        Err(e) => assert!(e.to_string().contains("cut.bag"), "{e}"),
    }
    // Forcing the wrong format rejects every line.
    let forced = DvlReadOptions {
        format: Some(DvlFormat::Serial),
        ..lenient()
    };
    let e = read_dvl_log(&real("dvl_circle", "jsonl"), &forced).unwrap_err();
    assert!(e.to_string().contains("no velocity reports"), "{e}");
    // Unknown topic names the topics there are.
    let t = DvlReadOptions {
        topic: Some("/nope".into()),
        ..lenient()
    };
    let e = read_dvl_log(&real("dvl_circle", "bag"), &t)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("/dvl/json_data") && e.contains("/dvl/data"),
        "{e}"
    );
    let e = read_dvl_log(&dir.join("missing.jsonl"), &lenient()).unwrap_err();
    assert!(e.to_string().contains("missing.jsonl"));
}

#[test]
fn dropouts_of_the_real_logs_are_listed_as_gaps() {
    // Computed here from the JSON lines alone: valid reports' time_of_validity, repeats
    // dropped, a gap being four median intervals and at least 0.5 s.
    let mut total = 0;
    for (name, ..) in REAL {
        let text = std::fs::read_to_string(real(name, "jsonl")).unwrap();
        let mut valid: Vec<(i64, usize)> = Vec::new();
        for (i, l) in text.lines().enumerate() {
            let v: serde_json::Value = serde_json::from_str(l).unwrap();
            if v["type"] == "velocity" && v["velocity_valid"] == true {
                valid.push((v["time_of_validity"].as_i64().unwrap(), i + 1));
            }
        }
        valid.sort();
        valid.dedup_by_key(|x| x.0);
        let mut dt: Vec<f64> = valid
            .windows(2)
            .map(|w| (w[1].0 - w[0].0) as f64 * 1e-6)
            .collect();
        dt.sort_by(f64::total_cmp);
        let threshold = (4.0 * dt[dt.len() / 2]).max(0.5);
        let expected: Vec<(f64, usize)> = valid
            .windows(2)
            .map(|w| ((w[1].0 - w[0].0) as f64 * 1e-6, w[0].1))
            .filter(|(g, _)| *g >= threshold)
            .collect();
        for ext in ["jsonl", "bag"] {
            let log = read(&real(name, ext));
            assert!(
                (log.gap_threshold_s() - threshold).abs() < 1e-9,
                "{name}.{ext}"
            );
            let gaps = log.gaps(log.gap_threshold_s());
            assert_eq!(gaps.len(), expected.len(), "{name}.{ext}");
            for (g, (len, line)) in gaps.iter().zip(&expected) {
                assert!((g.end_s - g.start_s - len).abs() < 1e-6, "{name}.{ext}");
                assert_eq!(g.lines.0, *line, "{name}.{ext}");
            }
            let j = log.summary_json();
            assert_eq!(j["gaps"].as_array().unwrap().len(), expected.len());
            assert!(
                log.summary_text()
                    .contains(&format!("gaps              {}", expected.len()))
                    || expected.is_empty()
            );
        }
        total += expected.len();
    }
    // The real logs do drop out (dvl.bag: 128 invalid reports of 1423).
    assert!(total >= 10, "{total}");
}
