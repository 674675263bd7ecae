//! The lever arm on the trolley track with DVL noise correlated over 1 s (docs/method.md,
//! "Correlated DVL errors"): `cargo run --release --example ar1_lever -- [SEEDS]` (default 10).
//! Each seed is simulated as in `benches/real_motion.rs` (10 Hz poses of 2 mm / 0.1 deg, DVL
//! noise of 1 cm/s per axis, first-order autoregressive with a 1 s correlation time) and
//! calibrated by the spline estimator, by dvlcal, and by dvlcal with `honest_covariance` off (the
//! reports weighed as independent, no inflation). Printed: each seed's lever-arm error, then the
//! RMS error per axis and dvlcal's RMS err/std along z.

use dvlcal::calib::model::difference;
use dvlcal::calib::{CalibOptions, calibrate};
use dvlcal::eval::spline_baseline::{BaselineOptions, spline_baseline};
use dvlcal::sim::{Corruption, TrackOptions, corrupt, replay_track, simulate_with};

#[path = "common/trolley.rs"]
mod trolley;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let seeds: u64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(10);
    let piece = trolley::trolley_piece()?;
    let track = replay_track(&piece, &TrackOptions::default())?;
    let names = ["splines", "dvlcal", "dvlcal, reports as independent"];
    let mut squares = [[0.0f64; 3]; 3];
    let mut z2 = 0.0;
    for seed in 0..seeds {
        let cfg = trolley::bench_config(seed, &track);
        let mut ds = simulate_with(&cfg, &track.motion)?;
        let ar1 = Corruption {
            dvl_ar1_tau_s: Some(1.0),
            ..Corruption::default()
        };
        corrupt(&mut ds, &ar1, 0.01, 7000 + seed)?;
        let spline = spline_baseline(
            &ds.poses,
            &ds.dvl,
            &BaselineOptions {
                pose_sigma_pos_m: 0.002,
                pose_sigma_rot_rad: 0.1f64.to_radians(),
                ..BaselineOptions::default()
            },
        )?;
        let own = calibrate(&ds.poses, &ds.dvl, &CalibOptions::default())?;
        let plain = calibrate(
            &ds.poses,
            &ds.dvl,
            &CalibOptions {
                honest_covariance: false,
                ..CalibOptions::default()
            },
        )?;
        let mut row = format!("seed {seed}:");
        for (v, p) in [&spline.params, &own.params, &plain.params]
            .into_iter()
            .enumerate()
        {
            let d = difference(p, &ds.truth);
            for k in 0..3 {
                squares[v][k] += d[3 + k] * d[3 + k];
            }
            row += &format!(
                " | {} {:+.0} {:+.0} {:+.0} mm",
                names[v],
                d[3] * 1e3,
                d[4] * 1e3,
                d[5] * 1e3
            );
        }
        let d = difference(&own.params, &ds.truth);
        z2 += d[5] * d[5] / own.covariance[(5, 5)];
        println!("{row}");
    }
    let n = seeds as f64;
    for (name, sq) in names.iter().zip(squares) {
        println!(
            "{name}: lever arm RMS error {:.1} {:.1} {:.1} mm",
            (sq[0] / n).sqrt() * 1e3,
            (sq[1] / n).sqrt() * 1e3,
            (sq[2] / n).sqrt() * 1e3
        );
    }
    println!(
        "dvlcal: RMS err/std of the lever arm's z {:.2}",
        (z2 / n).sqrt()
    );
    Ok(())
}
