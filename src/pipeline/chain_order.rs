//! Why stereo poses reproject badly, when the reason is the camera chain's order: the same frames
//! solved again with cam1's `T_cn_cnm1` inverted (a transform written the other way round), with
//! its translation negated (a baseline of the wrong sign) and with cam0 and cam1 swapped (image
//! folders or topics the other way round from the camchain). An order that fits far better is
//! named in the error.

use crate::error::Result;
use crate::io::bag::frames::BagFrames;
use crate::io::frames::FrameSource;
use crate::io::images::StereoFrame;
use crate::lie::Se3;
use crate::types::board::Board;
use crate::types::camera::Camchain;
use crate::vision::detect::DetectorSettings;
use crate::vision::frames::detect_source_tags;
use crate::vision::pnp::{PnpOptions, PoseOutcome, solve_stereo};

/// Frames solved again for the check (spread over the recording).
pub const CHECKED_FRAMES: usize = 12;

/// Another order must fit at least this many times better than the chain as given to be named.
pub const BETTER_BY: f64 = 3.0;

/// The reprojection RMS, px, of the chain as given and of each other order, over the same frames.
#[derive(Clone, Debug, PartialEq)]
pub struct ChainOrderCheck {
    /// Frames solved in every order.
    pub frames: usize,
    /// The chain as given.
    pub given_px: f64,
    /// cam1's `T_cn_cnm1` inverted.
    pub inverted_px: f64,
    /// cam1's `T_cn_cnm1` with its translation negated (its rotation kept).
    pub negated_px: f64,
    /// cam0 and cam1 swapped (their intrinsics, and the transform between them inverted).
    pub swapped_px: f64,
}

impl ChainOrderCheck {
    /// The sentence that names the order that fits, when one fits far better than the chain as
    /// given and within `max_px` (the RMS poses are accepted with); `None` otherwise. Cameras with alike intrinsics fit
    /// alike swapped and with the transform inverted: then both causes are named.
    pub fn hint(&self, max_px: f64) -> Option<String> {
        let fits = |px: f64| px <= max_px && px * BETTER_BY < self.given_px;
        let transform = self.inverted_px.min(self.negated_px);
        let (t_fits, s_fits) = (fits(transform), fits(self.swapped_px));
        let head = format!(
            "on {} frames the chain as given reprojects with {:.1} px RMS",
            self.frames, self.given_px
        );
        let convention = "T_cn_cnm1 maps points from cam0 into cam1: for a cam1 to the right of \
                          cam0 its x translation is negative, minus the baseline";
        let (t_words, t_fix) = if self.negated_px < self.inverted_px {
            (
                "with its translation negated",
                "the baseline in T_cn_cnm1 of cam1 has the wrong sign: negate its translation",
            )
        } else {
            (
                "inverted",
                "T_cn_cnm1 of cam1 is written the other way round: invert it",
            )
        };
        let swapped = "the image folders (or --image-topics) and the camchain's cameras are the \
                       other way round: swap the cam0 and cam1 folders (or topics), or the \
                       camchain's cam0 and cam1 entries (and invert T_cn_cnm1)";
        let tail = "(the board size measured with the chain as given means nothing then)";
        let (lo, hi) = (
            transform.min(self.swapped_px),
            transform.max(self.swapped_px),
        );
        let msg = match (t_fits, s_fits) {
            (false, false) => return None,
            (true, true) if hi <= 1.2 * lo => format!(
                "{head}, {transform:.2} px with cam1's T_cn_cnm1 {t_words} and {:.2} px with \
                 cam0 and cam1 swapped: either {t_fix}, or {swapped} ({convention}) {tail}",
                self.swapped_px
            ),
            (true, _) if !s_fits || transform <= self.swapped_px => format!(
                "{head}, {transform:.2} px with cam1's T_cn_cnm1 {t_words}: {t_fix} \
                 ({convention}) {tail}"
            ),
            _ => format!(
                "{head}, {:.2} px with cam0 and cam1 swapped: {swapped} {tail}",
                self.swapped_px
            ),
        };
        Some(msg)
    }
}

/// Solves up to [`CHECKED_FRAMES`] frames of `src` that have images of cam0 and cam1 with the
/// chain as given, inverted and swapped (see the module documentation); `None` for a chain of
/// one camera or too few frames solved in every order.
pub fn check_chain_order(
    src: FrameSource<'_>,
    board: &Board,
    chain: &Camchain,
    det: &DetectorSettings,
    pnp: &PnpOptions,
) -> Result<Option<ChainOrderCheck>> {
    if chain.cams.len() < 2 || chain.t_cn_c0.len() < 2 {
        return Ok(None);
    }
    let stereo: Vec<&StereoFrame> = src
        .frames()
        .iter()
        .filter(|f| f.images.len() >= 2 && f.images[0].is_some() && f.images[1].is_some())
        .collect();
    if stereo.is_empty() {
        return Ok(None);
    }
    let step = stereo.len().div_ceil(CHECKED_FRAMES);
    let picked: Vec<StereoFrame> = stereo
        .iter()
        .step_by(step)
        .map(|f| StereoFrame {
            t_ns: f.t_ns,
            images: f.images[..2].to_vec(),
        })
        .collect();
    let plan;
    let sub = match src {
        FrameSource::Files(_) => FrameSource::Files(&picked),
        FrameSource::Bag { path, plan: p } => {
            plan = BagFrames {
                frames: picked.clone(),
                ..p.clone()
            };
            FrameSource::Bag { path, plan: &plan }
        }
    };
    let sizes: Vec<(u32, u32)> = chain.cams[..2]
        .iter()
        .map(|c| (c.width, c.height))
        .collect();
    let (dets, _) = detect_source_tags(sub, &sizes, None, det, false)?;

    let given = Camchain {
        cams: chain.cams[..2].to_vec(),
        t_cn_c0: chain.t_cn_c0[..2].to_vec(),
        topics: vec![None, None],
    };
    let inverted = Camchain {
        t_cn_c0: vec![given.t_cn_c0[0], given.t_cn_c0[1].inverse()],
        ..given.clone()
    };
    let t = given.t_cn_c0[1];
    let negated = Camchain {
        t_cn_c0: vec![
            given.t_cn_c0[0],
            Se3 {
                trans: -t.trans,
                ..t
            },
        ],
        ..given.clone()
    };
    let swapped = Camchain {
        cams: vec![given.cams[1].clone(), given.cams[0].clone()],
        ..inverted.clone()
    };
    let mut sq = [0.0f64; 4];
    let mut solved = 0usize;
    for d in &dets {
        let mut rms = [0.0f64; 4];
        let mut all = true;
        for (k, c) in [&given, &inverted, &negated, &swapped]
            .into_iter()
            .enumerate()
        {
            match solve_stereo(board, c, d, pnp)? {
                PoseOutcome::Pose(p) if p.rms_px.is_finite() => rms[k] = p.rms_px,
                _ => all = false,
            }
        }
        if all {
            solved += 1;
            for (s, r) in sq.iter_mut().zip(rms) {
                *s += r * r;
            }
        }
    }
    if solved * 2 < dets.len().max(2) {
        return Ok(None);
    }
    let px = |k: usize| (sq[k] / solved as f64).sqrt();
    Ok(Some(ChainOrderCheck {
        frames: solved,
        given_px: px(0),
        inverted_px: px(1),
        negated_px: px(2),
        swapped_px: px(3),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(given: f64, inverted: f64, negated: f64, swapped: f64) -> Option<String> {
        ChainOrderCheck {
            frames: 12,
            given_px: given,
            inverted_px: inverted,
            negated_px: negated,
            swapped_px: swapped,
        }
        .hint(3.0)
    }

    #[test]
    fn the_order_that_fits_far_better_is_named() {
        assert_eq!(check(1.0, 9.0, 9.0, 9.0), None);
        // Better, but not good enough to use: not named.
        assert_eq!(check(40.0, 5.0, 6.0, 30.0), None);
        let inv = check(14.0, 0.3, 1.5, 6.0).unwrap();
        assert!(
            inv.contains("invert it") && !inv.contains("swapped"),
            "{inv}"
        );
        let neg = check(14.0, 1.5, 0.3, 6.0).unwrap();
        assert!(
            neg.contains("wrong sign") && !neg.contains("swapped"),
            "{neg}"
        );
        let sw = check(7.0, 4.0, 4.0, 0.3).unwrap();
        assert!(
            sw.contains("cam0 and cam1 swapped") && !sw.contains("either"),
            "{sw}"
        );
        let both = check(7.0, 0.31, 0.4, 0.3).unwrap();
        assert!(both.contains("either"), "{both}");
    }
}
