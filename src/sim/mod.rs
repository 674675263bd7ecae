//! Synthetic datasets with known truth.
//!
//! Random draws come from [`crate::rng`], the crate's own seeded generator.
//!
//! - [`motion`]: continuous camera motions with exact poses, twists and twist rates.
//! - [`dataset`]: noisy camera poses and DVL velocities simulated from a motion and a known
//!   calibration.
//! - [`corrupt`](mod@corrupt): damage to a simulated dataset as real recordings suffer it (DVL
//!   spikes, bad poses, coloured DVL noise, gaps).
//! - [`track`]: a recorded vehicle track (motion capture, INS) cut at tracking losses and glitches
//!   and replayed as a motion.
//! - [`a50`]: simulated DVL samples as the A50's json_v3 reports.
//! - [`render`]: camera images of a board, rendered from libapriltag's own tag patterns.
//! - [`image_dataset`]: the stereo images of a simulated recording, written as a dataset folder.
//! - [`imu`](mod@imu): an IMU on a simulated motion, with noise and walking biases.
//! - [`camcal_views`]: board poses of a camera calibration, spread over the image, distances and
//!   tilts as a person waving a board in front of a stereo rig shows them.

pub mod a50;
pub mod camcal_views;
pub mod corrupt;
pub mod dataset;
pub mod image_dataset;
pub mod imu;
pub mod motion;
pub mod render;
pub mod track;

pub use corrupt::{Corruption, CorruptionLog, corrupt};
pub use dataset::{
    MotionKind, SimConfig, SimDataset, build_motion, dvl_model, simulate, simulate_with,
};
pub use motion::{
    MeanReversion, Motion, MotionState, SampledConfig, SampledMotion, ScrewMotion, SinusoidMotion,
    SinusoidTerm,
};
pub use track::{CutOptions, CutTrack, TrackMotion, TrackOptions, cut_track, replay_track};
