//! AprilTag detection through the system libapriltag (Debian 3.3) and its `apriltag-sys` bindings.
//!
//! With tag36h11 (the default) the detector also reads boards printed by Kalibr (two-bit
//! borders, black squares at the tag corners), which libapriltag alone does not: a widened copy
//! of the family in libapriltag, and a second pass of its own (`vision::kalibr`).
//! [`TagDetection::border_bits`] says which print a tag came from.
//!
//! The grey image is handed to the library without a copy: an `image_u8_t` header is built around
//! the [`image::GrayImage`] buffer (stride = width). Debian's `libapriltag.so` does not export the
//! `image_u8_*` functions (they live in `libapriltag-utils.so`), so none of them is called here.
//!
//! # Conventions of the detections
//!
//! - **Pixel convention.** libapriltag puts the centre of the top-left pixel at (0.5, 0.5); OpenCV and
//!   Kalibr put it at (0, 0). [`TagDetection::corners`] are libapriltag's corners minus 0.5, ready for
//!   OpenCV/Kalibr intrinsics.
//! - **Corner order.** For a tag seen upright (as `apriltag_to_image` draws it, image y down), the
//!   corners of the black square come counter-clockwise on screen starting at the bottom-left:
//!   `corners[0]` bottom-left, `corners[1]` bottom-right, `corners[2]` top-right, `corners[3]`
//!   top-left. Debian's `apriltag -v` CLI names its columns the same way (xlb, xrb, xrt, xlt);
//!   `tests/vision_detect.rs` checks it on a rendered tag. On a Kalibr board (x right, y up, tags
//!   upright) these are the tag's corners (0,0), (s,0), (s,s), (0,s) from its bottom-left corner.
//! - **Accuracy.** libapriltag 3.3's own corners (after its `refine_edges`) carry a systematic error:
//!   on exactly area-sampled, axis-aligned tags a common shift of about (-0.08, -0.09) px
//!   (|bias| 0.12 px, RMS 0.19 px); on blurred perspective renders the detected squares come out
//!   slightly small, which biases the depth of a PnP pose. With `refine_corners` (the default) each
//!   side is re-located with an interpolating, unbiased edge estimate and the corners are
//!   intersections of line fits (`vision::refine`): |bias| under 0.001 px and RMS 0.002 px
//!   on the same tags. `tests/vision_detect.rs` and `tests/vision_render.rs` measure both.

use std::collections::HashMap;
use std::os::raw::c_int;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use apriltag_sys as sys;
use nalgebra::Vector2;

use crate::error::{Error, Result};
use crate::types::board::TagFamily;
use crate::types::camera::Camera;
use crate::vision::family::{Destroy, FamilyCodes, family_codes, ffi};
use crate::vision::kalibr::{
    KALIBR_BORDER_BITS, KALIBR_CELLS_ACROSS, coarse_fit, decode_quad, grow, has_light_code_cell,
    max_decimate, max3_decimate, quads, saddle_point, widen_border,
};
use crate::vision::refine::{quad_centre, refine_corners};

/// Detections kept across runs over the same image files, for a folder solved again as it grows
/// (`dvlcal watch`): per image file, camera and camera model, the tags found and the width of the
/// image's sharpest edges. An image file must not change once written under its name (writers
/// rename finished files into place). Clones share one store; two caches are equal when they
/// are the same store.
///
/// It also keeps what a whole frame came to (its pose solved from those detections), keyed by
/// the frame and the settings it was solved with, so that a frame seen before is not solved
/// again ([`DetectionCache::solved`]).
#[derive(Clone, Default)]
pub struct DetectionCache(Arc<Mutex<CacheMap>>, Arc<Mutex<SolvedMap>>);

type CacheKey = (PathBuf, usize, String);
type CacheMap = HashMap<CacheKey, (Vec<TagDetection>, Option<f64>)>;
/// A frame's outcome by its key, with the image files it was made from.
type SolvedMap = HashMap<String, (Vec<PathBuf>, Arc<dyn std::any::Any + Send + Sync>)>;

impl DetectionCache {
    /// The key of camera `cam`'s image `path` detected with `camera` (its model refines the
    /// corners, so detections with another model are other entries).
    fn key(path: &std::path::Path, cam: usize, camera: Option<&Camera>) -> CacheKey {
        (path.to_path_buf(), cam, format!("{camera:?}"))
    }

    /// The detections kept for that image, if any.
    pub fn get(
        &self,
        path: &std::path::Path,
        cam: usize,
        camera: Option<&Camera>,
    ) -> Option<(Vec<TagDetection>, Option<f64>)> {
        let map = self.0.lock().unwrap_or_else(|p| p.into_inner());
        map.get(&Self::key(path, cam, camera)).cloned()
    }

    /// Keeps the detections of that image.
    pub fn put(
        &self,
        path: &std::path::Path,
        cam: usize,
        camera: Option<&Camera>,
        found: (Vec<TagDetection>, Option<f64>),
    ) {
        let mut map = self.0.lock().unwrap_or_else(|p| p.into_inner());
        map.insert(Self::key(path, cam, camera), found);
    }

    /// The name image message `index` (1-based, in record order) of `topic` in `bag` is kept
    /// under: a path inside the bag's, so that [`DetectionCache::rebased`] moves it with the
    /// bag (a recording renamed at its end). A bag being recorded only grows, so a message
    /// keeps its topic and number.
    pub fn message_key(bag: &std::path::Path, topic: &str, index: u64) -> PathBuf {
        bag.join(topic.trim_start_matches('/'))
            .join(format!("#{index}"))
    }

    /// How many images it holds.
    pub fn len(&self) -> usize {
        self.0.lock().unwrap_or_else(|p| p.into_inner()).len()
    }

    /// Whether it holds none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Drops what it holds of the image `path` (a file replaced under its name), and of the
    /// frames made from it.
    pub fn forget(&self, path: &std::path::Path) {
        let mut map = self.0.lock().unwrap_or_else(|p| p.into_inner());
        map.retain(|(p, _, _), _| p != path);
        let mut solved = self.1.lock().unwrap_or_else(|p| p.into_inner());
        solved.retain(|_, (files, _)| !files.iter().any(|f| f == path));
    }

    /// How many frames' outcomes it holds.
    pub fn frames(&self) -> usize {
        self.1.lock().unwrap_or_else(|p| p.into_inner()).len()
    }

    /// The outcome kept under `key` (see [`DetectionCache::keep_solved`]), if it is a `T`.
    pub fn solved<T: Clone + 'static>(&self, key: &str) -> Option<T> {
        let solved = self.1.lock().unwrap_or_else(|p| p.into_inner());
        solved.get(key)?.1.downcast_ref::<T>().cloned()
    }

    /// Keeps `value`, what a frame made of the image `files` came to, under `key` (which must
    /// name the frame and everything its outcome depends on).
    pub fn keep_solved<T: Send + Sync + 'static>(
        &self,
        key: String,
        files: Vec<PathBuf>,
        value: T,
    ) {
        let mut solved = self.1.lock().unwrap_or_else(|p| p.into_inner());
        solved.insert(key, (files, Arc::new(value)));
    }

    /// A new cache with the entries of the images under `from`, keyed as the same files under
    /// `to` (the detections of a staged copy of a folder, for the folder itself).
    pub fn rebased(&self, from: &std::path::Path, to: &std::path::Path) -> DetectionCache {
        let map = self.0.lock().unwrap_or_else(|p| p.into_inner());
        let moved = map
            .iter()
            .filter_map(|((p, cam, model), found)| {
                let rel = p.strip_prefix(from).ok()?;
                Some(((to.join(rel), *cam, model.clone()), found.clone()))
            })
            .collect();
        DetectionCache(Arc::new(Mutex::new(moved)), Arc::default())
    }
}

impl PartialEq for DetectionCache {
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.0, &other.0)
    }
}

impl std::fmt::Debug for DetectionCache {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "DetectionCache({} images)", self.len())
    }
}

/// Settings of the AprilTag detector. `Default` gives the library's defaults and at most one
/// corrected bit.
#[derive(Clone, Debug, PartialEq)]
pub struct DetectorSettings {
    /// Tag family to look for.
    pub family: TagFamily,
    /// Decimation of the image for quad detection (`quad_decimate`, >= 1). Corners are refined on
    /// the full-resolution image.
    pub decimate: f32,
    /// Gaussian blur (sigma, pixels) of the image for quad detection (`quad_sigma`); negative
    /// sharpens.
    pub sigma: f32,
    /// Sharpening of the decoded bits (`decode_sharpening`, >= 0).
    pub sharpening: f64,
    /// Snap the quad edges to strong gradients of the full-resolution image (`refine_edges`).
    pub refine_edges: bool,
    /// After libapriltag, re-locate each side of the black square on the full-resolution image
    /// and intersect straight-line fits of the sides (`vision::refine`). Removes the
    /// corner bias libapriltag 3.3 leaves; a tag whose sides cannot be located keeps
    /// libapriltag's corners. Kalibr-printed tags are refined this way and then put on the
    /// saddle points of their corner junctions; one whose sides cannot be located is dropped
    /// (its quad may have kept a piece of a corner square). Without it, second-pass Kalibr
    /// tags still come with line-fit corners (their bits are read off them).
    pub refine_corners: bool,
    /// Worker threads of the detector (`nthreads`, >= 1).
    pub threads: usize,
    /// Largest number of corrected bits of an accepted code (0..=3; more needs huge tables).
    pub max_hamming: u32,
    /// With [`TagFamily::Tag36h11`], also find tags printed by Kalibr (two-bit black border,
    /// black squares at the tag corners; see `vision::kalibr`). On by default; ignored for the
    /// other families.
    pub kalibr_layout: bool,
    /// The ids of the board in view, when it is known (`None`: any tags). The Kalibr second
    /// pass then stops as soon as every one of them has been found: what it could still add is
    /// a tag that is not on the board or a second tag with a board id, neither of which a
    /// board pose uses.
    pub board_ids: Option<Vec<u32>>,
    /// The board in view is printed the way Kalibr prints an aprilgrid (a Kalibr target YAML,
    /// [`crate::types::board::TagPrint::Kalibr`]). With `board_ids` and `kalibr_layout`, the
    /// Kalibr pass on the brightened half image runs first, and libapriltag's own detection of
    /// the whole image only when that pass leaves ids of the board unfound (see
    /// `vision::kalibr`). Off by default: without it the order suits any board.
    pub kalibr_print: bool,
    /// Detections of earlier runs over the same image files, used instead of decoding and
    /// detecting again, and added to (`None`: every image is detected).
    pub cache: Option<DetectionCache>,
    /// The bag the frames' image messages come from, when they come from one: its messages'
    /// detections are kept in `cache` under [`DetectionCache::message_key`] (`None`: image
    /// messages are always detected).
    pub cache_bag: Option<PathBuf>,
}

impl Default for DetectorSettings {
    fn default() -> Self {
        DetectorSettings {
            family: TagFamily::Tag36h11,
            decimate: 2.0,
            sigma: 0.0,
            sharpening: 0.25,
            refine_edges: true,
            refine_corners: true,
            threads: 1,
            max_hamming: 1,
            kalibr_layout: true,
            board_ids: None,
            kalibr_print: false,
            cache: None,
            cache_bag: None,
        }
    }
}

impl DetectorSettings {
    /// Checks the ranges the library accepts.
    pub fn validate(&self) -> Result<()> {
        if !(self.decimate.is_finite() && self.decimate >= 1.0) {
            return Err(Error::Input(format!(
                "detector decimation must be a number >= 1, got {}",
                self.decimate
            )));
        }
        if !self.sigma.is_finite() {
            return Err(Error::Input(format!(
                "detector sigma must be finite, got {}",
                self.sigma
            )));
        }
        if !(self.sharpening.is_finite() && self.sharpening >= 0.0) {
            return Err(Error::Input(format!(
                "detector sharpening must be a number >= 0, got {}",
                self.sharpening
            )));
        }
        if self.threads == 0 || self.threads > 1024 {
            return Err(Error::Input(format!(
                "detector threads must be between 1 and 1024, got {}",
                self.threads
            )));
        }
        if self.max_hamming > 3 {
            return Err(Error::Input(format!(
                "at most 3 corrected bits are supported, got {}",
                self.max_hamming
            )));
        }
        Ok(())
    }
}

/// One detected tag.
#[derive(Clone, Debug, PartialEq)]
pub struct TagDetection {
    /// Tag id within the family.
    pub id: u32,
    /// Number of corrected bits.
    pub hamming: u32,
    /// libapriltag's decision margin (average difference between the bit intensities and the
    /// threshold; larger is more confident).
    pub decision_margin: f32,
    /// libapriltag's p[0..4], converted to the OpenCV pixel convention (minus 0.5): bottom-left,
    /// bottom-right, top-right, top-left of the black square of the upright tag.
    pub corners: [Vector2<f64>; 4],
    /// Width of the tag's black border in bits: 1 for tags printed the way libapriltag draws
    /// them, 2 for tags printed by Kalibr ([`crate::vision::kalibr`]). The corners are those of
    /// the outer black square either way.
    pub border_bits: u32,
}

/// An AprilTag detector for one family. Owns the libapriltag detector and family and frees both
/// when dropped. Not shared between threads: make one per worker thread.
pub struct Detector {
    td: *mut sys::apriltag_detector_t,
    tf: *mut sys::apriltag_family_t,
    destroy_family: Destroy,
    settings: DetectorSettings,
    /// Pattern cells across the square the corners belong to (the family's `width_at_border`).
    cells_across: f64,
    /// The Kalibr-layout part (tag36h11 with a two-bit border), when enabled.
    kalibr: Option<KalibrPart>,
    /// The board's ids, sorted and without repeats (`DetectorSettings::board_ids`); `None` when
    /// the board is not known or has no tags.
    board_ids: Option<Vec<u32>>,
    /// Images given to libapriltag's own detection ([`Detector::library_detections`]).
    library_detections: usize,
}

/// What the detector needs to read Kalibr-printed tags: the widened copy of tag36h11 given to
/// libapriltag, and tag36h11's codes for decoding the second pass's quads.
struct KalibrPart {
    tf: *mut sys::apriltag_family_t,
    book: FamilyCodes,
}

// SAFETY: the detector and family are owned exclusively by this value and libapriltag keeps no
// thread-local state; moving them to another thread is sound. `detect` takes `&mut self`, so they
// are never used from two threads at once (the type is deliberately not `Sync`).
unsafe impl Send for Detector {}

impl Detector {
    /// A detector with these settings.
    pub fn new(s: &DetectorSettings) -> Result<Detector> {
        s.validate()?;
        let (create, destroy_family) = ffi(s.family);
        // SAFETY: plain constructors of the C library; null results are checked below.
        let tf = unsafe { create() };
        if tf.is_null() {
            return Err(Error::Input(format!(
                "libapriltag could not create the tag family {}",
                s.family.name()
            )));
        }
        // SAFETY: as above.
        let td = unsafe { sys::apriltag_detector_create() };
        if td.is_null() {
            // SAFETY: tf came from the matching constructor and is not used again.
            unsafe { destroy_family(tf) };
            return Err(Error::Input(
                "libapriltag could not create a detector".to_string(),
            ));
        }
        // SAFETY: tf is a valid family (checked non-null above).
        let cells_across = unsafe { (*tf).width_at_border }.max(1) as f64;
        // Owned from here on: Drop frees both on any early return.
        let mut det = Detector {
            td,
            tf,
            destroy_family,
            settings: s.clone(),
            cells_across,
            kalibr: None,
            board_ids: s.board_ids.as_ref().filter(|v| !v.is_empty()).map(|v| {
                let mut v = v.clone();
                v.sort_unstable();
                v.dedup();
                v
            }),
            library_detections: 0,
        };
        // SAFETY: td and tf are valid; the family outlives the detector (Drop destroys the detector
        // first). The settings fields are plain values.
        unsafe {
            sys::apriltag_detector_add_family_bits(td, tf, s.max_hamming as c_int);
            if (*td).tag_families.is_null() || (*(*td).tag_families).size != 1 {
                return Err(Error::Input(format!(
                    "libapriltag could not add the tag family {} with {} corrected bits",
                    s.family.name(),
                    s.max_hamming
                )));
            }
            (*td).quad_decimate = s.decimate;
            (*td).quad_sigma = s.sigma;
            (*td).decode_sharpening = s.sharpening;
            (*td).refine_edges = s.refine_edges;
            (*td).nthreads = s.threads as c_int;
        }
        if s.kalibr_layout && s.family == TagFamily::Tag36h11 {
            det.add_kalibr_layout()?;
        }
        Ok(det)
    }

    /// Adds tag36h11 with Kalibr's two-bit border to the libapriltag detector (first pass) and
    /// keeps the codes for the second pass (`vision::kalibr`).
    fn add_kalibr_layout(&mut self) -> Result<()> {
        let err =
            || Error::Input("libapriltag could not make tag36h11 with a two-bit border".into());
        let book = family_codes(TagFamily::Tag36h11).ok_or_else(err)?;
        // SAFETY: a fresh family from its constructor, checked non-null, changed before any
        // detector sees it; once added, it is owned by `self.kalibr` and destroyed in Drop after
        // the detector.
        unsafe {
            let tf = sys::tag36h11_create();
            if tf.is_null() {
                return Err(err());
            }
            if !widen_border(tf) {
                sys::tag36h11_destroy(tf);
                return Err(err());
            }
            self.kalibr = Some(KalibrPart { tf, book });
            sys::apriltag_detector_add_family_bits(self.td, tf, self.settings.max_hamming as c_int);
            if (*(*self.td).tag_families).size != 2 {
                return Err(err());
            }
        }
        Ok(())
    }

    /// The settings this detector was made with.
    pub fn settings(&self) -> &DetectorSettings {
        &self.settings
    }

    /// How many images this detector has given to libapriltag's own detection of the whole
    /// image: every image, except on a known Kalibr print
    /// ([`DetectorSettings::kalibr_print`]), where only those on which the brightened pass left
    /// an id of the board unfound.
    pub fn library_detections(&self) -> usize {
        self.library_detections
    }

    /// Detects the tags in a grey image. Detections are sorted by id, then by their first corner,
    /// so the result does not depend on the number of threads. With `refine_corners`, the sides
    /// are fitted as straight lines in the image.
    pub fn detect(&mut self, gray: &image::GrayImage) -> Vec<TagDetection> {
        self.detect_with_camera(gray, None)
    }

    /// [`Detector::detect`] for an image of a known camera: with `refine_corners`, the sides are
    /// fitted as straight lines after undistortion (a side of a tag bends in a distorted image).
    pub fn detect_with_camera(
        &mut self,
        gray: &image::GrayImage,
        cam: Option<&Camera>,
    ) -> Vec<TagDetection> {
        if self.kalibr.is_some() && self.settings.kalibr_print && self.board_ids.is_some() {
            return self.detect_kalibr_board(gray, cam);
        }
        let mut out = self.library_pass(gray, cam);
        let kalibr_seen = out.iter().any(|d| d.border_bits == KALIBR_BORDER_BITS);
        let second = self.kalibr.is_some() && (out.is_empty() || kalibr_seen);
        if second {
            let more = self.brightened_pass(gray, cam, &out, &BRIGHTENED_IMAGES);
            out.extend(more);
            sort_detections(&mut out);
        }
        out
    }

    /// libapriltag's detection of the whole image (both layouts), with the corners refined as
    /// `refine_corners` asks.
    fn library_pass(&mut self, gray: &image::GrayImage, cam: Option<&Camera>) -> Vec<TagDetection> {
        self.library_detections += 1;
        let mut out = self.detect_raw(gray);
        if self.settings.refine_corners {
            out.retain_mut(|d| {
                if d.border_bits == KALIBR_BORDER_BITS {
                    // A Kalibr tag's quad may have kept a bit of a corner square: refined
                    // corners or none (the second pass may still find the tag).
                    match settle_kalibr(gray, &d.corners, cam) {
                        Some(mut c) => {
                            kalibr_saddles(gray, &mut c);
                            d.corners = c;
                            true
                        }
                        None => false,
                    }
                } else {
                    if let Some(c) = refine_corners(gray, &d.corners, self.cells_across, cam) {
                        d.corners = c;
                    }
                    true
                }
            });
        }
        out
    }

    /// A known board printed by Kalibr: the pass on the 2x2-brightest half image first (on
    /// such a print it finds most or all of the tags, at under half the cost of libapriltag's
    /// own detection), then libapriltag's detection of the whole image and the 3x3-brightest
    /// image, each only while an id of the board is still missing. A tag found again by a later
    /// pass keeps the corners of the first.
    fn detect_kalibr_board(
        &mut self,
        gray: &image::GrayImage,
        cam: Option<&Camera>,
    ) -> Vec<TagDetection> {
        self.ensure_worker_pool();
        let mut out = self.brightened_pass(gray, cam, &[], &BRIGHTENED_IMAGES[..1]);
        if !self.board_complete(out.iter()) {
            let first = self.library_pass(gray, cam);
            for d in first {
                let centre = quad_centre(&d.corners);
                if !out.iter().any(|o| covers(o, &centre)) {
                    out.push(d);
                }
            }
        }
        let more = self.brightened_pass(gray, cam, &out, &BRIGHTENED_IMAGES[1..]);
        out.extend(more);
        sort_detections(&mut out);
        out
    }

    /// Whether every id of the board (when it is known) is among `found`.
    fn board_complete<'a>(&self, found: impl Iterator<Item = &'a TagDetection>) -> bool {
        self.board_ids
            .as_deref()
            .is_some_and(|ids| every_id_found(ids, found))
    }

    /// libapriltag makes its worker pool, which its segmentation alone (`vision::kalibr::quads`)
    /// needs, in its first detection: a detector whose first pass is the Kalibr one runs
    /// libapriltag once on a small blank image.
    fn ensure_worker_pool(&mut self) {
        // SAFETY: the detector is ours and used by this thread only.
        if unsafe { (*self.td).wp.is_null() } {
            let side = (8.0 * self.settings.decimate.max(1.0)).ceil() as u32;
            let _ = self.detect_raw(&image::GrayImage::new(side.max(16), side.max(16)));
        }
    }

    /// The Kalibr pass on brightened images (pass 2 of `vision::kalibr`; the first pass on a
    /// known Kalibr print): quads of the brightened half-resolution `images`, refined and
    /// decoded on `gray`. Quads on a tag already in `known`
    /// are skipped, and so are quads whose sides cannot be re-located (the bits of a small tag
    /// are read right only off accurate corners).
    fn brightened_pass(
        &mut self,
        gray: &image::GrayImage,
        cam: Option<&Camera>,
        known: &[TagDetection],
        images: &[BrightenedImage],
    ) -> Vec<TagDetection> {
        let Some(k) = &self.kalibr else {
            return Vec::new();
        };
        let mut out: Vec<TagDetection> = Vec::new();
        for level in images {
            if self.board_complete(known.iter().chain(&out)) {
                break;
            }
            let half = if level.max3_first {
                max3_decimate(gray)
            } else {
                max_decimate(gray)
            };
            // SAFETY: the detector is ours and used by this thread only.
            let found = unsafe { quads(self.td, &half) };
            for q in found {
                // Half-resolution pixels (libapriltag's convention) to full-resolution OpenCV
                // pixels.
                let q = q.map(|p| Vector2::new(2.0 * p[0] - 0.5, 2.0 * p[1] - 0.5));
                let centre = quad_centre(&q);
                if known.iter().chain(&out).any(|d| covers(d, &centre)) {
                    continue;
                }
                let Some(q) = grow(&q, level.growth) else {
                    continue;
                };
                // Too small to read (under 1.5 px per cell), or nothing light inside.
                let side = (0..4)
                    .map(|i| (q[(i + 1) % 4] - q[i]).norm())
                    .fold(f64::MAX, f64::min);
                if side < 1.5 * KALIBR_CELLS_ACROSS as f64 || !has_light_code_cell(gray, &q) {
                    continue;
                }
                let Some(refined) = settle_kalibr(gray, &q, cam) else {
                    continue;
                };
                let Some(t) = decode_quad(gray, &refined, &k.book, self.settings.max_hamming)
                else {
                    continue;
                };
                let mut corners = t.corners;
                if self.settings.refine_corners {
                    kalibr_saddles(gray, &mut corners);
                }
                out.push(TagDetection {
                    id: t.id,
                    hamming: t.hamming,
                    decision_margin: t.margin,
                    corners,
                    border_bits: KALIBR_BORDER_BITS,
                });
            }
        }
        out
    }

    fn detect_raw(&mut self, gray: &image::GrayImage) -> Vec<TagDetection> {
        let (w, h) = gray.dimensions();
        // libapriltag 3.3 crashes when the decimated image is under 3 pixels high (or, at
        // decimation 1.5, wide); no tag fits in such an image anyway. The bound below was checked
        // for decimations 1 to 13 and blur sigmas -2 to 10.
        let min_side = (4.0 * self.settings.decimate as f64).ceil().max(8.0);
        if (w as f64) < min_side
            || (h as f64) < min_side
            || w > i32::MAX as u32
            || h > i32::MAX as u32
        {
            return Vec::new();
        }
        let buf = gray.as_raw();
        debug_assert_eq!(buf.len(), w as usize * h as usize);
        let mut im = sys::image_u8_t {
            width: w as i32,
            height: h as i32,
            stride: w as i32,
            // libapriltag reads the input image and never writes to it.
            buf: buf.as_ptr() as *mut u8,
        };
        let mut out = Vec::new();
        // SAFETY: `im` points at `w * h` bytes that outlive the call; the detector is valid and used
        // by this thread only. The returned array holds `size` pointers to detections, all freed by
        // apriltag_detections_destroy after they are copied.
        unsafe {
            let dets = sys::apriltag_detector_detect(self.td, &mut im);
            if dets.is_null() {
                return out;
            }
            let n = usize::try_from((*dets).size).unwrap_or(0);
            let data = (*dets).data as *const *const sys::apriltag_detection_t;
            if !data.is_null() {
                for i in 0..n {
                    let d = *data.add(i);
                    if d.is_null() {
                        continue;
                    }
                    let d = &*d;
                    let corners =
                        std::array::from_fn(|k| Vector2::new(d.p[k][0] - 0.5, d.p[k][1] - 0.5));
                    let kalibr = self.kalibr.as_ref().is_some_and(|k| k.tf == d.family);
                    out.push(TagDetection {
                        id: d.id.max(0) as u32,
                        hamming: d.hamming.max(0) as u32,
                        decision_margin: d.decision_margin,
                        corners,
                        border_bits: if kalibr { KALIBR_BORDER_BITS } else { 1 },
                    });
                }
            }
            sys::apriltag_detections_destroy(dets);
        }
        sort_detections(&mut out);
        // A quad decoded by both layouts (not seen in practice): keep the first.
        let mut kept: Vec<TagDetection> = Vec::with_capacity(out.len());
        for d in out {
            if !kept.iter().any(|o| same_tag(o, &d)) {
                kept.push(d);
            }
        }
        kept
    }
}

/// One image of the Kalibr pass on brightened images.
struct BrightenedImage {
    /// A 3x3 brightest filter at full resolution before the 2x2-brightest decimation.
    max3_first: bool,
    /// How far the sides of its quads move out before refinement (full-resolution pixels:
    /// about what the brightening took off every black region).
    growth: f64,
}

/// The brightened pass's images: the 2x2-brightest half-resolution image, and the same after a 3x3
/// brightest filter at full resolution (for the blurred photos whose corner contacts are wider).
const BRIGHTENED_IMAGES: [BrightenedImage; 2] = [
    BrightenedImage {
        max3_first: false,
        growth: 0.5,
    },
    BrightenedImage {
        max3_first: true,
        growth: 1.5,
    },
];

/// The refined corners of a Kalibr tag from a rough quad: refined as they are, or, when that
/// fails, after its sides are re-fitted with a wider reach (`vision::kalibr::coarse_fit`).
fn settle_kalibr(
    gray: &image::GrayImage,
    q: &[Vector2<f64>; 4],
    cam: Option<&Camera>,
) -> Option<[Vector2<f64>; 4]> {
    let cells = KALIBR_CELLS_ACROSS as f64;
    let side = (0..4).map(|i| (q[(i + 1) % 4] - q[i]).norm()).sum::<f64>() / 4.0;
    refine_corners(gray, q, cells, cam).or_else(|| {
        let c = coarse_fit(gray, q, (0.18 * side).clamp(1.5, 12.0))?;
        refine_corners(gray, &c, cells, cam)
    })
}

/// A Kalibr tag's corners moved to the saddle points of their X-junctions with the corner
/// squares (`vision::kalibr::saddle_point`); a corner without a clear junction within a third
/// of a cell keeps its line-fit position.
fn kalibr_saddles(gray: &image::GrayImage, c: &mut [Vector2<f64>; 4]) {
    let cells = KALIBR_CELLS_ACROSS as f64;
    let side = (0..4).map(|i| (c[(i + 1) % 4] - c[i]).norm()).sum::<f64>() / 4.0;
    let cell = side / cells;
    let radius = (1.6 * cell).clamp(2.0, 10.0);
    for p in c.iter_mut() {
        if let Some(x) = saddle_point(gray, p, radius) {
            if (x - *p).norm() <= cell / 3.0 {
                *p = x;
            }
        }
    }
}

/// Whether every id of `ids` (sorted) is among the detections.
fn every_id_found<'a>(ids: &[u32], found: impl Iterator<Item = &'a TagDetection>) -> bool {
    let mut seen: Vec<u32> = found.map(|d| d.id).collect();
    seen.sort_unstable();
    ids.iter().all(|id| seen.binary_search(id).is_ok())
}

/// By id, then by the first corner, so that results do not depend on thread counts.
fn sort_detections(v: &mut [TagDetection]) {
    v.sort_by(|a, b| {
        a.id.cmp(&b.id)
            .then(a.corners[0].x.total_cmp(&b.corners[0].x))
            .then(a.corners[0].y.total_cmp(&b.corners[0].y))
    });
}

/// Whether `p` lies within a quarter of a detection's side from its centre (on the same tag).
fn covers(d: &TagDetection, p: &Vector2<f64>) -> bool {
    let centre = quad_centre(&d.corners);
    let side = (d.corners[1] - d.corners[0])
        .norm()
        .max((d.corners[2] - d.corners[1]).norm());
    (centre - p).norm() < 0.25 * side
}

/// Two detections of one tag: same id, centres closer than a quarter of the tag's side.
fn same_tag(a: &TagDetection, b: &TagDetection) -> bool {
    if a.id != b.id {
        return false;
    }
    let centre = |d: &TagDetection| quad_centre(&d.corners);
    let side = (a.corners[1] - a.corners[0])
        .norm()
        .max((a.corners[2] - a.corners[1]).norm());
    (centre(a) - centre(b)).norm() < 0.25 * side
}

impl Drop for Detector {
    fn drop(&mut self) {
        // SAFETY: both pointers came from their constructors and are freed exactly once, the
        // detector first since it refers to the family.
        unsafe {
            sys::apriltag_detector_destroy(self.td);
            (self.destroy_family)(self.tf);
            if let Some(k) = self.kalibr.take() {
                sys::tag36h11_destroy(k.tf);
            }
        }
    }
}

impl std::fmt::Debug for Detector {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Detector")
            .field("settings", &self.settings)
            .finish()
    }
}
