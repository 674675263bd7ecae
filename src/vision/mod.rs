//! Camera poses from stereo images of an AprilTag board: board and camera models, tag detection
//! through libapriltag, stereo PnP through OpenCV, and a renderer for datasets with known truth.
pub mod board;
pub mod camera;
pub mod detect;
pub mod images;
pub mod pipeline;
pub mod pnp;
pub mod refine;
pub mod render;
pub mod synth;
