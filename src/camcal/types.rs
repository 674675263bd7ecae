//! The values a camera calibration takes and gives.

use nalgebra::{Vector2, Vector3};

use crate::lie::Se3;
use crate::types::camera::{Camchain, Distortion};
use crate::vision::detect::TagDetection;

/// The camera model to fit (Kalibr's names: `pinhole-radtan`, `pinhole-equi`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CameraModel {
    /// Pinhole with radial-tangential distortion `[k1, k2, p1, p2]`.
    PinholeRadtan,
    /// Pinhole with equidistant (fisheye) distortion `[k1, k2, k3, k4]`.
    PinholeEqui,
}

impl CameraModel {
    /// Kalibr's name of the model.
    pub fn name(&self) -> &'static str {
        match self {
            CameraModel::PinholeRadtan => "pinhole-radtan",
            CameraModel::PinholeEqui => "pinhole-equi",
        }
    }

    /// The model named as Kalibr names it (`pinhole-radtan`, `pinhole-equi`).
    pub fn from_name(s: &str) -> Option<CameraModel> {
        match s {
            "pinhole-radtan" => Some(CameraModel::PinholeRadtan),
            "pinhole-equi" => Some(CameraModel::PinholeEqui),
            _ => None,
        }
    }

    /// The distortion of this model with the given coefficients.
    pub fn distortion(&self, k: [f64; 4]) -> Distortion {
        match self {
            CameraModel::PinholeRadtan => Distortion::RadTan {
                k1: k[0],
                k2: k[1],
                p1: k[2],
                p2: k[3],
            },
            CameraModel::PinholeEqui => Distortion::Equidistant {
                k1: k[0],
                k2: k[1],
                k3: k[2],
                k4: k[3],
            },
        }
    }
}

/// The tags one stereo frame shows: one detection list per camera.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameTags {
    /// The frame's name in messages and the report (an image file name or a time stamp).
    pub name: String,
    /// cam0's time stamp, ns (0 when unknown).
    pub t_ns: i64,
    /// Detections per camera (an empty list where a camera has no image or saw no tag).
    pub dets: Vec<Vec<TagDetection>>,
}

/// Settings of [`calibrate_cameras`](crate::camcal::calibrate_cameras).
#[derive(Clone, Debug, PartialEq)]
pub struct CamCalOptions {
    /// The camera model every camera is fitted with.
    pub model: CameraModel,
    /// A view (one camera, one frame) with fewer board corners is not used.
    pub min_view_corners: usize,
    /// A camera needs at least this many views.
    pub min_views: usize,
    /// A corner whose residual norm exceeds this many robust standard deviations of the residual
    /// components is an outlier.
    pub outlier_sigmas: f64,
    /// A frame whose reprojection RMS (after corner outliers) exceeds this many times the median
    /// frame RMS is an outlier frame: it is dropped and named.
    pub frame_rms_factor: f64,
    /// A tag with a corner closer than this to the image's edge (px) is not used: the side of a
    /// tag cut by the edge cannot be fitted, and its corners can be pixels off.
    pub border_px: f64,
    /// Levenberg-Marquardt iterations per fit.
    pub max_iterations: usize,
    /// Cells across the image width for the coverage grid (rows follow the aspect ratio).
    pub coverage_cells: usize,
}

impl Default for CamCalOptions {
    fn default() -> Self {
        CamCalOptions {
            model: CameraModel::PinholeRadtan,
            min_view_corners: 12,
            min_views: 5,
            outlier_sigmas: 5.0,
            frame_rms_factor: 3.0,
            border_px: 5.0,
            max_iterations: 100,
            coverage_cells: 12,
        }
    }
}

/// One corner seen in one camera in one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CornerObs {
    /// Index of the frame in the input.
    pub frame: usize,
    /// Camera index.
    pub cam: usize,
    /// Tag id and corner number (0..4, libapriltag's order).
    pub tag: u32,
    /// Corner number within the tag.
    pub corner: u8,
    /// The corner in the board frame, m.
    pub board: Vector3<f64>,
    /// The detected pixel (centre of the top-left pixel at 0).
    pub px: Vector2<f64>,
}

/// Standard deviations of one camera's parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraStd {
    /// `[fu, fv, pu, pv]`, px.
    pub intrinsics: [f64; 4],
    /// The four distortion coefficients, in Kalibr's order.
    pub distortion: [f64; 4],
    /// For cameras after cam0: the rotation of `T_cn_cnm1` about its x, y, z axes, rad (small-angle
    /// perturbation on the left, in cam n).
    pub rotation_rad: Option<[f64; 3]>,
    /// For cameras after cam0: the translation of `T_cn_cnm1`, m.
    pub translation_m: Option<[f64; 3]>,
    /// For cameras after cam0: the baseline `|t(T_cn_cnm1)|`, m.
    pub baseline_m: Option<f64>,
}

/// One residual of the final fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Residual {
    /// Frame index in the input.
    pub frame: usize,
    /// Camera index.
    pub cam: usize,
    /// The detected pixel.
    pub px: Vector2<f64>,
    /// Reprojected minus detected, px.
    pub r: Vector2<f64>,
    /// Whether the corner was used (false: dropped as an outlier corner or with its frame).
    pub used: bool,
}

/// How one frame fared.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameFit {
    /// Frame index in the input.
    pub frame: usize,
    /// The frame's name.
    pub name: String,
    /// cam0's time stamp, ns.
    pub t_ns: i64,
    /// Board corners per camera that were matched to the board.
    pub corners: Vec<usize>,
    /// The frame's board pose `T_c0_board`, when the frame was used.
    pub t_c0_board: Option<Se3>,
    /// Reprojection RMS per camera over the used corners, px (`None`: the camera had no view).
    pub rms_px: Vec<Option<f64>>,
    /// Why the frame was not used, if it was not.
    pub dropped: Option<String>,
}

/// Where the corners of one camera fell on its image.
#[derive(Clone, Debug, PartialEq)]
pub struct Coverage {
    /// Grid columns and rows.
    pub cols: usize,
    /// Grid rows.
    pub rows: usize,
    /// Used corners per cell, row-major.
    pub counts: Vec<usize>,
    /// Share of the cells holding at least one used corner.
    pub covered_fraction: f64,
    /// Largest distance of a used corner from the principal point over the distance of the
    /// farthest image corner: below 1 the distortion is extrapolated beyond it.
    pub radial_reach: f64,
}

/// The result of a camera calibration.
#[derive(Clone, Debug)]
pub struct CamCalResult {
    /// The fitted chain (intrinsics, distortion, `T_cn_c0`).
    pub chain: Camchain,
    /// The model fitted.
    pub model: CameraModel,
    /// Standard deviations per camera.
    pub std: Vec<CameraStd>,
    /// Corner noise estimated from the residuals, px per axis.
    pub sigma_px: f64,
    /// Reprojection RMS over all used corners, px (distance, both axes).
    pub rms_px: f64,
    /// Reprojection RMS per camera, px.
    pub rms_px_per_cam: Vec<f64>,
    /// The initial chain (OpenCV) the adjustment started from, and its RMS per camera.
    pub initial: Camchain,
    /// OpenCV's reprojection RMS per camera at the initial estimate, px.
    pub initial_rms_px: Vec<f64>,
    /// Every frame of the input.
    pub frames: Vec<FrameFit>,
    /// Every matched corner with its final residual.
    pub residuals: Vec<Residual>,
    /// Per camera: the coverage of its image.
    pub coverage: Vec<Coverage>,
    /// Views used per camera.
    pub views_used: Vec<usize>,
    /// Corners used and dropped as outliers (over all cameras).
    pub corners_used: usize,
    /// Corners dropped as outliers.
    pub corners_rejected: usize,
    /// Detections whose id is not on the board, or seen twice in one image.
    pub detections_unmatched: usize,
    /// Tags left out because they touch the image's border margin.
    pub tags_at_border: usize,
    /// The tilt of the board against cam0's optical axis (angle between the board's normal and
    /// the axis), 90th percentile over the used frames, degrees. Tilted views separate the focal
    /// length from the board's distance.
    pub tilt_p90_deg: f64,
    /// Levenberg-Marquardt iterations of the final fit.
    pub iterations: usize,
    /// What makes the result weak, in words (empty: nothing found).
    pub warnings: Vec<String>,
}
