//! Detections matched to the board: the corner observations of every usable view.

use crate::camcal::types::{CornerObs, FrameTags};
use crate::types::board::Board;

/// The corner observations of all frames, and what was left out.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Matched {
    /// Every corner of every usable view, frame by frame, camera by camera.
    pub obs: Vec<CornerObs>,
    /// Board corners matched per frame and camera (also for views too small to use).
    pub corners: Vec<Vec<usize>>,
    /// Detections whose id is not on the board, or whose id appears twice in one image, or whose
    /// corners are not finite.
    pub unmatched: usize,
    /// Views (one camera in one frame) with some corners but fewer than the minimum.
    pub small_views: usize,
    /// Tags left out because a corner lies within the border margin of the image.
    pub at_border: usize,
}

/// Matches each frame's detections to the board's corners. Tags with a corner within
/// `border_px` of the edge of their image (`sizes`: width, height per camera) are left out. A view
/// with fewer than `min_view_corners` corners contributes no observation (its corners are still
/// counted).
pub fn match_views(
    board: &Board,
    frames: &[FrameTags],
    sizes: &[(u32, u32)],
    border_px: f64,
    min_view_corners: usize,
) -> Matched {
    let cams = sizes.len();
    let mut m = Matched::default();
    for (fi, f) in frames.iter().enumerate() {
        let mut per_cam = vec![0; cams];
        for (cam, dets) in f.dets.iter().enumerate().take(cams) {
            let mut view = Vec::new();
            for d in dets {
                let twice = dets.iter().filter(|e| e.id == d.id).count() > 1;
                let finite = d.corners.iter().all(|c| c.x.is_finite() && c.y.is_finite());
                let Some(tag) = board.tag(d.id).filter(|_| !twice && finite) else {
                    m.unmatched += 1;
                    continue;
                };
                let (w, h) = (sizes[cam].0 as f64, sizes[cam].1 as f64);
                let inside = |p: &nalgebra::Vector2<f64>| {
                    p.x >= border_px - 0.5
                        && p.y >= border_px - 0.5
                        && p.x <= w - 0.5 - border_px
                        && p.y <= h - 0.5 - border_px
                };
                if !d.corners.iter().all(inside) {
                    m.at_border += 1;
                    continue;
                }
                for (k, (b, px)) in tag.corners.iter().zip(&d.corners).enumerate() {
                    view.push(CornerObs {
                        frame: fi,
                        cam,
                        tag: d.id,
                        corner: k as u8,
                        board: *b,
                        px: *px,
                    });
                }
            }
            per_cam[cam] = view.len();
            if view.len() >= min_view_corners.max(4) {
                m.obs.extend(view);
            } else if !view.is_empty() {
                m.small_views += 1;
            }
        }
        m.unmatched += f.dets.iter().skip(cams).map(Vec::len).sum::<usize>();
        m.corners.push(per_cam);
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::types::board::TagFamily;
    use crate::vision::detect::TagDetection;
    use nalgebra::Vector2;

    fn det(id: u32) -> TagDetection {
        TagDetection {
            id,
            hamming: 0,
            decision_margin: 50.0,
            corners: [Vector2::new(100.0, 100.0); 4],
            border_bits: 1,
        }
    }

    #[test]
    fn matches_known_ids_and_counts_the_rest() {
        let board = Board::grid(TagFamily::Tag36h11, 2, 2, 0.1, 0.3, 0);
        let frames = vec![FrameTags {
            name: "f".into(),
            t_ns: 0,
            // Tags 0..4 are on the board; 7 is not; 1 appears twice in cam1.
            dets: vec![
                vec![det(0), det(1), det(2), det(7)],
                vec![det(1), det(1), det(3)],
            ],
        }];
        let m = match_views(&board, &frames, &[(640, 480), (640, 480)], 5.0, 12);
        assert_eq!(m.corners, vec![vec![12, 4]]);
        assert_eq!(
            m.obs.len(),
            12,
            "cam1's 4 corners are a view too small to use"
        );
        assert_eq!(m.unmatched, 3);
        assert_eq!(m.small_views, 1);
        assert!(m.obs.iter().all(|o| o.cam == 0));
    }
}
