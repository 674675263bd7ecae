//! A simulated IMU on a simulated motion: samples at a fixed rate on the IMU's own clock, white
//! noise at the stated densities, and biases that walk as the noise file says they do.

use nalgebra::Vector3;

use super::motion::Motion;
use crate::error::{Error, Result};
use crate::lie::Se3;
use crate::rng::Rng;
use crate::types::imu::{ImuBias, ImuNoise, ImuSample, STANDARD_GRAVITY, imu_measurement};

/// Stream numbers of [`Rng::stream`] for the IMU (kept apart from the dataset's other streams).
const STREAM_IMU_NOISE: u64 = 41;
const STREAM_IMU_BIAS: u64 = 42;

/// What a simulated IMU is: where it is mounted, its clock, its noise and its first biases.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImuSimConfig {
    /// `T_cam_imu`: maps IMU-frame points into the camera frame.
    pub t_cam_imu: Se3,
    /// `t_cam = t_imu + time_offset_s`.
    pub time_offset_s: f64,
    /// The noise densities, random walks and sample rate.
    pub noise: ImuNoise,
    /// The biases at the first sample.
    pub initial_bias: ImuBias,
    /// Gravity in the world (board) frame, m/s^2, pointing down.
    pub gravity_world: Vector3<f64>,
}

impl ImuSimConfig {
    /// A consumer-grade MEMS IMU (noise of the order of the EuRoC's ADIS16448, doubled as Kalibr
    /// advises) at 200 Hz, mounted 8 cm beside the camera, turned about 90 degrees, 5 ms late,
    /// with biases of a few tenths of a degree per second and a few hundredths of g; gravity
    /// along the world's `-z`.
    pub fn default_truth() -> ImuSimConfig {
        let mount = crate::lie::so3::exp(&Vector3::new(0.0, 0.0, std::f64::consts::FRAC_PI_2));
        let misalignment = crate::lie::so3::exp(&Vector3::new(0.015, -0.01, 0.02));
        ImuSimConfig {
            t_cam_imu: Se3::new(mount * misalignment, Vector3::new(0.08, -0.02, 0.03)),
            time_offset_s: 0.005,
            noise: ImuNoise {
                accelerometer_noise_density: 4.0e-3,
                accelerometer_random_walk: 6.0e-4,
                gyroscope_noise_density: 3.4e-4,
                gyroscope_random_walk: 3.8e-5,
                update_rate: 200.0,
            },
            initial_bias: ImuBias {
                gyro: Vector3::new(0.004, -0.006, 0.003),
                accel: Vector3::new(0.08, -0.05, 0.12),
            },
            gravity_world: Vector3::new(0.0, 0.0, -STANDARD_GRAVITY),
        }
    }

    fn validate(&self) -> Result<()> {
        let n = &self.noise;
        let values = [
            ("accelerometer_noise_density", n.accelerometer_noise_density),
            ("accelerometer_random_walk", n.accelerometer_random_walk),
            ("gyroscope_noise_density", n.gyroscope_noise_density),
            ("gyroscope_random_walk", n.gyroscope_random_walk),
        ];
        for (name, v) in values {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::Input(format!(
                    "simulated IMU: {name} must be finite and not negative, got {v}"
                )));
            }
        }
        if !(n.update_rate.is_finite() && n.update_rate > 0.0) {
            return Err(Error::Input(format!(
                "simulated IMU: update_rate must be positive, got {}",
                n.update_rate
            )));
        }
        if !self.time_offset_s.is_finite() {
            return Err(Error::Input(
                "simulated IMU: time offset must be finite".into(),
            ));
        }
        Ok(())
    }
}

/// A simulated IMU stream with its truth.
#[derive(Clone, Debug)]
pub struct SimImu {
    /// The samples, on the IMU clock.
    pub samples: Vec<ImuSample>,
    /// The true biases at each sample.
    pub bias: Vec<ImuBias>,
}

/// The IMU of `cfg` on `motion`, sampled on the IMU clock at every multiple of the sample
/// period whose camera time lies in `[t0, t1]` (camera clock). The biases walk as random walks
/// of the stated densities; the same seed gives the same stream.
pub fn simulate_imu(
    motion: &dyn Motion,
    cfg: &ImuSimConfig,
    t0: f64,
    t1: f64,
    seed: u64,
) -> Result<SimImu> {
    cfg.validate()?;
    let rate = cfg.noise.update_rate;
    let dt = 1.0 / rate;
    let (sg, sa) = (cfg.noise.gyro_sample_std(), cfg.noise.accel_sample_std());
    let (wg, wa) = (
        cfg.noise.gyroscope_random_walk * dt.sqrt(),
        cfg.noise.accelerometer_random_walk * dt.sqrt(),
    );
    // A tick on an end of the span counts though rounding puts it a hair outside
    // (`(10 - 0.005) * 200` is 1998.9999999999998).
    let first = ((t0 - cfg.time_offset_s) * rate - 1e-6).ceil() as i64;
    let last = ((t1 - cfg.time_offset_s) * rate + 1e-6).floor() as i64;
    if last < first {
        return Err(Error::Input(format!(
            "simulated IMU: no sample between {t0} s and {t1} s"
        )));
    }
    let mut noise = Rng::stream(seed, STREAM_IMU_NOISE);
    let mut walk = Rng::stream(seed, STREAM_IMU_BIAS);
    let mut bias = cfg.initial_bias;
    let n = (last - first + 1) as usize;
    let mut samples = Vec::with_capacity(n);
    let mut biases = Vec::with_capacity(n);
    for j in first..=last {
        let t_imu = j as f64 * dt;
        let s = motion.state(t_imu + cfg.time_offset_s);
        let (gyro, accel) = imu_measurement(
            &s.pose,
            &s.twist,
            &s.twist_rate,
            &cfg.t_cam_imu,
            &cfg.gravity_world,
        );
        samples.push(ImuSample {
            t: t_imu,
            gyro: gyro + bias.gyro + noise.normal_vec3() * sg,
            accel: accel + bias.accel + noise.normal_vec3() * sa,
        });
        biases.push(bias);
        bias.gyro += walk.normal_vec3() * wg;
        bias.accel += walk.normal_vec3() * wa;
    }
    Ok(SimImu {
        samples,
        bias: biases,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::motion::SinusoidMotion;

    #[test]
    fn samples_sit_on_the_imu_clock_with_the_stated_noise() {
        let motion = SinusoidMotion::lively(20.0).expect("motion");
        let mut cfg = ImuSimConfig::default_truth();
        cfg.noise.gyroscope_random_walk = 0.0;
        cfg.noise.accelerometer_random_walk = 0.0;
        let imu = simulate_imu(&motion, &cfg, 0.0, 20.0, 7).expect("imu");
        // Camera times -5 ms .. 19.995 s: IMU ticks -1 ..= 3999.
        assert_eq!(imu.samples.len(), 4001);
        // Every sample at a multiple of 5 ms; the camera time of the first at or after 0.
        assert!(
            imu.samples
                .iter()
                .all(|s| ((s.t * 200.0).round() - s.t * 200.0).abs() < 1e-9)
        );
        assert!(imu.samples[0].t + cfg.time_offset_s >= 0.0);
        // The residuals against the noiseless model have the stated std (within 5 %).
        let mut sum = [0.0, 0.0];
        for (s, b) in imu.samples.iter().zip(&imu.bias) {
            let st = motion.state(s.t + cfg.time_offset_s);
            let (g, a) = imu_measurement(
                &st.pose,
                &st.twist,
                &st.twist_rate,
                &cfg.t_cam_imu,
                &cfg.gravity_world,
            );
            sum[0] += (s.gyro - g - b.gyro).norm_squared();
            sum[1] += (s.accel - a - b.accel).norm_squared();
        }
        let m = 3.0 * imu.samples.len() as f64;
        let (sg, sa) = ((sum[0] / m).sqrt(), (sum[1] / m).sqrt());
        assert!(
            (sg / cfg.noise.gyro_sample_std() - 1.0).abs() < 0.05,
            "{sg}"
        );
        assert!(
            (sa / cfg.noise.accel_sample_std() - 1.0).abs() < 0.05,
            "{sa}"
        );
    }

    #[test]
    fn biases_walk_at_the_stated_rate() {
        let motion = SinusoidMotion::lively(200.0).expect("motion");
        let cfg = ImuSimConfig::default_truth();
        // Over 200 s, the walk's variance per axis is density^2 * T; over 100 seeds' worth of
        // axes (3 x 20 runs) its mean square must be within 30 % of that.
        let mut ms = 0.0;
        let runs = 20;
        for seed in 0..runs {
            let imu = simulate_imu(&motion, &cfg, 0.0, 200.0, seed).expect("imu");
            let d = imu.bias[imu.bias.len() - 1].gyro - imu.bias[0].gyro;
            ms += d.norm_squared();
        }
        let want = cfg.noise.gyroscope_random_walk.powi(2) * 200.0;
        let got = ms / (3.0 * runs as f64);
        assert!((got / want - 1.0).abs() < 0.3, "{got} vs {want}");
    }

    #[test]
    fn a_bad_noise_is_refused() {
        let motion = SinusoidMotion::lively(2.0).expect("motion");
        let mut cfg = ImuSimConfig::default_truth();
        cfg.noise.update_rate = 0.0;
        assert!(simulate_imu(&motion, &cfg, 0.0, 2.0, 1).is_err());
    }
}
