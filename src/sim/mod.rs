//! Synthetic datasets with known truth.
//!
//! - [`rng`]: a deterministic random number generator of our own (streams never change).
//! - [`motion`]: continuous camera motions with exact poses, twists and twist rates.
//! - [`dataset`]: noisy camera poses and DVL velocities simulated from a motion and a known
//!   calibration.

pub mod dataset;
pub mod motion;
pub mod rng;

pub use dataset::{
    MotionKind, SimConfig, SimDataset, build_motion, dvl_model, simulate, simulate_with,
};
pub use motion::{
    MeanReversion, Motion, MotionState, SampledConfig, SampledMotion, ScrewMotion, SinusoidMotion,
    SinusoidTerm,
};
pub use rng::Rng;
