//! The trolley track of `benches/real_motion.rs`, shared by the examples that study it: its
//! longest piece after cutting, and the bench's simulation settings for one seed.

use std::path::Path;

use dvlcal::io::tum::read_tum;
use dvlcal::sim::{CutOptions, SimConfig, TrackMotion, cut_track};
use dvlcal::types::PoseMeasurement;

const TRACK: &str = "tests/fixtures/real_motion/uwb_trolley_slow_mocap.txt";

/// The trolley's recorded poses, cut at tracking losses and held poses: the longest piece.
pub fn trolley_piece() -> Result<Vec<PoseMeasurement>, Box<dyn std::error::Error>> {
    let recorded = read_tum(Path::new(TRACK), None)?.poses;
    let cut = cut_track(&recorded, &CutOptions::default())?;
    Ok(cut.longest().ok_or("no usable piece")?.to_vec())
}

/// The bench's settings for `seed` on `track`: 10 Hz poses of 2 mm / 0.1 deg, DVL noise of
/// 1 cm/s per axis.
pub fn bench_config(seed: u64, track: &TrackMotion) -> SimConfig {
    SimConfig {
        seed: 3000 + seed,
        duration_s: track.duration_s,
        dvl_sigma: 0.01,
        pose_sigma_pos_m: 0.002,
        pose_sigma_rot_rad: 0.1f64.to_radians(),
        ..SimConfig::default()
    }
}
