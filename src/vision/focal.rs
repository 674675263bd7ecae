//! The camchain's focal lengths checked against the recording itself.
//!
//! Every posed frame measures, per camera, a factor on that camera's focal lengths
//! ([`crate::vision::pnp::FramePose::focal_scale`]: its own view fitted with the pose and the
//! factor together, the principal point and the distortion kept). A board seen straight on
//! cannot tell the focal length from the distance, so such frames measure it poorly and weigh
//! little; tilted views measure it well. Over a recording the frames' factors are combined as
//! the board's scale is ([`crate::vision::scale::combine`]: outliers out, inverse-variance
//! weighted mean, standard deviation from the frames' spread, a floor added in quadrature).
//!
//! A focal length wrong by a fraction scales every distance the camera measures, and with them
//! the DVL's velocity scale and the lever arm; the board's scale does not show it (a focal
//! length and the distance it implies change together). A factor farther from 1 than
//! [`SIGNIFICANT_STD`] standard deviations and [`SIGNIFICANT_FRACTION`] is a warning; the
//! poses are not corrected (the camchain is the user's to recalibrate). A recording whose views
//! do not vary enough to measure it (standard deviation above [`MAX_USEFUL_STD`]) says so.

use crate::vision::frames::FrameResult;
use crate::vision::scale::combine;

/// Fewest frames with a factor for a camera's check.
pub const MIN_FRAMES: usize = 10;

/// Standard deviation added in quadrature for what the frames' spread cannot show: a bias of
/// the corners that every frame shares. On the rendered recording of `sample_data/stereo` the
/// focal lengths come out 0.4 % to 0.6 % long (a full `calibrate-cameras` of the same images
/// finds 0.7 %): with the renders' blur (sigma 0.7 px) and cells of 2 to 3 px, the corner
/// refinement places each tag's sides about 0.05 px too far out, and the strong radial
/// distortion (k1 = -0.28) makes tags near the edge smaller, so the enlargement grows with the
/// radius and reads as a focal length held against a fixed distortion. Without blur, or with
/// tags twice as large, the factor comes out within 0.01 % of 1. The floor keeps that from
/// warning.
pub const SYSTEMATIC_STD: f64 = 2.5e-3;

/// A factor is reported when it differs from 1 by more than this many standard deviations ...
pub const SIGNIFICANT_STD: f64 = 3.0;

/// ... and by more than this fraction (1 %).
pub const SIGNIFICANT_FRACTION: f64 = 0.01;

/// Above this standard deviation (2 %) the recording's views do not check the focal length.
pub const MAX_USEFUL_STD: f64 = 0.02;

/// One camera's focal length as the recording measures it.
#[derive(Clone, Debug, PartialEq)]
pub struct FocalScale {
    /// The camera's index in the chain.
    pub cam: usize,
    /// The measured focal length over the camchain's.
    pub scale: f64,
    /// Its standard deviation.
    pub std: f64,
    /// Frames it rests on.
    pub frames: usize,
}

impl FocalScale {
    /// Whether the recording's views measure the focal length usefully.
    pub fn useful(&self) -> bool {
        self.std <= MAX_USEFUL_STD
    }

    /// Whether the camchain's focal length is contradicted.
    pub fn significant(&self) -> bool {
        let d = (self.scale - 1.0).abs();
        self.useful() && d > SIGNIFICANT_STD * self.std && d > SIGNIFICANT_FRACTION
    }

    /// "cam1's focal length measures 102.0 +- 0.2 % of camchain.yaml's".
    pub fn measures(&self, camchain: &str) -> String {
        format!(
            "cam{}'s focal length measures {:.1} +- {:.1} % of {camchain}'s",
            self.cam,
            100.0 * self.scale,
            100.0 * self.std
        )
    }

    /// What a significant factor means.
    pub fn warning(&self, camchain: &str) -> String {
        format!(
            "{} (from {} frames): a focal length off by a fraction scales every distance the \
             camera measures, and with them the DVL's velocity scale and lever arm; recalibrate \
             the camera (dvlcal calibrate-cameras) or check that {camchain} belongs to these \
             images",
            self.measures(camchain),
            self.frames
        )
    }
}

/// Each camera's focal length over the posed frames of `results` (`None` for a camera with
/// fewer than [`MIN_FRAMES`] usable frames).
pub fn focal_scales(results: &[FrameResult], cams: usize) -> Vec<Option<FocalScale>> {
    (0..cams)
        .map(|cam| {
            let fits: Vec<_> = results
                .iter()
                .filter_map(|r| r.pose.as_ref())
                .filter_map(|p| p.focal_scale.get(cam).copied().flatten())
                .collect();
            let c = combine(&fits, MIN_FRAMES, SYSTEMATIC_STD)?;
            Some(FocalScale {
                cam,
                scale: c.value,
                std: c.std,
                frames: c.frames,
            })
        })
        .collect()
}
