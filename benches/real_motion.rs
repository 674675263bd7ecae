//! Calibration on real vehicles' motion (docs/accuracy.md, "Real vehicle motion").
//!
//! `cargo bench --bench real_motion -- [SEEDS] [TIME_SCALE...] [TRACK...]` (defaults: 20 seeds,
//! every track of `TRACKS` at its own time scales). Numbers are the seed count and then time
//! scales (which replace every track's own); any other word names a track of `TRACKS`
//! (`euroc_v101`, `tumvi_room6`, `trolley_slow`) and runs only the tracks named. The environment
//! variable `DVLCAL_TRACK` (names separated by commas) selects tracks the same way. So
//! `-- 20 1 2 euroc_v101` is the EuRoC-only run of docs/accuracy.md, and `-- 2` a quick look at
//! every track (about a minute on two cores).
//!
//! Each track (`tests/fixtures/real_motion/`) is cut at its tracking losses and glitches by
//! `dvlcal::sim::cut_track`, and its longest piece replayed with `dvlcal::sim::replay_track` (time
//! scale 2 plays it at half speed, closer to an underwater vehicle's). From it: 10 Hz camera poses
//! of 2 mm / 0.1 deg and 10 Hz DVL reports of 1 cm/s from the simulator's default calibration.
//! Each seed is calibrated by dvlcal (defaults) and by the independent smoothing-spline estimator
//! (`dvlcal::eval::spline_baseline`). Printed per parameter group: RMSE of each with a 95 %
//! percentile-bootstrap interval, their ratio, and the RMS of dvlcal's `err / std`, over the runs
//! dvlcal did not fail (those whose status failed are counted apart). For the tracks
//! marked so in `TRACKS` (EuRoC V1_01), a last table per time scale refits with the jerk density
//! `Qc` fixed at 0.3, 1, 3, 10 and 30 times the one the hyperparameter search chooses from the
//! poses, and prints the mean lever-arm error (its bias) and the marginal likelihood of poses and
//! DVL together at each factor. Each track's section ends with its run time.
//!
//! `DVLCAL_BENCH_THREADS` sets the worker threads (default: all CPUs).

mod common;

use std::path::Path;

use common::par_map;
use dvlcal::calib::model::difference;
use dvlcal::calib::{CalibOptions, WeakCause, calibrate, jerk_density_evidence};
use dvlcal::eval::spline_baseline::{BaselineOptions, spline_baseline};
use dvlcal::io::tum::read_tum;
use dvlcal::sim::{
    Corruption, CutOptions, SimConfig, TrackMotion, TrackOptions, corrupt, cut_track, replay_track,
    simulate_with,
};
use dvlcal::types::PoseMeasurement;

/// A recorded track: its name on the command line, its file, what moved, the time scales it is
/// replayed at by default, and whether the jerk-density table is printed for it.
struct Track {
    name: &'static str,
    file: &'static str,
    kind: &'static str,
    scales: &'static [f64],
    qc_table: bool,
}

const TRACKS: [Track; 3] = [
    Track {
        name: "euroc_v101",
        file: "tests/fixtures/real_motion/euroc_v101_vicon.txt",
        kind: "EuRoC V1_01, a flying vehicle",
        scales: &[1.0, 2.0],
        qc_table: true,
    },
    Track {
        name: "tumvi_room6",
        file: "tests/fixtures/real_motion/tumvi_room6_mocap.txt",
        kind: "TUM VI room6, a hand-held rig",
        scales: &[2.0],
        qc_table: false,
    },
    Track {
        name: "trolley_slow",
        file: "tests/fixtures/real_motion/uwb_trolley_slow_mocap.txt",
        kind: "a trolley at 0.1 m/s, a slow ground vehicle",
        scales: &[1.0],
        qc_table: false,
    },
];
const DVL_SIGMA: f64 = 0.01;
const POSE_SIGMA_M: f64 = 0.002;
const POSE_SIGMA_DEG: f64 = 0.1;

const GROUPS: [(&str, std::ops::Range<usize>, f64, &str); 4] = [
    ("rotation", 0..3, 57.295_779_513_082_32, "deg"),
    ("lever arm", 3..6, 1e3, "mm"),
    ("scale", 6..7, 1e3, "1e-3"),
    ("clock offset", 7..8, 1e3, "ms"),
];

#[derive(Clone, Copy)]
struct Run {
    ours: [f64; 8],
    z: [f64; 8],
    spline: [f64; 8],
    lever_held: bool,
    /// The lever arm held along the one axis the motion turned about, the rest estimated.
    lever_axis_held: bool,
    /// dvlcal's status said the result cannot be trusted.
    failed: bool,
}

/// The simulation of seed `seed` on the replayed track.
fn config(seed: u64, track: &TrackMotion) -> SimConfig {
    SimConfig {
        seed: 3000 + seed,
        duration_s: track.duration_s,
        dvl_sigma: DVL_SIGMA,
        pose_sigma_pos_m: POSE_SIGMA_M,
        pose_sigma_rot_rad: POSE_SIGMA_DEG.to_radians(),
        ..SimConfig::default()
    }
}

fn run(seed: u64, track: &TrackMotion, damage: &Corruption) -> Option<Run> {
    let cfg = config(seed, track);
    let mut ds = simulate_with(&cfg, &track.motion).ok()?;
    corrupt(&mut ds, damage, DVL_SIGMA, 7000 + seed).ok()?;
    let o = match calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()) {
        Ok(o) => o,
        Err(e) => {
            eprintln!("seed {seed}: dvlcal: {e}");
            return None;
        }
    };
    let b = match spline_baseline(
        &ds.poses,
        &ds.dvl,
        &BaselineOptions {
            pose_sigma_pos_m: POSE_SIGMA_M,
            pose_sigma_rot_rad: POSE_SIGMA_DEG.to_radians(),
            ..BaselineOptions::default()
        },
    ) {
        Ok(b) => b,
        Err(e) => {
            eprintln!("seed {seed}: spline baseline: {e}");
            return None;
        }
    };
    let d = difference(&o.params, &ds.truth);
    let ds_ = difference(&b.params, &ds.truth);
    let mut r = Run {
        ours: [0.0; 8],
        z: [0.0; 8],
        spline: [0.0; 8],
        lever_held: o.lever_arm_from_default_prior,
        lever_axis_held: o.verdicts.lever_arm.cause == Some(WeakCause::FewRotationAxes),
        failed: !o.status.is_ok(),
    };
    for k in 0..8 {
        r.ours[k] = d[k];
        r.spline[k] = ds_[k];
        r.z[k] = d[k] / o.covariance[(k, k)].max(1e-300).sqrt();
    }
    Some(r)
}

/// Lever-arm error vector, offset error and scale error of dvlcal with the jerk density fixed at
/// `factor` times the one it chooses itself (white DVL noise).
fn run_qc(seed: u64, track: &TrackMotion, factor: f64) -> Option<([f64; 3], f64, f64, f64)> {
    let cfg = config(seed, track);
    let ds = simulate_with(&cfg, &track.motion).ok()?;
    let mut opts = CalibOptions::default();
    let own = calibrate(&ds.poses, &ds.dvl, &opts).ok()?;
    let evidence = jerk_density_evidence(&ds.poses, &own, factor).ok()?
        - jerk_density_evidence(&ds.poses, &own, 1.0).ok()?;
    opts.fit.qc = Some(own.trajectory.qc * factor);
    let o = calibrate(&ds.poses, &ds.dvl, &opts).ok()?;
    let d = difference(&o.params, &ds.truth);
    Some(([d[3], d[4], d[5]], d[7], d[6], evidence))
}

/// RMS over the runs of a group's error norm and a 95 % percentile-bootstrap interval.
fn rmse(runs: &[Run], pick: fn(&Run) -> [f64; 8], range: &std::ops::Range<usize>) -> [f64; 3] {
    let sq: Vec<f64> = runs
        .iter()
        .map(|r| range.clone().map(|k| pick(r)[k].powi(2)).sum())
        .collect();
    common::rms_bootstrap(&sq, range.start as u64)
}

/// The longest piece of `track`'s recording after cutting, with a line saying what was cut.
fn load(track: &Track) -> Result<(Vec<PoseMeasurement>, String), String> {
    let recorded = read_tum(Path::new(track.file), None)
        .map_err(|e| e.to_string())?
        .poses;
    let cut = cut_track(&recorded, &CutOptions::default()).map_err(|e| e.to_string())?;
    let piece = cut
        .longest()
        .ok_or_else(|| format!("{}: no usable piece", track.file))?
        .to_vec();
    let note = format!(
        "{} poses cut into {} pieces ({} tracking losses, {} holds of {} poses, {} glitches of {} \
         poses, {} jumps, {} repeated times, {} short pieces dropped); the longest has {} poses",
        recorded.len(),
        cut.pieces.len(),
        cut.gaps,
        cut.holds,
        cut.held_poses,
        cut.glitches,
        cut.glitch_poses,
        cut.jumps,
        cut.duplicates,
        cut.short_pieces,
        piece.len()
    );
    Ok((piece, note))
}

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let numbers: Vec<f64> = args.iter().filter_map(|a| a.parse().ok()).collect();
    let mut names: Vec<String> = args
        .iter()
        .filter(|a| a.parse::<f64>().is_err())
        .cloned()
        .collect();
    if let Ok(env) = std::env::var("DVLCAL_TRACK") {
        names.extend(
            env.split(',')
                .map(|s| s.trim().to_string())
                .filter(|s| !s.is_empty()),
        );
    }
    if let Some(bad) = names
        .iter()
        .find(|n| !TRACKS.iter().any(|t| t.name == n.as_str()))
    {
        let known: Vec<&str> = TRACKS.iter().map(|t| t.name).collect();
        eprintln!("unknown track {bad}; the tracks are {}", known.join(", "));
        std::process::exit(2);
    }
    let seeds = numbers.first().map_or(20, |&s| s.max(1.0) as usize);
    let scales_arg: Vec<f64> = numbers.iter().skip(1).copied().collect();
    for track in TRACKS
        .iter()
        .filter(|t| names.is_empty() || names.iter().any(|n| n == t.name))
    {
        let start = std::time::Instant::now();
        let (piece, note) = match load(track) {
            Ok(p) => p,
            Err(e) => {
                eprintln!("{e}");
                std::process::exit(1);
            }
        };
        println!("# {} ({}): {note}\n", track.name, track.kind);
        let scales = if scales_arg.is_empty() {
            track.scales.to_vec()
        } else {
            scales_arg.clone()
        };
        for &scale in &scales {
            bench_scale(track, &piece, scale, seeds);
        }
        println!(
            "{}: {:.0} s in all\n",
            track.name,
            start.elapsed().as_secs_f64()
        );
    }
}

/// The tables of one track at one time scale.
fn bench_scale(track_def: &Track, recorded: &[PoseMeasurement], scale: f64, seeds: usize) {
    let track = match replay_track(
        recorded,
        &TrackOptions {
            time_scale: scale,
            ..TrackOptions::default()
        },
    ) {
        Ok(t) => t,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1);
        }
    };
    let d = track.duration_s;
    // Six tracking losses of 2-6 s spread over the recording (poses and the DVL reports in
    // them stay; the camera loses the board, the DVL keeps its lock).
    let losses: Vec<(f64, f64)> = [
        (0.12, 3.0),
        (0.27, 5.0),
        (0.41, 2.0),
        (0.56, 6.0),
        (0.72, 4.0),
        (0.87, 3.0),
    ]
    .iter()
    .map(|&(f, len)| (f * d, len))
    .collect();
    let scenarios = [
        ("white DVL noise", Corruption::default()),
        (
            "AR(1) DVL noise, 1 s",
            Corruption {
                dvl_ar1_tau_s: Some(1.0),
                ..Corruption::default()
            },
        ),
        (
            "white DVL noise, six tracking losses of 2-6 s",
            Corruption {
                pose_gaps: losses,
                ..Corruption::default()
            },
        ),
    ];
    println!(
        "## {} replayed at time scale {scale}: {:.1} s, RMS speed {:.3} m/s, RMS rate {:.3} rad/s \
         (twists smoothed over {:.0} ms, replay drift {:.1} mm RMS)\n",
        track_def.name,
        track.duration_s,
        track.rms_speed_mps,
        track.rms_rate_radps,
        track.smoothing_s * 1e3,
        track.position_drift_rms_m * 1e3
    );
    for (name, damage) in &scenarios {
        let start = std::time::Instant::now();
        // A run whose status fails is one a user is told not to take: counted, not averaged.
        let (failed, runs): (Vec<Run>, Vec<Run>) = par_map(seeds, |s| run(s, &track, damage))
            .into_iter()
            .flatten()
            .partition(|r| r.failed);
        println!(
            "### {name}: {} runs, lever arm held at the default prior in {} (along one axis \
             in {} more), {} more failed by dvlcal's status (not in the table) ({:.0} s)\n",
            runs.len(),
            runs.iter().filter(|r| r.lever_held).count(),
            runs.iter().filter(|r| r.lever_axis_held).count(),
            failed.len(),
            start.elapsed().as_secs_f64()
        );
        println!(
            "| parameter | dvlcal RMSE [95 % CI] | spline RMSE [95 % CI] | dvlcal / spline | RMS err/std dvlcal |"
        );
        println!("|---|---|---|---|---|");
        for (label, range, f, unit) in GROUPS.iter() {
            let a = rmse(&runs, |r| r.ours, range);
            let b = rmse(&runs, |r| r.spline, range);
            let zs: f64 = runs
                .iter()
                .flat_map(|r| range.clone().map(move |k| r.z[k] * r.z[k]))
                .sum::<f64>()
                / (runs.len() * range.len()).max(1) as f64;
            println!(
                "| {label} ({unit}) | {:.3} [{:.3}, {:.3}] | {:.3} [{:.3}, {:.3}] | {:.2} | {:.2} |",
                a[0] * f,
                a[1] * f,
                a[2] * f,
                b[0] * f,
                b[1] * f,
                b[2] * f,
                a[0] / b[0],
                zs.sqrt()
            );
        }
        println!();
    }
    if !track_def.qc_table {
        return;
    }
    println!(
        "### Jerk density: dvlcal with Qc fixed at a multiple of the one it chooses (white DVL \
         noise)\n"
    );
    println!(
        "| Qc factor | mean lever-arm error x, y, z (mm) | lever-arm RMSE (mm) | scale RMSE (1e-3) | offset RMSE (ms) | log evidence - factor 1's (mean) |"
    );
    println!("|---|---|---|---|---|---|");
    for factor in [0.3, 1.0, 3.0, 10.0, 30.0] {
        let runs: Vec<_> = par_map(seeds, |s| run_qc(s, &track, factor))
            .into_iter()
            .flatten()
            .collect();
        let n = runs.len().max(1) as f64;
        let mut mean = [0.0; 3];
        let (mut lever2, mut off2, mut scale2, mut ev) = (0.0, 0.0, 0.0, 0.0);
        for (p, off, sc, e) in &runs {
            ev += e / n;
            for k in 0..3 {
                mean[k] += p[k] / n;
                lever2 += p[k] * p[k] / n;
            }
            off2 += off * off / n;
            scale2 += sc * sc / n;
        }
        println!(
            "| {factor} | {:.1}, {:.1}, {:.1} | {:.2} | {:.3} | {:.3} | {:.0} |",
            mean[0] * 1e3,
            mean[1] * 1e3,
            mean[2] * 1e3,
            lever2.sqrt() * 1e3,
            scale2.sqrt() * 1e3,
            off2.sqrt() * 1e3,
            ev
        );
    }
    println!();
}
