//! Helpers shared by the DVL ingest tests: real log paths and renderings of velocity reports as
//! serial sentences and as older JSON protocol versions.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use dvlcal::io::dvl::a50::with_checksum;
use dvlcal::io::dvl::a50::{A50VelocityReport, parse_velocity_report};

/// The real logs, in the shared folder beside the repository.
pub const DATA: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data/a50-ros-driver");

/// The four real logs with their README counts: (name, velocity reports, valid, span s).
pub const REAL: [(&str, usize, usize, f64); 4] = [
    ("dvl", 1423, 1295, 154.8),
    ("dvl_circle", 378, 303, 46.0),
    ("dvl_fast_rectangle", 396, 363, 34.4),
    ("dvl_slow_rectangle", 457, 407, 56.6),
];

pub fn real(name: &str, ext: &str) -> PathBuf {
    Path::new(DATA).join(format!("{name}.{ext}"))
}

pub fn temp_dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("dvlcal-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The velocity reports of a real JSON-lines log.
pub fn real_reports(name: &str) -> Vec<A50VelocityReport> {
    std::fs::read_to_string(real(name, "jsonl"))
        .unwrap()
        .lines()
        .map(|l| parse_velocity_report(l).unwrap())
        .collect()
}

fn yn(b: bool) -> &'static str {
    if b { "y" } else { "n" }
}

/// A report as a `wrz` sentence with its CRC-8 and CRLF, numbers in shortest round-trip form.
pub fn wrz_sentence(r: &A50VelocityReport) -> String {
    dvlcal::io::dvl::a50::wrz_sentence(r)
}

/// A report as a deprecated `wrx` sentence (no absolute time, no covariance).
pub fn wrx_sentence(r: &A50VelocityReport) -> String {
    with_checksum(&format!(
        "wrx,{},{},{},{},{},{},{},{}",
        r.time,
        r.vx,
        r.vy,
        r.vz,
        r.fom,
        r.altitude,
        yn(r.velocity_valid),
        r.status
    ))
}

/// A report as a json_v1 line: no `type`, no covariance, no absolute time.
pub fn json_v1_line(r: &A50VelocityReport) -> String {
    format!(
        "{{\"time\":{},\"vx\":{},\"vy\":{},\"vz\":{},\"fom\":{},\"altitude\":{},\"transducers\":[],\"velocity_valid\":{},\"status\":{},\"format\":\"json_v1\"}}",
        r.time, r.vx, r.vy, r.vz, r.fom, r.altitude, r.velocity_valid, r.status
    )
}
