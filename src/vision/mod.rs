//! Camera poses from stereo images of an AprilTag board: board and camera models, tag detection
//! through libapriltag, and stereo PnP through OpenCV. (Rendered images with known truth are simulation: `sim::render`.)
pub mod board;
pub mod board_svg;
pub mod camera;
pub mod detect;
pub mod family;
pub mod frames;
pub mod images;
pub mod kalibr;
pub mod pnp;
pub(crate) mod refine;
