//! Calibration on simulated data with known truth: accuracy against the reported uncertainty,
//! observability verdicts, fallbacks and bad input.

use dvlcal::calib::model::{NPARAM, difference};
use dvlcal::calib::offset::OffsetMethod;
use dvlcal::calib::{CalibOptions, CalibrationOutcome, Method, calibrate};
use dvlcal::lie::so3;
use dvlcal::sim::dataset::{MotionKind, SimConfig, SimDataset, simulate};
use dvlcal::types::CalibrationParams;
use nalgebra::{SVector, Vector3};

fn dataset(seed: u64, motion: MotionKind, duration: f64) -> SimDataset {
    simulate(&SimConfig {
        seed,
        motion,
        duration_s: duration,
        ..SimConfig::default()
    })
    .expect("simulation")
}

/// Error of an estimate in the parameterisation of the covariance.
fn error(est: &CalibrationParams, truth: &CalibrationParams) -> SVector<f64, NPARAM> {
    difference(est, truth)
}

fn nees(o: &CalibrationOutcome, truth: &CalibrationParams) -> f64 {
    let e = error(&o.params, truth);
    let info = o.covariance.try_inverse().expect("invertible covariance");
    (e.transpose() * info * e)[0]
}

#[test]
fn errors_are_consistent_with_reported_uncertainty_over_seeds() {
    // Sum over seeds of the 8-dof NEES is chi-square with 8 * seeds dof when the covariance is
    // honest. With 10 seeds (80 dof) the two-sided 99.9% interval of chi2_80 / 80 is
    // [0.58, 1.55].
    let seeds = 1..=10u64;
    let mut total = 0.0;
    let mut count = 0;
    for seed in seeds {
        let ds = dataset(seed, MotionKind::CalmThenRotate, 60.0);
        let truth = ds.truth;
        let o = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("calibration");
        let n = nees(&o, &truth);
        eprintln!(
            "seed {seed}: NEES {n:.2}; offset {:.4} (std {:.4}), lever {:?}",
            o.params.time_offset_s,
            o.std.time_offset_s,
            o.params.lever_arm_cam_m().as_slice()
        );
        assert!(
            o.verdicts.rotation.ok && o.verdicts.lever_arm.ok,
            "seed {seed}: {:?}",
            o.verdicts
        );
        assert!(o.verdicts.time_offset.ok && o.verdicts.velocity_scale.ok);
        total += n;
        count += NPARAM;
    }
    let mean = total / count as f64;
    assert!(
        (0.58..=1.55).contains(&mean),
        "mean NEES per dof {mean:.3} outside the 99.9% chi-square interval"
    );
}

#[test]
fn weak_rotation_flags_the_lever_arm_but_keeps_the_rest() {
    let ds = dataset(3, MotionKind::WeakRotation, 60.0);
    let truth = ds.truth;
    let o = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("calibration");
    assert!(
        !o.verdicts.lever_arm.ok,
        "lever arm should be weak: {:?}",
        o.std
    );
    assert!(o.verdicts.lever_arm.reason.contains("rotated too little"));
    assert!(o.verdicts.rotation.ok && o.verdicts.velocity_scale.ok && o.verdicts.time_offset.ok);
    let e = error(&o.params, &truth);
    // Rotation, scale and offset within four reported standard deviations.
    for k in [0, 1, 2, 6, 7] {
        let sd = o.covariance[(k, k)].sqrt();
        assert!(
            e[k].abs() < 4.0 * sd,
            "param {k}: error {} vs std {sd}",
            e[k]
        );
    }
    assert!(e.fixed_rows::<3>(0).norm().to_degrees() < 0.5);
    assert!(e[7].abs() < 0.01);
}

#[test]
fn motion_without_calm_segment_falls_back_and_says_so() {
    let ds = dataset(2, MotionKind::Sinusoid, 40.0);
    let truth = ds.truth;
    let o = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("calibration");
    let init = o.init.as_ref().expect("UIC has an init report");
    assert_eq!(init.offset.method, OffsetMethod::SpeedCorrelation);
    assert!(o.warnings.iter().any(|w| w.contains("speed magnitudes")));
    let e = error(&o.params, &truth);
    assert!(e[7].abs() < 0.01, "offset error {}", e[7]);
    assert!(e.fixed_rows::<3>(3).norm() < 0.01);
}

#[test]
fn bcd_from_a_rough_guess_reaches_the_uic_answer() {
    let ds = dataset(4, MotionKind::CalmThenRotate, 60.0);
    let truth = ds.truth;
    let uic = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).unwrap();
    let guess = CalibrationParams::from_r_dvl_cam(
        so3::exp(&Vector3::new(0.05, -0.04, 0.03)) * truth.r_dvl_cam(),
        truth.lever_arm_cam_m() + Vector3::new(0.05, -0.05, 0.05),
        1.0,
        0.0,
    );
    let bcd = calibrate(
        &ds.poses,
        &ds.dvl,
        &CalibOptions {
            method: Method::Bcd(guess),
            ..CalibOptions::default()
        },
    )
    .unwrap();
    let d = error(&bcd.params, &uic.params);
    for k in 0..NPARAM {
        let sd = uic.covariance[(k, k)].sqrt();
        assert!(
            d[k].abs() < 0.05 * sd + 1e-9,
            "param {k}: {} vs std {sd}",
            d[k]
        );
    }
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let ds = dataset(5, MotionKind::CalmThenRotate, 30.0);
    let opts = CalibOptions::default();
    // Empty and too short logs.
    assert!(calibrate(&ds.poses, &[], &opts).is_err());
    assert!(calibrate(&ds.poses, &ds.dvl[..5], &opts).is_err());
    // No valid reports.
    let mut invalid = ds.dvl.clone();
    invalid.iter_mut().for_each(|s| s.valid = false);
    let e = calibrate(&ds.poses, &invalid, &opts)
        .unwrap_err()
        .to_string();
    assert!(e.contains("valid"), "{e}");
    // Logs that cannot overlap by the shortest overlap considered (10 s) at any clock offset:
    // five seconds of DVL reports.
    let short: Vec<_> = ds.dvl.iter().filter(|s| s.t < 5.0).cloned().collect();
    let e = calibrate(&ds.poses, &short, &opts).unwrap_err();
    assert!(matches!(e, dvlcal::Error::NoTimeOverlap(_)), "{e:?}");
    assert!(e.to_string().contains("overlap"), "{e}");
    // Too few poses.
    assert!(calibrate(&ds.poses[..2], &ds.dvl, &opts).is_err());
}

#[test]
fn a_still_camera_gives_an_error_or_weak_verdicts() {
    // The camera does not move: every parameter is unobservable.
    let mut ds = dataset(6, MotionKind::CalmThenRotate, 30.0);
    let first = ds.poses[0].pose;
    ds.poses.iter_mut().for_each(|p| p.pose = first);
    ds.dvl
        .iter_mut()
        .for_each(|s| s.v = Vector3::new(0.001, -0.002, 0.0005));
    match calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()) {
        Err(e) => assert!(!e.to_string().is_empty()),
        Ok(o) => {
            assert!(!o.verdicts.rotation.ok);
            assert!(!o.verdicts.lever_arm.ok);
        }
    }
}

/// Every message of an outcome: warnings, verdict reasons and failure reasons.
fn messages(o: &CalibrationOutcome) -> Vec<String> {
    let mut m = o.warnings.clone();
    let v = &o.verdicts;
    for r in [&v.rotation, &v.lever_arm, &v.time_offset, &v.velocity_scale] {
        m.push(r.reason.clone());
    }
    if let dvlcal::calib::Status::Failed(r) = &o.status {
        m.extend(r.iter().cloned());
    }
    m
}

#[test]
fn the_estimator_names_its_settings_in_its_own_words_or_the_callers() {
    use dvlcal::calib::Setting;
    // Extrinsics held at a guess whose lever arm is 30 cm off: the messages say what to run
    // instead and how the held parameters were given.
    let data = dataset(4, MotionKind::CalmThenRotate, 60.0);
    let t = &data.truth;
    let wrong = CalibrationParams::from_r_dvl_cam(
        t.r_dvl_cam(),
        t.lever_arm_cam_m() + Vector3::new(0.3, 0.0, 0.0),
        t.velocity_scale,
        t.time_offset_s,
    );
    let held = CalibOptions {
        method: Method::Fixed {
            guess: wrong,
            estimate_offset: true,
        },
        ..CalibOptions::default()
    };
    let o = calibrate(&data.poses, &data.dvl, &held).expect("calibration");
    let all = messages(&o);
    assert!(
        all.iter().any(|m| m.contains("method Method::Uic")),
        "{all:#?}"
    );
    assert!(
        all.iter().any(|m| m.contains("the method's guess")),
        "{all:#?}"
    );
    assert!(
        all.iter().all(|m| !m.contains("--")),
        "a flag in a library message: {all:#?}"
    );
    // A caller's words replace the field names.
    fn words(s: Setting) -> &'static str {
        match s {
            Setting::Uic => "UIC-WORDS",
            Setting::Guess => "GUESS-WORDS",
            other => other.field(),
        }
    }
    let o = calibrate(
        &data.poses,
        &data.dvl,
        &CalibOptions {
            names: words,
            ..held
        },
    )
    .expect("calibration");
    let all = messages(&o);
    assert!(all.iter().any(|m| m.contains("UIC-WORDS")), "{all:#?}");
    assert!(all.iter().any(|m| m.contains("GUESS-WORDS")), "{all:#?}");
    assert!(all.iter().all(|m| !m.contains("Method::Uic")), "{all:#?}");
    // So do the errors of the settings' checks.
    let bad = CalibOptions {
        dvl_sigma: Some(-1.0),
        ..CalibOptions::default()
    };
    let e = calibrate(&data.poses, &data.dvl, &bad).expect_err("bad sigma");
    assert_eq!(e.to_string(), "dvl_sigma must be positive");
    let mut bad = CalibOptions::default();
    bad.offset.range = Some((0.5, -0.5));
    let e = calibrate(&data.poses, &data.dvl, &bad).expect_err("bad range");
    assert_eq!(
        e.to_string(),
        "offset.range takes two increasing values: min,max"
    );
    assert_eq!(
        Setting::from_field("offset.range"),
        Some(Setting::OffsetRange)
    );
    for s in Setting::ALL {
        assert_eq!(Setting::from_field(s.field()), Some(s), "{s:?}");
    }
}

#[test]
fn the_offset_range_bounds_the_refinement_too() {
    // The truth's offset is 0.07 s; a range that ends at 0.03 s excludes it.
    let data = dataset(2, MotionKind::CalmThenRotate, 60.0);
    let truth = data.truth.time_offset_s;
    assert!((truth - 0.07).abs() < 1e-12, "{truth}");
    let mut opts = CalibOptions::default();
    opts.offset.range = Some((-0.5, 0.03));
    let o = calibrate(&data.poses, &data.dvl, &opts).expect("calibration");
    assert!(o.params.time_offset_s <= 0.03, "{}", o.params.time_offset_s);
    let failed = match &o.status {
        dvlcal::calib::Status::Failed(r) => r.join("; "),
        dvlcal::calib::Status::Ok => String::new(),
    };
    assert!(failed.contains("offset.range"), "{failed}");
    // Started from a guess (the truth), the refinement stays inside the range and says why the
    // result cannot be trusted.
    let opts = CalibOptions {
        method: Method::Bcd(data.truth),
        ..opts
    };
    let o = calibrate(&data.poses, &data.dvl, &opts).expect("calibration");
    assert!(o.params.time_offset_s <= 0.03, "{}", o.params.time_offset_s);
    let failed = match &o.status {
        dvlcal::calib::Status::Failed(r) => r.join("; "),
        dvlcal::calib::Status::Ok => String::new(),
    };
    assert!(
        failed.contains("ended on a bound of offset.range"),
        "{failed}"
    );
    // A range around the truth that the search's window lies inside changes nothing.
    let mut around = CalibOptions::default();
    around.offset.range = Some((-5.0, 5.0));
    let a = calibrate(&data.poses, &data.dvl, &around).expect("calibration");
    let b = calibrate(&data.poses, &data.dvl, &CalibOptions::default()).expect("calibration");
    assert_eq!(a.params, b.params);
    assert!(a.status.is_ok());
}

/// The truth with its lever arm moved by `dp` and its rotation turned by `dphi` (rad, about the
/// DVL axes).
fn moved(t: &CalibrationParams, dp: Vector3<f64>, dphi: Vector3<f64>) -> CalibrationParams {
    CalibrationParams::from_r_dvl_cam(
        so3::exp(&dphi) * t.r_dvl_cam(),
        t.lever_arm_cam_m() + dp,
        t.velocity_scale,
        t.time_offset_s,
    )
}

fn reasons(o: &CalibrationOutcome) -> String {
    match &o.status {
        dvlcal::calib::Status::Failed(r) => r.join("; "),
        dvlcal::calib::Status::Ok => "ok".into(),
    }
}

#[test]
fn given_values_are_checked_for_their_units_and_against_the_data() {
    let data = dataset(6, MotionKind::CalmThenRotate, 60.0);
    let t = data.truth;
    let fixed = |guess: CalibrationParams| CalibOptions {
        method: Method::Fixed {
            guess,
            estimate_offset: true,
        },
        ..CalibOptions::default()
    };
    // Millimetres given as metres: an error that says so, with the value in metres.
    let mm = CalibrationParams::from_r_dvl_cam(
        t.r_dvl_cam(),
        t.lever_arm_cam_m() * 1000.0,
        t.velocity_scale,
        t.time_offset_s,
    );
    let e = calibrate(&data.poses, &data.dvl, &fixed(mm)).expect_err("mm as m");
    let msg = e.to_string();
    assert!(msg.contains("the method's guess has a lever arm"), "{msg}");
    assert!(msg.contains("millimetres given as metres"), "{msg}");
    // The truth held: no contradiction, a usable result.
    let o = calibrate(&data.poses, &data.dvl, &fixed(t)).expect("calibration");
    assert!(o.contradicted.is_empty(), "{:?}", o.contradicted);
    assert!(o.status.is_ok(), "{}", reasons(&o));
    // A lever arm 5 cm off: the failure names the lever arm first.
    let o = calibrate(
        &data.poses,
        &data.dvl,
        &fixed(moved(&t, Vector3::new(0.05, 0.0, 0.0), Vector3::zeros())),
    )
    .expect("calibration");
    let r = reasons(&o);
    assert!(
        r.starts_with("the data contradict the given lever arm"),
        "{r}"
    );
    assert_eq!(o.contradicted[0].what, "lever arm");
    // Freed, it returns to about the truth: +50 mm on x.
    assert!(
        (o.contradicted[0].moved[0] + 50.0).abs() < 10.0,
        "{:?}",
        o.contradicted[0]
    );
    // A rotation 4 degrees off: the rotation is named.
    let o = calibrate(
        &data.poses,
        &data.dvl,
        &fixed(moved(
            &t,
            Vector3::zeros(),
            Vector3::new(0.0, 0.0, 4f64.to_radians()),
        )),
    )
    .expect("calibration");
    assert!(
        o.contradicted.iter().any(|c| c.what == "rotation"),
        "{}",
        reasons(&o)
    );
    assert!(
        reasons(&o).starts_with("the data contradict the given rotation"),
        "{}",
        reasons(&o)
    );
    // Unusual values of a guess to refine from, and a prior that says nothing, are warnings.
    let far = moved(&t, Vector3::new(4.0, 0.0, 0.0), Vector3::zeros());
    let mut opts = CalibOptions {
        method: Method::Bcd(far),
        ..CalibOptions::default()
    };
    opts.priors.lever_arm = Some(dvlcal::calib::prior::LeverArmPrior {
        lever_arm_cam_m: t.lever_arm_cam_m(),
        sigma_m: 20.0,
    });
    let o = calibrate(&data.poses, &data.dvl, &opts).expect("calibration");
    assert!(
        o.warnings
            .iter()
            .any(|w| w.contains("lever arm 4.") && w.contains("check its units")),
        "{:#?}",
        o.warnings
    );
    assert!(
        o.warnings.iter().any(|w| w.contains("constrains nothing")),
        "{:#?}",
        o.warnings
    );
}
