//! Calibration on real vehicles' motion: recorded tracks (`tests/fixtures/real_motion/`), cut at
//! their tracking losses and glitches, replayed as the truth of simulated 10 Hz poses (2 mm,
//! 0.1 deg) and 10 Hz DVL reports (1 cm/s), calibrated by dvlcal and by the independent
//! smoothing-spline estimator (`eval::spline_baseline`). The full tables over 20 seeds are
//! `cargo bench --bench real_motion` (docs/accuracy.md).

use std::path::Path;

use dvlcal::calib::model::difference;
use dvlcal::calib::{CalibOptions, calibrate, jerk_density_evidence};
use dvlcal::eval::spline_baseline::{BaselineOptions, SplineTrack, spline_baseline};
use dvlcal::io::tum::read_tum;
use dvlcal::sim::{
    CutOptions, CutTrack, Motion, SimConfig, TrackMotion, TrackOptions, cut_track, replay_track,
    simulate_with,
};
use dvlcal::types::PoseMeasurement;

const EUROC: &str = "tests/fixtures/real_motion/euroc_v101_vicon.txt";
const TUMVI_ROOM6: &str = "tests/fixtures/real_motion/tumvi_room6_mocap.txt";
const TROLLEY: &str = "tests/fixtures/real_motion/uwb_trolley_slow_mocap.txt";

fn recorded(file: &str) -> Vec<PoseMeasurement> {
    read_tum(Path::new(file), None).expect("track").poses
}

fn cut(file: &str) -> CutTrack {
    cut_track(&recorded(file), &CutOptions::default()).expect("cut")
}

/// The longest piece of a cut track, replayed at `time_scale`.
fn replay_longest(c: &CutTrack, time_scale: f64) -> TrackMotion {
    let piece = c.longest().expect("a usable piece");
    let opts = TrackOptions {
        time_scale,
        ..TrackOptions::default()
    };
    replay_track(piece, &opts).expect("replay")
}

/// The longest piece of a track replayed at its own speed with the twists smoothed over 50 ms
/// only, less than the default's two steps: on a 10 Hz track the tracker's jitter stays in
/// the replay as a vibration of the vehicle.
fn replay_with_jitter(file: &str) -> TrackMotion {
    let c = cut(file);
    let piece = c.longest().expect("a usable piece");
    let opts = TrackOptions {
        min_smoothing_steps: 0.0,
        ..TrackOptions::default()
    };
    replay_track(piece, &opts).expect("replay")
}

/// The longest piece of a track, replayed at `time_scale`.
fn replay(file: &str, time_scale: f64) -> TrackMotion {
    replay_longest(&cut(file), time_scale)
}

/// A track cut and its longest piece replayed at its own speed, both described on stderr.
fn cut_and_replay(name: &str, file: &str) -> (CutTrack, TrackMotion) {
    let c = cut(file);
    eprintln!(
        "{name}: {} pieces, gaps {}, holds {} ({} poses), glitches {} ({} poses), jumps {}, short {}",
        c.pieces.len(),
        c.gaps,
        c.holds,
        c.held_poses,
        c.glitches,
        c.glitch_poses,
        c.jumps,
        c.short_pieces
    );
    let r = replay_longest(&c, 1.0);
    eprintln!(
        "{name}: {:.1} s, {:.3} m/s, {:.3} rad/s, drift {:.4} m",
        r.duration_s, r.rms_speed_mps, r.rms_rate_radps, r.position_drift_rms_m
    );
    (c, r)
}

/// Poses, twists and rates of a replay agree: a finite difference of the pose is the twist.
fn assert_consistent(r: &TrackMotion) {
    let h = 1e-4;
    for f in [0.1, 0.37, 0.69, 0.95] {
        let t = f * r.duration_s;
        let s = r.motion.state(t);
        let d = (s.pose.inverse() * r.motion.state(t + h).pose).log() / h;
        let mid = r.motion.state(t + 0.5 * h).twist;
        assert!((d - mid).norm() < 1e-6, "t {t}: {} vs {}", d, mid);
    }
}

#[test]
fn the_recorded_track_replays_with_its_speeds_and_little_drift() {
    let rec = recorded(EUROC);
    assert_eq!(rec.len(), 2895);
    // Nothing to cut: the Vicon track has no losses and no glitches.
    let c = cut(EUROC);
    assert_eq!(c.pieces.len(), 1);
    assert_eq!(c.pieces[0].len(), 2895);
    let r = replay(EUROC, 1.0);
    assert!((r.duration_s - 144.7).abs() < 1e-6, "{}", r.duration_s);
    // A pilot's flight: about 0.45 m/s and 0.3 rad/s RMS.
    assert!((0.4..0.5).contains(&r.rms_speed_mps), "{}", r.rms_speed_mps);
    assert!(
        (0.25..0.4).contains(&r.rms_rate_radps),
        "{}",
        r.rms_rate_radps
    );
    // The integral of the smoothed twist (two 50 ms steps of the 20 Hz track) stays within
    // about a centimetre of the recorded positions.
    assert!((r.smoothing_s - 0.1).abs() < 1e-9, "{}", r.smoothing_s);
    assert!(r.position_drift_rms_m < 0.02, "{}", r.position_drift_rms_m);
    assert_consistent(&r);
}

#[test]
fn the_hand_held_track_is_cut_at_its_tracking_loss_and_replays() {
    let (c, r) = cut_and_replay("room6", TUMVI_ROOM6);
    // The tracker lost the rig once for 3.15 s: two pieces, the longer 88.2 s.
    assert_eq!((c.gaps, c.pieces.len()), (1, 2));
    assert!((r.duration_s - 88.2).abs() < 0.05, "{}", r.duration_s);
    // A person walking with a rig in hand: about 0.55 m/s and 0.85 rad/s RMS.
    assert!((0.4..0.8).contains(&r.rms_speed_mps), "{}", r.rms_speed_mps);
    assert!(
        (0.6..1.2).contains(&r.rms_rate_radps),
        "{}",
        r.rms_rate_radps
    );
    // A hand's shake smoothed away with the tracker's jitter (two 50 ms steps): under 25 cm
    // over some 50 m of path.
    assert!(r.position_drift_rms_m < 0.25, "{}", r.position_drift_rms_m);
    assert_consistent(&r);
}

#[test]
fn the_slow_trolley_track_replays_slowly() {
    let (c, r) = cut_and_replay("trolley", TROLLEY);
    // No glitches, but five holds: the motion capture repeated its last pose for 1-4 frames
    // while the trolley rolled on at 9 cm/s, then caught up in one step (at 123.0, 123.2,
    // 125.7, 126.2 and 289.5 s). Without them the last hold is a 0.5 s tracking loss: two
    // pieces, the longer the first 289.5 s.
    assert_eq!((c.gaps, c.glitches, c.pieces.len()), (1, 0, 2));
    assert_eq!((c.holds, c.held_poses), (5, 10));
    assert_eq!(c.pieces.iter().map(|p| p.len()).sum::<usize>(), 3111);
    assert!((r.duration_s - 289.5).abs() < 0.05, "{}", r.duration_s);
    assert!(
        (0.05..0.2).contains(&r.rms_speed_mps),
        "{}",
        r.rms_speed_mps
    );
    assert!(r.rms_rate_radps < 0.3, "{}", r.rms_rate_radps);
    assert!(r.position_drift_rms_m < 0.01, "{}", r.position_drift_rms_m);
    assert_consistent(&r);
}

/// dvlcal and the spline estimator on `seeds` simulations of one replayed track.
struct Figures {
    /// dvlcal's RMSE over the spline estimator's, per group (rotation, lever arm, scale, offset).
    ratio: [f64; 4],
    /// RMS of dvlcal's err/std per group.
    z: [f64; 4],
    /// Runs where dvlcal held the lever arm at its default prior.
    lever_held: usize,
    /// Runs whose status said the result cannot be trusted.
    failed: usize,
    /// Runs where the spline estimator split the recording.
    spline_split: usize,
    /// RMS error of the spline estimator's twists, m/s and rad/s.
    spline_twist: (f64, f64),
}

const GROUPS: [std::ops::Range<usize>; 4] = [0..3, 3..6, 6..7, 7..8];
const GROUP_NAMES: [&str; 4] = ["rotation", "lever arm", "scale", "clock offset"];

/// Seed `seed`'s settings on `track` (the simulator's noise, rotations of 0.1 deg).
fn seed_config(seed: u64, track: &TrackMotion) -> SimConfig {
    SimConfig {
        seed: 3000 + seed,
        duration_s: track.duration_s,
        pose_sigma_rot_rad: 0.1f64.to_radians(),
        ..SimConfig::default()
    }
}

fn accuracy(track: &TrackMotion, seeds: u64) -> Figures {
    let (mut ours, mut spline, mut z2) = ([0.0f64; 4], [0.0f64; 4], [0.0f64; 4]);
    let mut twist_err = (0.0, 0.0, 0usize);
    let (mut lever_held, mut spline_split, mut failed) = (0, 0, 0);
    for seed in 0..seeds {
        let cfg = seed_config(seed, track);
        let ds = simulate_with(&cfg, &track.motion).expect("simulate");
        let o = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("dvlcal");
        lever_held += usize::from(o.lever_arm_from_default_prior);
        failed += usize::from(!o.status.is_ok());
        let bopts = BaselineOptions::default();
        let b = spline_baseline(&ds.poses, &ds.dvl, &bopts).expect("baseline");
        spline_split += usize::from(b.stretches != 1);
        let st = SplineTrack::fit(&ds.poses, &bopts).expect("splines");
        for k in 0..500 {
            let t = 1.0 + k as f64 * ((track.duration_s - 2.0) / 500.0).min(0.28);
            if let Some(tw) = st.twist(t) {
                let d = tw - track.motion.state(t).twist;
                twist_err.0 += d.fixed_rows::<3>(0).norm_squared();
                twist_err.1 += d.fixed_rows::<3>(3).norm_squared();
                twist_err.2 += 1;
            }
        }
        let d = difference(&o.params, &ds.truth);
        let e = difference(&b.params, &ds.truth);
        for (g, r) in GROUPS.iter().enumerate() {
            for k in r.clone() {
                ours[g] += d[k] * d[k];
                spline[g] += e[k] * e[k];
                z2[g] += d[k] * d[k] / o.covariance[(k, k)];
            }
        }
    }
    let n = twist_err.2.max(1) as f64;
    let mut f = Figures {
        ratio: [0.0; 4],
        z: [0.0; 4],
        lever_held,
        failed,
        spline_split,
        spline_twist: ((twist_err.0 / n).sqrt(), (twist_err.1 / n).sqrt()),
    };
    for g in 0..4 {
        f.ratio[g] = (ours[g] / spline[g]).sqrt();
        f.z[g] = (z2[g] / (seeds as usize * GROUPS[g].len()) as f64).sqrt();
    }
    f
}

#[test]
fn on_real_motion_dvlcal_matches_the_spline_estimator_with_honest_std() {
    let track = replay(EUROC, 1.0);
    let f = accuracy(&track, 4);
    assert_eq!(f.lever_held, 0);
    assert_eq!(f.spline_split, 0);
    // The reference's twists are as good as a spline can give (about 1.5 cm/s, 0.03 rad/s).
    let (v_rms, w_rms) = f.spline_twist;
    assert!(
        v_rms < 0.025 && w_rms < 0.05,
        "spline twists {v_rms} m/s, {w_rms} rad/s"
    );
    for (g, name) in GROUP_NAMES.iter().enumerate() {
        assert!(
            f.ratio[g] <= 1.5,
            "{name}: dvlcal / spline RMSE {}",
            f.ratio[g]
        );
        assert!(f.z[g] <= 2.0, "{name}: RMS err/std {}", f.z[g]);
    }
}

/// The other tracks on 2 seeds: dvlcal's status is ok on every seed and its std hold (RMS
/// err/std under 2.5 per group; the bench's 10 seeds give at most 1.41). Their ratios to the
/// spline estimator are printed, not held: on 2 seeds they swing by a factor of ten (the full
/// tables are docs/accuracy.md's).
#[test]
fn on_the_other_tracks_dvlcal_succeeds_with_honest_std() {
    for (name, file, scale) in [
        ("tumvi_room6", TUMVI_ROOM6, 2.0),
        ("trolley_slow", TROLLEY, 1.0),
    ] {
        let track = replay(file, scale);
        let f = accuracy(&track, 2);
        eprintln!(
            "{name} at time scale {scale} ({:.0} s): lever arm held {} of 2, spline split {}, \
             spline twists {:.3} m/s {:.3} rad/s",
            track.duration_s, f.lever_held, f.spline_split, f.spline_twist.0, f.spline_twist.1
        );
        for (g, group) in GROUP_NAMES.iter().enumerate() {
            eprintln!(
                "  {group}: dvlcal / spline RMSE {:.2}, RMS err/std {:.2}",
                f.ratio[g], f.z[g]
            );
        }
        assert_eq!(f.failed, 0, "{name}: a run failed");
        for (g, group) in GROUP_NAMES.iter().enumerate() {
            assert!(f.z[g] < 2.5, "{name}: {group} err/std {}", f.z[g]);
        }
    }
}

#[test]
fn the_poses_and_the_dvl_together_prefer_the_jerk_density_chosen_from_the_poses() {
    let track = replay(EUROC, 1.0);
    let cfg = seed_config(0, &track);
    let ds = simulate_with(&cfg, &track.motion).expect("simulate");
    let o = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("dvlcal");
    let ev = |f: f64| jerk_density_evidence(&ds.poses, &o, f).expect("evidence");
    let (low, own, high) = (ev(0.5), ev(1.0), ev(2.0));
    assert!(own > low + 10.0 && own > high + 10.0, "{low} {own} {high}");
    assert!(jerk_density_evidence(&ds.poses, &o, 0.0).is_err());
}

/// The trolley moves forward only: the camera's velocity stays along one direction of its
/// frame, and the closed form's linear rotation rests on the small sideways velocities. On seed
/// 1 of the bench it came out 135 deg off, and the refinement from there collapsed the scale
/// to -0.02 (a rotation 171 deg, a lever arm 1.6 m and an offset 0.47 s off). The minimum of
/// the DVL residuals over rotations replaces it, with a warning, and the result is right.
#[test]
fn a_trolley_moving_only_forward_is_calibrated_from_the_best_rotation() {
    // The seed and the assertions below were found on the replay with the tracker's jitter
    // (the default before the two-step smoothing); the rotation search and the one-axis hold do
    // not depend on it, so the test keeps that replay.
    let track = replay_with_jitter(TROLLEY);
    let cfg = SimConfig {
        seed: 3001,
        duration_s: track.duration_s,
        dvl_sigma: 0.01,
        pose_sigma_pos_m: 0.002,
        pose_sigma_rot_rad: 0.1f64.to_radians(),
        ..SimConfig::default()
    };
    let ds = simulate_with(&cfg, &track.motion).expect("simulate");
    let o = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("dvlcal");
    let init = o.init.as_ref().expect("UIC");
    let cf = difference(&init.closed_form.params, &ds.truth);
    let searched = init.rotation_search.as_ref().expect("the rotation search");
    assert!(
        cf.fixed_rows::<3>(0).norm().to_degrees() > 60.0 && searched.angle_deg > 60.0,
        "closed form {} deg off, search moved {} deg",
        cf.fixed_rows::<3>(0).norm().to_degrees(),
        searched.angle_deg
    );
    assert!(
        o.warnings
            .iter()
            .any(|w| w.contains("spans too few directions")),
        "{:?}",
        o.warnings
    );
    let d = difference(&o.params, &ds.truth);
    let start = difference(&o.start, &ds.truth);
    assert!(
        start.fixed_rows::<3>(0).norm().to_degrees() < 5.0,
        "{start}"
    );
    assert!(o.status.is_ok(), "{:?}", o.status);
    assert!(d.fixed_rows::<3>(0).norm().to_degrees() < 5.0, "{d}");
    // With the motion capture's holds dropped, the trolley turns about one axis only (its
    // pitch and roll rates are noise at 0.1 deg per pose): the lever arm along that axis, the
    // camera's z, is held at the broad default prior with the prior's std, the verdict says so,
    // and x and y are measured (before, the whole lever arm was held, 0.27 m off).
    let v = &o.verdicts.lever_arm;
    assert!(
        !v.ok
            && v.cause == Some(dvlcal::calib::WeakCause::FewRotationAxes)
            && v.reason.contains("along the camera's z axis"),
        "{v:?}"
    );
    assert!(!o.lever_arm_from_default_prior);
    assert!(o.std.lever_arm_m.z > 0.5, "{:?}", o.std.lever_arm_m);
    assert!(o.std.lever_arm_m.x < 0.02 && o.std.lever_arm_m.y < 0.02);
    assert!(d[3].abs() < 0.02 && d[4].abs() < 0.02, "{d}");
    assert!(d[6].abs() < 0.01 && d[7].abs() < 0.06, "{d}");
    // Each within three of its standard deviations.
    for k in 0..8 {
        let z = d[k] / o.covariance[(k, k)].sqrt();
        assert!(z.abs() < 3.0, "parameter {k}: err/std {z}");
    }
}

/// DVL noise correlated over 1 s on the trolley: weighed as independent reports, the DVL bent
/// the trajectory's small pitch and roll rates, the lever arm's only regressors along the yaw
/// axis, and its z error was twice the spline estimator's. Refined again with the reports
/// weighed by the information they carry, the error falls by a third (10 seeds: 100 to 66 mm RMS
/// against the splines' 50), with the same std. The run without it is `honest_covariance:
/// false`, which neither reweighs nor inflates.
#[test]
fn correlated_dvl_noise_is_weighed_by_the_information_it_carries() {
    use dvlcal::sim::{Corruption, corrupt};
    let track = replay(TROLLEY, 1.0);
    let (mut reweighed, mut independent, mut z2) = (0.0, 0.0, 0.0);
    let seeds = 4;
    for seed in 0..seeds {
        let cfg = seed_config(seed, &track);
        let mut ds = simulate_with(&cfg, &track.motion).expect("simulate");
        let ar1 = Corruption {
            dvl_ar1_tau_s: Some(1.0),
            ..Corruption::default()
        };
        corrupt(&mut ds, &ar1, cfg.dvl_sigma, 7000 + seed).expect("corrupt");
        let o = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("dvlcal");
        assert!(o.status.is_ok(), "seed {seed}: {:?}", o.status);
        assert!(
            o.warnings
                .iter()
                .any(|w| w.contains("correlated in time") && w.contains("refined again")),
            "seed {seed}: {:?}",
            o.warnings
        );
        let plain = CalibOptions {
            honest_covariance: false,
            ..CalibOptions::default()
        };
        let p = calibrate(&ds.poses, &ds.dvl, &plain).expect("dvlcal");
        let (d, e) = (
            difference(&o.params, &ds.truth),
            difference(&p.params, &ds.truth),
        );
        reweighed += d[5] * d[5];
        independent += e[5] * e[5];
        for k in 3..6 {
            z2 += d[k] * d[k] / o.covariance[(k, k)];
        }
    }
    let (a, b) = (
        (reweighed / seeds as f64).sqrt(),
        (independent / seeds as f64).sqrt(),
    );
    eprintln!(
        "lever arm z RMS: {:.1} mm reweighed, {:.1} mm as independent",
        1e3 * a,
        1e3 * b
    );
    assert!(a < 0.75 * b, "{a} m reweighed against {b} m");
    let z = (z2 / (3 * seeds) as f64).sqrt();
    assert!(z < 2.5, "lever arm err/std {z}");
}
