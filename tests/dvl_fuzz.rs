//! Property tests of every DVL parser: no input bytes make one panic, and a valid report reads
//! to the same sample in every format. Case counts are kept small for `cargo test`; raise them
//! with `DVL_FUZZ_CASES=...` for a longer run (bags get a fiftieth of that).

mod dvl_common;

use std::path::Path;
use std::sync::OnceLock;

use dvl_common::*;
use dvlcal::io::dvl::a50::crc8;
use dvlcal::io::dvl::a50::{A50Transducer, A50VelocityReport, velocity_report_line};
use dvlcal::io::dvl::{
    DvlReadOptions, Parsed, VelocityReport, detect_format, parse_json_line, parse_serial_line,
    read_dvl_log, read_dvl_text,
};
use proptest::prelude::*;

/// Cases per property: `n`, or `DVL_FUZZ_CASES` for a longer run.
fn cases(n: u32) -> u32 {
    std::env::var("DVL_FUZZ_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(n)
}

fn real_lines() -> &'static Vec<String> {
    static L: OnceLock<Vec<String>> = OnceLock::new();
    L.get_or_init(|| {
        std::fs::read_to_string(real("dvl_circle", "jsonl"))
            .unwrap()
            .lines()
            .map(String::from)
            .collect()
    })
}

fn real_wrz() -> &'static Vec<String> {
    static L: OnceLock<Vec<String>> = OnceLock::new();
    L.get_or_init(|| {
        real_reports("dvl_circle")
            .iter()
            .map(wrz_sentence)
            .collect()
    })
}

/// Applies byte edits (position, operation, byte) to `s`.
fn mutate(s: &[u8], edits: &[(usize, u8, u8)]) -> Vec<u8> {
    let mut b = s.to_vec();
    for &(pos, op, byte) in edits {
        let i = if b.is_empty() { 0 } else { pos % (b.len() + 1) };
        match op % 4 {
            0 if i < b.len() => b[i] = byte,
            1 => b.insert(i, byte),
            2 if i < b.len() => {
                b.remove(i);
            }
            _ => b.truncate(i),
        }
    }
    b
}

fn edits() -> impl Strategy<Value = Vec<(usize, u8, u8)>> {
    prop::collection::vec((any::<usize>(), any::<u8>(), any::<u8>()), 1..6)
}

fn check_velocity(p: &Parsed) {
    if let Parsed::Velocity(r) = p {
        assert!(r.v.iter().all(|x| x.is_finite()));
        assert!(r.cov.is_none_or(|c| c.iter().all(|x| x.is_finite())));
    }
}

fn finite() -> impl Strategy<Value = f64> {
    prop_oneof![
        -10.0f64..10.0,
        any::<f64>().prop_filter("finite", |x| x.is_finite()),
        Just(0.0),
        Just(-0.0),
        1e-12f64..1e-6,
    ]
}

fn report() -> impl Strategy<Value = A50VelocityReport> {
    (
        prop::array::uniform3(finite()),
        prop::array::uniform9(finite()),
        (finite(), finite(), 0.0f64..1e6),
        any::<bool>(),
        (0i64..4_000_000_000_000_000, 0i64..1_000_000_000),
        0i64..3,
    )
        .prop_map(|(v, c, (fom, alt, time), valid, (tov, dt), status)| {
            let beam = |id| A50Transducer {
                id,
                velocity: 0.1,
                distance: 1.0,
                rssi: -40.0,
                nsd: -90.0,
                beam_valid: true,
            };
            A50VelocityReport {
                time,
                vx: v[0],
                vy: v[1],
                vz: v[2],
                fom,
                covariance: [[c[0], c[1], c[2]], [c[3], c[4], c[5]], [c[6], c[7], c[8]]],
                altitude: alt,
                transducers: [beam(0), beam(1), beam(2), beam(3)],
                velocity_valid: valid,
                status,
                format: "json_v3.1".into(),
                report_type: "velocity".into(),
                time_of_validity: tov,
                time_of_transmission: tov + dt,
            }
        })
}

fn velocity(p: Result<Parsed, dvlcal::io::dvl::Reject>) -> VelocityReport {
    match p {
        Ok(Parsed::Velocity(r)) => r,
        other => panic!("not a velocity report: {other:?}"),
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(25000), ..ProptestConfig::default() })]

    #[test]
    fn json_parser_never_panics_on_random_bytes(b in prop::collection::vec(any::<u8>(), 0..300)) {
        if let Ok(p) = parse_json_line(&b) { check_velocity(&p) }
    }

    #[test]
    fn json_parser_never_panics_on_mutated_real_lines(k in 0usize..378, e in edits()) {
        let line = &real_lines()[k];
        let m = mutate(line.as_bytes(), &e);
        if let Ok(p) = parse_json_line(&m) { check_velocity(&p) }
    }

    #[test]
    fn serial_parser_never_panics_on_random_bytes(b in prop::collection::vec(any::<u8>(), 0..200)) {
        if let Ok(p) = parse_serial_line(&b) { check_velocity(&p) }
    }

    #[test]
    fn serial_parser_never_panics_on_mutated_sentences(k in 0usize..378, e in edits(), fix in any::<bool>()) {
        let s = real_wrz()[k].trim_end();
        let mut m = mutate(s.as_bytes(), &e);
        if fix {
            // Re-checksum the damaged body so that the field parsers see it.
            if let Some(star) = m.iter().rposition(|&c| c == b'*') {
                let sum = format!("{:02x}", crc8(&m[..star]));
                m.truncate(star + 1);
                m.extend_from_slice(sum.as_bytes());
            }
        }
        if let Ok(p) = parse_serial_line(&m) { check_velocity(&p) }
    }

    #[test]
    fn serial_sentence_with_random_prefix_still_reads(k in 0usize..378, pre in prop::collection::vec(any::<u8>(), 0..40)) {
        let s = &real_wrz()[k];
        let mut line = pre.clone();
        line.extend_from_slice(s.trim_end().as_bytes());
        let clean = velocity(parse_serial_line(s.trim_end().as_bytes()));
        let got = velocity(parse_serial_line(&line));
        prop_assert!(got.same_report(&clean));
    }

    #[test]
    fn valid_reports_read_the_same_in_json_and_serial(r in report()) {
        let j = velocity(parse_json_line(velocity_report_line(&r).as_bytes()));
        let s = velocity(parse_serial_line(wrz_sentence(&r).trim_end().as_bytes()));
        let again = velocity(parse_json_line(velocity_report_line(&r).as_bytes()));
        prop_assert_eq!(j.v, [r.vx, r.vy, r.vz]);
        prop_assert_eq!(j.valid, r.velocity_valid);
        prop_assert_eq!(j.time_of_validity_us, Some(r.time_of_validity));
        prop_assert_eq!(j.time_of_transmission_us, Some(r.time_of_transmission));
        let flat: Vec<f64> = r.covariance.iter().flatten().copied().collect();
        prop_assert_eq!(j.cov.map(|c| c.to_vec()), Some(flat));
        prop_assert!(j.same_report(&again));
        for (a, b) in j.v.iter().zip(&s.v) { prop_assert_eq!(a.to_bits(), b.to_bits()); }
        prop_assert_eq!(j.cov.map(|c| c.map(f64::to_bits)), s.cov.map(|c| c.map(f64::to_bits)));
        prop_assert_eq!((j.valid, j.time_of_validity_us, j.time_of_transmission_us), (s.valid, s.time_of_validity_us, s.time_of_transmission_us));
        prop_assert_eq!(j.time_ms.map(f64::to_bits), s.time_ms.map(f64::to_bits));
    }

    #[test]
    fn whole_text_logs_never_panic(lines in prop::collection::vec((0usize..378, edits(), any::<bool>()), 0..30), strict in any::<bool>()) {
        let mut text = Vec::new();
        for (k, e, ser) in &lines {
            let base = if *ser { real_wrz()[*k].clone() } else { real_lines()[*k].clone() + "\n" };
            text.extend(mutate(base.as_bytes(), e));
        }
        let _ = detect_format(&text);
        let opts = DvlReadOptions { strict, ..Default::default() };
        if let Ok(log) = read_dvl_text(Path::new("fuzz"), &text, &opts) {
            // Time-ordered within each clock segment; the segments cover the samples in turn.
            let mut next = 0;
            for c in &log.clock_segments {
                prop_assert_eq!(c.samples.start, next);
                next = c.samples.end;
                let seg = &log.samples[c.samples.clone()];
                prop_assert!(seg.windows(2).all(|w| w[0].t <= w[1].t));
            }
            prop_assert_eq!(next, log.samples.len());
            prop_assert!(log.clock_segments.len() <= log.stats.clock_steps.len() + 1);
            prop_assert!(log.samples.iter().all(|s| s.t.is_finite() && s.valid));
            let st = &log.stats;
            prop_assert_eq!(st.valid + st.invalid, st.velocity_reports);
            prop_assert_eq!(st.lines, st.velocity_reports + st.water_velocity_reports + st.other_reports + st.rejected_lines);
        }
    }
}

proptest! {
    // A bag is read from a file: fewer cases.
    #![proptest_config(ProptestConfig { cases: cases(15_000) / 50, ..ProptestConfig::default() })]

    #[test]
    fn bag_reader_never_panics_on_damaged_bags(e in prop::collection::vec((any::<usize>(), 0u8..3, any::<u8>()), 1..20)) {
        static BAG: OnceLock<Vec<u8>> = OnceLock::new();
        let bag = BAG.get_or_init(|| std::fs::read(real("dvl_circle", "bag")).unwrap());
        // Replace bytes only (or cut the end), so the file stays a bag in outline.
        let e: Vec<(usize, u8, u8)> = e.into_iter().map(|(p, op, b)| (p, if op == 2 { 3 } else { 0 }, b)).collect();
        let m = mutate(bag, &e);
        let dir = temp_dir("fuzzbag");
        let p = dir.join(format!("{}.bag", e[0].0 % 1000));
        std::fs::write(&p, &m).unwrap();
        let _ = read_dvl_log(&p, &DvlReadOptions::default());
        let _ = std::fs::remove_file(&p);
    }
}
