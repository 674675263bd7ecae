//! A calibration started from an earlier solution (`CalibOptions::warm_start`, what `dvlcal
//! watch` passes from one update to the next) ends where UIC from the data alone ends: near the
//! right answer, far from it, or with a solution gone astray.

use dvlcal::calib::model::{NPARAM, difference};
use dvlcal::calib::{CalibOptions, CalibrationOutcome, WARM_WINDOW_S, WarmStartUse, calibrate};
use dvlcal::error::Error;
use dvlcal::lie::{Se3, so3};
use dvlcal::sim::dataset::{MotionKind, SimConfig, SimDataset, simulate};
use dvlcal::types::CalibrationParams;
use nalgebra::Vector3;

fn dataset(seed: u64) -> SimDataset {
    simulate(&SimConfig {
        seed,
        motion: MotionKind::CalmThenRotate,
        duration_s: 60.0,
        ..SimConfig::default()
    })
    .expect("simulation")
}

fn run(ds: &SimDataset, warm: Option<CalibrationParams>) -> CalibrationOutcome {
    let opts = CalibOptions {
        warm_start: warm,
        ..CalibOptions::default()
    };
    calibrate(&ds.poses, &ds.dvl, &opts).expect("calibration")
}

/// The truth moved by `rot_deg` about a tilted axis, `lever_m` along x, `offset_s` and 1 % of scale.
fn moved(t: &CalibrationParams, rot_deg: f64, lever_m: f64, offset_s: f64) -> CalibrationParams {
    let turn = so3::exp(&(Vector3::new(0.3, -0.5, 0.8).normalize() * rot_deg.to_radians()));
    CalibrationParams {
        t_cam_dvl: Se3::new(
            turn * t.t_cam_dvl.rot,
            t.t_cam_dvl.trans + Vector3::new(lever_m, 0.0, 0.0),
        ),
        time_offset_s: t.time_offset_s + offset_s,
        velocity_scale: t.velocity_scale * 1.01,
    }
}

/// The largest difference between two results, in the first one's std per parameter.
fn apart_in_std(a: &CalibrationOutcome, b: &CalibrationOutcome) -> f64 {
    let d = difference(&a.params, &b.params);
    (0..NPARAM)
        .map(|i| d[i].abs() / a.covariance[(i, i)].sqrt())
        .fold(0.0, f64::max)
}

fn warm_use(o: &CalibrationOutcome) -> WarmStartUse {
    o.init.as_ref().expect("a UIC run").warm
}

/// The first `seconds` of `ds`, on the camera clock.
fn first(ds: &SimDataset, seconds: f64) -> SimDataset {
    let mut d = ds.clone();
    d.poses.retain(|p| p.t <= seconds);
    d.dvl.retain(|s| s.t + ds.truth.time_offset_s <= seconds);
    d
}

#[test]
fn the_last_updates_solution_searches_a_narrow_window_and_ends_where_uic_ends() {
    for seed in [3, 11] {
        let ds = dataset(seed);
        let uic = run(&ds, None);
        assert_eq!(warm_use(&uic), WarmStartUse::None);
        // What a watch's earlier update would have found, on the first 45 s.
        let last = run(&first(&ds, 45.0), None).params;
        let warm = run(&ds, Some(last));
        assert_eq!(warm_use(&warm), WarmStartUse::Started, "seed {seed}");
        let (a, b) = warm.init.as_ref().expect("init").offset.searched;
        assert!(b - a <= 2.0 * WARM_WINDOW_S + 1e-9, "searched [{a}, {b}]");
        let (ua, ub) = uic.init.as_ref().expect("init").offset.searched;
        assert!(
            b - a < ub - ua,
            "UIC searched [{ua}, {ub}], warm [{a}, {b}]"
        );
        let apart = apart_in_std(&uic, &warm);
        assert!(apart < 0.05, "seed {seed}: {apart} std apart");
        assert_eq!(uic.status, warm.status);
        assert_eq!(uic.verdicts.lever_arm.ok, warm.verdicts.lever_arm.ok);
    }
}

#[test]
fn a_start_whose_clock_is_far_off_searches_again() {
    let ds = dataset(5);
    let uic = run(&ds, None);
    let warm = run(&ds, Some(moved(&ds.truth, 1.0, 0.01, 1.5)));
    assert_eq!(warm_use(&warm), WarmStartUse::SearchedAgain);
    let apart = apart_in_std(&uic, &warm);
    assert!(apart < 0.05, "{apart} std apart");
}

#[test]
fn a_solution_gone_astray_is_not_carried_on() {
    // Half a turn off: the closed form fits the velocities far better and starts the refinement.
    let ds = dataset(7);
    let uic = run(&ds, None);
    let warm = run(&ds, Some(moved(&ds.truth, 120.0, 0.5, 0.0)));
    assert_eq!(warm_use(&warm), WarmStartUse::OffsetOnly);
    let apart = apart_in_std(&uic, &warm);
    assert!(apart < 0.05, "{apart} std apart");
}

#[test]
fn a_warm_start_that_is_not_finite_is_refused() {
    let ds = dataset(3);
    let mut bad = ds.truth;
    bad.time_offset_s = f64::NAN;
    let opts = CalibOptions {
        warm_start: Some(bad),
        ..CalibOptions::default()
    };
    match calibrate(&ds.poses, &ds.dvl, &opts) {
        Err(Error::InvalidOption { option, .. }) => assert_eq!(option, "warm_start"),
        other => panic!(
            "expected the option refused, got {:?}",
            other.map(|o| o.params)
        ),
    }
}
