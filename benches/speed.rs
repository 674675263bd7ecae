//! The speed figures of docs/performance.md as ratios that can be compared between machines:
//! the calibration of 3 hours of data against 18 minutes (linear cost gives 10), with the wall
//! time of each stage; and `dvlcal detect` against Debian's `apriltag` CLI on the same frames.
//!
//! `cargo bench --bench speed` (`-- --calibration-only` or `-- --detection-only` for one part,
//! `-- --calibration-only --short-only` for the 18 minutes alone, e.g. under callgrind;
//! `-- --frames N` for the number of stereo frames of the detection part, default 30). Data: the
//! simulated sinusoid motion, camera poses at 10 Hz and A50 reports at 8 Hz, 1080 s and 10800 s
//! (10.8k and 108k poses, 8.6k and 86k reports), default truth.

#[path = "common/detect_compare.rs"]
mod detect_compare;

use std::time::Instant;

use dvlcal::calib::{CalibOptions, CalibrationOutcome, calibrate};
use dvlcal::sim::{MotionKind, SimConfig, simulate};

/// One calibration of `seconds` of simulated data: the outcome, its wall time, and the data's size.
fn calibration(seconds: f64) -> (CalibrationOutcome, f64, usize, usize) {
    let cfg = SimConfig {
        duration_s: seconds,
        seed: 3,
        dvl_rate_hz: 8.0,
        motion: MotionKind::Sinusoid,
        ..SimConfig::default()
    };
    let ds = simulate(&cfg).expect("simulate");
    let t0 = Instant::now();
    let out = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default()).expect("calibrate");
    let dt = t0.elapsed().as_secs_f64();
    let err = 1e3 * (out.params.time_offset_s - ds.truth.time_offset_s);
    eprintln!("{seconds} s: offset error {err:+.3} ms");
    (out, dt, ds.poses.len(), ds.dvl.len())
}

fn calibration_part() {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    println!("## Calibration ({threads} threads available)\n");
    let short = calibration(1080.0);
    if std::env::args().any(|a| a == "--short-only") {
        return;
    }
    let long = calibration(10800.0);
    println!("| stage | 18 min | 3 h | ratio |");
    println!("|---|---|---|---|");
    for ((name, a), (_, b)) in short.0.stage_seconds.iter().zip(&long.0.stage_seconds) {
        println!("| {name} | {a:.3} s | {b:.3} s | {:.1} |", b / a);
    }
    println!(
        "| **whole calibration** ({} / {} poses, {} / {} DVL reports) | {:.3} s | {:.3} s | {:.1} |\n",
        short.2,
        long.2,
        short.3,
        long.3,
        short.1,
        long.1,
        long.1 / short.1
    );
}

/// `dvlcal detect` (PNG decode, detection, corner refinement, stereo PnP) against the CLI run as
/// one single-threaded process per core (its fastest use of the cores), on one core and on all.
fn detection_part(frames: usize) {
    use detect_compare::{Print, compare, have_cli};
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    println!("## Detection ({frames} rendered 752x480 stereo frames per board print)\n");
    if !have_cli() {
        println!("(the apriltag CLI is not installed: no ratio)\n");
    }
    println!("| board print | threads | dvlcal detect, images/s | CLI, images/s | dvlcal / CLI |");
    println!("|---|---|---|---|---|");
    let threads: Vec<usize> = if cores > 1 { vec![1, cores] } else { vec![1] };
    for print in [Print::Apriltag, Print::Kalibr] {
        for row in compare(print, frames, &threads, 3) {
            println!(
                "| {} | {} | {:.1} | {} | {} |",
                print.label(),
                row.threads,
                row.dvlcal,
                row.cli.map_or("-".into(), |c| format!("{c:.1}")),
                row.ratio().map_or("-".into(), |r| format!("**{r:.2}**"))
            );
        }
    }
    println!();
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let only = |flag: &str| args.iter().any(|a| a == flag);
    let frames = args
        .iter()
        .position(|a| a == "--frames")
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(30);
    if !only("--detection-only") {
        calibration_part();
    }
    if !only("--calibration-only") {
        detection_part(frames);
    }
}
