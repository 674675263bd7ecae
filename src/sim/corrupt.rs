//! Damage to a simulated dataset of the kinds real recordings suffer, so that a calibration can be
//! measured on data that is not clean.
//!
//! - DVL spikes: a velocity error of fixed size in a random direction added to a report that stays
//!   flagged valid (a fish, a lost beam, a bubble).
//! - Bad camera poses: a pose moved by a fixed translation and rotation (a misdetected tag); it
//!   keeps its stated covariance.
//! - Coloured DVL noise: first-order autoregressive noise in place of the white noise, while the
//!   reports still state white noise.
//! - DVL gaps: stretches without bottom lock, whose reports are flagged invalid with zero velocity.
//! - Pose gaps: stretches without the board in view, whose poses are missing.
//!
//! Everything is drawn from the seed given to [`corrupt`], each kind of damage from its own stream:
//! turning one kind on or off, or changing its strength, leaves the others as they were.

use nalgebra::{Vector3, Vector6};

use super::dataset::{SimDataset, dvl_model};
use crate::error::{Error, Result};
use crate::lie::so3;
use crate::rng::Rng;

/// Stream numbers of [`Rng::stream`] used here (apart from the motion's and the dataset's).
const STREAM_DVL_AR1: u64 = 21;
const STREAM_DVL_SPIKES: u64 = 22;
const STREAM_POSE_OUTLIERS: u64 = 23;

/// The damage [`corrupt`] does to a dataset. The default does none.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Corruption {
    /// Fraction of DVL reports (0..1) that get a spike: a velocity error of `dvl_spike_mps`
    /// magnitude in a uniformly random 3-D direction added to the report (a fish, a lost beam, a
    /// bubble). The report stays flagged valid and keeps its stated covariance.
    pub dvl_spike_fraction: f64,
    /// Magnitude of a DVL spike, m/s.
    pub dvl_spike_mps: f64,
    /// Fraction of camera poses (0..1) replaced by a bad pose: the measured pose perturbed on the
    /// right by a translation of magnitude `pose_outlier_pos_m` and a rotation of angle
    /// `pose_outlier_rot_rad`, each along/about a uniformly random direction (a misdetected tag).
    /// The pose keeps its stated covariance.
    pub pose_outlier_fraction: f64,
    /// Translation of a bad pose relative to the measured one, metres (camera frame).
    pub pose_outlier_pos_m: f64,
    /// Rotation angle of a bad pose relative to the measured one, radians (at most pi).
    pub pose_outlier_rot_rad: f64,
    /// When `Some(tau)`: the DVL noise is replaced by first-order autoregressive noise of the
    /// same per-axis standard deviation `dvl_sigma` (the argument of [`corrupt`]) and correlation
    /// time `tau` seconds: `n_k = a n_{k-1} + sqrt(1 - a^2) sigma e_k` with
    /// `a = exp(-(t_k - t_{k-1}) / tau)`, `n_0 ~ N(0, sigma^2)`. The reports are rebuilt as the
    /// noise-free reading ([`dvl_model`] of the true twist) plus this noise. The stated covariance
    /// is left as it was (`sigma^2 I` for a simulated dataset: the recording claims white noise).
    pub dvl_ar1_tau_s: Option<f64>,
    /// Stretches where the DVL lost bottom lock: `(start, duration)` in DVL-clock seconds; the
    /// reports with `start <= t < start + duration` are flagged invalid (`valid = false`) and
    /// their velocity set to zero, as the A50 does.
    pub dvl_gaps: Vec<(f64, f64)>,
    /// Stretches where the board was out of view: `(start, duration)` in camera-clock seconds;
    /// the poses with `start <= t < start + duration` are removed (and their entries of
    /// `truth_poses` too, so the two stay aligned).
    pub pose_gaps: Vec<(f64, f64)>,
}

impl Corruption {
    /// Checks the settings: fractions in `[0, 1]`, magnitudes finite and non-negative (the
    /// rotation angle at most pi), `tau` finite and positive, gaps with finite start and finite
    /// positive duration. The error ([`Error::Input`]) names the field.
    pub fn validate(&self) -> Result<()> {
        let fraction = |name: &str, x: f64| {
            if (0.0..=1.0).contains(&x) {
                Ok(())
            } else {
                Err(Error::Input(format!("{name} must be in [0, 1], got {x}")))
            }
        };
        let magnitude = |name: &str, x: f64| {
            if x.is_finite() && x >= 0.0 {
                Ok(())
            } else {
                Err(Error::Input(format!(
                    "{name} must be non-negative and finite, got {x}"
                )))
            }
        };
        let gaps = |name: &str, gaps: &[(f64, f64)]| {
            for (i, &(start, duration)) in gaps.iter().enumerate() {
                if !(start.is_finite()
                    && duration.is_finite()
                    && duration > 0.0
                    && (start + duration).is_finite())
                {
                    return Err(Error::Input(format!(
                        "{name}[{i}] must have a finite start and a finite positive duration, \
                         got ({start}, {duration})"
                    )));
                }
            }
            Ok(())
        };
        fraction("dvl_spike_fraction", self.dvl_spike_fraction)?;
        magnitude("dvl_spike_mps", self.dvl_spike_mps)?;
        fraction("pose_outlier_fraction", self.pose_outlier_fraction)?;
        magnitude("pose_outlier_pos_m", self.pose_outlier_pos_m)?;
        magnitude("pose_outlier_rot_rad", self.pose_outlier_rot_rad)?;
        if self.pose_outlier_rot_rad > std::f64::consts::PI {
            return Err(Error::Input(format!(
                "pose_outlier_rot_rad must be at most pi, got {}",
                self.pose_outlier_rot_rad
            )));
        }
        if let Some(tau) = self.dvl_ar1_tau_s {
            if !(tau.is_finite() && tau > 0.0) {
                return Err(Error::Input(format!(
                    "dvl_ar1_tau_s must be positive and finite, got {tau}"
                )));
            }
        }
        gaps("dvl_gaps", &self.dvl_gaps)?;
        gaps("pose_gaps", &self.pose_gaps)?;
        Ok(())
    }
}

/// What [`corrupt`] did to a dataset.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct CorruptionLog {
    /// Indices (into `ds.dvl`) of the reports given a spike, ascending. A report that a DVL gap
    /// then flagged invalid is not listed (its spike is gone).
    pub dvl_spiked: Vec<usize>,
    /// Indices (into `ds.poses` after pose gaps were cut) of the poses replaced by bad ones,
    /// ascending. A bad pose that a pose gap then removed is not listed.
    pub bad_poses: Vec<usize>,
    /// Number of DVL reports inside a DVL gap (each counted once).
    pub dvl_in_gaps: usize,
    /// Number of poses removed by pose gaps.
    pub poses_removed: usize,
}

/// Whether `t` lies in one of the `(start, duration)` stretches, `start <= t < start + duration`.
fn in_gaps(t: f64, gaps: &[(f64, f64)]) -> bool {
    gaps.iter()
        .any(|&(start, duration)| t >= start && t < start + duration)
}

/// A direction drawn uniformly on the unit sphere.
fn unit_direction(rng: &mut Rng) -> Vector3<f64> {
    loop {
        let z = rng.normal_vec3();
        let n = z.norm();
        if n > 1e-12 {
            return z / n;
        }
    }
}

/// Damages `ds` as `c` describes, drawing from streams of `seed`; the same arguments always give
/// bit-identical output. The damage is applied in this order: AR(1) noise, spikes, DVL gaps, pose
/// outliers, pose gaps. `dvl_sigma` is the per-axis standard deviation of the white DVL noise the
/// dataset was simulated with (`SimConfig::dvl_sigma`), the standard deviation of the AR(1) noise.
///
/// Which reports get a spike and which poses are replaced is decided by one uniform draw per
/// sample (below the fraction), so their counts are binomial; reports already flagged invalid are
/// left alone. The AR(1) noise rebuilds only reports flagged valid (an invalid report keeps its
/// zero velocity).
///
/// Errors ([`Error::Input`]): invalid settings ([`Corruption::validate`]), a negative or
/// non-finite `dvl_sigma`, and, when the damage needs them, DVL truth or pose truth not aligned
/// with the measurements or DVL times that are not finite and non-decreasing. On error `ds` is
/// unchanged.
pub fn corrupt(
    ds: &mut SimDataset,
    c: &Corruption,
    dvl_sigma: f64,
    seed: u64,
) -> Result<CorruptionLog> {
    c.validate()?;
    if !(dvl_sigma.is_finite() && dvl_sigma >= 0.0) {
        return Err(Error::Input(format!(
            "dvl_sigma must be non-negative and finite, got {dvl_sigma}"
        )));
    }
    if c.dvl_ar1_tau_s.is_some() {
        if ds.dvl.len() != ds.dvl_truth.len() {
            return Err(Error::Input(format!(
                "AR(1) DVL noise needs one true state per DVL report ({} reports, {} states)",
                ds.dvl.len(),
                ds.dvl_truth.len()
            )));
        }
        let ordered =
            ds.dvl.iter().all(|s| s.t.is_finite()) && ds.dvl.windows(2).all(|w| w[1].t >= w[0].t);
        if !ordered {
            return Err(Error::Input(
                "AR(1) DVL noise needs finite, non-decreasing DVL times".into(),
            ));
        }
    }
    if !c.pose_gaps.is_empty() && ds.poses.len() != ds.truth_poses.len() {
        return Err(Error::Input(format!(
            "pose gaps need one true state per pose ({} poses, {} states)",
            ds.poses.len(),
            ds.truth_poses.len()
        )));
    }

    let mut log = CorruptionLog::default();

    // AR(1) DVL noise.
    if let Some(tau) = c.dvl_ar1_tau_s {
        let mut rng = Rng::stream(seed, STREAM_DVL_AR1);
        let mut noise = Vector3::zeros();
        let mut t_prev: Option<f64> = None;
        for (sample, state) in ds.dvl.iter_mut().zip(&ds.dvl_truth) {
            let e = rng.normal_vec3();
            noise = match t_prev {
                None => e * dvl_sigma,
                Some(t0) => {
                    let a: f64 = (-(sample.t - t0) / tau).exp();
                    noise * a + e * ((1.0 - a * a).sqrt() * dvl_sigma)
                }
            };
            t_prev = Some(sample.t);
            if sample.valid {
                sample.v = dvl_model(&ds.truth, &state.twist) + noise;
            }
        }
    }

    // DVL spikes.
    let mut spiked = Vec::new();
    if c.dvl_spike_fraction > 0.0 {
        let mut rng = Rng::stream(seed, STREAM_DVL_SPIKES);
        for (i, sample) in ds.dvl.iter_mut().enumerate() {
            if rng.uniform() < c.dvl_spike_fraction {
                let dir = unit_direction(&mut rng);
                if sample.valid {
                    sample.v += dir * c.dvl_spike_mps;
                    spiked.push(i);
                }
            }
        }
    }

    // DVL gaps.
    if !c.dvl_gaps.is_empty() {
        for sample in ds.dvl.iter_mut() {
            if in_gaps(sample.t, &c.dvl_gaps) {
                sample.valid = false;
                sample.v = Vector3::zeros();
                log.dvl_in_gaps += 1;
            }
        }
    }
    log.dvl_spiked = spiked
        .into_iter()
        .filter(|&i| !in_gaps(ds.dvl[i].t, &c.dvl_gaps))
        .collect();

    // Pose outliers.
    let mut bad = vec![false; ds.poses.len()];
    if c.pose_outlier_fraction > 0.0 {
        let mut rng = Rng::stream(seed, STREAM_POSE_OUTLIERS);
        for (p, is_bad) in ds.poses.iter_mut().zip(bad.iter_mut()) {
            if rng.uniform() < c.pose_outlier_fraction {
                let trans = unit_direction(&mut rng) * c.pose_outlier_pos_m;
                let phi = unit_direction(&mut rng) * c.pose_outlier_rot_rad;
                // exp([rho; phi]) translates by J_l(phi) rho: choose rho so that the translation
                // is exactly `trans`.
                let rho = so3::left_jacobian_inv(&phi) * trans;
                let xi = Vector6::new(rho.x, rho.y, rho.z, phi.x, phi.y, phi.z);
                p.pose = p.pose.retract(&xi);
                *is_bad = true;
            }
        }
    }

    // Pose gaps.
    if c.pose_gaps.is_empty() {
        log.bad_poses = (0..bad.len()).filter(|&k| bad[k]).collect();
    } else {
        let keep: Vec<bool> = ds
            .poses
            .iter()
            .map(|p| !in_gaps(p.t, &c.pose_gaps))
            .collect();
        let mut kept = 0;
        for (k, &kp) in keep.iter().enumerate() {
            if kp {
                if bad[k] {
                    log.bad_poses.push(kept);
                }
                kept += 1;
            }
        }
        log.poses_removed = keep.len() - kept;
        ds.poses = std::mem::take(&mut ds.poses)
            .into_iter()
            .zip(&keep)
            .filter_map(|(p, &k)| k.then_some(p))
            .collect();
        ds.truth_poses = std::mem::take(&mut ds.truth_poses)
            .into_iter()
            .zip(&keep)
            .filter_map(|(s, &k)| k.then_some(s))
            .collect();
    }

    Ok(log)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lie::Se3;
    use crate::sim::{MotionKind, SimConfig, simulate};
    use crate::types::{DvlSample, PoseMeasurement};
    use nalgebra::Matrix3;

    /// The stated DVL covariance of a simulated dataset with white noise `sigma`: `sigma^2 I`.
    fn white_cov(sigma: f64) -> Matrix3<f64> {
        Matrix3::identity() * (sigma * sigma)
    }

    fn dataset(duration_s: f64, motion: MotionKind) -> SimDataset {
        simulate(&SimConfig {
            duration_s,
            motion,
            ..SimConfig::default()
        })
        .unwrap()
    }

    fn bits3(v: &Vector3<f64>) -> Vec<u64> {
        v.iter().map(|x| x.to_bits()).collect()
    }

    fn same_dvl(a: &DvlSample, b: &DvlSample) -> bool {
        a.t.to_bits() == b.t.to_bits()
            && bits3(&a.v) == bits3(&b.v)
            && a.valid == b.valid
            && a.cov
                .map(|m| m.iter().map(|x| x.to_bits()).collect::<Vec<_>>())
                == b.cov
                    .map(|m| m.iter().map(|x| x.to_bits()).collect::<Vec<_>>())
    }

    fn same_se3(a: &Se3, b: &Se3) -> bool {
        a.rot
            .iter()
            .zip(b.rot.iter())
            .all(|(x, y)| x.to_bits() == y.to_bits())
            && bits3(&a.trans) == bits3(&b.trans)
    }

    fn same_pose(a: &PoseMeasurement, b: &PoseMeasurement) -> bool {
        a.t.to_bits() == b.t.to_bits()
            && same_se3(&a.pose, &b.pose)
            && a.cov
                .map(|m| m.iter().map(|x| x.to_bits()).collect::<Vec<_>>())
                == b.cov
                    .map(|m| m.iter().map(|x| x.to_bits()).collect::<Vec<_>>())
    }

    fn same_dataset(a: &SimDataset, b: &SimDataset) -> bool {
        a.dvl.len() == b.dvl.len()
            && a.poses.len() == b.poses.len()
            && a.truth_poses.len() == b.truth_poses.len()
            && a.dvl.iter().zip(&b.dvl).all(|(x, y)| same_dvl(x, y))
            && a.poses.iter().zip(&b.poses).all(|(x, y)| same_pose(x, y))
            && a.truth_poses
                .iter()
                .zip(&b.truth_poses)
                .all(|(x, y)| same_se3(&x.pose, &y.pose))
    }

    /// Whether `count` successes of `n` trials at `p` lie within 4 standard deviations.
    fn binomial_ok(count: usize, n: usize, p: f64) -> bool {
        let mean = n as f64 * p;
        let sd = (n as f64 * p * (1.0 - p)).sqrt();
        (count as f64 - mean).abs() <= 4.0 * sd
    }

    fn everything() -> Corruption {
        Corruption {
            dvl_spike_fraction: 0.05,
            dvl_spike_mps: 0.3,
            pose_outlier_fraction: 0.05,
            pose_outlier_pos_m: 0.2,
            pose_outlier_rot_rad: 0.1,
            dvl_ar1_tau_s: Some(1.5),
            dvl_gaps: vec![(12.0, 4.0)],
            pose_gaps: vec![(30.0, 2.5), (45.0, 1.0)],
        }
    }

    #[test]
    fn default_leaves_the_dataset_unchanged() {
        let original = dataset(60.0, MotionKind::default());
        let mut ds = original.clone();
        let log = corrupt(&mut ds, &Corruption::default(), 0.01, 5).unwrap();
        assert_eq!(log, CorruptionLog::default());
        assert!(same_dataset(&ds, &original));
    }

    #[test]
    fn spikes_are_binomial_and_of_the_stated_size() {
        let original = dataset(60.0, MotionKind::default());
        let mut ds = original.clone();
        let c = Corruption {
            dvl_spike_fraction: 0.03,
            dvl_spike_mps: 0.4,
            ..Corruption::default()
        };
        let log = corrupt(&mut ds, &c, 0.01, 7).unwrap();
        let n = ds.dvl.len();
        assert!(n > 500, "{n} reports");
        assert!(
            binomial_ok(log.dvl_spiked.len(), n, 0.03),
            "{} spikes of {n}",
            log.dvl_spiked.len()
        );
        assert!(!log.dvl_spiked.is_empty());
        for (i, (new, old)) in ds.dvl.iter().zip(&original.dvl).enumerate() {
            if log.dvl_spiked.contains(&i) {
                assert!(((new.v - old.v).norm() - 0.4).abs() < 1e-12, "report {i}");
                assert!(new.valid);
                assert_eq!(new.t.to_bits(), old.t.to_bits());
                assert_eq!(new.cov, old.cov);
            } else {
                assert!(same_dvl(new, old), "report {i} changed");
            }
        }
    }

    #[test]
    fn bad_poses_move_by_the_stated_translation_and_angle() {
        let original = dataset(60.0, MotionKind::default());
        let mut ds = original.clone();
        let c = Corruption {
            pose_outlier_fraction: 0.1,
            pose_outlier_pos_m: 0.3,
            pose_outlier_rot_rad: 0.25,
            ..Corruption::default()
        };
        let log = corrupt(&mut ds, &c, 0.01, 9).unwrap();
        assert_eq!(ds.poses.len(), original.poses.len());
        assert!(binomial_ok(log.bad_poses.len(), ds.poses.len(), 0.1));
        assert!(!log.bad_poses.is_empty());
        for (k, (new, old)) in ds.poses.iter().zip(&original.poses).enumerate() {
            if log.bad_poses.contains(&k) {
                let delta = old.pose.inverse() * new.pose;
                assert!((delta.trans.norm() - 0.3).abs() < 1e-12, "pose {k}");
                assert!(
                    (so3::log(&delta.rot).norm() - 0.25).abs() < 1e-12,
                    "pose {k}"
                );
                assert_eq!(new.t.to_bits(), old.t.to_bits());
                assert_eq!(new.cov, old.cov);
            } else {
                assert!(same_pose(new, old), "pose {k} changed");
            }
        }
        assert!(same_dataset(
            &SimDataset {
                poses: original.poses.clone(),
                ..ds.clone()
            },
            &original
        ));
    }

    #[test]
    fn ar1_noise_has_the_stated_spread_and_correlation() {
        let sigma = 0.01;
        let original = simulate(&SimConfig {
            duration_s: 2000.0,
            dvl_sigma: sigma,
            motion: MotionKind::Sinusoid,
            ..SimConfig::default()
        })
        .unwrap();
        // Reports 0.1 s apart (10 Hz, 2 ms jitter): lag-1 autocorrelation exp(-0.1 / tau).
        for tau in [2.0, 1.0] {
            let mut ds = original.clone();
            let c = Corruption {
                dvl_ar1_tau_s: Some(tau),
                ..Corruption::default()
            };
            let log = corrupt(&mut ds, &c, sigma, 3).unwrap();
            assert_eq!(log, CorruptionLog::default());
            let noise: Vec<Vector3<f64>> = ds
                .dvl
                .iter()
                .zip(&ds.dvl_truth)
                .map(|(s, st)| s.v - dvl_model(&ds.truth, &st.twist))
                .collect();
            let n = noise.len();
            assert!(n > 19_000, "{n} reports");
            for s in &ds.dvl {
                assert!(s.valid);
                assert_eq!(s.cov, Some(white_cov(sigma)));
            }
            let expected = (-0.1 / tau).exp();
            for axis in 0..3 {
                let x: Vec<f64> = noise.iter().map(|v| v[axis]).collect();
                let mean = x.iter().sum::<f64>() / n as f64;
                let var = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64;
                let std = var.sqrt();
                assert!(
                    (std / sigma - 1.0).abs() < 0.1,
                    "tau {tau}, axis {axis}: std {std}"
                );
                let lag1 = x
                    .windows(2)
                    .map(|w| (w[0] - mean) * (w[1] - mean))
                    .sum::<f64>()
                    / n as f64
                    / var;
                assert!(
                    (lag1 - expected).abs() < 0.03,
                    "tau {tau}, axis {axis}: lag-1 autocorrelation {lag1}, expected {expected}"
                );
            }
        }
    }

    #[test]
    fn gaps_flag_and_remove_exactly_the_samples_inside() {
        let original = dataset(60.0, MotionKind::default());
        let mut ds = original.clone();
        let dvl_gaps = vec![(9.95, 5.0), (14.0, 3.05), (40.03, 0.5)];
        let pose_gaps = vec![(20.0, 3.05), (49.95, 0.1)];
        let c = Corruption {
            dvl_spike_fraction: 0.2,
            dvl_spike_mps: 0.5,
            pose_outlier_fraction: 0.2,
            pose_outlier_pos_m: 0.1,
            pose_outlier_rot_rad: 0.1,
            dvl_gaps: dvl_gaps.clone(),
            pose_gaps: pose_gaps.clone(),
            ..Corruption::default()
        };
        let log = corrupt(&mut ds, &c, 0.01, 11).unwrap();

        let inside = |t: f64, gaps: &[(f64, f64)]| gaps.iter().any(|&(s, d)| s <= t && t < s + d);
        let mut in_gap = 0;
        for (i, (new, old)) in ds.dvl.iter().zip(&original.dvl).enumerate() {
            if inside(old.t, &dvl_gaps) {
                in_gap += 1;
                assert!(!new.valid, "report {i}");
                assert_eq!(new.v, Vector3::zeros());
                assert!(!log.dvl_spiked.contains(&i));
            } else {
                assert!(new.valid, "report {i}");
                assert_eq!(log.dvl_spiked.contains(&i), new.v != old.v, "report {i}");
            }
        }
        // 10.0 s .. 17.0 s at 10 Hz (overlapping gaps count once), and 40.1 s .. 40.5 s.
        assert_eq!(in_gap, 76);
        assert_eq!(log.dvl_in_gaps, in_gap);

        // Without the gaps, the same poses are bad; cutting them keeps the rest in order.
        let mut no_gaps = original.clone();
        let log_no_gaps = corrupt(
            &mut no_gaps,
            &Corruption {
                dvl_gaps: vec![],
                pose_gaps: vec![],
                ..c.clone()
            },
            0.01,
            11,
        )
        .unwrap();
        let kept: Vec<usize> = (0..original.poses.len())
            .filter(|&k| !inside(original.poses[k].t, &pose_gaps))
            .collect();
        // 20.0 .. 23.0 and 50.0 (10 Hz).
        assert_eq!(original.poses.len() - kept.len(), 32);
        assert_eq!(log.poses_removed, 32);
        assert_eq!(ds.poses.len(), kept.len());
        assert_eq!(ds.truth_poses.len(), kept.len());
        for (new_k, &k) in kept.iter().enumerate() {
            assert!(same_pose(&ds.poses[new_k], &no_gaps.poses[k]));
            assert!(same_se3(
                &ds.truth_poses[new_k].pose,
                &original.truth_poses[k].pose
            ));
            assert_eq!(
                log.bad_poses.contains(&new_k),
                log_no_gaps.bad_poses.contains(&k)
            );
        }
    }

    #[test]
    fn validate_rejects_bad_settings() {
        let err = Corruption {
            dvl_spike_fraction: 1.5,
            ..Corruption::default()
        }
        .validate()
        .unwrap_err();
        assert!(
            matches!(&err, Error::Input(m) if m.contains("dvl_spike_fraction")),
            "{err}"
        );
        let err = Corruption {
            dvl_ar1_tau_s: Some(-1.0),
            ..Corruption::default()
        }
        .validate()
        .unwrap_err();
        assert!(
            matches!(&err, Error::Input(m) if m.contains("dvl_ar1_tau_s")),
            "{err}"
        );
        for c in [
            Corruption {
                pose_outlier_fraction: f64::NAN,
                ..Corruption::default()
            },
            Corruption {
                dvl_spike_mps: -0.1,
                ..Corruption::default()
            },
            Corruption {
                pose_outlier_rot_rad: 4.0,
                ..Corruption::default()
            },
            Corruption {
                dvl_gaps: vec![(1.0, 0.0)],
                ..Corruption::default()
            },
            Corruption {
                pose_gaps: vec![(f64::INFINITY, 1.0)],
                ..Corruption::default()
            },
        ] {
            assert!(matches!(c.validate(), Err(Error::Input(_))), "{c:?}");
        }
        assert!(Corruption::default().validate().is_ok());
        assert!(everything().validate().is_ok());

        // A rejected corruption leaves the dataset alone.
        let original = dataset(20.0, MotionKind::default());
        let mut ds = original.clone();
        let bad = Corruption {
            dvl_gaps: vec![(1.0, -2.0)],
            ..everything()
        };
        assert!(corrupt(&mut ds, &bad, 0.01, 1).is_err());
        assert!(corrupt(&mut ds, &everything(), f64::NAN, 1).is_err());
        assert!(same_dataset(&ds, &original));
    }

    #[test]
    fn same_seed_same_output() {
        let original = dataset(60.0, MotionKind::default());
        let mut a = original.clone();
        let mut b = original.clone();
        let mut other = original.clone();
        let log_a = corrupt(&mut a, &everything(), 0.01, 42).unwrap();
        let log_b = corrupt(&mut b, &everything(), 0.01, 42).unwrap();
        let log_other = corrupt(&mut other, &everything(), 0.01, 43).unwrap();
        assert_eq!(log_a, log_b);
        assert!(same_dataset(&a, &b));
        assert!(!same_dataset(&a, &other));
        assert_ne!(log_a.dvl_spiked, log_other.dvl_spiked);
    }

    #[test]
    fn kinds_of_damage_draw_independently() {
        let original = dataset(60.0, MotionKind::default());
        let spikes = Corruption {
            dvl_spike_fraction: 0.05,
            dvl_spike_mps: 0.3,
            ..Corruption::default()
        };
        let outliers = Corruption {
            pose_outlier_fraction: 0.05,
            pose_outlier_pos_m: 0.2,
            pose_outlier_rot_rad: 0.1,
            ..Corruption::default()
        };
        let all = Corruption {
            dvl_gaps: vec![],
            pose_gaps: vec![],
            ..everything()
        };
        let run = |c: &Corruption| {
            let mut ds = original.clone();
            let log = corrupt(&mut ds, c, 0.01, 8).unwrap();
            (ds, log)
        };
        let (ds_spikes, log_spikes) = run(&spikes);
        let (ds_outliers, log_outliers) = run(&outliers);
        let (ds_all, log_all) = run(&all);
        assert_eq!(log_all.dvl_spiked, log_spikes.dvl_spiked);
        assert_eq!(log_all.bad_poses, log_outliers.bad_poses);
        assert!(
            ds_all
                .poses
                .iter()
                .zip(&ds_outliers.poses)
                .all(|(a, b)| same_pose(a, b))
        );
        assert!(
            ds_spikes
                .poses
                .iter()
                .zip(&original.poses)
                .all(|(a, b)| same_pose(a, b))
        );
        // The spike vectors are the same whatever noise they are added to.
        let (ar_only, _) = run(&Corruption {
            dvl_ar1_tau_s: all.dvl_ar1_tau_s,
            ..Corruption::default()
        });
        for &i in &log_spikes.dvl_spiked {
            let without_ar = ds_spikes.dvl[i].v - original.dvl[i].v;
            let with_ar = ds_all.dvl[i].v - ar_only.dvl[i].v;
            assert!((without_ar - with_ar).norm() < 1e-12, "report {i}");
        }
    }
}
