//! IMU samples averaged in short bins, once, before any iteration: the estimator compares each
//! bin's mean with the trajectory's prediction at the bin's mean time. A bin of `n` samples
//! carries `n` times a sample's information; its span is a fraction of the knot spacing, so the
//! prediction at the mean time stands for the mean of the predictions (the difference is of
//! the order of the span squared times the signal's second derivative, far below the noise).

use nalgebra::Vector3;

use crate::types::imu::{ImuNoise, ImuSample};

/// The mean of a few consecutive IMU samples.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImuBin {
    /// Mean time, IMU clock, seconds.
    pub t: f64,
    /// Mean gyro reading, rad/s.
    pub gyro: Vector3<f64>,
    /// Mean accelerometer reading, m/s^2.
    pub accel: Vector3<f64>,
    /// Samples averaged.
    pub n: usize,
}

impl ImuBin {
    /// The inverse variances of the bin's gyro and accelerometer means.
    pub fn information(&self, noise: &ImuNoise) -> (f64, f64) {
        let n = self.n as f64;
        (
            n / noise.gyro_sample_std().powi(2),
            n / noise.accel_sample_std().powi(2),
        )
    }
}

/// Consecutive samples in bins of at most `width` seconds (at least one sample each); a bin
/// never spans a gap longer than twice the sample period.
pub fn make_bins(samples: &[ImuSample], width: f64, rate: f64) -> Vec<ImuBin> {
    let gap = 2.0 / rate;
    let mut bins = Vec::with_capacity(samples.len() / 2 + 1);
    let mut i = 0;
    while i < samples.len() {
        let start = samples[i].t;
        let mut j = i + 1;
        while j < samples.len()
            && samples[j].t - start < width * (1.0 - 1e-9)
            && samples[j].t - samples[j - 1].t <= gap
        {
            j += 1;
        }
        let group = &samples[i..j];
        let n = group.len() as f64;
        bins.push(ImuBin {
            t: group.iter().map(|s| s.t).sum::<f64>() / n,
            gyro: group.iter().map(|s| s.gyro).sum::<Vector3<f64>>() / n,
            accel: group.iter().map(|s| s.accel).sum::<Vector3<f64>>() / n,
            n: group.len(),
        });
        i = j;
    }
    bins
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bins_average_and_stop_at_gaps() {
        let mut s: Vec<ImuSample> = (0..10)
            .map(|k| ImuSample {
                t: k as f64 * 0.005,
                gyro: Vector3::new(k as f64, 0.0, 0.0),
                accel: Vector3::zeros(),
            })
            .collect();
        s[7].t += 0.05;
        s[8].t += 0.05;
        s[9].t += 0.05;
        let b = make_bins(&s, 0.025, 200.0);
        let counts: Vec<usize> = b.iter().map(|b| b.n).collect();
        assert_eq!(counts, vec![5, 2, 3]);
        assert!((b[0].gyro.x - 2.0).abs() < 1e-12);
        assert!((b[0].t - 0.01).abs() < 1e-12);
    }
}
