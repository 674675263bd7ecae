//! The board's printed size, measured by a stereo pair over a recording.
//!
//! Every posed frame seen by two or more cameras measures the scale of the board relative to the
//! size its file states ([`crate::vision::pnp::FramePose::board_scale`]: pose and scale fitted
//! together, the chain's baseline fixing the distance). Over a recording:
//!
//! 1. frames whose scale lies more than [`OUTLIER_MADS`] robust standard deviations from the
//!    median (in units of each frame's own standard deviation) are left out;
//! 2. the scale is the mean of the rest weighted by each frame's inverse variance,
//!    `s = sum(w_i s_i) / sum(w_i)`, `w_i = 1 / std_i^2`;
//! 3. its standard deviation comes from the frames' spread about it, as independent
//!    measurements: `std^2 = sum(w_i (s_i - s)^2) / ((n - 1) sum(w_i))` (`std(s_i) / sqrt(n)` for
//!    equal weights), so that it holds whatever noise the frames' own standard deviations state;
//!    a floor for what no spread over frames shows, the corner detector's own bias
//!    ([`SYSTEMATIC_STD`]), is added in quadrature.
//!
//! A scale that differs from 1 by more than [`SIGNIFICANT_STD`] standard deviations and more
//! than [`SIGNIFICANT_FRACTION`] is the board's true size (a misprint, a printer that scaled the
//! page to fit): the pipeline then poses the frames again with the board scaled by it.

use crate::vision::frames::FrameResult;
use crate::vision::pnp::FrameScale;

/// Fewest frames seen by two cameras for a scale.
pub const MIN_STEREO_FRAMES: usize = 5;

/// Frames farther from the median than this many robust standard deviations are left out.
pub const OUTLIER_MADS: f64 = 4.0;

/// Standard deviation of the scale that the corner detector's bias leaves, added in quadrature
/// to the spread over frames. On the rendered recording of `sample_data/stereo` a board printed
/// as stated, at 97 % and at 103 % of its file measures 0.009 % larger than it is, every time
/// (a bias of about 0.001 px at the corners of tags 20 px wide, which the frames share); real
/// images, with their blur and lighting, are allowed twice that.
pub const SYSTEMATIC_STD: f64 = 2e-4;

/// A scale is applied when it differs from 1 by more than this many standard deviations ...
pub const SIGNIFICANT_STD: f64 = 3.0;

/// ... and by more than this fraction (0.2 %).
pub const SIGNIFICANT_FRACTION: f64 = 0.002;

/// The board's print scale over a recording.
#[derive(Clone, Debug, PartialEq)]
pub struct BoardScale {
    /// The board's size over the size its file states (1: printed as stated).
    pub scale: f64,
    /// Its standard deviation.
    pub std: f64,
    /// Frames the scale rests on.
    pub frames: usize,
    /// Frames left out as outliers.
    pub rejected: usize,
    /// Whether the poses were solved with the board scaled by `scale`.
    pub applied: bool,
}

impl BoardScale {
    /// Whether the scale differs from 1 by more than [`SIGNIFICANT_STD`] standard deviations
    /// and [`SIGNIFICANT_FRACTION`].
    pub fn significant(&self) -> bool {
        let d = (self.scale - 1.0).abs();
        d > SIGNIFICANT_STD * self.std && d > SIGNIFICANT_FRACTION
    }

    /// "the board measures 97.0 +- 0.1 % of target.yaml" (`target`: the board file's name).
    pub fn measures(&self, target: &str) -> String {
        // As many decimals as the standard deviation needs to show (one at least).
        let pct = 100.0 * self.std;
        let decimals = if pct > 0.0 && pct.is_finite() {
            ((-pct.log10()).ceil().max(0.0) as usize).clamp(1, 3)
        } else {
            1
        };
        format!(
            "the board measures {:.*} +- {:.*} % of {target}",
            decimals,
            100.0 * self.scale,
            decimals,
            pct
        )
    }

    /// What a significant scale means, and what was done about it.
    pub fn warning(&self, target: &str) -> String {
        format!(
            "{} (from {} stereo frames): a board printed at another size than its file states \
             scales every camera pose, and with them the DVL's velocity scale and lever arm; {}",
            self.measures(target),
            self.frames,
            if self.applied {
                "the poses were solved with the board at its measured size (board_scale in the \
                 result)"
            } else {
                "the poses were solved with the size the file states"
            }
        )
    }
}

/// The scales the posed frames of a run measured, in frame order.
pub fn frame_scales(results: &[FrameResult]) -> Vec<FrameScale> {
    results
        .iter()
        .filter_map(|r| r.pose.as_ref().and_then(|p| p.board_scale))
        .collect()
}

/// The board's scale over the frames' scales (see the module documentation), not yet applied;
/// `None` with fewer than [`MIN_STEREO_FRAMES`] usable frames.
pub fn estimate_board_scale(fits: &[FrameScale]) -> Option<BoardScale> {
    let c = combine(fits, MIN_STEREO_FRAMES, SYSTEMATIC_STD)?;
    Some(BoardScale {
        scale: c.value,
        std: c.std,
        frames: c.frames,
        rejected: c.rejected,
        applied: false,
    })
}

/// A factor measured over the frames of a recording ([`combine`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Combined {
    /// The weighted mean of the frames' factors.
    pub value: f64,
    /// Its standard deviation.
    pub std: f64,
    /// Frames it rests on.
    pub frames: usize,
    /// Frames left out as outliers.
    pub rejected: usize,
}

/// Per-frame factors combined as the module documentation describes for the board's scale:
/// outliers by their distance from the median, the inverse-variance weighted mean, its standard
/// deviation from the frames' spread with `systematic` added in quadrature. `None` with fewer
/// than `min_frames` usable frames.
pub fn combine(fits: &[FrameScale], min_frames: usize, systematic: f64) -> Option<Combined> {
    let fits: Vec<FrameScale> = fits
        .iter()
        .copied()
        .filter(|f| f.scale.is_finite() && f.std.is_finite() && f.std > 0.0)
        .collect();
    if fits.len() < min_frames.max(2) {
        return None;
    }
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        let n = v.len();
        if n % 2 == 1 {
            v[n / 2]
        } else {
            0.5 * (v[n / 2 - 1] + v[n / 2])
        }
    };
    let m = median(fits.iter().map(|f| f.scale).collect());
    let z: Vec<f64> = fits.iter().map(|f| (f.scale - m) / f.std).collect();
    let spread = 1.4826 * median(z.iter().map(|z| z.abs()).collect());
    let keep: Vec<&FrameScale> = fits
        .iter()
        .zip(&z)
        .filter(|(_, z)| spread == 0.0 || z.abs() <= OUTLIER_MADS * spread)
        .map(|(f, _)| f)
        .collect();
    let n = keep.len();
    if n < min_frames.max(2) {
        return None;
    }
    let sw: f64 = keep.iter().map(|f| f.std.powi(-2)).sum();
    let mean = keep.iter().map(|f| f.scale * f.std.powi(-2)).sum::<f64>() / sw;
    let ss: f64 = keep
        .iter()
        .map(|f| (f.scale - mean).powi(2) * f.std.powi(-2))
        .sum();
    let std = (ss / ((n - 1) as f64 * sw) + systematic * systematic).sqrt();
    (mean.is_finite() && std.is_finite()).then_some(Combined {
        value: mean,
        std,
        frames: n,
        rejected: fits.len() - n,
    })
}

/// What a run of the image pipeline knows of the board's printed size.
#[derive(Clone, Debug, PartialEq)]
pub enum BoardSize {
    /// Measured by the stereo baseline.
    Measured(BoardScale),
    /// One camera: the board's size and the distances are one unknown, so the board's printed
    /// size and the DVL's velocity scale cannot be told apart.
    OneCamera,
    /// Fewer than [`MIN_STEREO_FRAMES`] frames seen by two cameras.
    TooFewStereoFrames,
    /// The baseline was calibrated from the same board, so it is in the board's units and
    /// cannot measure it.
    BaselineFromBoard,
}

impl BoardSize {
    /// The measured scale, if any.
    pub fn measured(&self) -> Option<&BoardScale> {
        match self {
            BoardSize::Measured(b) => Some(b),
            _ => None,
        }
    }

    /// One sentence on the board's size for the user (`target`: the board file's name): the
    /// measured scale, or why there is none and what that means.
    pub fn words(&self, target: &str) -> String {
        match self {
            BoardSize::Measured(b) if b.significant() => b.warning(target),
            BoardSize::Measured(b) => format!(
                "{} (from {} stereo frames): as printed, within the measurement",
                b.measures(target),
                b.frames
            ),
            BoardSize::OneCamera => format!(
                "with one camera the board's printed size and the DVL's velocity scale cannot be \
                 told apart: a board printed at another size than {target} states shows as a \
                 velocity scale error of the same fraction (measure the printed tags, or use a \
                 stereo pair)"
            ),
            BoardSize::TooFewStereoFrames => format!(
                "the board's printed size was not measured: fewer than {MIN_STEREO_FRAMES} \
                 frames were seen by two cameras; a board printed at another size than \
                 {target} states shows as a velocity scale error of the same fraction"
            ),
            BoardSize::BaselineFromBoard => format!(
                "the board's printed size cannot be checked: the stereo baseline was calibrated \
                 from the same board, so a board printed at another size than {target} states \
                 scales the baseline with it and shows as a velocity scale error of the same \
                 fraction"
            ),
        }
    }
}
