//! Results in words, shared by the report and the printed summary.

use crate::calib::Method;

/// The velocity scale read as a speed of sound. A piston-array DVL like the A50 reports the true
/// velocity times `c_assumed / c_water`, so with the sound speed the DVL assumed the scale says
/// what the water's was; without it, how far apart the two are in per cent.
pub fn sound_speed_words(scale: f64, scale_std: f64, assumed_mps: Option<f64>) -> String {
    match assumed_mps {
        Some(c) if scale > 0.0 => {
            let water = c / scale;
            format!(
                "the DVL assumes a sound speed of {c:.0} m/s; the data say the water's is about \
                 {water:.0} m/s (+- {:.0} m/s)",
                water * scale_std / scale
            )
        }
        _ if scale > 0.0 => format!(
            "the DVL's velocities are {:.2} % {} than the camera's (+- {:.2} %): the sound speed it \
             assumes is that much {} than the water's",
            100.0 * (scale - 1.0).abs(),
            if scale >= 1.0 { "higher" } else { "lower" },
            100.0 * scale_std,
            if scale >= 1.0 { "higher" } else { "lower" }
        ),
        _ => "the velocity scale is not positive: no sound speed can be read from it".into(),
    }
}

/// Whether the method estimated a group of parameters (rotation and lever arm, or clock offset
/// and scale).
pub(super) fn estimated(m: &Method, extrinsic: bool) -> bool {
    match m {
        Method::Uic | Method::Bcd(_) => true,
        Method::Fixed {
            estimate_offset, ..
        } => !extrinsic && *estimate_offset,
    }
}

pub(super) fn method_words(m: &Method) -> &'static str {
    match m {
        Method::Uic => "UIC: initialised from the data alone, then refined",
        Method::Bcd(_) => "refinement from the given initial guess",
        Method::Fixed {
            estimate_offset: true,
            ..
        } => "extrinsics held at the given values; clock offset and scale estimated",
        Method::Fixed { .. } => "all parameters held at the given values (evaluation only)",
    }
}
