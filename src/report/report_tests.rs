//! The values behind the report's newer plots and tables, checked on simulated calibrations:
//! the residual band is three times the stated noise, decimation keeps every extreme and every
//! sample outside the band, the correlation matrix is the covariance's, and the reprojection
//! plots draw a bounded, evenly spread sample of the corners.

use std::sync::OnceLock;

use nalgebra::Vector3;

use super::correlation::Correlation;
use super::data::{Derived, Sample};
use super::input::{FrameStat, ReportInput};
use super::reprojection::{MAX_CORNERS_PER_CAMERA, camera_errors};
use super::timeline::{COLUMNS, axis_timeline};
use crate::calib::model::NPARAM;
use crate::calib::{CalibOptions, CalibrationOutcome, Method, calibrate};
use crate::sim::dataset::{MotionKind, SimConfig, SimDataset, simulate};
use crate::vision::pnp::CornerResidual;

fn dataset() -> &'static SimDataset {
    static DS: OnceLock<SimDataset> = OnceLock::new();
    DS.get_or_init(|| {
        simulate(&SimConfig {
            seed: 21,
            motion: MotionKind::CalmThenRotate,
            duration_s: 30.0,
            ..SimConfig::default()
        })
        .expect("simulation")
    })
}

/// The calibration with `--dvl-sigma 0.012`.
fn with_sigma() -> &'static CalibrationOutcome {
    static O: OnceLock<CalibrationOutcome> = OnceLock::new();
    O.get_or_init(|| {
        let ds = dataset();
        let opts = CalibOptions {
            dvl_sigma: Some(0.012),
            ..CalibOptions::default()
        };
        calibrate(&ds.poses, &ds.dvl, &opts).expect("calibration")
    })
}

fn derived(o: &CalibrationOutcome) -> Derived {
    Derived::compute(&ReportInput::new(o, &dataset().poses)).expect("derived")
}

#[test]
fn band_is_three_times_the_stated_sigma() {
    let d = derived(with_sigma());
    assert!(d.samples.len() > 100);
    for k in 0..3 {
        // Every sample drawn: one band value per sample, 3 x 0.012 m/s.
        let tl = axis_timeline(&d.samples, k, d.samples.len());
        assert!(!tl.decimated);
        assert_eq!(tl.band.len(), d.samples.len());
        assert_eq!(tl.drawn.len(), d.samples.len());
        for b in &tl.band {
            assert!((b.1 - 0.036).abs() < 1e-12, "{b:?}");
        }
        // Decimated: one band value per column, still 3 sigma.
        let tl = axis_timeline(&d.samples, k, 20);
        assert!(tl.decimated);
        assert!(tl.band.len() <= 20 && tl.band.len() >= 19);
        assert!(tl.band.iter().all(|b| (b.1 - 0.036).abs() < 1e-12));
    }
}

#[test]
fn band_follows_each_samples_reported_covariance() {
    // The reports' own covariances (no --dvl-sigma), different per sample.
    let mut o = with_sigma().clone();
    for (k, ob) in o.observations.iter_mut().enumerate() {
        let s = 0.005 + 0.001 * (k % 7) as f64;
        ob.cov = nalgebra::Matrix3::from_diagonal(&Vector3::new(s * s, 4.0 * s * s, 9.0 * s * s));
    }
    let d = derived(&o);
    let tl = axis_timeline(&d.samples, 2, d.samples.len());
    let mut times: Vec<&Sample> = d.samples.iter().collect();
    times.sort_by(|a, b| a.t_dvl.total_cmp(&b.t_dvl));
    for (b, s) in tl.band.iter().zip(times) {
        assert_eq!(b.0, s.t_dvl);
        let stated = (o.observations.iter().find(|x| x.t == s.t_dvl).unwrap().cov[(2, 2)]).sqrt();
        assert!((b.1 - 3.0 * stated).abs() < 1e-12);
    }
}

#[test]
fn decimation_keeps_extremes_and_every_sample_outside_the_band() {
    let d = derived(with_sigma());
    // A long, noisy log: 100k samples spread over the recording's samples, residuals with a few
    // spikes outside the band.
    let base = &d.samples;
    let n = 100_000;
    let samples: Vec<Sample> = (0..n)
        .map(|i| {
            let mut s = base[i % base.len()].clone();
            s.t_dvl = i as f64 * 1e-3;
            let r = 0.01 * ((i as f64 * 0.7).sin()) + if i % 997 == 0 { 0.2 } else { 0.0 };
            s.measured = s.after + Vector3::new(r, -r, 0.5 * r);
            s.weight = if i % 5003 == 0 { 0.1 } else { 1.0 };
            s
        })
        .collect();
    let tl = axis_timeline(&samples, 0, COLUMNS);
    assert!(tl.decimated);
    assert!(tl.drawn.len() <= 2 * COLUMNS, "{}", tl.drawn.len());
    let spikes = (0..n).filter(|i| i % 997 == 0).count();
    assert_eq!(tl.outside.len(), spikes);
    assert_eq!(
        tl.downweighted.len(),
        (0..n).filter(|i| i % 5003 == 0).count()
    );
    // The lowest and the highest residual of the whole log are among those drawn.
    let res: Vec<f64> = samples.iter().map(|s| s.measured[0] - s.after[0]).collect();
    let lo = res.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = res.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    assert!(tl.drawn.iter().any(|p| p.1 == lo));
    assert!(tl.drawn.iter().any(|p| p.1 == hi.min(tl.half_range)));
    // The y range holds the band and 99.9 % of the residuals.
    assert!(tl.half_range >= 1.5 * 0.036);
    assert_eq!(tl.n, n);
}

#[test]
fn correlation_is_the_covariance_normalised() {
    let o = with_sigma();
    let c = Correlation::of(o);
    assert!(c.estimated.iter().all(|&e| e));
    let cov = &o.covariance;
    for i in 0..NPARAM {
        assert_eq!(c.r[i][i], Some(1.0));
        for j in 0..NPARAM {
            let r = c.r[i][j].expect("estimated");
            assert_eq!(r, c.r[j][i].unwrap(), "symmetric");
            assert!(r.abs() <= 1.0);
            let back = r * (cov[(i, i)] * cov[(j, j)]).sqrt();
            assert!(
                (back - cov[(i, j)]).abs() <= 1e-9 * (cov[(i, i)] * cov[(j, j)]).sqrt(),
                "{i},{j}"
            );
        }
    }
    // The strong pairs are exactly those above 0.9.
    let strong = c.strong_pairs();
    for i in 0..NPARAM {
        for j in i + 1..NPARAM {
            let listed = strong.iter().any(|p| (p.0, p.1) == (i, j));
            assert_eq!(listed, c.r[i][j].unwrap().abs() > 0.9);
        }
    }
}

#[test]
fn fixed_parameters_have_no_correlation() {
    let ds = dataset();
    let opts = CalibOptions {
        method: Method::Fixed {
            guess: ds.truth,
            estimate_offset: true,
        },
        ..CalibOptions::default()
    };
    let o = calibrate(&ds.poses, &ds.dvl, &opts).expect("calibration");
    let c = Correlation::of(&o);
    assert_eq!(
        c.estimated,
        [false, false, false, false, false, false, true, true]
    );
    for i in 0..NPARAM {
        for j in 0..NPARAM {
            assert_eq!(c.r[i][j].is_some(), i >= 6 && j >= 6, "{i},{j}");
        }
    }
    let html = super::correlation::correlation_section(&o);
    assert_eq!(html.matches(">fixed</td>").count(), NPARAM * NPARAM - 4);
    assert!(!html.contains("NaN"));
    assert!(html.contains("Fixed in this run"));
}

#[test]
fn a_lever_arm_held_at_the_default_prior_has_no_correlation() {
    // Held, the lever arm has the prior's variance and no covariance with the rest.
    let mut o = with_sigma().clone();
    o.lever_arm_from_default_prior = true;
    for k in 3..6 {
        for j in 0..NPARAM {
            if !(3..6).contains(&j) {
                o.covariance[(k, j)] = 0.0;
                o.covariance[(j, k)] = 0.0;
            }
        }
        o.covariance[(k, k)] = 1.0;
    }
    let c = Correlation::of(&o);
    assert!(c.lever_arm_held);
    assert_eq!(
        c.estimated,
        [true, true, true, false, false, false, true, true]
    );
    assert!(c.r[0][3].is_none() && c.r[6][7].is_some());
    let html = super::correlation::correlation_section(&o);
    assert!(html.contains("The lever arm is held at its prior (the broad default prior"));
    // Its cells say "prior", not "fixed": the prior gave its value (3 rows and 3 columns).
    assert_eq!(html.matches(">prior</td>").count(), NPARAM * NPARAM - 5 * 5);
    assert!(!html.contains(">fixed</td>"));
    // Determined by the data (covariance with the rest), it is estimated whatever the flag says.
    let mut o = with_sigma().clone();
    o.lever_arm_from_default_prior = true;
    let c = Correlation::of(&o);
    assert!(!c.lever_arm_held && c.estimated.iter().all(|&e| e));
}

fn frame(t: f64, cams: usize, per_cam: usize) -> FrameStat {
    let corners = (0..cams)
        .flat_map(|c| {
            (0..per_cam).map(move |k| CornerResidual {
                cam: c as u8,
                u: 10.0 * k as f32,
                v: 5.0 * k as f32,
                du: 0.1 * (c + 1) as f32,
                dv: 0.0,
            })
        })
        .collect();
    FrameStat {
        t,
        posed: true,
        tags_detected: 10,
        tags_used: 10,
        rms_px: Some(0.15),
        rms_px_per_cam: (0..cams).map(|c| Some(0.1 * (c + 1) as f64)).collect(),
        corners,
        edge_width_px: Some(0.9),
        dropped: None,
    }
}

#[test]
fn reprojection_draws_a_bounded_sample_per_camera() {
    // Few frames: all kept corners drawn, each camera its own.
    let frames: Vec<FrameStat> = (0..10).map(|k| frame(k as f64, 2, 12)).collect();
    let e = camera_errors(&frames, 1);
    assert_eq!((e.corners.len(), e.sampled, e.stride), (120, 120, 1));
    assert!(
        e.corners
            .iter()
            .all(|(_, x)| x.cam == 1 && (x.norm() - 0.2).abs() < 1e-6)
    );
    assert_eq!(e.rms.len(), 10);
    assert!(e.rms.iter().all(|r| (r.1 - 0.2).abs() < 1e-12));
    // Mono frames give cam1 nothing.
    let mono: Vec<FrameStat> = (0..10).map(|k| frame(k as f64, 1, 12)).collect();
    let e = camera_errors(&mono, 1);
    assert!(e.corners.is_empty() && e.rms.is_empty());
    // A long recording: every k-th frame, at most the cap, spread over the whole time.
    let long: Vec<FrameStat> = (0..5000).map(|k| frame(k as f64, 2, 12)).collect();
    let e = camera_errors(&long, 0);
    assert_eq!(e.sampled, 60_000);
    assert_eq!(e.stride, 4);
    assert!(e.corners.len() <= MAX_CORNERS_PER_CAMERA);
    assert_eq!(e.corners.len(), 1250 * 12);
    assert_eq!(e.corners.first().unwrap().0, 0.0);
    assert_eq!(e.corners.last().unwrap().0, 4996.0);
    let html =
        super::reprojection::reprojection_section(Some(&long), Some(&[(752, 480), (752, 480)]));
    assert!(html.contains("from one frame in 4"));
    assert!(html.len() < 400_000, "{}", html.len());
}
