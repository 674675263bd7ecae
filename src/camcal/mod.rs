//! Camera calibration from images of a board: the intrinsics and distortion of every camera of a
//! chain and the extrinsics `T_cn_c0`, by one bundle adjustment over all usable frames.
//!
//! The steps:
//! 1. [`views`]: the tag detections of every frame matched to the board's corners; views (one
//!    camera in one frame) with too few corners are left out and counted.
//! 2. [`init`]: a first estimate per camera from OpenCV's `calibrateCamera` (Zhang's method on the
//!    board's homographies, then OpenCV's own refinement), the stereo extrinsics from the board
//!    poses both cameras saw in the same frames.
//! 3. [`bundle`]: Levenberg-Marquardt over the reprojection errors of every corner in every
//!    camera, with each frame's board pose `T_c0_board` as a free 6-dof unknown eliminated by a
//!    Schur complement. Corners whose residual exceeds `outlier_sigmas` robust standard deviations
//!    are dropped, frames whose RMS is far above the others are dropped and named, and the fit is
//!    repeated until nothing more is dropped.
//! 4. [`quality`]: standard deviations of every parameter (`sigma^2 (J^T J)^-1` with the
//!    estimated corner noise), the coverage of each image by corners, and warnings where the
//!    result is weak (distortion fitted where no corner was, a wide uncertainty).
//!
//! The result is a [`Camchain`](crate::types::camera::Camchain), written in Kalibr's camchain format.

pub mod bundle;
pub mod init;
pub mod quality;
pub mod types;
pub mod views;

pub use bundle::calibrate_cameras;
pub use types::{
    CamCalOptions, CamCalResult, CameraModel, CameraStd, CornerObs, Coverage, FrameFit, FrameTags,
    Residual,
};
