//! Noise levels estimated, not trusted: a DVL noise stated ten times too small or too large is
//! found by the variance components of the joint estimate, and the standard deviations stay
//! honest (docs/method.md, "Noise levels").

use dvlcal::calib::model::{NPARAM, difference};
use dvlcal::calib::{CalibOptions, calibrate};
use dvlcal::sim::dataset::{MotionKind, SimConfig, simulate};

const TRUE_SIGMA: f64 = 0.01;
const SEEDS: u64 = 6;

/// For each seed: the DVL's variance component (the data's variance over the stated), the
/// factor applied to the stated variances, and the normalised errors `err / std`.
fn runs(stated_sigma: f64) -> Vec<(f64, f64, [f64; NPARAM])> {
    (1..=SEEDS)
        .map(|seed| {
            let d = simulate(&SimConfig {
                seed: 500 + seed,
                motion: MotionKind::CalmThenRotate,
                duration_s: 60.0,
                dvl_sigma: TRUE_SIGMA,
                ..SimConfig::default()
            })
            .expect("simulation");
            let o = calibrate(
                &d.poses,
                &d.dvl,
                &CalibOptions {
                    dvl_sigma: Some(stated_sigma),
                    ..CalibOptions::default()
                },
            )
            .expect("calibration");
            assert!(o.status.is_ok(), "seed {seed}: {:?}", o.status);
            let e = difference(&o.params, &d.truth);
            let mut z = [0.0; NPARAM];
            for k in 0..NPARAM {
                z[k] = e[k] / o.covariance[(k, k)].sqrt();
            }
            (o.noise.dvl.total(), o.noise.dvl.applied, z)
        })
        .collect()
}

/// The mean of `z^2` over every seed and parameter (1 when the standard deviations are honest).
fn mean_square(r: &[(f64, f64, [f64; NPARAM])]) -> f64 {
    let n = (r.len() * NPARAM) as f64;
    r.iter().flat_map(|x| x.2).map(|z| z * z).sum::<f64>() / n
}

#[test]
fn a_dvl_noise_stated_ten_times_too_small_is_found_and_weighed_right() {
    let r = runs(0.1 * TRUE_SIGMA);
    for (seed, (component, applied, _)) in r.iter().enumerate() {
        // The variance is 100 times the stated one.
        assert!(
            (60.0..160.0).contains(component),
            "seed {seed}: variance component {component}"
        );
        assert!(*applied > 30.0, "seed {seed}: applied {applied}");
    }
    let ms = mean_square(&r);
    // 48 values of a chi-square with one degree of freedom each (correlated within a seed):
    // honest standard deviations give a mean near 1; the stated noise unchecked gives ~100.
    assert!((0.3..2.5).contains(&ms), "mean z^2 {ms}");
}

#[test]
fn a_dvl_noise_stated_ten_times_too_large_is_found_and_weighed_right() {
    let r = runs(10.0 * TRUE_SIGMA);
    for (seed, (component, applied, _)) in r.iter().enumerate() {
        assert!(
            (0.006..0.016).contains(component),
            "seed {seed}: variance component {component}"
        );
        assert!(*applied < 0.05, "seed {seed}: applied {applied}");
    }
    let ms = mean_square(&r);
    // Unchecked, the standard deviations would be ten times too large (mean z^2 near 0.01).
    assert!((0.3..2.5).contains(&ms), "mean z^2 {ms}");
}

#[test]
fn a_dvl_noise_stated_right_is_left_as_stated() {
    let r = runs(TRUE_SIGMA);
    for (seed, (component, applied, _)) in r.iter().enumerate() {
        assert!(
            (0.6..1.6).contains(component),
            "seed {seed}: variance component {component}"
        );
        assert_eq!(*applied, 1.0, "seed {seed}");
    }
    let ms = mean_square(&r);
    assert!((0.3..2.5).contains(&ms), "mean z^2 {ms}");
}
