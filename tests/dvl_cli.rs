//! `dvlcal dvl-info` from the command line.

mod dvl_common;

use std::process::Command;

use dvl_common::*;

fn dvlcal(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_dvlcal"))
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn dvl_info_json_has_the_counts_of_every_real_log() {
    for (name, total, valid, span) in REAL {
        for ext in ["jsonl", "bag"] {
            let p = real(name, ext);
            let out = dvlcal(&["dvl-info", "--json", p.to_str().unwrap()]);
            assert!(
                out.status.success(),
                "{}",
                String::from_utf8_lossy(&out.stderr)
            );
            let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
            for key in [
                "format",
                "velocity_reports",
                "valid",
                "invalid",
                "duplicates",
                "other_reports",
                "rejected_lines",
                "first_time_s",
                "last_time_s",
                "rate_hz",
            ] {
                assert!(v.get(key).is_some(), "{key} missing");
            }
            assert_eq!(v["velocity_reports"], total);
            assert_eq!(v["valid"], valid);
            assert_eq!(v["invalid"], total - valid);
            assert_eq!(v["format"], if ext == "bag" { "rosbag" } else { "json" });
            let s = v["last_time_s"].as_f64().unwrap() - v["first_time_s"].as_f64().unwrap();
            assert!((s - span).abs() < 0.05);
            let rate = v["rate_hz"].as_f64().unwrap();
            assert!((rate - (valid - 1) as f64 / s).abs() < 1e-9);
        }
    }
}

#[test]
fn dvl_info_summary_and_strict_errors_name_file_and_line() {
    let dir = temp_dir("cli");
    let lines: Vec<String> = std::fs::read_to_string(real("dvl_circle", "jsonl"))
        .unwrap()
        .lines()
        .map(String::from)
        .collect();
    let mut text = lines[..10].join("\n");
    text.push_str("\n{\"vx\": oops}\n");
    text.push_str(&lines[10..].join("\n"));
    let p = dir.join("one-bad.jsonl");
    std::fs::write(&p, text).unwrap();
    let ps = p.to_str().unwrap();
    let out = dvlcal(&["dvl-info", ps]);
    assert!(out.status.success());
    let s = String::from_utf8_lossy(&out.stdout);
    assert!(s.contains("rejected lines    1"), "{s}");
    assert!(s.contains(&format!("{ps}:11: not valid JSON")), "{s}");
    assert!(s.contains("velocity reports  378"), "{s}");
    let out = dvlcal(&["dvl-info", "--strict", ps]);
    assert!(!out.status.success());
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains(&format!("{ps}:11: not valid JSON")), "{e}");
    let out = dvlcal(&["dvl-info", "--dvl-format", "nope", ps]);
    assert!(!out.status.success());
}
