//! The motion prior's jerk density along the recording (docs/method.md, "A motion prior that
//! follows the vehicle"): raised where the motion is livelier than the recording's density, kept
//! where one density describes the motion, and never making the calibration worse.

use dvlcal::calib::model::{NPARAM, difference};
use dvlcal::calib::{CalibOptions, calibrate};
use dvlcal::sim::dataset::{MotionKind, SimConfig, simulate};

fn sim(seed: u64, motion: MotionKind) -> dvlcal::sim::SimDataset {
    simulate(&SimConfig {
        seed,
        motion,
        duration_s: 120.0,
        dvl_sigma: 0.01,
        pose_sigma_pos_m: 0.002,
        pose_sigma_rot_rad: 0.1f64.to_radians(),
        ..SimConfig::default()
    })
    .expect("simulation")
}

fn opts(varying: bool) -> CalibOptions {
    CalibOptions {
        varying_motion_prior: varying,
        ..CalibOptions::default()
    }
}

#[test]
fn a_calm_then_rotating_motion_gets_a_higher_rotational_density_where_it_rotates() {
    // The simulated motion's rotational jerk density is 1e-10 for 60 s, then 1 (translation
    // the same throughout): the stretches of the second half are raised, the first half's
    // stay at the base density, which the search set between the two.
    let mut applied = 0;
    for seed in [3001, 3003, 3005] {
        let d = sim(seed, MotionKind::CalmThenRotate);
        let o = calibrate(&d.poses, &d.dvl, &opts(true)).expect("calibration");
        assert!(o.status.is_ok(), "seed {seed}: {:?}", o.status);
        let m = o.motion_prior.as_ref().expect("the density was chosen");
        let (calm, rotating): (Vec<_>, Vec<_>) =
            m.stretches.iter().partition(|s| s.span_s.1 <= 60.0);
        let mean_ln = |v: &[&dvlcal::calib::motion_prior::Stretch], part: usize| {
            v.iter().map(|s| s.factor[part].ln()).sum::<f64>() / v.len() as f64
        };
        assert!(mean_ln(&calm, 1) < 0.05, "seed {seed}: {:?}", m.stretches);
        assert!(
            mean_ln(&rotating, 1) > 0.2,
            "seed {seed}: rotating half's mean log factor {}",
            mean_ln(&rotating, 1)
        );
        assert!(
            m.factor_range()[1].0 >= 1.0 && m.stretches.iter().all(|s| s.factor[0] >= 1.0),
            "factors are never below 1"
        );
        applied += usize::from(m.applied);
        // Kept or not, the result is right within its std.
        let e = difference(&o.params, &d.truth);
        for k in 0..NPARAM {
            let z = e[k] / o.covariance[(k, k)].sqrt();
            assert!(z.abs() < 3.5, "seed {seed}: parameter {k} err/std {z}");
        }
    }
    // The evidence gain exceeds the factors' effective number on most seeds.
    assert!(applied >= 2, "applied on {applied} of 3 seeds");
}

#[test]
fn where_one_density_describes_the_motion_the_result_is_the_constant_prior_s() {
    // Sinusoidal motion: nothing to raise, so the result is exactly the one of the constant
    // density (the stage adds no noise of its own).
    for seed in [11, 12] {
        let d = sim(seed, MotionKind::Sinusoid);
        let varying = calibrate(&d.poses, &d.dvl, &opts(true)).expect("calibration");
        let constant = calibrate(&d.poses, &d.dvl, &opts(false)).expect("calibration");
        let m = varying
            .motion_prior
            .as_ref()
            .expect("the density was chosen");
        assert!(
            !m.applied,
            "seed {seed}: gain {} over {}",
            m.evidence_gain, m.effective_parameters
        );
        assert!(constant.motion_prior.is_none());
        assert_eq!(varying.params, constant.params, "seed {seed}");
        assert_eq!(varying.covariance, constant.covariance, "seed {seed}");
    }
}

#[test]
fn a_density_given_by_the_user_is_kept() {
    let d = sim(3001, MotionKind::CalmThenRotate);
    let mut o = opts(true);
    o.fit.qc = Some(nalgebra::Vector6::new(1e-3, 1e-3, 1e-3, 1e-2, 1e-2, 1e-2));
    let out = calibrate(&d.poses, &d.dvl, &o).expect("calibration");
    assert!(out.motion_prior.is_none());
    assert!(out.fitted.density().is_constant());
}
