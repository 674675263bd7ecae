//! JSON lines: the A50's TCP stream (json_v1 to json_v3.x), JSON forwarded over UDP, and the
//! logs of `record-dvl` (which add `host_time_us`, the host receive time in Unix microseconds).

use serde::Deserialize;

use super::report::{Parsed, Reject, VelocityReport, content_hash, not_microseconds};
use crate::time::RawTime;

/// The key `record-dvl` adds to every line: host receive time, Unix microseconds.
pub const HOST_TIME_KEY: &str = "host_time_us";

/// The fields of any A50 JSON report that matter here; others are ignored.
#[derive(Deserialize)]
struct Fields<'a> {
    #[serde(rename = "type", borrow, default)]
    report_type: Option<std::borrow::Cow<'a, str>>,
    #[serde(borrow, default)]
    format: Option<std::borrow::Cow<'a, str>>,
    #[serde(default)]
    time: Option<f64>,
    #[serde(default)]
    vx: Option<f64>,
    #[serde(default)]
    vy: Option<f64>,
    #[serde(default)]
    vz: Option<f64>,
    #[serde(default)]
    covariance: Option<[[f64; 3]; 3]>,
    #[serde(default)]
    velocity_valid: Option<bool>,
    #[serde(default)]
    time_of_validity: Option<serde_json::Number>,
    #[serde(default)]
    time_of_transmission: Option<serde_json::Number>,
    #[serde(default)]
    host_time_us: Option<serde_json::Number>,
}

/// A time field in whole microseconds; a fraction (seconds or milliseconds written as a decimal)
/// or a value beyond i64 is rejected, naming the field and the unit it needs.
fn micros(n: &Option<serde_json::Number>, name: &str) -> Result<Option<i64>, Reject> {
    let Some(n) = n else { return Ok(None) };
    match n.as_i64() {
        Some(v) => Ok(Some(v)),
        None => Err(not_microseconds(
            name,
            &n.to_string(),
            n.as_f64().unwrap_or(f64::NAN),
        )),
    }
}

/// At most this many characters of a label taken from the input.
const LABEL_MAX: usize = 32;

fn clip(s: &str) -> String {
    s.chars().take(LABEL_MAX).collect()
}

/// The text that identifies a report: the line without the host time `record-dvl` appended.
fn identity(line: &[u8]) -> &[u8] {
    let key = b",\"host_time_us\":";
    if let Some(pos) = line.windows(key.len()).rposition(|w| w == key) {
        let rest = &line[pos + key.len()..];
        let digits = rest
            .iter()
            .take_while(|b| b.is_ascii_digit() || **b == b'-')
            .count();
        if rest[digits..]
            .iter()
            .all(|b| *b == b'}' || b.is_ascii_whitespace())
        {
            return &line[..pos];
        }
    }
    line
}

/// The sound speed of a successful `get_config` reply (`Some(None)` for a reply without one);
/// `None` for any other response.
fn config_reply(line: &[u8]) -> Option<Option<f64>> {
    let v: serde_json::Value = serde_json::from_slice(line).ok()?;
    if v.get("response_to")?.as_str()? != "get_config" {
        return None;
    }
    let ok = v.get("success").and_then(|s| s.as_bool()).unwrap_or(false);
    let c = v
        .get("result")
        .and_then(|r| r.get("speed_of_sound"))
        .and_then(|c| c.as_f64())
        .filter(|c| ok && c.is_finite() && *c > 0.0);
    Some(c)
}

/// Parses one line of an A50 JSON log.
pub fn parse_line(line: &[u8]) -> Result<Parsed, Reject> {
    let line = line.trim_ascii();
    let f: Fields<'_> = match serde_json::from_slice(line) {
        Ok(f) => f,
        Err(e) => return diagnose(line, e),
    };
    let label = match &f.format {
        Some(s) => clip(s),
        None => "json (no format field)".to_string(),
    };
    match f.report_type.as_deref() {
        Some("velocity") => {}
        Some("velocity_water") => return Ok(Parsed::WaterVelocity { label }),
        Some("response") => {
            if let Some(c) = config_reply(line) {
                return Ok(Parsed::Config {
                    label,
                    speed_of_sound: c,
                });
            }
            return Ok(Parsed::Other {
                label,
                kind: "response".into(),
            });
        }
        Some(other) => {
            return Ok(Parsed::Other {
                label,
                kind: clip(other),
            });
        }
        // json_v1 has no `type`: a report with a velocity is a velocity report.
        None if f.vx.is_some() || f.velocity_valid.is_some() => {}
        None => {
            return Err(Reject::new(
                "unknown report",
                "no 'type' field and no velocity fields",
            ));
        }
    }
    let need = |v: Option<f64>, name: &str| {
        let v = v.ok_or_else(|| {
            Reject::new("missing field", format!("velocity report without '{name}'"))
        })?;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(Reject::new("non-finite value", format!("'{name}' is {v}")))
        }
    };
    let v = [need(f.vx, "vx")?, need(f.vy, "vy")?, need(f.vz, "vz")?];
    let valid = f
        .velocity_valid
        .ok_or_else(|| Reject::new("missing field", "velocity report without 'velocity_valid'"))?;
    let cov = match f.covariance {
        Some(c) => {
            let flat = [
                c[0][0], c[0][1], c[0][2], c[1][0], c[1][1], c[1][2], c[2][0], c[2][1], c[2][2],
            ];
            if flat.iter().any(|x| !x.is_finite()) {
                return Err(Reject::new("non-finite value", "covariance"));
            }
            Some(flat)
        }
        None => None,
    };
    if let Some(t) = f.time {
        if !t.is_finite() {
            return Err(Reject::new("non-finite value", format!("'time' is {t}")));
        }
    }
    let time_of_validity = micros(&f.time_of_validity, "time_of_validity")?;
    let time_of_transmission = micros(&f.time_of_transmission, "time_of_transmission")?;
    let host_time_us = micros(&f.host_time_us, HOST_TIME_KEY)?;
    Ok(Parsed::Velocity(VelocityReport {
        label,
        v,
        cov,
        valid,
        time_ms: f.time,
        time_of_validity_us: time_of_validity,
        time_of_transmission_us: time_of_transmission,
        host_time: host_time_us.map(RawTime::from_micros),
        host_time_kind: host_time_us.map(|_| "host receive time (host_time_us, record-dvl)"),
        key: content_hash(identity(line)),
    }))
}

/// Explains why a line did not deserialise: not JSON at all, or a velocity report with a field
/// of the wrong kind. Reports of other types may carry fields of their own kind under the same
/// names: they are still recognised and counted.
fn diagnose(line: &[u8], e: serde_json::Error) -> Result<Parsed, Reject> {
    let value: serde_json::Value = match serde_json::from_slice(line) {
        Ok(v) => v,
        Err(e2) => {
            let reason = if e2.is_eof() {
                "truncated JSON"
            } else if std::str::from_utf8(line).is_err() {
                "invalid UTF-8"
            } else {
                "not valid JSON"
            };
            return Err(Reject::new(reason, e2.to_string()));
        }
    };
    let Some(obj) = value.as_object() else {
        return Err(Reject::new(
            "not a JSON object",
            "the line is JSON but not an object",
        ));
    };
    let label = match obj.get("format") {
        Some(serde_json::Value::String(s)) => clip(s),
        _ => "json (no format field)".to_string(),
    };
    match obj.get("type") {
        Some(serde_json::Value::String(t)) if t != "velocity" && t != "velocity_water" => {
            Ok(Parsed::Other {
                label,
                kind: clip(t),
            })
        }
        Some(serde_json::Value::String(_)) | None => {
            let reason = if e.to_string().contains("duplicate field") {
                "duplicate field"
            } else {
                "non-numeric field"
            };
            Err(Reject::new(reason, e.to_string()))
        }
        Some(_) => Err(Reject::new(
            "non-numeric field",
            format!("'type' is not a string: {e}"),
        )),
    }
}
