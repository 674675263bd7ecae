//! The A50 serial protocol: `w` + `r` + letter + `,fields` + `*xx`, one sentence per line, with
//! a CRC-8 checksum (two hex digits) over everything before the `*`. Real serial captures carry
//! garbage bytes before the `w`; such a line is used when the sentence itself is intact.
//!
//! Sentences read: `wrz` (bottom-track velocity: vx, vy, vz, valid y/n, altitude, fom,
//! covariance as nine `;`-separated values, time_of_validity, time_of_transmission, time,
//! status), `wrs` (water-track velocity, like `wrz` without altitude; counted), deprecated `wrx`
//! (time, vx, vy, vz, fom, altitude, valid, status: velocity without absolute time), and `wru`,
//! `wrp`, `wrt` and other replies (counted as other reports).

use super::report::{Parsed, Reject, VelocityReport, content_hash, crc8, not_microseconds};

/// Parses one line of a serial capture.
///
/// Every `wr<letter>` in the line is a candidate sentence start, tried from the left; the first
/// intact one is parsed. Otherwise the error is the first checksum mismatch, or else the first
/// candidate's problem. The work is linear in the line's length however many candidates it
/// holds (a long line of `wr`s and stars is garbage, but must not take quadratic time).
pub fn parse_line(line: &[u8]) -> Result<Parsed, Reject> {
    // Only the last '*' of a line can be followed by exactly two hex digits and the line end, so
    // only candidates whose first '*' is that one (those after the one before it) can be intact.
    let last_star = line.iter().rposition(|&b| b == b'*');
    let prev_star = last_star.and_then(|p| line[..p].iter().rposition(|&b| b == b'*'));
    let sum = last_star.and_then(|p| parse_hex2(line[p + 1..].trim_ascii_end()));
    let mut first_problem: Option<Reject> = None;
    let mut mismatch: Option<Reject> = None;
    // CRC-8 of line[lo + k..star] for every k, built when a second checksum candidate appears.
    let mut suffix_crcs: Option<(usize, Vec<u8>)> = None;
    for i in sentence_starts(line) {
        let (star, sum) = match (last_star, sum) {
            (Some(star), _) if i < star => match (prev_star, sum) {
                (Some(q), _) if q > i => {
                    first_problem.get_or_insert_with(not_two_hex);
                    continue;
                }
                (_, None) => {
                    first_problem.get_or_insert_with(not_two_hex);
                    continue;
                }
                (_, Some(sum)) => (star, sum),
            },
            _ => {
                first_problem.get_or_insert_with(|| {
                    Reject::new("truncated sentence", "no '*' checksum separator")
                });
                continue;
            }
        };
        let body = &line[i..star];
        let crc = match &suffix_crcs {
            Some((lo, crcs)) => crcs[i - lo],
            None if mismatch.is_none() => crc8(body),
            None => {
                let crcs = super::report::suffix_crc8(body);
                let crc = crcs[0];
                suffix_crcs = Some((i, crcs));
                crc
            }
        };
        if crc == sum {
            return parse_body(body);
        }
        // Keep the first mismatch.
        mismatch.get_or_insert_with(|| {
            Reject::new(
                "bad checksum",
                format!("checksum {sum:02x}, computed {crc:02x}"),
            )
        });
    }
    Err(mismatch
        .or(first_problem)
        .unwrap_or_else(|| Reject::new("not a DVL sentence", "no 'wr' sentence start")))
}

fn not_two_hex() -> Reject {
    Reject::new(
        "truncated sentence",
        "checksum is not two hex digits at the end of the line",
    )
}

/// Offsets of every `wr` followed by a letter or `?`, in order.
fn sentence_starts(s: &[u8]) -> impl Iterator<Item = usize> + '_ {
    s.windows(3).enumerate().filter_map(|(i, w)| {
        (w[0] == b'w' && w[1] == b'r' && (w[2].is_ascii_alphabetic() || w[2] == b'?')).then_some(i)
    })
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
    field
        .trim()
        .parse()
        .map_err(|_| match field.trim().parse::<f64>() {
            // A time with a fraction: seconds or milliseconds where microseconds belong.
            Ok(x) if x.is_finite() && name.starts_with("time_of") => {
                not_microseconds(name, field.trim(), x)
            }
            _ => Reject::new(
                "non-numeric field",
                format!("{name}: '{}' is not an integer", clip(field)),
            ),
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
