//! The IMU's noise files: Kalibr's `imu.yaml` (read and written) and EuRoC's
//! `imu0/sensor.yaml` (read).
//!
//! Kalibr's: `accelerometer_noise_density` (m/s^2/sqrt(Hz)), `accelerometer_random_walk`
//! (m/s^3/sqrt(Hz)), `gyroscope_noise_density` (rad/s/sqrt(Hz)), `gyroscope_random_walk`
//! (rad/s^2/sqrt(Hz)), `update_rate` (Hz) and `rostopic` (ignored), at the top level or under
//! `imu0:` (Kalibr's IMU results, OpenVINS's `kalibr_imu_chain.yaml`). EuRoC's has the same
//! noise keys, `rate_hz` for the rate and the IMU's pose on the body `T_BS` (an OpenCV matrix
//! `rows, cols, data`, or 4x4 rows), after an OpenCV `%YAML:1.0` line that YAML parsers refuse
//! (it is skipped).

use std::fmt::Write as _;
use std::path::Path;

use nalgebra::{Matrix3, Matrix4};
use serde_yaml::{Mapping, Value};

use super::super::last_line;
use crate::error::{Error, Result};
use crate::lie::Se3;
use crate::types::imu::ImuNoise;

/// The four noise keys, in Kalibr's order.
pub const NOISE_KEYS: [&str; 4] = [
    "accelerometer_noise_density",
    "accelerometer_random_walk",
    "gyroscope_noise_density",
    "gyroscope_random_walk",
];

/// Which file a noise came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NoiseFileKind {
    /// Kalibr's `imu.yaml` (keys at the top level, rate in `update_rate`).
    Kalibr,
    /// Kalibr's keys under `imu0:`.
    KalibrImu0,
    /// EuRoC's `sensor.yaml` (rate in `rate_hz`).
    EurocSensor,
}

/// An IMU noise file as read.
#[derive(Clone, Debug, PartialEq)]
pub struct ImuNoiseFile {
    /// The noise densities, random walks and rate.
    pub noise: ImuNoise,
    /// The form it was in.
    pub kind: NoiseFileKind,
    /// EuRoC's `T_BS` (the IMU's pose on the body), when given.
    pub t_bs: Option<Se3>,
}

/// How many of the four noise keys a parsed YAML holds (at the top level or under `imu0`), for
/// recognising noise files: `(found, missing)`.
pub fn noise_keys_in(value: &Value) -> (Vec<&'static str>, Vec<&'static str>) {
    let top = value.as_mapping();
    let nested = top
        .and_then(|m| m.get(Value::String("imu0".into())))
        .and_then(Value::as_mapping);
    let count = |m: Option<&Mapping>| {
        NOISE_KEYS
            .iter()
            .filter(|k| m.is_some_and(|m| m.contains_key(Value::String((**k).into()))))
            .count()
    };
    let m = if count(nested) > count(top) {
        nested
    } else {
        top
    };
    NOISE_KEYS
        .into_iter()
        .partition(|k| m.is_some_and(|m| m.contains_key(Value::String((*k).into()))))
}

/// The text without OpenCV's `%YAML:1.0` first line (replaced by a blank line, so that line
/// numbers stay), which YAML parsers refuse.
pub(crate) fn without_opencv_directive(text: &str) -> std::borrow::Cow<'_, str> {
    let first = text.lines().next().unwrap_or("");
    if first.trim_start().starts_with("%YAML:") {
        std::borrow::Cow::Owned(text.replacen(first, "", 1))
    } else {
        std::borrow::Cow::Borrowed(text)
    }
}

/// Reads an IMU noise file: Kalibr's `imu.yaml` (flat or under `imu0`) or EuRoC's
/// `sensor.yaml`. Errors name the file, the key and its line.
pub fn read_imu_noise(path: &Path) -> Result<ImuNoiseFile> {
    let text = crate::files::read_text(path)?;
    parse_imu_noise(&text, path)
}

/// The 1-based line of `key:` in `text` (its first occurrence at the start of a line, after
/// indentation), or the file's last line.
fn key_line(text: &str, key: &str) -> usize {
    text.lines()
        .position(|l| {
            l.trim_start()
                .strip_prefix(key)
                .is_some_and(|r| r.trim_start().starts_with(':'))
        })
        .map_or(last_line(text), |i| i + 1)
}

/// Parses the text of a noise file as [`read_imu_noise`] does; `path` names it in messages.
pub fn parse_imu_noise(text: &str, path: &Path) -> Result<ImuNoiseFile> {
    let text = without_opencv_directive(text);
    let text = text.as_ref();
    let value: Value = serde_yaml::from_str(text).map_err(|e| {
        let line = e.location().map_or(last_line(text), |l| l.line());
        Error::parse(path, line, format!("not readable as YAML: {e}"))
    })?;
    let top = value
        .as_mapping()
        .ok_or_else(|| Error::parse(path, 1, "an IMU noise file must be a YAML mapping"))?;
    let nested = top
        .get(Value::String("imu0".into()))
        .and_then(Value::as_mapping);
    let (map, under) = match nested {
        Some(m) if !top.contains_key(Value::String(NOISE_KEYS[0].into())) => (m, "imu0."),
        _ => (top, ""),
    };
    let get = |key: &str| map.get(Value::String(key.into()));
    let number = |key: &str, v: &Value| -> Result<f64> {
        let line = key_line(text, key);
        let x = match v {
            Value::Number(n) => n.as_f64(),
            Value::String(s) => s.trim().parse::<f64>().ok(),
            _ => None,
        }
        .ok_or_else(|| {
            Error::parse(
                path,
                line,
                format!("key '{under}{key}': {} is not a number", show(v)),
            )
        })?;
        if !x.is_finite() {
            return Err(Error::parse(
                path,
                line,
                format!("key '{under}{key}': {x} is not finite"),
            ));
        }
        Ok(x)
    };
    let mut values = [0.0; 4];
    for (slot, key) in values.iter_mut().zip(NOISE_KEYS) {
        let v = get(key).ok_or_else(|| {
            Error::parse(
                path,
                last_line(text),
                format!(
                    "key '{under}{key}' is missing (an IMU noise file gives {}, and \
                     update_rate or rate_hz)",
                    NOISE_KEYS.join(", ")
                ),
            )
        })?;
        let x = number(key, v)?;
        let density = key.ends_with("noise_density");
        if x < 0.0 || (density && x == 0.0) {
            return Err(Error::parse(
                path,
                key_line(text, key),
                format!(
                    "key '{under}{key}': {x} must be {} (a continuous-time {})",
                    if density { "positive" } else { "0 or more" },
                    if density {
                        "noise density"
                    } else {
                        "bias random walk"
                    }
                ),
            ));
        }
        *slot = x;
    }
    let (rate_key, kind) = match (get("update_rate"), get("rate_hz")) {
        (Some(_), _) => (
            "update_rate",
            if under.is_empty() {
                NoiseFileKind::Kalibr
            } else {
                NoiseFileKind::KalibrImu0
            },
        ),
        (None, Some(_)) => ("rate_hz", NoiseFileKind::EurocSensor),
        (None, None) => {
            return Err(Error::parse(
                path,
                last_line(text),
                format!(
                    "key '{under}update_rate' is missing (Kalibr's sample rate in Hz; EuRoC's \
                     sensor.yaml calls it rate_hz)"
                ),
            ));
        }
    };
    let rate = number(rate_key, get(rate_key).unwrap_or(&Value::Null))?;
    if !(rate > 0.0 && rate <= 1e5) {
        return Err(Error::parse(
            path,
            key_line(text, rate_key),
            format!("key '{under}{rate_key}': {rate} Hz is not a sample rate (0 to 100 kHz)"),
        ));
    }
    let t_bs = match get("T_BS") {
        Some(v) => Some(transform(v).map_err(|msg| {
            Error::parse(path, key_line(text, "T_BS"), format!("key 'T_BS': {msg}"))
        })?),
        None => None,
    };
    Ok(ImuNoiseFile {
        noise: ImuNoise {
            accelerometer_noise_density: values[0],
            accelerometer_random_walk: values[1],
            gyroscope_noise_density: values[2],
            gyroscope_random_walk: values[3],
            update_rate: rate,
        },
        kind,
        t_bs,
    })
}

/// A YAML value in a message, on one line.
fn show(v: &Value) -> String {
    match v {
        Value::String(s) => format!("'{s}'"),
        Value::Null => "nothing".into(),
        other => serde_yaml::to_string(other)
            .map(|s| s.trim().replace('\n', " "))
            .unwrap_or_else(|_| "the value".into()),
    }
}

/// A rigid transform from OpenCV's `{rows: 4, cols: 4, data: [16]}` or from 4 rows of 4.
fn transform(v: &Value) -> std::result::Result<Se3, String> {
    let nums = |v: &Value| -> Option<Vec<f64>> {
        v.as_sequence()?
            .iter()
            .map(|x| x.as_f64())
            .collect::<Option<Vec<f64>>>()
    };
    let data: Vec<f64> = if let Some(m) = v.as_mapping() {
        let data = m
            .get(Value::String("data".into()))
            .and_then(nums)
            .ok_or("an OpenCV matrix needs 'data', a list of numbers")?;
        let dim = |k: &str| m.get(Value::String(k.into())).and_then(Value::as_u64);
        if dim("rows") != Some(4) || dim("cols") != Some(4) {
            return Err("must be 4 rows by 4 columns".into());
        }
        data
    } else {
        let rows = v
            .as_sequence()
            .ok_or("must be a 4x4 matrix (4 rows of 4 numbers, or OpenCV's rows/cols/data)")?;
        let mut all = Vec::new();
        for r in rows {
            let r = nums(r).ok_or("every row must be a list of numbers")?;
            if r.len() != 4 {
                return Err("every row must hold 4 numbers".into());
            }
            all.extend(r);
        }
        all
    };
    if data.len() != 16 || data.iter().any(|x| !x.is_finite()) {
        return Err(format!(
            "must hold 16 finite numbers, got {} values",
            data.len()
        ));
    }
    let m = Matrix4::from_row_slice(&data);
    let r: Matrix3<f64> = m.fixed_view::<3, 3>(0, 0).into_owned();
    let ortho = (r.transpose() * r - Matrix3::identity()).abs().max();
    let last = m[(3, 0)].abs() + m[(3, 1)].abs() + m[(3, 2)].abs() + (m[(3, 3)] - 1.0).abs();
    if ortho > 1e-6 || last > 1e-9 || r.determinant() < 0.0 {
        return Err(format!(
            "is not a rigid transform (max |R^T R - I| = {ortho:.2e}, det {:.4}, last row \
             {:?})",
            r.determinant(),
            [m[(3, 0)], m[(3, 1)], m[(3, 2)], m[(3, 3)]]
        ));
    }
    Ok(Se3::new(r, m.fixed_view::<3, 1>(0, 3).into_owned()).renormalized())
}

/// A number as YAML 1.1 reads it as a float, for Kalibr's Python reader too: the shortest
/// digits that read back exactly, with a decimal point, and an exponent with its sign
/// (`3.8e-5`, `1.0e-5`, `200.0`).
pub(crate) fn yaml11_float(v: f64) -> String {
    let s = format!("{v:?}");
    match s.split_once('e') {
        Some((mantissa, exp)) => {
            let mantissa = if mantissa.contains('.') {
                mantissa.to_string()
            } else {
                format!("{mantissa}.0")
            };
            let exp = if exp.starts_with('-') {
                exp.to_string()
            } else {
                format!("+{exp}")
            };
            format!("{mantissa}e{exp}")
        }
        None if s.contains('.') || !v.is_finite() => s,
        None => format!("{s}.0"),
    }
}

/// The text of Kalibr's `imu.yaml` for `noise`, with `rostopic`.
pub fn kalibr_imu_yaml(noise: &ImuNoise, rostopic: &str) -> String {
    let mut s = String::from(
        "# IMU noise in Kalibr's imu.yaml form (continuous-time densities).\n#Accelerometers\n",
    );
    let rows = [
        (
            NOISE_KEYS[0],
            noise.accelerometer_noise_density,
            "m/s^2/sqrt(Hz), white noise",
        ),
        (
            NOISE_KEYS[1],
            noise.accelerometer_random_walk,
            "m/s^3/sqrt(Hz), bias random walk",
        ),
        (
            NOISE_KEYS[2],
            noise.gyroscope_noise_density,
            "rad/s/sqrt(Hz), white noise",
        ),
        (
            NOISE_KEYS[3],
            noise.gyroscope_random_walk,
            "rad/s^2/sqrt(Hz), bias random walk",
        ),
    ];
    for (k, (key, v, unit)) in rows.iter().enumerate() {
        if k == 2 {
            s.push_str("#Gyroscopes\n");
        }
        let _ = writeln!(s, "{key}: {}   # {unit}", yaml11_float(*v));
    }
    let _ = writeln!(s, "rostopic: {rostopic}");
    let _ = writeln!(s, "update_rate: {}   # Hz", yaml11_float(noise.update_rate));
    s
}

/// Writes Kalibr's `imu.yaml` ([`kalibr_imu_yaml`]) atomically; non-finite values are refused.
pub fn write_kalibr_imu_yaml(path: &Path, noise: &ImuNoise, rostopic: &str) -> Result<()> {
    let values = [
        noise.accelerometer_noise_density,
        noise.accelerometer_random_walk,
        noise.gyroscope_noise_density,
        noise.gyroscope_random_walk,
        noise.update_rate,
    ];
    if values.iter().any(|x| !x.is_finite()) {
        return Err(super::super::non_finite(path, "an IMU noise value".into()));
    }
    super::super::write_atomic(path, kalibr_imu_yaml(noise, rostopic).as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floats_read_as_floats_in_yaml_1_1() {
        assert_eq!(yaml11_float(3.8e-5), "3.8e-5");
        assert_eq!(yaml11_float(1e-5), "1.0e-5");
        assert_eq!(yaml11_float(200.0), "200.0");
        assert_eq!(yaml11_float(0.004), "0.004");
        assert_eq!(yaml11_float(1e20), "1.0e+20");
        for v in [3.8e-5, 1e-5, 200.0, 0.004, 1e20, 1.6968e-4] {
            assert_eq!(yaml11_float(v).parse::<f64>().unwrap(), v);
        }
    }

    #[test]
    fn kalibr_nested_under_imu0_reads() {
        let text = "imu0:\n  T_i_b: [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]\n  \
                    accelerometer_noise_density: 0.002\n  accelerometer_random_walk: 0.003\n  \
                    gyroscope_noise_density: 0.00017\n  gyroscope_random_walk: 2.0e-5\n  \
                    rostopic: /imu0\n  update_rate: 200\n";
        let f = parse_imu_noise(text, Path::new("kalibr_imu_chain.yaml")).unwrap();
        assert_eq!(f.kind, NoiseFileKind::KalibrImu0);
        assert_eq!(f.noise.update_rate, 200.0);
        assert_eq!(f.noise.gyroscope_random_walk, 2.0e-5);
        let v: Value = serde_yaml::from_str(text).unwrap();
        assert_eq!(noise_keys_in(&v).0.len(), 4);
    }

    #[test]
    fn a_word_where_a_number_belongs_names_key_and_line() {
        let text = "accelerometer_noise_density: 0.002\naccelerometer_random_walk: 0.003\n\
                    gyroscope_noise_density: fast\ngyroscope_random_walk: 2.0e-5\n\
                    update_rate: 200.0\n";
        let e = parse_imu_noise(text, Path::new("imu.yaml"))
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "imu.yaml:3: key 'gyroscope_noise_density': 'fast' is not a number"
        );
    }
}
