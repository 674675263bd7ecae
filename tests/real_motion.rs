//! Calibration on a real vehicle's motion: the EuRoC V1_01 motion-capture track replayed as the
//! truth of simulated 10 Hz poses (2 mm, 0.1 deg) and 10 Hz DVL reports (1 cm/s), calibrated by
//! dvlcal and by the independent smoothing-spline estimator (`eval::spline_baseline`).
//! The full table over 20 seeds is `cargo bench --bench real_motion` (docs/accuracy.md).

use std::path::Path;

use dvlcal::calib::model::difference;
use dvlcal::calib::{CalibOptions, calibrate, jerk_density_evidence};
use dvlcal::eval::spline_baseline::{BaselineOptions, SplineTrack, spline_baseline};
use dvlcal::io::tum::read_tum;
use dvlcal::sim::{Motion, SimConfig, TrackOptions, replay_track, simulate_with};

const TRACK: &str = "tests/fixtures/real_motion/euroc_v101_vicon.txt";

fn recorded() -> Vec<dvlcal::types::PoseMeasurement> {
    read_tum(Path::new(TRACK), None).expect("track").poses
}

#[test]
fn the_recorded_track_replays_with_its_speeds_and_little_drift() {
    let rec = recorded();
    assert_eq!(rec.len(), 2895);
    let r = replay_track(&rec, &TrackOptions::default()).expect("replay");
    assert!((r.duration_s - 144.7).abs() < 1e-6, "{}", r.duration_s);
    // A pilot's flight: about 0.45 m/s and 0.3 rad/s RMS.
    assert!((0.4..0.5).contains(&r.rms_speed_mps), "{}", r.rms_speed_mps);
    assert!(
        (0.25..0.4).contains(&r.rms_rate_radps),
        "{}",
        r.rms_rate_radps
    );
    // The integral of the smoothed twist stays within millimetres of the recorded positions.
    assert!(r.position_drift_rms_m < 0.01, "{}", r.position_drift_rms_m);
    // Poses, twists and rates agree: a finite difference of the replayed pose is the twist.
    let h = 1e-4;
    for t in [10.0, 55.5, 100.25] {
        let s = r.motion.state(t);
        let d = (s.pose.inverse() * r.motion.state(t + h).pose).log() / h;
        let mid = r.motion.state(t + 0.5 * h).twist;
        assert!((d - mid).norm() < 1e-6, "t {t}: {} vs {}", d, mid);
    }
}

#[test]
fn on_real_motion_dvlcal_matches_the_spline_estimator_with_honest_std() {
    let rec = recorded();
    let track = replay_track(&rec, &TrackOptions::default()).expect("replay");
    let seeds = 4;
    let (mut ours, mut spline, mut z2) = ([0.0f64; 4], [0.0f64; 4], [0.0f64; 4]);
    let groups = [0..3, 3..6, 6..7, 7..8];
    let mut twist_err = (0.0, 0.0, 0usize);
    for seed in 0..seeds {
        let cfg = SimConfig {
            seed: 3000 + seed,
            duration_s: track.duration_s,
            pose_sigma_rot_rad: 0.1f64.to_radians(),
            ..SimConfig::default()
        };
        let ds = simulate_with(&cfg, &track.motion).expect("simulate");
        let o = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("dvlcal");
        assert!(!o.lever_arm_from_default_prior);
        let bopts = BaselineOptions::default();
        let b = spline_baseline(&ds.poses, &ds.dvl, &bopts).expect("baseline");
        assert_eq!(b.stretches, 1);
        // The reference's twists are as good as a spline can give (about 1.5 cm/s, 0.03 rad/s).
        let st = SplineTrack::fit(&ds.poses, &bopts).expect("splines");
        for k in 0..500 {
            let t = 1.0 + k as f64 * 0.28;
            if let Some(tw) = st.twist(t) {
                let d = tw - track.motion.state(t).twist;
                twist_err.0 += d.fixed_rows::<3>(0).norm_squared();
                twist_err.1 += d.fixed_rows::<3>(3).norm_squared();
                twist_err.2 += 1;
            }
        }
        let d = difference(&o.params, &ds.truth);
        let e = difference(&b.params, &ds.truth);
        for (g, r) in groups.iter().enumerate() {
            for k in r.clone() {
                ours[g] += d[k] * d[k];
                spline[g] += e[k] * e[k];
                z2[g] += d[k] * d[k] / o.covariance[(k, k)];
            }
        }
    }
    let n = twist_err.2 as f64;
    let (v_rms, w_rms) = ((twist_err.0 / n).sqrt(), (twist_err.1 / n).sqrt());
    assert!(
        v_rms < 0.025 && w_rms < 0.05,
        "spline twists {v_rms} m/s, {w_rms} rad/s"
    );
    for (g, name) in ["rotation", "lever arm", "scale", "clock offset"]
        .iter()
        .enumerate()
    {
        let ratio = (ours[g] / spline[g]).sqrt();
        let z = (z2[g] / (seeds as usize * groups[g].len()) as f64).sqrt();
        assert!(ratio <= 1.5, "{name}: dvlcal / spline RMSE {ratio}");
        assert!(z <= 2.0, "{name}: RMS err/std {z}");
    }
}

#[test]
fn the_poses_and_the_dvl_together_prefer_the_jerk_density_chosen_from_the_poses() {
    let rec = recorded();
    let track = replay_track(&rec, &TrackOptions::default()).expect("replay");
    let cfg = SimConfig {
        seed: 3000,
        duration_s: track.duration_s,
        pose_sigma_rot_rad: 0.1f64.to_radians(),
        ..SimConfig::default()
    };
    let ds = simulate_with(&cfg, &track.motion).expect("simulate");
    let o = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("dvlcal");
    let ev = |f: f64| jerk_density_evidence(&ds.poses, &o, f).expect("evidence");
    let (low, own, high) = (ev(0.5), ev(1.0), ev(2.0));
    assert!(own > low + 10.0 && own > high + 10.0, "{low} {own} {high}");
    assert!(jerk_density_evidence(&ds.poses, &o, 0.0).is_err());
}
