//! The A50 serial protocol: `w` + `r` + letter + `,fields` + `*xx`, one sentence per line, with
//! a CRC-8 checksum (two hex digits) over everything before the `*`. Real serial captures carry
//! garbage bytes before the `w`; such a line is used when the sentence itself is intact.
//!
//! Sentences read: `wrz` (bottom-track velocity: vx, vy, vz, valid y/n, altitude, fom,
//! covariance as nine `;`-separated values, time_of_validity, time_of_transmission, time,
//! status), `wrs` (water-track velocity, like `wrz` without altitude; counted), deprecated `wrx`
//! (time, vx, vy, vz, fom, altitude, valid, status: velocity without absolute time), and `wru`,
//! `wrp`, `wrt` and other replies (counted as other reports).

use super::report::{Parsed, Reject, VelocityReport, content_hash, crc8};

/// Parses one line of a serial capture.
pub fn parse_line(line: &[u8]) -> Result<Parsed, Reject> {
    let mut problem: Option<Reject> = None;
    let mut start = 0;
    while let Some(off) = find_start(&line[start..]) {
        let i = start + off;
        start = i + 1;
        let Some(star_off) = line[i..].iter().position(|&b| b == b'*') else {
            problem.get_or_insert(Reject::new(
                "truncated sentence",
                "no '*' checksum separator",
            ));
            continue;
        };
        let star = i + star_off;
        let tail = line[star + 1..].trim_ascii_end();
        let Some(sum) = parse_hex2(tail) else {
            problem.get_or_insert(Reject::new(
                "truncated sentence",
                "checksum is not two hex digits at the end of the line",
            ));
            continue;
        };
        let body = &line[i..star];
        let crc = crc8(body);
        if crc != sum {
            // Keep the first mismatch, unless a candidate further on is intact.
            if problem.as_ref().is_none_or(|p| p.reason != "bad checksum") {
                problem = Some(Reject::new(
                    "bad checksum",
                    format!("checksum {sum:02x}, computed {crc:02x}"),
                ));
            }
            continue;
        }
        return parse_body(body);
    }
    Err(problem.unwrap_or_else(|| Reject::new("not a DVL sentence", "no 'wr' sentence start")))
}

/// Offset of the next `wr` followed by a letter or `?`.
fn find_start(s: &[u8]) -> Option<usize> {
    s.windows(3)
        .position(|w| w[0] == b'w' && w[1] == b'r' && (w[2].is_ascii_alphabetic() || w[2] == b'?'))
}

fn parse_hex2(s: &[u8]) -> Option<u8> {
    if s.len() != 2 {
        return None;
    }
    let d = |c: u8| (c as char).to_digit(16);
    Some((d(s[0])? * 16 + d(s[1])?) as u8)
}

fn num(field: &str, name: &str) -> Result<f64, Reject> {
    let v: f64 = field.trim().parse().map_err(|_| {
        Reject::new(
            "non-numeric field",
            format!("{name}: '{}' is not a number", clip(field)),
        )
    })?;
    if v.is_finite() {
        Ok(v)
    } else {
        Err(Reject::new("non-finite value", format!("{name} is {v}")))
    }
}

fn int(field: &str, name: &str) -> Result<i64, Reject> {
    field.trim().parse().map_err(|_| {
        Reject::new(
            "non-numeric field",
            format!("{name}: '{}' is not an integer", clip(field)),
        )
    })
}

fn flag(field: &str, name: &str) -> Result<bool, Reject> {
    match field.trim() {
        "y" | "Y" => Ok(true),
        "n" | "N" => Ok(false),
        other => Err(Reject::new(
            "non-numeric field",
            format!("{name}: '{}' is not y or n", clip(other)),
        )),
    }
}

fn clip(s: &str) -> String {
    s.chars().take(24).collect()
}

fn count(fields: &[&str], n: usize, name: &str) -> Result<(), Reject> {
    if fields.len() == n {
        Ok(())
    } else {
        Err(Reject::new(
            "wrong field count",
            format!("{name} with {} fields, expected {n}", fields.len()),
        ))
    }
}

fn cov9(field: &str) -> Result<[f64; 9], Reject> {
    let parts: Vec<&str> = field.split(';').collect();
    if parts.len() != 9 {
        return Err(Reject::new(
            "wrong field count",
            format!("covariance with {} values, expected 9", parts.len()),
        ));
    }
    let mut c = [0.0; 9];
    for (k, p) in parts.iter().enumerate() {
        c[k] = num(p, "covariance")?;
    }
    Ok(c)
}

/// Parses a sentence whose checksum matched (`body` without `*xx`).
fn parse_body(body: &[u8]) -> Result<Parsed, Reject> {
    let text = std::str::from_utf8(body)
        .map_err(|_| Reject::new("invalid UTF-8", "sentence is not text"))?;
    let fields: Vec<&str> = text.split(',').collect();
    let name = fields.first().copied().unwrap_or_default();
    let f = fields.get(1..).unwrap_or_default();
    let label = format!("serial {}", clip(name));
    match name {
        "wrz" => {
            count(f, 11, name)?;
            let v = [num(f[0], "vx")?, num(f[1], "vy")?, num(f[2], "vz")?];
            let valid = flag(f[3], "valid")?;
            num(f[4], "altitude")?;
            num(f[5], "fom")?;
            let cov = cov9(f[6])?;
            let tov = int(f[7], "time_of_validity")?;
            let tot = int(f[8], "time_of_transmission")?;
            let time = num(f[9], "time")?;
            int(f[10], "status")?;
            Ok(Parsed::Velocity(VelocityReport {
                label,
                v,
                cov: Some(cov),
                valid,
                time_ms: Some(time),
                time_of_validity_us: Some(tov),
                time_of_transmission_us: Some(tot),
                host_time: None,
                host_time_kind: None,
                key: content_hash(body),
            }))
        }
        "wrx" => {
            count(f, 8, name)?;
            let time = num(f[0], "time")?;
            let v = [num(f[1], "vx")?, num(f[2], "vy")?, num(f[3], "vz")?];
            num(f[4], "fom")?;
            num(f[5], "altitude")?;
            let valid = flag(f[6], "valid")?;
            int(f[7], "status")?;
            Ok(Parsed::Velocity(VelocityReport {
                label,
                v,
                cov: None,
                valid,
                time_ms: Some(time),
                time_of_validity_us: None,
                time_of_transmission_us: None,
                host_time: None,
                host_time_kind: None,
                key: content_hash(body),
            }))
        }
        "wrs" if f.len() == 10 => {
            for (k, x) in f.iter().enumerate() {
                match k {
                    3 => {
                        flag(x, "valid")?;
                    }
                    5 => {
                        cov9(x)?;
                    }
                    _ => {
                        num(x, "wrs field")?;
                    }
                }
            }
            Ok(Parsed::WaterVelocity { label })
        }
        "wru" | "wrp" | "wrt" => {
            let n = match name {
                "wru" => 5,
                "wrp" => 9,
                _ => 4,
            };
            count(f, n, name)?;
            for x in f {
                num(x, name)?;
            }
            Ok(Parsed::Other {
                label,
                kind: name.to_string(),
            })
        }
        "wrc" => {
            // wrc,speed_of_sound,mounting_rotation_offset,acoustic_enabled,dark_mode
            let c = match f.first() {
                Some(x) => Some(num(x, "wrc speed of sound")?),
                None => None,
            };
            Ok(Parsed::Config {
                label,
                speed_of_sound: c.filter(|c| c.is_finite() && *c > 0.0),
            })
        }
        _ => Ok(Parsed::Other {
            label,
            kind: clip(name),
        }),
    }
}
