//! Clocks far apart or drifting, and results that cannot be trusted: the global alignment finds
//! any clock offset without help, logs that do not overlap say so, periodic motion is flagged as
//! ambiguous, a drifting clock is detected, and the sanity checks fail loudly on a DVL log of
//! another recording, poses in the wrong frame or in the wrong units.

use dvlcal::calib::model::{NPARAM, difference};
use dvlcal::calib::{CalibOptions, CalibrationOutcome, Status, calibrate};
use dvlcal::lie::Se3;
use dvlcal::sim::dataset::{MotionKind, SimConfig, SimDataset, simulate, simulate_with};
use dvlcal::sim::motion::{SinusoidMotion, SinusoidTerm};
use nalgebra::Vector3;

fn config(seed: u64, offset: f64, duration: f64, motion: MotionKind) -> SimConfig {
    let mut cfg = SimConfig {
        seed,
        duration_s: duration,
        motion,
        ..SimConfig::default()
    };
    cfg.truth.time_offset_s = offset;
    cfg
}

fn recording(seed: u64, offset: f64, duration: f64, motion: MotionKind) -> SimDataset {
    simulate(&config(seed, offset, duration, motion)).expect("simulation")
}

/// Largest |error| / std over the eight parameters.
fn worst_z(o: &CalibrationOutcome, ds: &SimDataset) -> f64 {
    let e = difference(&o.params, &ds.truth);
    (0..NPARAM)
        .map(|k| (e[k] / o.covariance[(k, k)].sqrt()).abs())
        .fold(0.0, f64::max)
}

#[test]
fn any_clock_offset_is_found_without_help() {
    // 2.5 s and 37 s (leap seconds), ten minutes, a DVL clock 1e8 s off (an A50 without NTP),
    // and a DVL counting from zero against a Unix camera clock (1.7e9 s).
    for &offset in &[2.5, 37.0, -600.0, 1e8, 1.7e9] {
        for seed in 1..=3u64 {
            let ds = recording(seed, offset, 120.0, MotionKind::CalmThenRotate);
            let o = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("calibration");
            let a = &o
                .init
                .as_ref()
                .expect("UIC initialisation")
                .offset
                .alignment;
            let z = worst_z(&o, &ds);
            println!(
                "offset {offset}: seed {seed}: lag {:.3} (corr {:.3}, uniqueness {:.2}), \
                 estimate {:.5}, worst error {z:.2} std",
                a.lag_s,
                a.correlation,
                a.uniqueness(),
                o.params.time_offset_s
            );
            assert!(
                (a.lag_s - offset).abs() < 0.5,
                "lag {} for {offset}",
                a.lag_s
            );
            assert!(
                o.status.is_ok(),
                "offset {offset} seed {seed}: {:?}",
                o.status
            );
            // Every parameter within 4 std (8 parameters x 15 runs: a 4-sigma excursion of any
            // of them has probability below 1 %).
            assert!(
                z < 4.0,
                "offset {offset} seed {seed}: an error of {z:.2} std"
            );
        }
    }
}

#[test]
fn a_short_recording_with_the_dvl_clock_far_ahead_is_aligned() {
    // 30 s of data with the DVL's clock 1000 s ahead of the camera's: the logs overlap only at
    // the right offset.
    let ds = recording(5, -1000.0 + 0.07, 30.0, MotionKind::CalmThenRotate);
    let o = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("calibration");
    assert!(
        (o.params.time_offset_s - ds.truth.time_offset_s).abs() < 0.01,
        "offset {} against {}",
        o.params.time_offset_s,
        ds.truth.time_offset_s
    );
    assert!(o.status.is_ok(), "{:?}", o.status);
}

#[test]
fn logs_that_cannot_overlap_are_an_error() {
    let ds = recording(6, 0.07, 60.0, MotionKind::CalmThenRotate);
    // Eight seconds of DVL reports: shorter than the shortest overlap a lag needs (10 s).
    let short: Vec<_> = ds.dvl.iter().filter(|s| s.t < 8.0).cloned().collect();
    let e = calibrate(&ds.poses, &short, &CalibOptions::default()).unwrap_err();
    assert!(matches!(e, dvlcal::Error::NoTimeOverlap(_)), "{e:?}");
    // A limit that excludes every offset at which the logs overlap.
    let mut opts = CalibOptions::default();
    opts.offset.range = Some((500.0, 600.0));
    let e = calibrate(&ds.poses, &ds.dvl, &opts).unwrap_err();
    assert!(matches!(e, dvlcal::Error::NoTimeOverlap(_)), "{e:?}");
    assert!(e.to_string().contains("[500, 600]"), "{e}");
}

#[test]
fn periodic_motion_makes_the_offset_ambiguous_and_says_so() {
    // Translation and rotation repeating every 5 s: the speeds match at every multiple of the
    // period.
    let f = 0.2;
    let motion = SinusoidMotion {
        duration_s: 90.0,
        position_offset: Vector3::zeros(),
        position: vec![SinusoidTerm::new(
            [0.3, 0.2, 0.1],
            [f, 2.0 * f, f],
            [0.0, 0.5, 1.0],
        )],
        rotation_offset: Vector3::zeros(),
        rotation: vec![SinusoidTerm::new(
            [0.3, 0.2, 0.25],
            [f, f, 2.0 * f],
            [0.3, 0.0, 0.7],
        )],
    };
    let cfg = config(7, 3.0, 90.0, MotionKind::Sinusoid);
    let ds = simulate_with(&cfg, &motion).expect("simulation");
    let o = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("calibration");
    let a = &o
        .init
        .as_ref()
        .expect("UIC initialisation")
        .offset
        .alignment;
    println!(
        "periodic: lag {:.3}, second {:?} at {:?}, uniqueness {:.3}",
        a.lag_s,
        a.second_correlation,
        a.second_lag_s,
        a.uniqueness()
    );
    assert!(a.ambiguous, "uniqueness {:.3}", a.uniqueness());
    let second = a.second_lag_s.expect("a second peak");
    // The second peak is a whole number of half periods away (the speed of a sinusoidal motion
    // repeats every half period).
    let halves = (second - a.lag_s) * f * 2.0;
    assert!(
        (halves - halves.round()).abs() < 0.1,
        "{halves} half periods"
    );
    assert!(
        o.warnings.iter().any(|w| w.contains("ambiguous")),
        "{:?}",
        o.warnings
    );
}

#[test]
fn a_drifting_dvl_clock_is_detected_and_a_steady_one_is_not() {
    // 200 ppm over ten minutes: 120 ms from start to end.
    let mut cfg = config(8, 0.07, 600.0, MotionKind::Sinusoid);
    cfg.clock_drift_ppm = 200.0;
    let ds = simulate(&cfg).expect("simulation");
    let o = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("calibration");
    let d = o.drift.as_ref().expect("drift check");
    println!("drift: {d:?}");
    assert!(d.significant);
    // The two thirds' offsets differ by the drift over the time between their middles.
    let sd_ppm = 1e6 * d.difference_std_s / 400.0;
    assert!(
        (d.drift_ppm - 200.0).abs() < 3.0 * sd_ppm + 5.0,
        "{} ppm (std {sd_ppm:.1})",
        d.drift_ppm
    );
    assert!(
        o.warnings.iter().any(|w| w.contains("ppm")),
        "{:?}",
        o.warnings
    );
    for seed in 1..=3 {
        let ds = simulate(&config(seed, 0.07, 600.0, MotionKind::Sinusoid)).expect("simulation");
        let o = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("calibration");
        let d = o.drift.as_ref().expect("drift check");
        assert!(!d.significant, "seed {seed}: {d:?}");
    }
}

fn failure(o: &CalibrationOutcome) -> String {
    match &o.status {
        Status::Failed(r) => r.join(" | "),
        Status::Ok => panic!("the calibration passed: {:?}", o.params),
    }
}

#[test]
fn a_dvl_log_of_another_recording_fails_loudly() {
    let ds = recording(9, 0.07, 120.0, MotionKind::CalmThenRotate);
    let other = recording(10, 0.07, 120.0, MotionKind::CalmThenRotate);
    match calibrate(&ds.poses, &other.dvl, &CalibOptions::default()) {
        Ok(o) => {
            let f = failure(&o);
            println!("another recording: {f}");
            assert!(f.contains("residuals") || f.contains("scale"), "{f}");
        }
        Err(e) => assert!(matches!(e, dvlcal::Error::NoTimeOverlap(_)), "{e:?}"),
    }
}

#[test]
fn poses_in_the_wrong_frame_fail_loudly() {
    // T_cam_world given where T_world_cam is expected.
    let mut ds = recording(11, 0.07, 120.0, MotionKind::CalmThenRotate);
    ds.poses.iter_mut().for_each(|p| p.pose = p.pose.inverse());
    let o = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("calibration");
    let f = failure(&o);
    println!("inverted poses: {f}");
}

#[test]
fn poses_in_millimetres_fail_on_the_scale() {
    let mut ds = recording(12, 0.07, 120.0, MotionKind::CalmThenRotate);
    ds.poses
        .iter_mut()
        .for_each(|p| p.pose = Se3::new(p.pose.rot, p.pose.trans * 1000.0));
    let o = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("calibration");
    let f = failure(&o);
    println!("millimetres: {f}");
    assert!(f.contains("scale"), "{f}");
}

#[test]
fn fixed_extrinsics_with_a_wrong_offset_in_the_guess_still_calibrate() {
    use dvlcal::calib::Method;
    // The user's extrinsics are right, but their clock offset is 2.5 s off (and 37 s off): the
    // data give the offset; no sample ever falls outside the trajectory.
    for &wrong in &[2.5, 37.0] {
        let ds = recording(13, 0.07, 120.0, MotionKind::CalmThenRotate);
        let mut guess = ds.truth;
        guess.time_offset_s += wrong;
        for method in [
            Method::Fixed {
                guess,
                estimate_offset: true,
            },
            Method::Bcd(guess),
        ] {
            let opts = CalibOptions {
                method,
                ..CalibOptions::default()
            };
            let o = calibrate(&ds.poses, &ds.dvl, &opts).expect("calibration");
            assert!(
                (o.params.time_offset_s - ds.truth.time_offset_s).abs() < 0.005,
                "{} against {}",
                o.params.time_offset_s,
                ds.truth.time_offset_s
            );
            assert!(o.status.is_ok(), "{:?}", o.status);
            assert!(
                o.warnings
                    .iter()
                    .any(|w| w.contains("the guess's clock offset")),
                "{:?}",
                o.warnings
            );
        }
    }
}

#[test]
fn a_negative_scale_from_a_half_turn_guess_is_mirrored_back() {
    use dvlcal::calib::Method;
    // Planar motion (x-y translation, yaw only): a rotation half a turn about the camera's z axis
    // with a negative scale predicts the same DVL velocities, a trap for a refinement that starts
    // there (as a hand-measured guess with a flipped axis would).
    let f = 0.05;
    let motion = SinusoidMotion {
        duration_s: 120.0,
        position_offset: Vector3::zeros(),
        position: vec![
            SinusoidTerm::new([0.8, 0.6, 0.0], [f, 1.3 * f, 0.0], [0.0, 0.4, 0.0]),
            SinusoidTerm::new([0.2, 0.3, 0.0], [3.1 * f, 2.3 * f, 0.0], [1.0, 0.2, 0.0]),
        ],
        rotation_offset: Vector3::zeros(),
        rotation: vec![SinusoidTerm::new(
            [0.0, 0.0, 0.6],
            [0.0, 0.0, 2.7 * f],
            [0.0, 0.0, 0.3],
        )],
    };
    let cfg = config(14, 0.07, 120.0, MotionKind::Sinusoid);
    let ds = simulate_with(&cfg, &motion).expect("simulation");
    let flip = nalgebra::Matrix3::new(-1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 1.0);
    let mut guess = dvlcal::CalibrationParams::from_r_dvl_cam(
        ds.truth.r_dvl_cam() * flip,
        ds.truth.lever_arm_cam_m(),
        -ds.truth.velocity_scale,
        ds.truth.time_offset_s,
    );
    guess.velocity_scale *= 1.02;
    let opts = CalibOptions {
        method: Method::Bcd(guess),
        ..CalibOptions::default()
    };
    let o = calibrate(&ds.poses, &ds.dvl, &opts).expect("calibration");
    println!(
        "scale {}, warnings {:?}",
        o.params.velocity_scale, o.warnings
    );
    assert!(o.params.velocity_scale > 0.0, "{}", o.params.velocity_scale);
    let rot = dvlcal::lie::so3::log(&(o.params.r_dvl_cam() * ds.truth.r_dvl_cam().transpose()));
    assert!(
        rot.norm().to_degrees() < 2.0,
        "{} deg",
        rot.norm().to_degrees()
    );
    assert!(
        o.warnings.iter().any(|w| w.contains("mirrored")),
        "{:?}",
        o.warnings
    );
}
