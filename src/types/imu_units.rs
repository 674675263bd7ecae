//! Whether an IMU stream is in the units dvlcal reads (gyro rad/s, specific force m/s^2), from
//! the numbers alone: pure math on samples and rates, no files.
//!
//! - The accelerometer: the median norm of the specific force is gravity's, about 9.81 m/s^2,
//!   for any vehicle that is not in free fall most of the time; about 1 means g.
//! - The gyro, against a reference (the camera trajectory's angular rates): the norm of an
//!   angular velocity is the same in every frame, so the gyro's norms over the reference's give
//!   the gyro's scale whatever the mounting: about 1 for rad/s, 57.3 for deg/s.
//! - The gyro, against gravity: while the IMU tilts, gravity turns in the accelerometer's frame
//!   at `|w x u|` (`u` the specific force's direction); a gyro reading 57 times that rate is in
//!   deg/s. Linear accelerations blur this (a drone's in flight gives ratios of 0.7 to 1.6 for
//!   rad/s data), but nothing makes a rad/s gyro read tens of times the tilt rate.

use nalgebra::Vector3;

use super::imu::{ImuSample, STANDARD_GRAVITY};

/// Degrees in a radian: the factor a gyro in deg/s is off by.
pub const DEG_PER_RAD: f64 = 180.0 / std::f64::consts::PI;

/// Reference rates slower than this, rad/s, are not used to judge a gyro's scale (a bias of a
/// few hundredths of a rad/s would dominate their ratio).
pub const MIN_REFERENCE_RATE: f64 = 0.1;

/// Pairs of rates needed for a verdict against a reference.
pub const MIN_REFERENCE_PAIRS: usize = 10;

/// Length of the stretches the accelerometer's direction is averaged over, s.
pub const TILT_WINDOW_S: f64 = 0.2;

/// Tilt rates of the specific force below this, rad/s, are not used (noise and vibration).
pub const MIN_TILT_RATE: f64 = 0.05;

/// Pairs of stretches needed for a verdict against gravity.
pub const MIN_TILT_PAIRS: usize = 5;

/// What a gyro's rates over a reference's say about its unit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GyroScale {
    /// Within a factor 2 of the reference: rad/s.
    RadiansPerSecond,
    /// Within a factor 2 of 57.3 times the reference: deg/s.
    DegreesPerSecond,
    /// Within a factor 2 of 1/57.3 of the reference: rad/s converted to radians once more (or a
    /// reference in deg/s).
    RadiansConvertedTwice,
    /// None of these: another unit, a broken gyro, or rates that do not belong together.
    Unexplained,
    /// Too little rotation to tell.
    Inconclusive,
}

/// A verdict on a gyro's scale with the figures it rests on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GyroScaleCheck {
    /// The verdict.
    pub scale: GyroScale,
    /// The median ratio of the gyro's rate to the reference's (NaN without pairs).
    pub ratio: f64,
    /// How many pairs the ratio rests on.
    pub pairs: usize,
}

impl GyroScaleCheck {
    /// The verdict for `ratio` over `pairs` pairs, `min_pairs` needed.
    pub fn classify(ratio: f64, pairs: usize, min_pairs: usize) -> GyroScaleCheck {
        let near = |target: f64| (ratio.ln() - target.ln()).abs() <= std::f64::consts::LN_2;
        let scale = if pairs < min_pairs || !(ratio.is_finite() && ratio > 0.0) {
            GyroScale::Inconclusive
        } else if near(1.0) {
            GyroScale::RadiansPerSecond
        } else if near(DEG_PER_RAD) {
            GyroScale::DegreesPerSecond
        } else if near(1.0 / DEG_PER_RAD) {
            GyroScale::RadiansConvertedTwice
        } else {
            GyroScale::Unexplained
        };
        GyroScaleCheck {
            scale,
            ratio,
            pairs,
        }
    }

    /// The verdict in words, with its figures.
    pub fn describe(&self) -> String {
        let what = match self.scale {
            GyroScale::RadiansPerSecond => "rad/s",
            GyroScale::DegreesPerSecond => "deg/s (57.3 times rad/s)",
            GyroScale::RadiansConvertedTwice => "rad/s divided by 57.3 once more",
            GyroScale::Unexplained => "neither rad/s nor deg/s",
            GyroScale::Inconclusive => "not told (too little rotation)",
        };
        if self.pairs == 0 {
            format!("gyro scale {what}")
        } else {
            format!(
                "gyro scale {what}: {:.3} times the reference over {} pairs",
                self.ratio, self.pairs
            )
        }
    }
}

/// The gyro's scale against reference angular rates taken at the same instants (the camera
/// trajectory's `w`, interpolated to the IMU samples' camera times): the median of
/// `|gyro| / |reference|` over the pairs whose reference turns at [`MIN_REFERENCE_RATE`] or
/// faster. The two may be in different frames (norms do not depend on the frame); pairs beyond
/// the shorter slice, and non-finite ones, are left out.
pub fn gyro_scale_against(reference: &[Vector3<f64>], gyro: &[Vector3<f64>]) -> GyroScaleCheck {
    let mut ratios: Vec<f64> = reference
        .iter()
        .zip(gyro)
        .filter(|(r, g)| r.iter().chain(g.iter()).all(|x| x.is_finite()))
        .filter(|(r, _)| r.norm() >= MIN_REFERENCE_RATE)
        .map(|(r, g)| g.norm() / r.norm())
        .collect();
    let ratio = median(&mut ratios);
    GyroScaleCheck::classify(ratio, ratios.len(), MIN_REFERENCE_PAIRS)
}

/// The gyro's scale against gravity turning in the accelerometer's frame: over stretches of
/// [`TILT_WINDOW_S`], the median of the rate the gyro says the specific force's direction turns
/// at (`|w x u|`) over the rate it does turn at, for the pairs of successive stretches that
/// tilt at [`MIN_TILT_RATE`] or more. Samples must be in time order; stretches across a gap
/// are not paired. Works whatever the accelerometer's unit (only its direction counts).
pub fn gyro_scale_from_gravity(samples: &[ImuSample]) -> GyroScaleCheck {
    let inconclusive = GyroScaleCheck::classify(f64::NAN, 0, MIN_TILT_PAIRS);
    let mut dts: Vec<f64> = samples
        .windows(2)
        .map(|w| w[1].t - w[0].t)
        .filter(|d| *d > 0.0)
        .collect();
    let dt = median(&mut dts);
    if !(dt.is_finite() && dt > 0.0) {
        return inconclusive;
    }
    let per_window = ((TILT_WINDOW_S / dt).round() as usize).max(2);
    let mut norms: Vec<f64> = samples.iter().map(|s| s.accel.norm()).collect();
    let typical = median(&mut norms);
    // Each stretch: mean time, mean specific force, mean rate.
    let stretches: Vec<(f64, Vector3<f64>, Vector3<f64>)> = samples
        .chunks_exact(per_window)
        .map(|c| {
            let n = c.len() as f64;
            let t = c.iter().map(|s| s.t).sum::<f64>() / n;
            let f = c.iter().map(|s| s.accel).sum::<Vector3<f64>>() / n;
            let w = c.iter().map(|s| s.gyro).sum::<Vector3<f64>>() / n;
            (t, f, w)
        })
        .collect();
    let mut ratios = Vec::new();
    for pair in stretches.windows(2) {
        let ((t0, f0, w0), (t1, f1, w1)) = (pair[0], pair[1]);
        let span = t1 - t0;
        // A gap between the stretches, or a specific force too weak to give a direction.
        if !(span > 0.0 && span <= 1.5 * per_window as f64 * dt) {
            continue;
        }
        if f0.norm() < 0.5 * typical || f1.norm() < 0.5 * typical {
            continue;
        }
        let (u0, u1) = (f0.normalize(), f1.normalize());
        let tilt = u0.dot(&u1).clamp(-1.0, 1.0).acos() / span;
        if !(tilt.is_finite() && tilt >= MIN_TILT_RATE) {
            continue;
        }
        let u = (u0 + u1).normalize();
        let w = (w0 + w1) * 0.5;
        let said = w.cross(&u).norm();
        if said.is_finite() {
            ratios.push(said / tilt);
        }
    }
    let ratio = median(&mut ratios);
    GyroScaleCheck::classify(ratio, ratios.len(), MIN_TILT_PAIRS)
}

/// What the median norm of a specific force says about the accelerometer's unit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AccelUnit {
    /// 6 to 14: m/s^2, gravity included.
    MetresPerSecondSquared,
    /// 0.6 to 1.4: g.
    G,
    /// 600 to 1400: milli-g.
    MilliG,
    /// 6000 to 14000: mm/s^2.
    MillimetresPerSecondSquared,
    /// Below 0.5: gravity removed (a linear acceleration, not a specific force).
    GravityRemoved,
    /// Anything else.
    Unknown,
}

impl AccelUnit {
    /// The unit the median norm `m` of the specific force points to.
    pub fn from_median_norm(m: f64) -> AccelUnit {
        let g = STANDARD_GRAVITY;
        let within = |lo: f64, hi: f64| (lo..=hi).contains(&m);
        if within(6.0, 14.0) {
            AccelUnit::MetresPerSecondSquared
        } else if within(0.6, 1.4) {
            AccelUnit::G
        } else if within(600.0, 1400.0) {
            AccelUnit::MilliG
        } else if within(6.0e3, 14.0e3) {
            AccelUnit::MillimetresPerSecondSquared
        } else if m.is_finite() && m >= 0.0 && m < 0.05 * g {
            AccelUnit::GravityRemoved
        } else {
            AccelUnit::Unknown
        }
    }

    /// The factor that turns values in this unit into m/s^2 (NaN where there is none).
    pub fn to_si(self) -> f64 {
        match self {
            AccelUnit::MetresPerSecondSquared => 1.0,
            AccelUnit::G => STANDARD_GRAVITY,
            AccelUnit::MilliG => 0.00980665,
            AccelUnit::MillimetresPerSecondSquared => 1e-3,
            AccelUnit::GravityRemoved | AccelUnit::Unknown => f64::NAN,
        }
    }
}

/// The median of `v` (sorted in place; NaN when empty; NaNs sort last).
pub fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The `q` quantile (0..1) of `v`, the value at rank `floor(q (n - 1))` (sorted in place; NaN
/// when empty).
pub fn quantile(v: &mut [f64], q: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let k = ((v.len() - 1) as f64 * q.clamp(0.0, 1.0)).floor() as usize;
    v[k]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(t: f64, gyro: Vector3<f64>, accel: Vector3<f64>) -> ImuSample {
        ImuSample { t, gyro, accel }
    }

    /// An IMU rocking about x at 0.5 rad/s peak, gravity along its z at rest.
    fn rocking(scale: f64) -> Vec<ImuSample> {
        (0..2000)
            .map(|k| {
                let t = k as f64 * 0.005;
                let angle = 0.25 * (2.0 * t).sin();
                let rate = 0.5 * (2.0 * t).cos();
                let up = Vector3::new(0.0, angle.sin(), angle.cos()) * STANDARD_GRAVITY;
                sample(t, Vector3::new(rate * scale, 0.0, 0.0), up)
            })
            .collect()
    }

    #[test]
    fn gravity_tells_radians_from_degrees() {
        let rad = gyro_scale_from_gravity(&rocking(1.0));
        assert_eq!(rad.scale, GyroScale::RadiansPerSecond, "{rad:?}");
        assert!((rad.ratio - 1.0).abs() < 0.05, "{rad:?}");
        assert!(rad.pairs >= 20, "{rad:?}");
        let deg = gyro_scale_from_gravity(&rocking(DEG_PER_RAD));
        assert_eq!(deg.scale, GyroScale::DegreesPerSecond, "{deg:?}");
        assert!((deg.ratio / DEG_PER_RAD - 1.0).abs() < 0.05, "{deg:?}");
    }

    #[test]
    fn a_still_imu_or_a_yawing_one_tells_nothing() {
        let still: Vec<ImuSample> = (0..1000)
            .map(|k| sample(k as f64 * 0.005, Vector3::zeros(), Vector3::z() * 9.8))
            .collect();
        assert_eq!(
            gyro_scale_from_gravity(&still).scale,
            GyroScale::Inconclusive
        );
        // Turning about gravity does not tilt it: no pair qualifies.
        let yaw: Vec<ImuSample> = (0..1000)
            .map(|k| sample(k as f64 * 0.005, Vector3::z() * 30.0, Vector3::z() * 9.8))
            .collect();
        assert_eq!(gyro_scale_from_gravity(&yaw).pairs, 0);
    }

    #[test]
    fn a_reference_gives_the_scale_in_any_frame() {
        // Reference rates, and the gyro's in another frame (a permutation with signs).
        let reference: Vec<Vector3<f64>> = (0..50)
            .map(|k| Vector3::new(0.3 + 0.01 * k as f64, -0.2, 0.1))
            .collect();
        let frame = |v: &Vector3<f64>| Vector3::new(-v.z, v.x, -v.y);
        let rad: Vec<Vector3<f64>> = reference.iter().map(frame).collect();
        let deg: Vec<Vector3<f64>> = rad.iter().map(|v| v * DEG_PER_RAD).collect();
        let twice: Vec<Vector3<f64>> = rad.iter().map(|v| v / DEG_PER_RAD).collect();
        let c = gyro_scale_against(&reference, &rad);
        assert_eq!((c.scale, c.pairs), (GyroScale::RadiansPerSecond, 50));
        assert!((c.ratio - 1.0).abs() < 1e-12);
        let c = gyro_scale_against(&reference, &deg);
        assert_eq!(c.scale, GyroScale::DegreesPerSecond);
        assert!((c.ratio - DEG_PER_RAD).abs() < 1e-9);
        assert!(c.describe().contains("deg/s"), "{}", c.describe());
        let c = gyro_scale_against(&reference, &twice);
        assert_eq!(c.scale, GyroScale::RadiansConvertedTwice);
        let c = gyro_scale_against(&reference, &rad.iter().map(|v| v * 5.0).collect::<Vec<_>>());
        assert_eq!(c.scale, GyroScale::Unexplained);
        // Too slow a reference: no pair counts.
        let slow: Vec<Vector3<f64>> = reference.iter().map(|v| v * 0.1).collect();
        let c = gyro_scale_against(&slow, &rad);
        assert_eq!((c.scale, c.pairs), (GyroScale::Inconclusive, 0));
    }

    #[test]
    fn the_median_norm_names_the_accelerometer_unit() {
        assert_eq!(
            AccelUnit::from_median_norm(9.79),
            AccelUnit::MetresPerSecondSquared
        );
        assert_eq!(AccelUnit::from_median_norm(1.01), AccelUnit::G);
        assert_eq!(AccelUnit::from_median_norm(998.0), AccelUnit::MilliG);
        assert_eq!(
            AccelUnit::from_median_norm(9806.0),
            AccelUnit::MillimetresPerSecondSquared
        );
        assert_eq!(AccelUnit::from_median_norm(0.02), AccelUnit::GravityRemoved);
        assert_eq!(AccelUnit::from_median_norm(3.0), AccelUnit::Unknown);
        assert_eq!(AccelUnit::from_median_norm(f64::NAN), AccelUnit::Unknown);
        assert!((AccelUnit::G.to_si() - 9.80665).abs() < 1e-12);
    }

    #[test]
    fn median_and_quantile_take_ranks() {
        let mut v = vec![5.0, 1.0, 4.0, 2.0, 3.0];
        assert_eq!(median(&mut v), 3.0);
        assert_eq!(quantile(&mut v, 0.99), 4.0);
        assert_eq!(quantile(&mut v, 1.0), 5.0);
        assert!(median(&mut []).is_nan());
    }
}
