//! Time of the whole calibration (UIC: trajectory fit with Qc by marginal likelihood, clock offset,
//! closed form, refinement, covariance) for 1k, 10k and 100k DVL samples.
//!
//! `cargo bench --bench calibration` (optionally `-- 1000 10000` for other sizes). Data: the
//! lively sinusoid motion (the sampled motions stop at 4000 s) with the default truth (70 ms
//! offset, 1 % scale), camera and DVL at 10 Hz, N / 10 seconds long. Small sizes are repeated and the median is reported. Prints a markdown
//! table.
//!
//! A second table gives the cost of the motion prior that follows the vehicle
//! (`calib::motion_prior`): the calibration with `CalibOptions::varying_motion_prior` off and on
//! (median of 3), on motions where it is applied: the EuRoC V1_01 flight replayed
//! (`tests/fixtures/real_motion/`) and the calm-then-rotate simulation at 120 s and 1200 s.

use std::time::Instant;

use std::path::Path;

use dvlcal::calib::align::{AlignOptions, align_clocks};
use dvlcal::calib::{CalibOptions, calibrate};
use dvlcal::io::tum::read_tum;
use dvlcal::sim::{MotionKind, SimConfig, TrackOptions, replay_track, simulate, simulate_with};
use dvlcal::types::{DvlSample, PoseMeasurement};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let sizes: Vec<usize> = {
        let args: Vec<usize> = std::env::args()
            .skip(1)
            .filter_map(|a| a.parse().ok())
            .collect();
        if args.is_empty() {
            vec![1_000, 10_000, 100_000]
        } else {
            args
        }
    };
    println!(
        "| DVL samples | poses | runs | calibration (median) | us/sample | ratio to previous size | \
         rotation error (deg) | lever arm error (mm) | offset error (ms) | of which clock alignment |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let mut prev: Option<f64> = None;
    for n in sizes {
        let cfg = SimConfig {
            duration_s: n as f64 / 10.0,
            seed: 7,
            motion: MotionKind::Sinusoid,
            ..SimConfig::default()
        };
        let ds = simulate(&cfg).expect("simulate");
        let reps = if n <= 1_000 {
            5
        } else if n <= 10_000 {
            3
        } else {
            1
        };
        let opts = CalibOptions::default();
        let mut times = Vec::new();
        let mut last = None;
        for _ in 0..reps {
            let t0 = Instant::now();
            let out = calibrate(&ds.poses, &ds.dvl, &opts).expect("calibrate");
            times.push(t0.elapsed().as_secs_f64());
            last = Some(out);
        }
        let out = last.expect("one run");
        let t = median(times);
        // The global clock alignment on its own (it runs inside every calibration), median of 5.
        let align: Vec<f64> = (0..5)
            .map(|_| {
                let t0 = Instant::now();
                align_clocks(
                    &out.fitted,
                    &out.observations,
                    None,
                    &AlignOptions::default(),
                )
                .expect("alignment");
                t0.elapsed().as_secs_f64()
            })
            .collect();
        let align = median(align);
        let truth = ds.truth;
        let rot = dvlcal::lie::so3::log(&(out.params.r_dvl_cam() * truth.r_dvl_cam().transpose()))
            .norm()
            .to_degrees();
        println!(
            "| {} | {} | {reps} | {t:.3} s | {:.1} | {} | {rot:.4} | {:.2} | {:.3} | {:.3} s ({:.1} %) |",
            ds.dvl.len(),
            ds.poses.len(),
            1e6 * t / ds.dvl.len() as f64,
            prev.map_or("-".to_string(), |p| format!("{:.1}", t / p)),
            1e3 * (out.params.lever_arm_cam_m() - truth.lever_arm_cam_m()).norm(),
            1e3 * (out.params.time_offset_s - truth.time_offset_s).abs(),
            align,
            100.0 * align / t
        );
        prev = Some(t);
    }
    motion_prior_cost();
}

/// Median seconds of 3 calibrations and the last outcome.
fn timed(
    poses: &[PoseMeasurement],
    dvl: &[DvlSample],
    varying: bool,
) -> (f64, dvlcal::calib::CalibrationOutcome) {
    let opts = CalibOptions {
        varying_motion_prior: varying,
        ..CalibOptions::default()
    };
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..3 {
        let t0 = Instant::now();
        last = Some(calibrate(poses, dvl, &opts).expect("calibrate"));
        times.push(t0.elapsed().as_secs_f64());
    }
    (median(times), last.expect("one run"))
}

fn motion_prior_cost() {
    println!();
    println!(
        "| motion | length | constant prior (median) | varying prior (median) | ratio | kept | refinements again |"
    );
    println!("|---|---|---|---|---|---|---|");
    let track = read_tum(
        Path::new("tests/fixtures/real_motion/euroc_v101_vicon.txt"),
        None,
    )
    .expect("track");
    let euroc = replay_track(&track.poses, &TrackOptions::default()).expect("replay");
    let cfg = |duration_s: f64| SimConfig {
        seed: 3000,
        duration_s,
        pose_sigma_pos_m: 0.002,
        pose_sigma_rot_rad: 0.1f64.to_radians(),
        ..SimConfig::default()
    };
    let cases = [
        (
            "EuRoC V1_01 replayed",
            simulate_with(&cfg(euroc.duration_s), &euroc.motion).expect("simulate"),
        ),
        ("calm then rotate", simulate(&cfg(120.0)).expect("simulate")),
        (
            "calm then rotate",
            simulate(&cfg(1200.0)).expect("simulate"),
        ),
    ];
    for (name, ds) in &cases {
        let (constant, _) = timed(&ds.poses, &ds.dvl, false);
        let (varying, out) = timed(&ds.poses, &ds.dvl, true);
        let (kept, rounds) = out
            .motion_prior
            .as_ref()
            .map_or((false, 0), |m| (m.applied, m.rounds));
        let span = ds.poses.last().map_or(0.0, |p| p.t) - ds.poses.first().map_or(0.0, |p| p.t);
        println!(
            "| {name} | {span:.0} s | {constant:.2} s | {varying:.2} s | {:.2} | {kept} | {rounds} |",
            varying / constant
        );
    }
}
