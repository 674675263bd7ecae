//! The calibration on damaged recordings: DVL spikes and bad camera poses are down-weighted by
//! the robust loss (and counted), clean data are calibrated exactly as by least squares,
//! correlated DVL noise and a calibration that changed mid-recording inflate the covariance so
//! that it covers the error, a weakly observed lever arm is left to the data, and one the motion
//! does not observe at all should be held by the broad default prior (ignored: it is not).

use dvlcal::calib::model::difference;
use dvlcal::calib::robust::Loss;
use dvlcal::calib::{CalibOptions, CalibrationOutcome, DeterminedBy, calibrate};
use dvlcal::lie::so3;
use dvlcal::sim::{
    Corruption, CorruptionLog, MotionKind, SimConfig, SimDataset, corrupt, simulate,
};

/// The default simulation (60 s, CalmThenRotate unless `motion` says otherwise) of `seed`.
fn sim(seed: u64, motion: MotionKind) -> SimDataset {
    simulate(&SimConfig {
        seed,
        motion,
        ..SimConfig::default()
    })
    .expect("simulation")
}

fn run(ds: &SimDataset, opts: &CalibOptions) -> CalibrationOutcome {
    calibrate(&ds.poses, &ds.dvl, opts).expect("calibration")
}

fn with_loss(loss: Loss) -> CalibOptions {
    CalibOptions {
        loss,
        ..CalibOptions::default()
    }
}

/// 3 % of the DVL reports with a 0.3 m/s spike (30 times the noise) and 1 % of the poses moved by
/// 5 cm and 3 deg.
fn spikes_and_bad_poses() -> Corruption {
    Corruption {
        dvl_spike_fraction: 0.03,
        dvl_spike_mps: 0.3,
        pose_outlier_fraction: 0.01,
        pose_outlier_pos_m: 0.05,
        pose_outlier_rot_rad: 3f64.to_radians(),
        ..Corruption::default()
    }
}

fn damaged(seed: u64, c: &Corruption) -> (SimDataset, CorruptionLog) {
    let mut ds = sim(seed, MotionKind::CalmThenRotate);
    let log = corrupt(&mut ds, c, SimConfig::default().dvl_sigma, seed).expect("corruption");
    (ds, log)
}

/// Errors of an estimate: rotation (deg, angle), lever arm (m, norm), scale, clock offset (s).
fn errors(o: &CalibrationOutcome, ds: &SimDataset) -> [f64; 4] {
    let d = difference(&o.params, &ds.truth);
    [
        d.fixed_rows::<3>(0).norm().to_degrees(),
        d.fixed_rows::<3>(3).norm(),
        d[6].abs(),
        d[7].abs(),
    ]
}

/// Root mean square over the runs, per quantity.
fn rmse(errs: &[[f64; 4]]) -> [f64; 4] {
    let mut out = [0.0; 4];
    for (k, o) in out.iter_mut().enumerate() {
        *o = (errs.iter().map(|e| e[k] * e[k]).sum::<f64>() / errs.len() as f64).sqrt();
    }
    out
}

/// Each parameter's error in its reported standard deviations.
fn z_scores(o: &CalibrationOutcome, ds: &SimDataset) -> [f64; 8] {
    let d = difference(&o.params, &ds.truth);
    std::array::from_fn(|k| d[k] / o.covariance[(k, k)].sqrt())
}

const QUANTITIES: [&str; 4] = ["rotation deg", "lever arm m", "scale", "offset s"];

#[test]
fn spikes_and_bad_poses_cost_little_and_are_counted() {
    let c = spikes_and_bad_poses();
    let (mut clean, mut robust, mut l2) = (Vec::new(), Vec::new(), Vec::new());
    for seed in 1..=4 {
        let ds = sim(seed, MotionKind::CalmThenRotate);
        clean.push(errors(&run(&ds, &CalibOptions::default()), &ds));
        let (bad, log) = damaged(seed, &c);
        let o = run(&bad, &CalibOptions::default());
        robust.push(errors(&o, &bad));
        l2.push(errors(&run(&bad, &with_loss(Loss::L2)), &bad));

        // Every report is valid, so observation i is report i.
        assert_eq!(o.observations.len(), bad.dvl.len());
        let down: Vec<usize> = o
            .used
            .iter()
            .copied()
            .filter(|&i| o.robust.dvl_weights[i] < 0.5)
            .collect();
        let spiked_used: Vec<usize> = log
            .dvl_spiked
            .iter()
            .copied()
            .filter(|i| o.used.contains(i))
            .collect();
        let caught = spiked_used.iter().filter(|i| down.contains(i)).count();
        let true_down = down.iter().filter(|i| log.dvl_spiked.contains(i)).count();
        let bad_caught = log
            .bad_poses
            .iter()
            .filter(|&&i| o.robust.pose_weights[i] < 0.5)
            .count();
        let clean_down = (0..bad.poses.len())
            .filter(|&i| o.robust.pose_weights[i] < 0.5 && !log.bad_poses.contains(&i))
            .count();
        println!(
            "seed {seed}: DVL spikes {} ({} used), {caught} of them down-weighted; {} \
             down-weighted, {true_down} of them spikes (counts: {} down-weighted, {} screened); \
             bad poses {}, {bad_caught} down-weighted; clean poses down-weighted {clean_down} \
             (count {})",
            log.dvl_spiked.len(),
            spiked_used.len(),
            down.len(),
            o.counts.dvl_downweighted,
            o.counts.dvl_spikes_screened,
            log.bad_poses.len(),
            o.counts.poses_downweighted
        );
        assert!(!spiked_used.is_empty() && !log.bad_poses.is_empty());
        assert!(
            caught as f64 >= 0.8 * spiked_used.len() as f64,
            "seed {seed}: {caught} of {} used spikes down-weighted",
            spiked_used.len()
        );
        assert!(
            true_down as f64 >= 0.9 * down.len() as f64,
            "seed {seed}: {true_down} of {} down-weighted reports are spikes",
            down.len()
        );
        assert!(
            bad_caught as f64 >= 0.8 * log.bad_poses.len() as f64,
            "seed {seed}: {bad_caught} of {} bad poses down-weighted",
            log.bad_poses.len()
        );
        assert!(
            clean_down <= 2,
            "seed {seed}: {clean_down} clean poses down-weighted"
        );
        // The counts report what the weights did: outliers lie beyond the threshold, where the
        // weight is below one half, and the spikes and bad poses are most of them.
        let counted = o.counts.dvl_downweighted;
        assert!(
            counted as f64 >= 0.8 * spiked_used.len() as f64 && counted <= down.len(),
            "seed {seed}: {counted} DVL reports counted as down-weighted"
        );
        let counted = o.counts.poses_downweighted;
        assert!(
            counted as f64 >= 0.8 * log.bad_poses.len() as f64
                && counted <= log.bad_poses.len() + 2,
            "seed {seed}: {counted} poses counted as down-weighted"
        );
    }
    let (clean, robust, l2) = (rmse(&clean), rmse(&robust), rmse(&l2));
    for k in 0..4 {
        println!(
            "RMSE {:>12}: clean {:.3e}, robust {:.3e} ({:.2}x), least squares {:.3e} ({:.2}x)",
            QUANTITIES[k],
            clean[k],
            robust[k],
            robust[k] / clean[k],
            l2[k],
            l2[k] / clean[k]
        );
    }
    for k in 0..4 {
        // No absolute slack is needed: on these seeds the damage costs at most a third of the
        // clean RMSE (the scale, 1.33 times), inside the factor.
        assert!(
            robust[k] <= 1.5 * clean[k],
            "{}: robust RMSE {:.3e} against clean {:.3e}",
            QUANTITIES[k],
            robust[k],
            clean[k]
        );
    }
    // Least squares follows the outliers: the same damage costs the scale and the offset more
    // than twice their clean error.
    for k in [2, 3] {
        assert!(
            l2[k] >= 2.0 * clean[k],
            "{}: least-squares RMSE {:.3e} against clean {:.3e}",
            QUANTITIES[k],
            l2[k],
            clean[k]
        );
    }
}

#[test]
fn least_squares_keeps_outliers_and_says_so() {
    let (bad, log) = damaged(5, &spikes_and_bad_poses());
    let o = run(&bad, &with_loss(Loss::L2));
    println!(
        "spikes {}, bad poses {}; applied {:?}/{:?}, outliers {}/{}; warnings {:#?}",
        log.dvl_spiked.len(),
        log.bad_poses.len(),
        o.robust.dvl.applied,
        o.robust.poses.applied,
        o.robust.dvl.outliers,
        o.robust.poses.outliers,
        o.warnings
    );
    assert_eq!(o.robust.loss, Loss::L2);
    assert_eq!(o.robust.dvl.applied, None);
    assert_eq!(o.robust.poses.applied, None);
    assert!(o.robust.dvl_weights.iter().all(|&w| w == 1.0));
    assert!(o.robust.pose_weights.iter().all(|&w| w == 1.0));
    // The spikes are still found and reported, only not down-weighted.
    assert!(o.robust.dvl.outliers > 0, "{:?}", o.robust.dvl);
    assert!(
        o.warnings
            .iter()
            .any(|w| w.contains("kept at full weight (loss Loss::L2)")),
        "{:#?}",
        o.warnings
    );
}

#[test]
fn clean_data_are_calibrated_as_by_least_squares() {
    // The halves check is a three-sigma test of five compared parameters, so a clean recording
    // is flagged now and then: of seeds 11 to 40, seed 12 alone (clock offset, 4.1 standard
    // deviations). These seeds are not among the flagged.
    for seed in 13..=15 {
        let ds = sim(seed, MotionKind::CalmThenRotate);
        let robust = run(&ds, &CalibOptions::default());
        let l2 = run(&ds, &with_loss(Loss::L2));
        println!(
            "seed {seed}: applied {:?}/{:?}, outliers {}/{}, screened {}, tau {:?}, halves {:?}",
            robust.robust.dvl.applied,
            robust.robust.poses.applied,
            robust.robust.dvl.outliers,
            robust.robust.poses.outliers,
            robust.counts.dvl_spikes_screened,
            robust.whiteness.tau,
            robust.halves.as_ref().map(|h| h.inflation)
        );
        let bits = |o: &CalibrationOutcome| {
            let p = &o.params;
            let q = so3::quaternion_from_matrix(&p.r_dvl_cam());
            let l = p.lever_arm_cam_m();
            let mut v: Vec<u64> = q.iter().map(|x| x.to_bits()).collect();
            v.extend(l.iter().map(|x| x.to_bits()));
            v.push(p.velocity_scale.to_bits());
            v.push(p.time_offset_s.to_bits());
            v
        };
        assert_eq!(bits(&robust), bits(&l2), "seed {seed}: parameters differ");
        let cov_bits = |o: &CalibrationOutcome| -> Vec<u64> {
            o.covariance.iter().map(|x| x.to_bits()).collect()
        };
        assert_eq!(
            cov_bits(&robust),
            cov_bits(&l2),
            "seed {seed}: covariances differ"
        );
        assert_eq!(robust.robust.dvl.applied, None);
        assert_eq!(robust.counts.dvl_downweighted, 0);
        assert_eq!(robust.counts.poses_downweighted, 0);
        assert!(!robust.whiteness.correlated, "{:?}", robust.whiteness.tau);
        let h = robust.halves.as_ref().expect("halves check");
        assert!(h.inflation.iter().all(|&f| f == 1.0), "{:?}", h.inflation);
    }
}

#[test]
fn correlated_dvl_noise_inflates_the_covariance() {
    // AR(1) noise with a 1 s correlation time at 10 Hz: a = exp(-0.1), integrated
    // autocorrelation time (1 + a) / (1 - a) = 20.0 samples.
    let a = (-0.1f64).exp();
    let tau_true = (1.0 + a) / (1.0 - a);
    let c = Corruption {
        dvl_ar1_tau_s: Some(1.0),
        ..Corruption::default()
    };
    let model_only = CalibOptions {
        honest_covariance: false,
        ..CalibOptions::default()
    };
    let (mut honest, mut naive) = (Vec::new(), Vec::new());
    for seed in 21..=26 {
        let (ds, _) = damaged(seed, &c);
        let o = run(&ds, &CalibOptions::default());
        let m = run(&ds, &model_only);
        let (zo, zm) = (z_scores(&o, &ds), z_scores(&m, &ds));
        println!(
            "seed {seed}: tau {:.1?} (true {tau_true:.1}), inflation {:.1}, halves {:?}\n  \
             err/std honest {zo:.2?}\n  err/std model  {zm:.2?}",
            o.whiteness.tau,
            o.whiteness.inflation,
            o.halves.as_ref().map(|h| h.inflation),
        );
        assert!(o.whiteness.correlated, "seed {seed}: {:?}", o.whiteness.tau);
        assert!(
            (5.0..=40.0).contains(&o.whiteness.inflation),
            "seed {seed}: inflation {}",
            o.whiteness.inflation
        );
        honest.extend(zo);
        naive.extend(zm);
    }
    let rms = |z: &[f64]| (z.iter().map(|x| x * x).sum::<f64>() / z.len() as f64).sqrt();
    let (h, n) = (rms(&honest), rms(&naive));
    println!("RMS err/std over 6 seeds x 8 parameters: honest {h:.2}, model only {n:.2}");
    assert!((0.4..=2.0).contains(&h), "honest RMS err/std {h}");
    assert!(n > 2.0, "model-only RMS err/std {n}");
}

#[test]
fn a_changed_calibration_between_halves_is_flagged() {
    // The lever arm moves 5 cm along x half way through: the DVL reports from 30 s on come from
    // the same motion and noise with the moved lever arm. The motion rotates throughout, so each
    // half determines the lever arm on its own.
    let seed = 5;
    let motion = MotionKind::Sinusoid;
    let first = sim(seed, motion);
    let mut moved = SimConfig::default_truth();
    moved.t_cam_dvl.trans.x += 0.05;
    let second = simulate(&SimConfig {
        seed,
        motion,
        truth: moved,
        ..SimConfig::default()
    })
    .expect("simulation");
    assert_eq!(first.dvl.len(), second.dvl.len());
    let mut ds = first.clone();
    for (s, later) in ds.dvl.iter_mut().zip(&second.dvl) {
        assert_eq!(s.t, later.t);
        if s.t >= 30.0 {
            *s = later.clone();
        }
    }
    let o = run(&ds, &CalibOptions::default());
    let h = o.halves.as_ref().expect("halves check");
    let x = o.params.lever_arm_cam_m().x;
    let std_x = o.std.lever_arm_m.x;
    let err_x = (x - first.truth.lever_arm_cam_m().x)
        .abs()
        .max((x - moved.lever_arm_cam_m().x).abs());
    println!(
        "halves: difference x {:.4} m ({:.1} std), inflation {:.1?}; lever arm x {x:.4} m \
         (truths {:.3}, {:.3}), std {std_x:.4} m against the larger error {err_x:.4} m; verdict \
         {:?}",
        h.difference[3],
        h.z(3),
        h.inflation,
        first.truth.lever_arm_cam_m().x,
        moved.lever_arm_cam_m().x,
        o.verdicts.lever_arm
    );
    assert!(h.compared[3]);
    assert!(h.inflation[3] > 1.0, "{:?}", h.inflation);
    assert!(!o.verdicts.lever_arm.ok);
    assert!(
        o.verdicts.lever_arm.reason.contains("halves"),
        "{}",
        o.verdicts.lever_arm.reason
    );
    assert!(
        std_x >= 0.5 * err_x,
        "lever arm x std {std_x} against error {err_x}"
    );
}

#[test]
fn a_weakly_observed_lever_arm_is_left_to_the_data() {
    // Weak rotation (about 0.035 rad/s) observes the lever arm to about 1.5 cm: too loose for
    // the verdict, far inside the broad default prior, which must then change nothing.
    for seed in 1..=2 {
        let ds = sim(seed, MotionKind::WeakRotation);
        let o = run(&ds, &CalibOptions::default());
        let free = run(
            &ds,
            &CalibOptions {
                default_lever_arm_sigma_m: None,
                ..CalibOptions::default()
            },
        );
        let z = z_scores(&o, &ds);
        let moved = (o.params.lever_arm_cam_m() - free.params.lever_arm_cam_m()).norm();
        println!(
            "seed {seed}: lever arm {:.4?} m, std {:.4?} m, from the default prior {}; without \
             the prior it moves {moved:.2e} m; err/std {z:.2?}; cost {:.3}",
            o.params.lever_arm_cam_m().as_slice(),
            o.std.lever_arm_m.as_slice(),
            o.lever_arm_from_default_prior,
            o.normalized_cost
        );
        assert!(!o.lever_arm_from_default_prior);
        assert!(!o.verdicts.lever_arm.ok);
        assert!(
            z.iter().all(|x| x.abs() < 4.0),
            "seed {seed}: err/std {z:?}"
        );
        assert!(o.params.lever_arm_cam_m().norm() < 1.5);
        // A 1 m prior on a lever arm known to 1.5 cm moves it by a small fraction of its std.
        assert!(
            moved < 0.05 * o.std.lever_arm_m.min(),
            "seed {seed}: the default prior moved the lever arm {moved} m"
        );
    }
}

/// The first half of [`MotionKind::CalmThenRotate`] alone (DVL reports before 30 s; the poses
/// of the whole minute): the camera hardly rotates while the DVL measures, and the DVL says
/// nothing about the lever arm.
fn calm_only(seed: u64) -> SimDataset {
    let mut ds = sim(seed, MotionKind::CalmThenRotate);
    let keep: Vec<bool> = ds.dvl.iter().map(|s| s.t < 30.0).collect();
    let mut k = keep.iter();
    ds.dvl.retain(|_| *k.next().expect("one flag per report"));
    let mut k = keep.iter();
    ds.dvl_truth
        .retain(|_| *k.next().expect("one flag per report"));
    ds
}

#[test]
fn an_unobserved_lever_arm_comes_from_the_default_prior() {
    let mut outcomes = Vec::new();
    for seed in 1..=4 {
        let ds = calm_only(seed);
        let o = run(&ds, &CalibOptions::default());
        let without = run(
            &ds,
            &CalibOptions {
                default_lever_arm_sigma_m: None,
                ..CalibOptions::default()
            },
        );
        for (name, r) in [("default prior", &o), ("no prior", &without)] {
            println!(
                "seed {seed} {name}: lever arm {:.3?} m (|p| {:.2} m), std {:.3?} m, from the \
                 default prior {}, normalized cost {:.3}, err/std {:.2?}",
                r.params.lever_arm_cam_m().as_slice(),
                r.params.lever_arm_cam_m().norm(),
                r.std.lever_arm_m.as_slice(),
                r.lever_arm_from_default_prior,
                r.normalized_cost,
                z_scores(r, &ds)
            );
        }
        // Without the prior the lever arm runs off: the angular velocity, mostly noise, bends
        // to fit the DVL noise through a long lever arm. (The residuals of that fit are
        // correlated, and reweighing the reports by the information they carry slows the run
        // but does not stop it: 0.8 m on seed 3, against a truth of 0.28 m.)
        assert!(
            without.params.lever_arm_cam_m().norm() > 0.5,
            "seed {seed}: {:?}",
            without.params.lever_arm_cam_m()
        );
        outcomes.push((seed, ds, o));
    }
    for (seed, ds, o) in &outcomes {
        let z = z_scores(o, ds);
        // Rotation, scale and clock offset are observed and stay honest.
        for k in [0, 1, 2, 6, 7] {
            assert!(z[k].abs() < 4.0, "seed {seed}: err/std {z:?}");
        }
        assert!(!o.verdicts.lever_arm.ok);
        assert!(o.lever_arm_from_default_prior, "seed {seed}");
        assert_eq!(o.verdicts.lever_arm.by, DeterminedBy::Prior, "seed {seed}");
        assert!(
            o.verdicts.lever_arm.reason.contains("prior"),
            "{}",
            o.verdicts.lever_arm.reason
        );
    }
    for (seed, ds, o) in &outcomes {
        let z = z_scores(o, ds);
        let p = o.params.lever_arm_cam_m();
        // What the prior is for: the lever arm stays near zero, and its std covers its error.
        assert!(p.norm() < 1.5, "seed {seed}: lever arm {p:?}");
        for k in 3..6 {
            assert!(z[k].abs() < 4.0, "seed {seed}: err/std {z:?}");
        }
    }
}

#[test]
fn a_recording_that_is_mostly_outliers_fails_instead_of_being_down_weighted() {
    // 3 % spikes are outliers; 40 % are a DVL that does not describe the camera's motion.
    let (few, _) = damaged(21, &spikes_and_bad_poses());
    let o = run(&few, &CalibOptions::default());
    assert!(o.status.is_ok(), "{:?}", o.status);
    let many = Corruption {
        dvl_spike_fraction: 0.4,
        dvl_spike_mps: 0.3,
        ..Corruption::default()
    };
    let (bad, log) = damaged(21, &many);
    for opts in [CalibOptions::default(), with_loss(Loss::L2)] {
        let o = run(&bad, &opts);
        let share = o.robust.dvl.outliers as f64 / o.robust.dvl.factors as f64;
        assert!(
            share > 0.25,
            "{} of {}",
            o.robust.dvl.outliers,
            log.dvl_spiked.len()
        );
        let reasons = match &o.status {
            dvlcal::calib::Status::Failed(r) => r.join(" "),
            dvlcal::calib::Status::Ok => panic!("{:?}: passed with {share} outliers", opts.loss),
        };
        assert!(reasons.contains("outliers to the fit"), "{reasons}");
    }
}
