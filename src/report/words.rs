//! Results in words, shared by the report and the printed summary.

use crate::calib::Method;

/// The sound speed of natural water, m/s: fresh water near 0 C to salt water at 35 C and a few
/// hundred metres (the A50's working range).
pub const WATER_SOUND_SPEED_MPS: (f64, f64) = (1400.0, 1570.0);

/// The velocity scale read as a speed of sound. A piston-array DVL like the A50 reports the true
/// velocity times `c_assumed / c_water`, so with the sound speed the DVL assumed the scale says
/// what the water's was; without it, how far apart the two are in per cent. The scale is also
/// the camera's scale error (focal lengths, the board's printed size, the stereo baseline): the
/// words say so, and name the camera when the water the scale implies cannot exist.
pub fn sound_speed_words(scale: f64, scale_std: f64, assumed_mps: Option<f64>) -> String {
    match assumed_mps {
        Some(c) if scale > 0.0 => {
            let water = c / scale;
            let mut w = format!(
                "the DVL assumes a sound speed of {c:.0} m/s; the data say the water's is about \
                 {water:.0} m/s (+- {:.0} m/s)",
                water * scale_std / scale
            );
            if let Some(camera) = implausible_water(scale, scale_std, Some(c)) {
                w.push_str("; ");
                w.push_str(&camera);
            }
            w
        }
        _ if scale > 0.0 => format!(
            "the DVL's velocities are {:.2} % {} than the camera's (+- {:.2} %): the sound speed it \
             assumes is that much {} than the water's, times any scale error of the camera \
             (focal lengths, the board's printed size, the baseline); give the DVL's sound speed \
             (--dvl-sound-speed, or a log with its configuration) to tell them apart",
            100.0 * (scale - 1.0).abs(),
            if scale >= 1.0 { "higher" } else { "lower" },
            100.0 * scale_std,
            if scale >= 1.0 { "higher" } else { "lower" }
        ),
        _ => "the velocity scale is not positive: no sound speed can be read from it".into(),
    }
}

/// When the DVL's sound speed is known and the water's the scale implies lies beyond
/// [`WATER_SOUND_SPEED_MPS`] by more than three standard deviations: the words naming the camera
/// side as the likely cause.
pub fn implausible_water(scale: f64, scale_std: f64, assumed_mps: Option<f64>) -> Option<String> {
    let c = assumed_mps?;
    if scale <= 0.0 {
        return None;
    }
    let water = c / scale;
    let std = water * scale_std / scale;
    let (lo, hi) = WATER_SOUND_SPEED_MPS;
    (water + 3.0 * std < lo || water - 3.0 * std > hi).then(|| {
        format!(
            "no natural water has a sound speed of {water:.0} m/s (+- {std:.0}; {lo:.0} to {hi:.0} \
             m/s from fresh and cold to salt and warm): the velocity scale {scale:.4} is more \
             likely the camera's scale error ({:.1} %: focal lengths in the camchain, the \
             board's printed size against target.yaml, or the stereo baseline)",
            100.0 * (c / ((lo + hi) / 2.0) / scale - 1.0)
        )
    })
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scale_of_water_that_exists_names_the_water_and_one_beyond_it_the_camera() {
        // 1500 m/s assumed; a scale of 1.01 says the water has 1485 m/s: plausible.
        assert!(implausible_water(1.01, 0.002, Some(1500.0)).is_none());
        let w = sound_speed_words(1.01, 0.002, Some(1500.0));
        assert!(w.contains("1485 m/s"), "{w}");
        assert!(!w.contains("camera"), "{w}");
        // A scale of 0.97 (a board printed at 97 %): water at 1546 m/s, still possible.
        assert!(implausible_water(0.97, 0.002, Some(1500.0)).is_none());
        // 0.93: 1613 m/s, which no water has, well beyond three standard deviations.
        let c = implausible_water(0.93, 0.002, Some(1500.0)).expect("implausible");
        assert!(c.contains("camera's scale error"), "{c}");
        assert!(sound_speed_words(0.93, 0.002, Some(1500.0)).contains("focal lengths"));
        // The same scale with a wide spread is not called implausible.
        assert!(implausible_water(0.93, 0.05, Some(1500.0)).is_none());
        // Without the DVL's sound speed both causes are named.
        let w = sound_speed_words(0.97, 0.002, None);
        assert!(
            w.contains("3.00 % lower") && w.contains("focal lengths"),
            "{w}"
        );
    }
}
