//! Camera poses from stereo images of an AprilTag board: tag detection through libapriltag, and
//! stereo PnP through OpenCV, on the board and camera models of `types`. (Rendered images with
//! known truth are simulation: `sim::render`.)
pub mod board_svg;
pub mod detect;
pub mod family;
pub mod focal;
pub mod frames;
pub mod kalibr;
pub mod pnp;
pub(crate) mod refine;
pub mod scale;
pub mod sharpness;
