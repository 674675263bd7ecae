//! Continuous-time camera trajectory: Lie groups and the white-noise-on-jerk Gaussian process.

pub mod lie;
