//! Gaps between camera poses (the board out of view): DVL samples there are left out and
//! counted, since the trajectory there is the motion prior's guess, not a measurement.

use dvlcal::calib::{CalibOptions, calibrate, model::difference, pose_gaps};
use dvlcal::sim::dataset::{SimConfig, simulate};

#[test]
fn dvl_samples_in_pose_gaps_are_left_out_and_counted() {
    let ds = simulate(&SimConfig {
        seed: 3,
        duration_s: 60.0,
        ..SimConfig::default()
    })
    .expect("simulation");
    // The board is out of view for 6 s and for 3 s.
    let out = |t: f64| (20.0..26.0).contains(&t) || (40.0..43.0).contains(&t);
    let poses: Vec<_> = ds.poses.iter().filter(|p| !out(p.t)).cloned().collect();
    let times: Vec<f64> = poses.iter().map(|p| p.t).collect();
    let gaps = pose_gaps(&times);
    assert_eq!(gaps.len(), 2, "{gaps:?}");
    assert!((gaps[0].1 - gaps[0].0 - 6.1).abs() < 0.05, "{gaps:?}");

    let o = calibrate(&poses, &ds.dvl, &CalibOptions::default()).expect("calibration");
    // DVL samples whose camera time falls strictly inside the gaps, counted from the truth.
    let expected = ds
        .dvl
        .iter()
        .filter(|s| {
            let t = s.t + o.params.time_offset_s;
            gaps.iter().any(|g| g.0 < t && t < g.1)
        })
        .count();
    assert!(expected > 50, "{expected}");
    assert_eq!(o.counts.dvl_in_pose_gaps, expected);
    assert!(
        o.warnings
            .iter()
            .any(|w| w.contains("gaps between camera poses")),
        "{:?}",
        o.warnings
    );
    // The result stays near the truth: within 5 of its standard deviations on every parameter.
    let d = difference(&o.params, &ds.truth);
    let std = o.covariance.diagonal().map(f64::sqrt);
    for k in 0..8 {
        assert!(
            d[k].abs() < 5.0 * std[k],
            "parameter {k}: {} vs std {}",
            d[k],
            std[k]
        );
    }
    // Without gaps, nothing is left out.
    let full = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("calibration");
    assert_eq!(full.counts.dvl_in_pose_gaps, 0);
    assert!(pose_gaps(&ds.poses.iter().map(|p| p.t).collect::<Vec<_>>()).is_empty());
}
