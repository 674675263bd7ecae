//! Continuous-time camera trajectory: Lie groups and the white-noise-on-jerk Gaussian process.

pub(crate) mod blocktri;
pub mod density;
pub mod factors;
pub mod fit;
pub mod gp;
pub(crate) mod hyper;
pub(crate) mod solver;
pub mod view;

pub use density::JerkDensity;
pub use fit::{FitOptions, FitReport, Trajectory};
pub use gp::{Knot, Motion};
pub use view::{KnotView, TrajectoryState, TwistJacobian};
