//! The clock offset on the trolley track under each robust loss and jerk density
//! (docs/accuracy.md, "Real vehicle motion"): `cargo run --release --example real_motion_loss --
//! [SEEDS] [STEPS]` (default 6 seeds; STEPS, the replay's smallest smoothing kernel in the
//! track's steps, default 2 as in the bench: 0 replays the motion capture's jitter). Each seed
//! is simulated as in `benches/real_motion.rs` (10 Hz poses of 2 mm / 0.1 deg, 10 Hz DVL
//! reports of 1 cm/s, white noise) and calibrated with the Cauchy
//! (default), least-squares and Huber losses, and with the first two at 30 times the jerk density
//! the fit chooses; the spline estimator gives the reference. Printed: each seed's offset error
//! (and dvlcal's std), then the RMS error of each.

use dvlcal::calib::model::difference;
use dvlcal::calib::robust::Loss;
use dvlcal::calib::{CalibOptions, calibrate};
use dvlcal::eval::spline_baseline::{BaselineOptions, spline_baseline};
use dvlcal::sim::{TrackOptions, replay_track, simulate_with};

#[path = "common/trolley.rs"]
mod trolley;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let seeds: u64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(6);
    let piece = trolley::trolley_piece()?;
    let steps: f64 = std::env::args()
        .nth(2)
        .and_then(|s| s.parse().ok())
        .unwrap_or(TrackOptions::default().min_smoothing_steps);
    let track = replay_track(
        &piece,
        &TrackOptions {
            min_smoothing_steps: steps,
            ..TrackOptions::default()
        },
    )?;
    println!(
        "trolley replayed with its twists smoothed over {:.0} ms",
        track.smoothing_s * 1e3
    );
    let variants: [(&str, Loss, f64); 5] = [
        ("cauchy", Loss::Cauchy, 1.0),
        ("l2", Loss::L2, 1.0),
        ("huber", Loss::Huber, 1.0),
        ("cauchy, Qc x30", Loss::Cauchy, 30.0),
        ("l2, Qc x30", Loss::L2, 30.0),
    ];
    let mut squares = [0.0f64; 6];
    for seed in 0..seeds {
        let cfg = trolley::bench_config(seed, &track);
        let ds = simulate_with(&cfg, &track.motion)?;
        let own = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default())?;
        let spline = spline_baseline(&ds.poses, &ds.dvl, &BaselineOptions::default())?;
        let e = difference(&spline.params, &ds.truth)[7];
        squares[0] += e * e;
        let mut row = format!("seed {seed}: spline {:.1} ms", e * 1e3);
        for (k, (name, loss, factor)) in variants.iter().enumerate() {
            let mut opts = CalibOptions {
                loss: *loss,
                // A fixed density turns the varying one off; keep the comparison like for like.
                varying_motion_prior: *factor == 1.0,
                ..CalibOptions::default()
            };
            if *factor != 1.0 {
                opts.fit.qc = Some(own.trajectory.qc * *factor);
            }
            let o = calibrate(&ds.poses, &ds.dvl, &opts)?;
            let d = difference(&o.params, &ds.truth)[7];
            squares[k + 1] += d * d;
            row += &format!(
                " | {name} {:.1} ({:.1})",
                d * 1e3,
                o.covariance[(7, 7)].sqrt() * 1e3
            );
        }
        println!("{row}");
    }
    let names = [
        "spline",
        "cauchy",
        "l2",
        "huber",
        "cauchy, Qc x30",
        "l2, Qc x30",
    ];
    for (name, sq) in names.iter().zip(squares) {
        println!(
            "{name}: RMS offset error {:.1} ms",
            (sq / seeds as f64).sqrt() * 1e3
        );
    }
    Ok(())
}
