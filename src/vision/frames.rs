//! Images to poses: decode, detect tags and solve the stereo PnP of every frame, in parallel.
//!
//! The frames come from an [`io::frames::FrameSource`](crate::io::frames::FrameSource) (a
//! folder or a bag), read in one pass on a thread of its own, which hands each frame's encoded
//! images to the workers through a queue a few frames long, so that memory stays bounded by the
//! worker count whatever the recording's length. The workers are rayon's (the pool the caller
//! runs in, so `ThreadPool::install` chooses the thread count); each owns one [`Detector`] and
//! decodes its frames' images itself ([`crate::io::frames::decode`]). Every frame is processed
//! independently, so the results, returned in frame order, are the same whatever the number of
//! threads. Images that cannot be read, or whose size differs from the camera chain's, are
//! counted and named in [`DetectStats::problems`]; they never stop the run.

use std::hash::{Hash, Hasher};
use std::sync::Mutex;
use std::sync::mpsc::sync_channel;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::io::frames::{FrameImages, FrameSource, decode};
use crate::io::images::{ImageRef, StereoFrame};
use crate::types::board::Board;
use crate::types::camera::{Camchain, Camera};
use crate::vision::detect::{DetectionCache, Detector, DetectorSettings, TagDetection};
use crate::vision::pnp::{FramePose, PnpOptions, PoseOutcome, solve_stereo};

/// The image of camera `c` of a frame (`None`: the frame has none), decoded on demand.
type LoadImage<'a> = &'a dyn Fn(usize) -> Option<Result<image::GrayImage>>;

/// Frames the source may have in flight beyond those being processed, per worker.
const QUEUE_PER_WORKER: usize = 2;

/// Runs `work` on every frame of `src` on the current rayon pool; results in frame order.
/// Frames the source never delivered (a bag cut short) get `work` with images that fail to load
/// (counted as unreadable, named); an error of the reading pass is returned after the workers
/// end. The images of the frames `needed` refuses (by index) may be left unread: `work` must
/// not need them (a frame whose outcome is kept).
fn for_each_frame<R: Send>(
    src: FrameSource<'_>,
    bar: &ProgressBar,
    needed: &(dyn Fn(usize) -> bool + Sync),
    work: &(dyn Fn(&StereoFrame, LoadImage<'_>) -> R + Sync),
) -> Result<Vec<R>> {
    let frames = src.frames();
    let workers = rayon::current_num_threads().max(1);
    let (tx, rx) = sync_channel::<(usize, FrameImages<'_>)>(QUEUE_PER_WORKER * workers);
    let (mut done, produced) = std::thread::scope(|scope| {
        let producer = scope.spawn(move || {
            src.read_some(needed, &mut |i, images| {
                tx.send((i, images))
                    .map_err(|_| Error::Input("the image workers stopped early".into()))
            })
        });
        let done: Vec<(usize, R)> = rx
            .into_iter()
            .par_bridge()
            .filter(|(i, _)| *i < frames.len())
            .map(|(i, images)| {
                let f = &frames[i];
                let load = |c: usize| {
                    let name = f.images.get(c).cloned().flatten()?;
                    Some(match images.get(c) {
                        Some(Some(Ok(image))) => decode(&name, image),
                        // A file that could not be read: its error, whose text is what is kept.
                        Some(Some(Err(e))) => Err(Error::Input(e.to_string())),
                        _ => Err(Error::Input(format!("{name}: not delivered by the stream"))),
                    })
                };
                let r = work(f, &load);
                bar.inc(1);
                (i, r)
            })
            .collect();
        let produced = producer
            .join()
            .unwrap_or_else(|_| Err(Error::Input("the image reader failed".into())));
        (done, produced)
    });
    produced?;
    // Frames the source never delivered (a bag cut short): their images fail to load.
    let mut seen = vec![false; frames.len()];
    for (i, _) in &done {
        seen[*i] = true;
    }
    done.sort_by_key(|(i, _)| *i);
    done.dedup_by_key(|(i, _)| *i);
    let missing: Vec<(usize, R)> = (0..frames.len())
        .filter(|&i| !seen[i])
        .map(|i| {
            let f = &frames[i];
            let load = |c: usize| {
                let name = f.images.get(c).cloned().flatten()?;
                Some(Err(Error::Input(format!(
                    "{name}: not delivered by the stream"
                ))))
            };
            (i, work(f, &load))
        })
        .collect();
    done.extend(missing);
    done.sort_by_key(|(i, _)| *i);
    Ok(done.into_iter().map(|(_, r)| r).collect())
}

/// What became of a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameStatus {
    /// The frame got a pose.
    Posed,
    /// None of the frame's images could be used.
    NoImage,
    /// Fewer corners on the board than `PnpOptions::min_corners`.
    TooFewCorners,
    /// No PnP solution (degenerate geometry, a corner behind a camera).
    NoSolution,
}

/// One frame's result.
#[derive(Clone, Debug)]
pub struct FrameResult {
    /// The frame's time and image paths.
    pub frame: StereoFrame,
    /// What became of the frame.
    pub status: FrameStatus,
    /// The frame's pose, `Some` exactly when `status` is [`FrameStatus::Posed`].
    pub pose: Option<FramePose>,
    /// Tags detected in each camera's image (before matching them to the board).
    pub tags_detected: Vec<usize>,
    /// The width of the sharpest edges in each camera's image, px
    /// ([`super::sharpness::edge_width_px`]; `None` for an image not read or without edges).
    pub edge_width_px: Vec<Option<f64>>,
}

/// Counts over a run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DetectStats {
    /// Frames processed.
    pub frames: usize,
    /// Frames that got a pose.
    pub poses: usize,
    /// Images decoded and detected on.
    pub images: usize,
    /// Images that could not be opened or decoded.
    pub unreadable: usize,
    /// Images whose size differs from their camera's resolution in the camchain.
    pub wrong_size: usize,
    /// Frames without a pose because none of their images could be used.
    pub no_image: usize,
    /// Frames without a pose because too few corners were on the board.
    pub too_few_corners: usize,
    /// Frames without a pose because PnP found no solution.
    pub no_solution: usize,
    /// Tag detections over all images (the fields below say how they were used).
    pub tags_detected: usize,
    /// Detections whose id is not on the board, summed over posed frames.
    pub tags_unknown: usize,
    /// Tag observations rejected (outliers, duplicate ids, non-finite corners), summed over
    /// posed frames.
    pub tags_rejected: usize,
    /// Tag observations used for the poses, summed over posed frames.
    pub tags_used: usize,
    /// Reprojection RMS (px) over all corners of all posed frames.
    pub rms_px: f64,
    /// One line per unusable image, naming it.
    pub problems: Vec<String>,
}

impl DetectStats {
    /// Mean tag detections per frame.
    pub fn tags_per_frame(&self) -> f64 {
        if self.frames == 0 {
            0.0
        } else {
            self.tags_detected as f64 / self.frames as f64
        }
    }
}

/// Poses of all frames; see [`detect_frames`]. A detector that cannot be made (invalid settings)
/// leaves every frame without a pose and is reported in `problems`.
pub fn detect_poses(
    frames: &[StereoFrame],
    board: &Board,
    chain: &Camchain,
    det: &DetectorSettings,
    opts: &PnpOptions,
    progress: bool,
) -> (Vec<(StereoFrame, Option<FramePose>)>, DetectStats) {
    match detect_frames(frames, board, chain, det, opts, progress) {
        Ok((results, stats)) => (
            results.into_iter().map(|r| (r.frame, r.pose)).collect(),
            stats,
        ),
        Err(e) => {
            let stats = DetectStats {
                frames: frames.len(),
                problems: vec![e.to_string()],
                ..DetectStats::default()
            };
            (frames.iter().map(|f| (f.clone(), None)).collect(), stats)
        }
    }
}

/// Decodes, detects and solves every frame in parallel; results in frame order. Errors only when
/// the detector cannot be made or a frame has more images than the chain has cameras.
pub fn detect_frames(
    frames: &[StereoFrame],
    board: &Board,
    chain: &Camchain,
    det: &DetectorSettings,
    opts: &PnpOptions,
    progress: bool,
) -> Result<(Vec<FrameResult>, DetectStats)> {
    detect_source(
        FrameSource::Files(frames),
        board,
        chain,
        det,
        opts,
        progress,
    )
}

/// [`detect_frames`] on frames from any [`FrameSource`].
pub fn detect_source(
    src: FrameSource<'_>,
    board: &Board,
    chain: &Camchain,
    det: &DetectorSettings,
    opts: &PnpOptions,
    progress: bool,
) -> Result<(Vec<FrameResult>, DetectStats)> {
    // Fail early on settings the detector refuses.
    let first = Detector::new(det)?;
    let frames = src.frames();
    let n_frames = frames.len();
    if let Some(f) = frames.iter().find(|f| f.images.len() > chain.cams.len()) {
        return Err(Error::Input(format!(
            "frame at {} ns has {} images, the camera chain {} cameras",
            f.t_ns,
            f.images.len(),
            chain.cams.len()
        )));
    }
    let workers = rayon::current_num_threads().max(1);
    let detectors: Vec<Mutex<Option<Detector>>> = (0..workers).map(|_| Mutex::new(None)).collect();
    if let Ok(mut slot) = detectors[0].lock() {
        *slot = Some(first);
    }
    let bar = progress_bar(n_frames as u64, progress);

    // A frame solved before with the same settings is taken from the cache, when there is one
    // (a bag's frames name their messages, so the bag is part of the settings).
    let settings = det.cache.as_ref().map(|_| {
        let mut h = std::hash::DefaultHasher::new();
        let det = DetectorSettings {
            cache: None,
            ..det.clone()
        };
        let bag = match &src {
            FrameSource::Bag { path, .. } => Some(*path),
            FrameSource::Files(_) => None,
        };
        format!("{bag:?}{board:?}{chain:?}{det:?}{opts:?}").hash(&mut h);
        h.finish()
    });
    let key_of = |f: &StereoFrame| settings.map(|s| format!("{s:016x} {f:?}"));
    // Frames solved before: their images are not read again.
    let kept: Vec<bool> = match &det.cache {
        Some(cache) => frames
            .iter()
            .map(|f| {
                key_of(f).is_some_and(|k| cache.solved::<(FrameResult, FrameCounts)>(&k).is_some())
            })
            .collect(),
        None => vec![false; n_frames],
    };
    let needed = |i: usize| !kept.get(i).copied().unwrap_or(false);
    let out: Vec<(FrameResult, FrameCounts)> = for_each_frame(src, &bar, &needed, &|f, load| {
        let key = key_of(f);
        if let (Some(cache), Some(key)) = (&det.cache, &key)
            && let Some(hit) = cache.solved::<(FrameResult, FrameCounts)>(key)
        {
            return hit;
        }
        let idx = rayon::current_thread_index().unwrap_or(0) % workers;
        // A poisoned lock only means another frame panicked; the detector is still whole.
        let mut guard = detectors[idx].lock().unwrap_or_else(|p| p.into_inner());
        let r = process_frame(f, load, board, chain, det, opts, &mut guard);
        drop(guard);
        if let (Some(cache), Some(key)) = (&det.cache, key) {
            let files = f
                .images
                .iter()
                .filter_map(|i| match i {
                    Some(ImageRef::File(p)) => Some(p.clone()),
                    _ => None,
                })
                .collect();
            cache.keep_solved(key, files, r.clone());
        }
        r
    })?;
    bar.finish_and_clear();

    let mut stats = DetectStats {
        frames: n_frames,
        ..DetectStats::default()
    };
    let mut results = Vec::with_capacity(out.len());
    let mut sq = 0.0;
    let mut corners = 0usize;
    for (r, c) in out {
        stats.images += c.images;
        stats.unreadable += c.unreadable;
        stats.wrong_size += c.wrong_size;
        stats.problems.extend(c.problems);
        stats.tags_detected += r.tags_detected.iter().sum::<usize>();
        match r.status {
            FrameStatus::Posed => stats.poses += 1,
            FrameStatus::NoImage => stats.no_image += 1,
            FrameStatus::TooFewCorners => stats.too_few_corners += 1,
            FrameStatus::NoSolution => stats.no_solution += 1,
        }
        if let Some(p) = &r.pose {
            stats.tags_unknown += p.tags_unknown;
            stats.tags_rejected += p.tags_rejected;
            stats.tags_used += p.tags_used;
            sq += p.rms_px * p.rms_px * p.corners_used as f64;
            corners += p.corners_used;
        }
        results.push(r);
    }
    if corners > 0 {
        stats.rms_px = (sq / corners as f64).sqrt();
    }
    Ok((results, stats))
}

#[derive(Clone)]
struct FrameCounts {
    images: usize,
    unreadable: usize,
    wrong_size: usize,
    problems: Vec<String>,
}

fn process_frame(
    f: &StereoFrame,
    load: &dyn Fn(usize) -> Option<Result<image::GrayImage>>,
    board: &Board,
    chain: &Camchain,
    det: &DetectorSettings,
    opts: &PnpOptions,
    slot: &mut Option<Detector>,
) -> (FrameResult, FrameCounts) {
    let mut c = FrameCounts {
        images: 0,
        unreadable: 0,
        wrong_size: 0,
        problems: Vec::new(),
    };
    let sizes: Vec<(u32, u32)> = chain.cams.iter().map(|c| (c.width, c.height)).collect();
    let cams: Vec<Option<&Camera>> = chain.cams.iter().map(Some).collect();
    let (dets, any, edge_width_px) = detect_images(f, load, &sizes, &cams, det, slot, &mut c);
    let detected: Vec<usize> = dets.iter().map(Vec::len).collect();
    let (status, pose) = if !any {
        (FrameStatus::NoImage, None)
    } else {
        match solve_stereo(board, chain, &dets, opts) {
            Ok(PoseOutcome::Pose(p)) => (FrameStatus::Posed, Some(p)),
            Ok(PoseOutcome::TooFewCorners { .. }) => (FrameStatus::TooFewCorners, None),
            Ok(PoseOutcome::Failed(_)) | Err(_) => (FrameStatus::NoSolution, None),
        }
    };
    (
        FrameResult {
            frame: f.clone(),
            status,
            pose,
            tags_detected: detected,
            edge_width_px,
        },
        c,
    )
}

/// Decodes and detects the images of one frame. `sizes` are the expected image sizes per camera;
/// `cams` the camera models for the corner refinement (`None`: not known yet). Unreadable and
/// wrongly sized images are counted and named in `c`. Returns the detections per camera,
/// whether any image was usable, and the width of each image's sharpest edges.
#[allow(clippy::type_complexity)]
fn detect_images(
    f: &StereoFrame,
    load: &dyn Fn(usize) -> Option<Result<image::GrayImage>>,
    sizes: &[(u32, u32)],
    cams: &[Option<&Camera>],
    det: &DetectorSettings,
    slot: &mut Option<Detector>,
    c: &mut FrameCounts,
) -> (Vec<Vec<TagDetection>>, bool, Vec<Option<f64>>) {
    let mut dets: Vec<Vec<TagDetection>> = vec![Vec::new(); f.images.len()];
    let mut widths = vec![None; f.images.len()];
    let mut any = false;
    for (cam, name) in f.images.iter().enumerate() {
        let Some(name) = name else { continue };
        let camera = cams.get(cam).copied().flatten();
        let key = match name {
            crate::io::images::ImageRef::File(p) => Some(p.clone()),
            crate::io::images::ImageRef::Message { topic, index } => det
                .cache_bag
                .as_deref()
                .map(|b| DetectionCache::message_key(b, topic, *index)),
        };
        let file = det.cache.as_ref().zip(key);
        if let Some((found, width)) = file.as_ref().and_then(|(c, p)| c.get(p, cam, camera)) {
            c.images += 1;
            any = true;
            widths[cam] = width;
            dets[cam] = found;
            continue;
        }
        let Some(loaded) = load(cam) else { continue };
        let img = match loaded {
            Ok(i) => i,
            Err(e) => {
                c.unreadable += 1;
                c.problems.push(e.to_string());
                continue;
            }
        };
        if let Some(&(w, h)) = sizes.get(cam)
            && (img.width() != w || img.height() != h)
        {
            c.wrong_size += 1;
            c.problems.push(format!(
                "{name}: {}x{} image, cam{cam} is {w}x{h}",
                img.width(),
                img.height(),
            ));
            continue;
        }
        let detector = match slot {
            Some(d) => d,
            None => match Detector::new(det) {
                Ok(d) => slot.insert(d),
                Err(e) => {
                    c.problems.push(e.to_string());
                    continue;
                }
            },
        };
        c.images += 1;
        any = true;
        widths[cam] = super::sharpness::edge_width_px(&img);
        dets[cam] = detector.detect_with_camera(&img, camera);
        if let Some((cache, path)) = &file {
            cache.put(path, cam, camera, (dets[cam].clone(), widths[cam]));
        }
    }
    (dets, any, widths)
}

/// The tags of every frame, detected in parallel (one detector per worker thread), in frame
/// order: per frame, one detection list per camera. `sizes` are the expected image sizes (an
/// image of another size is counted and skipped); `cams`, when known, refine the corners in
/// undistorted coordinates. The counts come back in a [`DetectStats`] (its pose fields stay zero).
pub fn detect_frame_tags(
    frames: &[StereoFrame],
    sizes: &[(u32, u32)],
    cams: Option<&Camchain>,
    det: &DetectorSettings,
    progress: bool,
) -> Result<(Vec<Vec<Vec<TagDetection>>>, DetectStats)> {
    detect_source_tags(FrameSource::Files(frames), sizes, cams, det, progress)
}

/// [`detect_frame_tags`] on frames from any [`FrameSource`].
pub fn detect_source_tags(
    src: FrameSource<'_>,
    sizes: &[(u32, u32)],
    cams: Option<&Camchain>,
    det: &DetectorSettings,
    progress: bool,
) -> Result<(Vec<Vec<Vec<TagDetection>>>, DetectStats)> {
    let first = Detector::new(det)?;
    let n_frames = src.frames().len();
    let workers = rayon::current_num_threads().max(1);
    let detectors: Vec<Mutex<Option<Detector>>> = (0..workers).map(|_| Mutex::new(None)).collect();
    if let Ok(mut slot) = detectors[0].lock() {
        *slot = Some(first);
    }
    let models: Vec<Option<&Camera>> = (0..sizes.len())
        .map(|i| cams.and_then(|ch| ch.cams.get(i)))
        .collect();
    let bar = progress_bar(n_frames as u64, progress);
    let out: Vec<(Vec<Vec<TagDetection>>, bool, FrameCounts)> =
        for_each_frame(src, &bar, &|_| true, &|f, load| {
            let idx = rayon::current_thread_index().unwrap_or(0) % workers;
            let mut guard = detectors[idx].lock().unwrap_or_else(|p| p.into_inner());
            let mut c = FrameCounts {
                images: 0,
                unreadable: 0,
                wrong_size: 0,
                problems: Vec::new(),
            };
            let (d, any, _) = detect_images(f, load, sizes, &models, det, &mut guard, &mut c);
            drop(guard);
            (d, any, c)
        })?;
    bar.finish_and_clear();
    let mut stats = DetectStats {
        frames: n_frames,
        ..DetectStats::default()
    };
    let mut all = Vec::with_capacity(out.len());
    for (d, any, c) in out {
        stats.images += c.images;
        stats.unreadable += c.unreadable;
        stats.wrong_size += c.wrong_size;
        stats.problems.extend(c.problems);
        stats.no_image += usize::from(!any);
        stats.tags_detected += d.iter().map(Vec::len).sum::<usize>();
        all.push(d);
    }
    Ok((all, stats))
}

/// A progress bar on stderr when asked for and stderr is a terminal; hidden otherwise.
fn progress_bar(len: u64, show: bool) -> ProgressBar {
    use std::io::IsTerminal;
    if !show || !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::with_draw_target(Some(len), ProgressDrawTarget::stderr());
    if let Ok(style) = ProgressStyle::with_template(
        "{elapsed_precise} [{bar:40}] {pos}/{len} frames ({per_sec}, {eta} left)",
    ) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar
}
