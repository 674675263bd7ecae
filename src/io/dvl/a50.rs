//! Writing the Water Linked A50's formats: json_v3 velocity reports exactly as the DVL sends them
//! on its TCP JSON stream (port 16171; one JSON object per line, lines ended by CRLF), the same
//! reports as serial `wrz` sentences with their CRC-8, and the typed report they are made from. Reading every A50 format is [`super::read_dvl_log`]'s job.

use std::fmt::Write as _;
use std::path::Path;

use serde::{Deserialize, Serialize};

pub use super::report::crc8;
use crate::error::Result;

/// One beam of a velocity report.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct A50Transducer {
    /// Beam index, 0..=3.
    pub id: i64,
    /// Velocity along the beam, m/s.
    pub velocity: f64,
    /// Distance to the bottom along the beam, m.
    pub distance: f64,
    /// Received signal strength, dBm.
    pub rssi: f64,
    /// Noise spectral density, dBm.
    pub nsd: f64,
    /// Whether the beam has a lock on the bottom.
    pub beam_valid: bool,
}

/// A json_v3 velocity report (bottom tracking), field for field in the order the DVL sends them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct A50VelocityReport {
    /// Milliseconds since the previous velocity report.
    pub time: f64,
    /// Velocity in the DVL frame, m/s.
    pub vx: f64,
    /// Velocity along the DVL frame's y axis, m/s.
    pub vy: f64,
    /// Velocity along the DVL frame's z axis, m/s.
    pub vz: f64,
    /// Figure of merit, m/s.
    pub fom: f64,
    /// Covariance of `[vx, vy, vz]`, (m/s)^2, row major.
    pub covariance: [[f64; 3]; 3],
    /// Distance to the bottom, m (-1 when invalid).
    pub altitude: f64,
    /// The four beams.
    pub transducers: [A50Transducer; 4],
    /// The DVL's validity flag for `vx, vy, vz`.
    pub velocity_valid: bool,
    /// 0 when normal, 1 on a high temperature warning.
    pub status: i64,
    /// Protocol format, e.g. `json_v3` or `json_v3.1`.
    pub format: String,
    /// Report type: `velocity` for bottom tracking.
    #[serde(rename = "type")]
    pub report_type: String,
    /// Mid-ping time of the measurement, Unix microseconds on the DVL clock.
    pub time_of_validity: i64,
    /// Time the report was sent, Unix microseconds on the DVL clock.
    pub time_of_transmission: i64,
}

/// Formats a number the way the DVL's JSON encoder does: the shortest digits that read back to
/// the same value (ties between two shortest candidates go to the even last digit), plain
/// decimal notation for magnitudes in [1e-6, 1e21), otherwise exponent notation (`1.5e-7`,
/// `1e+21`). Non-finite values, which JSON cannot carry, become `null`.
fn json_number(v: f64) -> String {
    if !v.is_finite() {
        return "null".to_string();
    }
    if v == 0.0 {
        return format!("{v}");
    }
    let (digits, exp) = shortest_digits(v);
    let sign = if v < 0.0 { "-" } else { "" };
    let a = v.abs();
    let n = digits.len() as i64;
    if (1e-6..1e21).contains(&a) {
        if exp >= 0 {
            let int_len = exp + 1;
            if n <= int_len {
                let zeros = "0".repeat((int_len - n) as usize);
                format!("{sign}{digits}{zeros}")
            } else {
                let (i, f) = digits.split_at(int_len as usize);
                format!("{sign}{i}.{f}")
            }
        } else {
            let zeros = "0".repeat((-exp - 1) as usize);
            format!("{sign}0.{zeros}{digits}")
        }
    } else {
        let (first, rest) = digits.split_at(1);
        let point = if rest.is_empty() { "" } else { "." };
        let esign = if exp >= 0 { "+" } else { "" };
        format!("{sign}{first}{point}{rest}e{esign}{exp}")
    }
}

/// The shortest significant digits `d1 d2 ... dn` and decimal exponent `e` of `|v|`
/// (`|v| ~ d1.d2...dn * 10^e`) that read back to `v`. When the exact value lies halfway
/// between two shortest candidates, the one with the even last digit is chosen.
fn shortest_digits(v: f64) -> (String, i64) {
    let a = v.abs();
    let parts = |s: String| -> (String, i64) {
        let (m, e) = s.split_once('e').unwrap_or((s.as_str(), "0"));
        (m.replace('.', ""), e.parse().unwrap_or(0))
    };
    let (digits, exp) = parts(format!("{a:e}"));
    // The exact decimal expansion of the double (at most 767 significant digits).
    let (exact, exact_exp) = parts(format!("{a:.800e}"));
    let exact = exact.trim_end_matches('0');
    let n = digits.len();
    if exact_exp != exp || exact.len() != n + 1 || !exact.ends_with('5') {
        return (digits, exp);
    }
    let last_odd = digits
        .as_bytes()
        .last()
        .is_some_and(|d| (d - b'0') % 2 == 1);
    if !last_odd {
        return (digits, exp);
    }
    let lower = &exact[..n];
    let candidate = if lower == digits {
        increment_digits(&digits)
    } else {
        lower.to_string()
    };
    // Keep the candidate only if it has the same length and reads back to the same value.
    let reads_back = candidate.len() == n
        && format!("{}.{}e{exp}", &candidate[..1], &candidate[1..])
            .parse::<f64>()
            .is_ok_and(|x| x == a);
    if reads_back {
        (candidate, exp)
    } else {
        (digits, exp)
    }
}

/// Adds one in the last place of a decimal digit string (the result may be one digit longer).
fn increment_digits(d: &str) -> String {
    let mut b = d.as_bytes().to_vec();
    for c in b.iter_mut().rev() {
        if *c == b'9' {
            *c = b'0';
        } else {
            *c += 1;
            return String::from_utf8_lossy(&b).into_owned();
        }
    }
    format!("1{}", String::from_utf8_lossy(&b))
}

/// A JSON string literal.
fn json_string(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push_str("\\t"),
            c if (c as u32) < 0x20 => {
                let _ = write!(out, "\\u{:04x}", c as u32);
            }
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// One velocity report as a single-line JSON object (no line terminator), with the keys in the
/// order and the number format of the DVL's own output. Non-finite numbers are written as
/// `null`; [`write_a50_jsonl`] refuses them.
pub fn velocity_report_line(r: &A50VelocityReport) -> String {
    let n = json_number;
    let mut s = String::with_capacity(1100);
    let _ = write!(
        s,
        "{{\"time\":{},\"vx\":{},\"vy\":{},\"vz\":{},\"fom\":{},\"covariance\":[",
        n(r.time),
        n(r.vx),
        n(r.vy),
        n(r.vz),
        n(r.fom)
    );
    for (i, row) in r.covariance.iter().enumerate() {
        if i > 0 {
            s.push(',');
        }
        let _ = write!(s, "[{},{},{}]", n(row[0]), n(row[1]), n(row[2]));
    }
    let _ = write!(s, "],\"altitude\":{},\"transducers\":[", n(r.altitude));
    for (i, b) in r.transducers.iter().enumerate() {
        if i > 0 {
            s.push(',');
        }
        let _ = write!(
            s,
            "{{\"id\":{},\"velocity\":{},\"distance\":{},\"rssi\":{},\"nsd\":{},\"beam_valid\":{}}}",
            b.id,
            n(b.velocity),
            n(b.distance),
            n(b.rssi),
            n(b.nsd),
            b.beam_valid
        );
    }
    let _ = write!(
        s,
        "],\"velocity_valid\":{},\"status\":{},\"format\":{},\"type\":{},\"time_of_validity\":{},\"time_of_transmission\":{}}}",
        r.velocity_valid,
        r.status,
        json_string(&r.format),
        json_string(&r.report_type),
        r.time_of_validity,
        r.time_of_transmission
    );
    s
}

fn report_is_finite(r: &A50VelocityReport) -> bool {
    let beams = r
        .transducers
        .iter()
        .flat_map(|b| [b.velocity, b.distance, b.rssi, b.nsd]);
    [r.time, r.vx, r.vy, r.vz, r.fom, r.altitude]
        .into_iter()
        .chain(r.covariance.iter().flatten().copied())
        .chain(beams)
        .all(f64::is_finite)
}

/// Writes velocity reports as a JSON-lines log, each line ended by CRLF like a real stream,
/// atomically.
pub fn write_a50_jsonl(path: &Path, reports: &[A50VelocityReport]) -> Result<()> {
    let mut out = String::with_capacity(reports.len() * 1100);
    for (i, r) in reports.iter().enumerate() {
        if !report_is_finite(r) {
            return Err(crate::io::non_finite(
                path,
                format!("a value of report {i}"),
            ));
        }
        out.push_str(&velocity_report_line(r));
        out.push_str("\r\n");
    }
    crate::io::write_atomic(path, out.as_bytes())
}

/// Parses one velocity report line. serde_json's `float_roundtrip` feature (enabled in
/// Cargo.toml) reads every number literal to the correctly rounded f64, so reports read back bit
/// for bit.
pub fn parse_velocity_report(line: &str) -> serde_json::Result<A50VelocityReport> {
    serde_json::from_str(line)
}

/// Renders a sentence body (`wrz,...`) with its checksum and CRLF, as the DVL sends it.
pub fn with_checksum(body: &str) -> String {
    format!("{body}*{:02x}\r\n", crc8(body.as_bytes()))
}

/// A velocity report as a `wrz` sentence (with checksum and CRLF), numbers in their shortest
/// round-trip form: the serial rendering of the same report the JSON protocol carries.
pub fn wrz_sentence(r: &A50VelocityReport) -> String {
    let cov: Vec<String> = r
        .covariance
        .iter()
        .flatten()
        .map(|x| x.to_string())
        .collect();
    with_checksum(&format!(
        "wrz,{},{},{},{},{},{},{},{},{},{},{}",
        r.vx,
        r.vy,
        r.vz,
        if r.velocity_valid { "y" } else { "n" },
        r.altitude,
        r.fom,
        cov.join(";"),
        r.time_of_validity,
        r.time_of_transmission,
        r.time,
        r.status
    ))
}
