//! A bag as a dataset: its images streamed to the detection workers ([`frame_source`]) for the
//! poses and for a camera calibration. Opening the bag, planning its frames, reading its poses
//! and its `CameraInfo` are `io::bag`'s.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;
use std::time::Instant;

use crate::error::{Error, Result};
use crate::io::bag::Bag;
use crate::io::bag::frames::BagFrames;
use crate::io::bag::open::OpenBag;
use crate::io::images::{ImageRef, raw_time};
use crate::io::target::read_board;
use crate::time::Epoch;
use crate::types::camera::Camchain;
use crate::vision::frames::{FrameBytes, FrameSource, FrameStream, detect_source};
use crate::vision::pnp::PnpOptions;

use super::cameras::{CameraCalOptions, CameraCalRun, calibrate_cameras_from_frames};
use super::vision::{VisionOptions, VisionRun, detector_settings, posed_frames};

/// The images of `plan`'s frames, streamed from the bag at `path` (opened again on the
/// reading thread) in one pass.
pub fn frame_source<'a>(path: &'a Path, plan: &'a BagFrames) -> FrameSource<'a> {
    let cams = plan.topics.len();
    let produce = Box::new(
        move |send: &mut dyn FnMut(usize, FrameBytes) -> Result<()>| {
            // Where each message goes: (camera, message number) -> frame.
            let mut slot: HashMap<(usize, u64), usize> = HashMap::new();
            let mut expected = vec![0usize; plan.frames.len()];
            for (fi, f) in plan.frames.iter().enumerate() {
                for (c, r) in f.images.iter().enumerate() {
                    if let Some(ImageRef::Message { index, .. }) = r {
                        slot.insert((c, *index), fi);
                        expected[fi] += 1;
                    }
                }
            }
            let bag = Bag::open(path)?;
            let cam_of: HashMap<usize, usize> = plan
                .topics
                .iter()
                .enumerate()
                .map(|(c, t)| (t.topic, c))
                .collect();
            let mut partial: BTreeMap<usize, FrameBytes> = BTreeMap::new();
            bag.messages(&|i| cam_of.contains_key(&i), &mut |m| {
                let Some(&c) = cam_of.get(&m.topic) else {
                    return Ok(());
                };
                let Some(&fi) = slot.get(&(c, m.index)) else {
                    return Ok(());
                };
                let entry = partial.entry(fi).or_insert_with(|| vec![None; cams]);
                entry[c] = Some(m.data.to_vec());
                if entry.iter().filter(|b| b.is_some()).count() >= expected[fi] {
                    if let Some(bytes) = partial.remove(&fi) {
                        send(fi, bytes)?;
                    }
                }
                Ok(())
            })?;
            // Frames whose images did not all come (a bag cut short): what came is used.
            for (fi, bytes) in std::mem::take(&mut partial) {
                send(fi, bytes)?;
            }
            Ok(())
        },
    );
    let topics = &plan.topics;
    FrameSource::Stream(FrameStream {
        frames: &plan.frames,
        produce,
        decode: Box::new(move |c: usize, b: &[u8]| {
            let t = topics
                .get(c)
                .ok_or_else(|| Error::Input(format!("no camera {c}")))?;
            crate::io::bag::image::message_to_gray(b, t.serialization, &t.type_name)
        }),
    })
}

/// Camera poses from a bag's images, as [`super::poses_from_images_with_chain`] does for a
/// folder: the frames planned from the header stamps, the images streamed, detected and
/// solved on `opts.threads` workers.
pub fn poses_from_bag(
    ob: &OpenBag,
    plan: &BagFrames,
    chain: Camchain,
    target: &Path,
    opts: &VisionOptions,
) -> Result<VisionRun> {
    opts.validate()?;
    let board = read_board(target)?;
    if chain.cams.len() < plan.topics.len() {
        return Err(Error::Input(format!(
            "{}: {} image topics, the camera chain has {} cameras",
            ob.path().display(),
            plan.topics.len(),
            chain.cams.len()
        )));
    }
    for (c, (&(w, h), cam)) in plan.sizes.iter().zip(&chain.cams).enumerate() {
        if (w, h) != (0, 0) && (w, h) != (cam.width, cam.height) {
            return Err(Error::Input(format!(
                "{}: {} images are {w}x{h}, cam{c} of the camera chain is {}x{}",
                ob.path().display(),
                plan.topics[c].name,
                cam.width,
                cam.height
            )));
        }
    }
    let pnp = PnpOptions {
        min_corners: opts.min_corners,
        sigma_px: opts.pixel_sigma,
        ..PnpOptions::default()
    };
    let det = detector_settings(&board, opts);
    let pool = crate::parallel::worker_pool(opts.threads)?;
    let start = Instant::now();
    let (results, mut stats) = pool.install(|| {
        detect_source(
            frame_source(ob.path(), plan),
            &board,
            &chain,
            &det,
            &pnp,
            opts.progress,
        )
    })?;
    stats.problems.splice(0..0, plan.unreadable.iter().cloned());
    let seconds = start.elapsed().as_secs_f64();
    let epoch = Epoch::at(raw_time(plan.frames.first().map_or(0, |f| f.t_ns)));
    let poses = posed_frames(&results, &epoch);
    Ok(VisionRun {
        images: ob.path().to_path_buf(),
        chain,
        epoch,
        poses,
        results,
        scan: plan.scan.clone(),
        stats,
        seconds,
    })
}

/// Calibrates the cameras of a bag's image topics from the board `target`, as
/// [`super::calibrate_cameras_from_images`] does for a folder (each detection pass streams the
/// bag once). The chain's `rostopic`s are the bag's image topics.
pub fn calibrate_cameras_from_bag(
    ob: &OpenBag,
    plan: &BagFrames,
    target: &Path,
    opts: &CameraCalOptions,
) -> Result<CameraCalRun> {
    opts.vision.validate()?;
    let board = read_board(target)?;
    let mut run = calibrate_cameras_from_frames(
        ob.path(),
        target,
        &board,
        &plan.frames,
        plan.scan.clone(),
        plan.sizes.clone(),
        &|| frame_source(ob.path(), plan),
        opts,
    )?;
    for (t, topic) in run.result.chain.topics.iter_mut().zip(&plan.topics) {
        *t = Some(topic.name.clone());
    }
    Ok(run)
}
