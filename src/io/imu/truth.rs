//! The truth of a simulated IMU, as `dvlcal simulate --imu` writes it in `truth/`:
//!
//! - `imu.yaml`: `T_cam_imu` (4x4 rows: IMU points into the camera frame),
//!   `imu_time_offset_s` (`t_cam = t_imu + imu_time_offset_s`), `gravity_world` (m/s^2, in the
//!   world frame of `truth/poses.txt`), the biases at the first sample
//!   (`gyroscope_bias_start`, rad/s; `accelerometer_bias_start`, m/s^2), `samples` (how many
//!   the stream holds) and `noise` (the densities, walks and rate simulated, Kalibr's keys).
//! - `imu_bias.csv`: `t,bgx,bgy,bgz,bax,bay,baz`, the biases at each sample, `t` its absolute
//!   IMU-clock time in seconds with nine decimals.

use std::fmt::Write as _;
use std::path::Path;

use nalgebra::{Matrix4, Vector3};
use serde::Deserialize;

use super::super::{fmt_f64, non_finite, parse_finite, parse_time};
use super::noise::{NOISE_KEYS, yaml11_float};
use crate::error::{Error, Result};
use crate::lie::Se3;
use crate::time::Epoch;
use crate::types::imu::{ImuBias, ImuNoise};

/// The header line of `truth/imu_bias.csv`.
pub const IMU_BIAS_CSV_HEADER: &str = "t,bgx,bgy,bgz,bax,bay,baz";

/// What a simulated IMU was made with.
#[derive(Clone, Debug, PartialEq)]
pub struct ImuTruth {
    /// `T_cam_imu`: maps IMU-frame points into the camera frame.
    pub t_cam_imu: Se3,
    /// `t_cam = t_imu + imu_time_offset_s`.
    pub imu_time_offset_s: f64,
    /// Gravity in the world frame, m/s^2 (pointing down).
    pub gravity_world: Vector3<f64>,
    /// The biases at the first sample.
    pub bias_start: ImuBias,
    /// Samples in the stream.
    pub samples: usize,
    /// The noise simulated.
    pub noise: ImuNoise,
}

#[derive(Deserialize)]
struct NoiseSection {
    accelerometer_noise_density: f64,
    accelerometer_random_walk: f64,
    gyroscope_noise_density: f64,
    gyroscope_random_walk: f64,
    update_rate: f64,
}

#[derive(Deserialize)]
struct TruthFile {
    #[serde(rename = "T_cam_imu")]
    t_cam_imu: [[f64; 4]; 4],
    imu_time_offset_s: f64,
    gravity_world: [f64; 3],
    gyroscope_bias_start: [f64; 3],
    accelerometer_bias_start: [f64; 3],
    samples: usize,
    noise: NoiseSection,
}

fn flow(v: &[f64]) -> String {
    let items: Vec<String> = v.iter().map(|x| yaml11_float(*x)).collect();
    format!("[{}]", items.join(", "))
}

/// The text of `truth/imu.yaml`.
pub fn imu_truth_yaml(t: &ImuTruth) -> String {
    let mut s = String::from(
        "# dvlcal simulate: the simulated IMU's truth.\n\
         # T_cam_imu maps IMU-frame points into the camera frame (rows); its translation is the\n\
         # IMU origin in camera coordinates. Clocks: t_cam = t_imu + imu_time_offset_s.\n\
         # gravity_world: m/s^2 in the world frame of truth/poses.txt. Biases at the first\n\
         # sample: gyroscope rad/s, accelerometer m/s^2 (truth/imu_bias.csv has them all).\n",
    );
    let m = t.t_cam_imu.to_matrix();
    let _ = writeln!(s, "T_cam_imu:");
    for r in 0..4 {
        let row: Vec<f64> = (0..4).map(|c| m[(r, c)]).collect();
        let _ = writeln!(s, "  - {}", flow(&row));
    }
    let _ = writeln!(
        s,
        "imu_time_offset_s: {}",
        yaml11_float(t.imu_time_offset_s)
    );
    let _ = writeln!(s, "gravity_world: {}", flow(t.gravity_world.as_slice()));
    let _ = writeln!(
        s,
        "gyroscope_bias_start: {}",
        flow(t.bias_start.gyro.as_slice())
    );
    let _ = writeln!(
        s,
        "accelerometer_bias_start: {}",
        flow(t.bias_start.accel.as_slice())
    );
    let _ = writeln!(s, "samples: {}", t.samples);
    let n = &t.noise;
    let _ = writeln!(s, "noise:");
    for (key, v) in NOISE_KEYS.iter().zip([
        n.accelerometer_noise_density,
        n.accelerometer_random_walk,
        n.gyroscope_noise_density,
        n.gyroscope_random_walk,
    ]) {
        let _ = writeln!(s, "  {key}: {}", yaml11_float(v));
    }
    let _ = writeln!(s, "  update_rate: {}", yaml11_float(n.update_rate));
    s
}

/// Writes `truth/imu.yaml` atomically.
pub fn write_imu_truth(path: &Path, t: &ImuTruth) -> Result<()> {
    let m = t.t_cam_imu.to_matrix();
    let n = &t.noise;
    let all = m
        .iter()
        .copied()
        .chain([t.imu_time_offset_s, n.update_rate])
        .chain(t.gravity_world.iter().copied())
        .chain(t.bias_start.gyro.iter().copied())
        .chain(t.bias_start.accel.iter().copied())
        .chain([
            n.accelerometer_noise_density,
            n.accelerometer_random_walk,
            n.gyroscope_noise_density,
            n.gyroscope_random_walk,
        ]);
    if all.clone().any(|x| !x.is_finite()) {
        return Err(non_finite(path, "an IMU truth value".into()));
    }
    super::super::write_atomic(path, imu_truth_yaml(t).as_bytes())
}

/// Reads `truth/imu.yaml` as [`write_imu_truth`] writes it.
pub fn read_imu_truth(path: &Path) -> Result<ImuTruth> {
    let text = crate::files::read_text(path)?;
    let f: TruthFile = serde_yaml::from_str(&text).map_err(|e| {
        let line = e.location().map_or(0, |l| l.line());
        Error::parse(path, line, e.to_string())
    })?;
    let m = Matrix4::from_fn(|r, c| f.t_cam_imu[r][c]);
    let t_cam_imu = Se3::new(
        m.fixed_view::<3, 3>(0, 0).into_owned(),
        m.fixed_view::<3, 1>(0, 3).into_owned(),
    )
    .renormalized();
    Ok(ImuTruth {
        t_cam_imu,
        imu_time_offset_s: f.imu_time_offset_s,
        gravity_world: Vector3::from(f.gravity_world),
        bias_start: ImuBias {
            gyro: Vector3::from(f.gyroscope_bias_start),
            accel: Vector3::from(f.accelerometer_bias_start),
        },
        samples: f.samples,
        noise: ImuNoise {
            accelerometer_noise_density: f.noise.accelerometer_noise_density,
            accelerometer_random_walk: f.noise.accelerometer_random_walk,
            gyroscope_noise_density: f.noise.gyroscope_noise_density,
            gyroscope_random_walk: f.noise.gyroscope_random_walk,
            update_rate: f.noise.update_rate,
        },
    })
}

/// Writes `truth/imu_bias.csv`: one row per `(t, bias)`, `t` on the IMU clock from `epoch`.
pub fn write_imu_bias_csv(path: &Path, epoch: Epoch, rows: &[(f64, ImuBias)]) -> Result<()> {
    let mut out = String::with_capacity(32 + rows.len() * 120);
    out.push_str(IMU_BIAS_CSV_HEADER);
    out.push('\n');
    for (i, (t, b)) in rows.iter().enumerate() {
        let values = b.gyro.iter().chain(b.accel.iter());
        if !t.is_finite() || values.clone().any(|x| !x.is_finite()) {
            return Err(non_finite(path, format!("bias row {i}")));
        }
        out.push_str(&epoch.format_abs(*t, 9));
        for x in values {
            let _ = write!(out, ",{}", fmt_f64(*x));
        }
        out.push('\n');
    }
    super::super::write_atomic(path, out.as_bytes())
}

/// Reads `truth/imu_bias.csv` with times relative to `epoch`.
pub fn read_imu_bias_csv(path: &Path, epoch: Epoch) -> Result<Vec<(f64, ImuBias)>> {
    let text = crate::files::read_text(path)?;
    let names: Vec<&str> = IMU_BIAS_CSV_HEADER.split(',').collect();
    let mut rows = Vec::new();
    let mut header = false;
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let l = raw.trim();
        if l.is_empty() {
            continue;
        }
        if !header {
            if l != IMU_BIAS_CSV_HEADER {
                return Err(Error::parse(
                    path,
                    line,
                    format!("expected the header '{IMU_BIAS_CSV_HEADER}'"),
                ));
            }
            header = true;
            continue;
        }
        let f: Vec<&str> = l.split(',').collect();
        if f.len() != 7 {
            return Err(Error::parse(
                path,
                line,
                format!("expected 7 fields, found {}", f.len()),
            ));
        }
        let t = epoch.rel(parse_time(path, line, f[0])?);
        let mut v = [0.0; 6];
        for k in 0..6 {
            v[k] = parse_finite(path, line, names[k + 1], f[k + 1])?;
        }
        rows.push((
            t,
            ImuBias {
                gyro: Vector3::new(v[0], v[1], v[2]),
                accel: Vector3::new(v[3], v[4], v[5]),
            },
        ));
    }
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_truth_reads_back_as_written() {
        let cfg = crate::types::imu::ImuNoise {
            accelerometer_noise_density: 4.0e-3,
            accelerometer_random_walk: 6.0e-4,
            gyroscope_noise_density: 3.4e-4,
            gyroscope_random_walk: 3.8e-5,
            update_rate: 200.0,
        };
        let t = ImuTruth {
            t_cam_imu: Se3::new(
                crate::lie::so3::exp(&Vector3::new(0.1, -0.2, 1.5)),
                Vector3::new(0.08, -0.02, 0.03),
            ),
            imu_time_offset_s: 0.005,
            gravity_world: Vector3::new(0.0, 0.0, -9.80665),
            bias_start: ImuBias {
                gyro: Vector3::new(0.004, -0.006, 0.003),
                accel: Vector3::new(0.08, -0.05, 0.12),
            },
            samples: 12001,
            noise: cfg,
        };
        let dir = std::env::temp_dir().join(format!("dvlcal-imu-truth-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("imu.yaml");
        write_imu_truth(&p, &t).unwrap();
        let back = read_imu_truth(&p).unwrap();
        let _ = std::fs::remove_dir_all(&dir);
        assert!(
            (back.t_cam_imu.to_matrix() - t.t_cam_imu.to_matrix())
                .abs()
                .max()
                < 1e-15
        );
        assert_eq!(
            (back.imu_time_offset_s, back.gravity_world, back.bias_start),
            (t.imu_time_offset_s, t.gravity_world, t.bias_start)
        );
        assert_eq!((back.samples, back.noise), (t.samples, t.noise));
    }
}
