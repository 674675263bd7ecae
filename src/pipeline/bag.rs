//! A bag as a dataset: its topics given parts ([`crate::io::bag::roles`]), its images turned
//! into frames and streamed to the detection workers, its poses read, its `CameraInfo` made a
//! camera model, and a listing of what it holds (`dvlcal bag-info`).
//!
//! Images are read in two passes. The first reads only the header stamp of each image message
//! (a few bytes, whatever the image's size) and pairs the cameras by stamp exactly as image
//! folders are paired ([`pair_frames`]); the second streams the messages again, gathers each
//! frame's images as they pass and hands complete frames to the workers through a short queue
//! ([`FrameStream`]). Memory holds the frames in the queue and those whose images are still
//! arriving, never the bag.

use std::collections::{BTreeMap, HashMap};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::error::{Error, Result};
use crate::io::bag::cdr;
use crate::io::bag::roles::{self, BagOptions, BagTime, Kind, Roles};
use crate::io::bag::{Bag, BagMessage, Serialization, Topic};
use crate::io::images::{ImageRef, Layout, ScanStats, StereoFrame, pair_frames, raw_time};
use crate::lie::Se3;
use crate::time::Epoch;
use crate::types::PoseMeasurement;
use crate::types::camera::{Camchain, Camera, Distortion};
use crate::vision::frames::{FrameBytes, FrameSource, FrameStream, detect_source};
use crate::vision::pnp::PnpOptions;

use super::cameras::{CameraCalOptions, CameraCalRun, calibrate_cameras_from_frames};
use super::vision::{VisionOptions, VisionRun, detector_settings, posed_frames};
use crate::io::target::read_board;

/// A bag opened, with the parts its topics play.
#[derive(Debug)]
pub struct OpenBag {
    /// The bag.
    pub bag: Bag,
    /// The parts its topics play.
    pub roles: Roles,
    /// The options the roles were chosen with.
    pub options: BagOptions,
}

impl OpenBag {
    /// Opens `path` and gives its topics their parts.
    pub fn open(path: &Path, options: &BagOptions) -> Result<OpenBag> {
        let bag = Bag::open(path)?;
        let roles = roles::assign(bag.topics(), options)
            .map_err(|e| Error::Input(format!("{}: {e}", path.display())))?;
        Ok(OpenBag {
            bag,
            roles,
            options: options.clone(),
        })
    }

    /// The bag's path.
    pub fn path(&self) -> &Path {
        self.bag.path()
    }

    fn topic(&self, i: usize) -> &Topic {
        &self.bag.topics()[i]
    }

    /// The topics with their types, for error messages.
    pub fn topic_list(&self) -> String {
        roles::topic_list(self.bag.topics())
    }
}

/// A time in nanoseconds from a header stamp and a record time, as `time` asks: the stamp, or
/// the record time when the stamp is zero (counted in `zero`) or when record times are asked
/// for.
fn message_time(stamp_ns: i64, record_ns: i64, time: BagTime, zero: &mut usize) -> i64 {
    match time {
        BagTime::Record => record_ns,
        BagTime::Header if stamp_ns == 0 => {
            *zero += 1;
            record_ns
        }
        BagTime::Header => stamp_ns,
    }
}

/// One camera's image topic.
#[derive(Clone, Debug)]
struct ImageTopic {
    topic: usize,
    name: String,
    serialization: Serialization,
    type_name: String,
}

/// The frames of a bag's image topics, planned by the first pass.
#[derive(Clone, Debug)]
pub struct BagFrames {
    /// The frames, in time order, their images named by topic and message number.
    pub frames: Vec<StereoFrame>,
    /// The pairing's counts and warnings.
    pub scan: ScanStats,
    /// The image size of each camera (from its first image that decodes).
    pub sizes: Vec<(u32, u32)>,
    /// Image messages whose header could not be read (skipped), with the first few named.
    pub unreadable: Vec<String>,
    /// Each camera's `header.frame_id` (of its first image message that names one).
    pub frame_ids: Vec<Option<String>>,
    topics: Vec<ImageTopic>,
}

/// How many unreadable image headers are named (the rest are counted).
const LISTED: usize = 10;

/// The first pass over the image topics: stamps, pairing, sizes.
pub fn plan_frames(ob: &OpenBag, tolerance_ns: i64) -> Result<BagFrames> {
    let cams = ob.roles.images.len();
    if cams == 0 {
        return Err(Error::Input(format!(
            "{}: no image topic (sensor_msgs/Image or CompressedImage) in this bag (topics: {})",
            ob.path().display(),
            ob.topic_list()
        )));
    }
    let topics: Vec<ImageTopic> = ob
        .roles
        .images
        .iter()
        .map(|&i| {
            let t = ob.topic(i);
            ImageTopic {
                topic: i,
                name: t.name.clone(),
                serialization: t.serialization,
                type_name: t.type_name(),
            }
        })
        .collect();
    let cam_of: HashMap<usize, usize> = topics
        .iter()
        .enumerate()
        .map(|(c, t)| (t.topic, c))
        .collect();
    let mut lists: Vec<Vec<(i64, ImageRef)>> = vec![Vec::new(); cams];
    let mut sizes: Vec<Option<(u32, u32)>> = vec![None; cams];
    let mut size_errors: Vec<Option<String>> = vec![None; cams];
    let mut frame_ids: Vec<Option<String>> = vec![None; cams];
    let mut unreadable = Vec::new();
    let mut n_unreadable = 0usize;
    let mut zero = 0usize;
    let time = ob.options.time;
    let summary = ob
        .bag
        .messages(&|i| cam_of.contains_key(&i), &mut |m: BagMessage<'_>| {
            let Some(&c) = cam_of.get(&m.topic) else {
                return Ok(());
            };
            let t = &topics[c];
            let stamp = match cdr::decode_header(m.data, t.serialization) {
                Ok(h) => {
                    let id = h.frame_id.trim_start_matches('/');
                    if frame_ids[c].is_none() && !id.is_empty() {
                        frame_ids[c] = Some(id.to_owned());
                    }
                    h.stamp.as_nanos()
                }
                Err(e) => {
                    n_unreadable += 1;
                    if unreadable.len() < LISTED {
                        unreadable.push(format!("{} message {}: {e}", t.name, m.index));
                    }
                    return Ok(());
                }
            };
            if sizes[c].is_none() {
                match crate::io::bag::image::message_to_gray(m.data, t.serialization, &t.type_name)
                {
                    Ok(img) => sizes[c] = Some((img.width(), img.height())),
                    Err(e) => size_errors[c] = Some(format!("{} message {}: {e}", t.name, m.index)),
                }
            }
            let t_ns = message_time(stamp, m.log_time_ns, time, &mut zero);
            lists[c].push((
                t_ns,
                ImageRef::Message {
                    topic: t.name.clone(),
                    index: m.index,
                },
            ));
            Ok(())
        })?;
    let mut scan = ScanStats {
        layout: Layout::Bag,
        folders: vec![None; cams],
        images: Vec::new(),
        complete: 0,
        unpaired_cam0: 0,
        unpaired_other: 0,
        ignored: n_unreadable,
        duplicates: 0,
        warnings: summary
            .problems
            .iter()
            .map(|p| format!("{}: {p}", ob.path().display()))
            .collect(),
    };
    if n_unreadable > LISTED {
        unreadable.push(format!("... and {} more", n_unreadable - LISTED));
    }
    if zero > 0 {
        scan.warnings.push(format!(
            "{zero} image messages have a zero header.stamp: their record time is used"
        ));
    }
    for list in &mut lists {
        list.sort_by_key(|(t, _)| *t);
        let before = list.len();
        list.dedup_by_key(|(t, _)| *t);
        scan.duplicates += before - list.len();
        scan.images.push(list.len());
    }
    if lists[0].is_empty() {
        return Err(Error::Input(format!(
            "{}: no readable image on {}{}",
            ob.path().display(),
            topics[0].name,
            unreadable
                .first()
                .map_or(String::new(), |u| format!(" ({u})"))
        )));
    }
    let mut out_sizes = Vec::with_capacity(cams);
    for c in 0..cams {
        match sizes[c] {
            Some(s) => out_sizes.push(s),
            None if lists[c].is_empty() => out_sizes.push((0, 0)),
            None => {
                return Err(Error::Input(format!(
                    "{}: no image of {} could be decoded{}",
                    ob.path().display(),
                    topics[c].name,
                    size_errors[c]
                        .as_ref()
                        .map_or(String::new(), |e| format!(" ({e})"))
                )));
            }
        }
    }
    let missing: Vec<String> = topics
        .iter()
        .map(|t| format!("{}: {} holds no images", ob.path().display(), t.name))
        .collect();
    let frames = pair_frames(lists, tolerance_ns, &missing, &mut scan);
    Ok(BagFrames {
        frames,
        scan,
        sizes: out_sizes,
        unreadable,
        frame_ids,
        topics,
    })
}

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

/// The camera of a bag's `CameraInfo` topic (its first message that describes a calibrated
/// camera), for a bag of one camera and no camchain. `None` when the image topic has no
/// `CameraInfo`.
pub fn camera_from_info(ob: &OpenBag, cam: usize) -> Result<Option<Camera>> {
    let Some(Some(info)) = ob.roles.camera_info.get(cam).copied() else {
        return Ok(None);
    };
    let topic = ob.topic(info).clone();
    let mut found: Option<Result<Camera>> = None;
    ob.bag.messages(&|i| i == info, &mut |m| {
        if matches!(found, Some(Ok(_))) {
            return Ok(());
        }
        let r = cdr::decode::<cdr::CameraInfo>(m.data, topic.serialization)
            .and_then(|ci| ci.model())
            .map(|model| camera_of(&model))
            .map_err(|e| Error::Input(format!("{} message {}: {e}", topic.name, m.index)));
        found = Some(r);
        Ok(())
    })?;
    match found {
        None => Ok(None),
        Some(r) => r.map(Some),
    }
}

fn camera_of(m: &crate::io::bag::camera_info::CameraInfoModel) -> Camera {
    use crate::io::bag::camera_info::DistortionModel as D;
    Camera {
        fu: m.fx,
        fv: m.fy,
        pu: m.cx,
        pv: m.cy,
        distortion: match m.distortion {
            D::RadTan { k1, k2, p1, p2 } => Distortion::RadTan { k1, k2, p1, p2 },
            D::Equidistant { k1, k2, k3, k4 } => Distortion::Equidistant { k1, k2, k3, k4 },
        },
        width: m.width,
        height: m.height,
    }
}

/// What reading a pose topic found.
#[derive(Clone, Debug, Default)]
pub struct BagPoses {
    /// The epoch of the pose times: the whole second of the first pose.
    pub epoch: Epoch,
    /// The poses `T_world_cam`, in time order, without covariance.
    pub poses: Vec<PoseMeasurement>,
    /// The topic (and, for TF, the child frame) read.
    pub source: String,
    /// Things the user should know (zero stamps, repeated stamps, skipped messages).
    pub warnings: Vec<String>,
}

/// The camera's poses from the bag's pose topic (`geometry_msgs/PoseStamped`,
/// `PoseWithCovarianceStamped`, `TransformStamped`, `nav_msgs/Odometry`, or the transforms of
/// one child frame in `tf2_msgs/TFMessage`): `T_parent_child` read as `T_world_cam`.
pub fn read_bag_poses(ob: &OpenBag) -> Result<BagPoses> {
    let Some(idx) = ob.roles.pose else {
        return Err(Error::Input(format!(
            "{}: no image or pose topic in this bag (topics: {}); choose one with \
             --image-topics or --pose-topic",
            ob.path().display(),
            ob.topic_list()
        )));
    };
    let topic = ob.topic(idx).clone();
    let Some(kind) = roles::kind(&topic) else {
        return Err(Error::Input(format!(
            "{}: {} is not a pose topic",
            ob.path().display(),
            topic.name
        )));
    };
    let ser = topic.serialization;
    let want_frame = ob
        .options
        .pose_frame
        .as_deref()
        .map(|f| f.trim_start_matches('/').to_string());
    // Per child frame (one, "", for the topics of one pose per message): (t_ns, pose).
    let mut by_child: BTreeMap<String, Vec<(i64, Se3)>> = BTreeMap::new();
    let mut zero = 0usize;
    let mut bad = Vec::new();
    let mut n_bad = 0usize;
    let time = ob.options.time;
    let summary = ob.bag.messages(&|i| i == idx, &mut |m| {
        let decoded: Result<Vec<(String, cdr::Time, cdr::Pose)>> = (|| {
            Ok(match kind {
                Kind::PoseStamped => {
                    let p: cdr::PoseStamped = cdr::decode(m.data, ser)?;
                    vec![(String::new(), p.header.stamp, p.pose)]
                }
                Kind::PoseCov => {
                    let p: cdr::PoseWithCovarianceStamped = cdr::decode(m.data, ser)?;
                    vec![(String::new(), p.header.stamp, p.pose.pose)]
                }
                Kind::Odometry => {
                    let p: cdr::Odometry = cdr::decode(m.data, ser)?;
                    vec![(String::new(), p.header.stamp, p.pose.pose)]
                }
                Kind::Transform => {
                    let t: cdr::TransformStamped = cdr::decode(m.data, ser)?;
                    vec![transform_pose(&t)]
                }
                Kind::Tf => {
                    let tf: cdr::TfMessage = cdr::decode(m.data, ser)?;
                    tf.transforms.iter().map(transform_pose).collect()
                }
                _ => Vec::new(),
            })
        })();
        match decoded {
            Ok(list) => {
                for (child, stamp, pose) in list {
                    let t_ns = message_time(stamp.as_nanos(), m.log_time_ns, time, &mut zero);
                    match se3_of(&pose) {
                        Some(p) => by_child.entry(child).or_default().push((t_ns, p)),
                        None => {
                            n_bad += 1;
                            if bad.len() < LISTED {
                                bad.push(format!(
                                    "{} message {}: not a pose (quaternion of norm far from 1, \
                                     or a value that is not finite)",
                                    topic.name, m.index
                                ));
                            }
                        }
                    }
                }
            }
            Err(e) => {
                n_bad += 1;
                if bad.len() < LISTED {
                    bad.push(format!("{} message {}: {e}", topic.name, m.index));
                }
            }
        }
        Ok(())
    })?;
    let mut warnings: Vec<String> = summary
        .problems
        .iter()
        .map(|p| format!("{}: {p}", ob.path().display()))
        .collect();
    let (child, mut list) = if kind == Kind::Tf || kind == Kind::Transform {
        let children: Vec<&String> = by_child.keys().collect();
        let chosen = match &want_frame {
            Some(f) => by_child.keys().find(|k| *k == f).cloned().ok_or_else(|| {
                Error::Input(format!(
                    "{}: no transform to child frame {f} on {} (child frames: {})",
                    ob.path().display(),
                    topic.name,
                    join(&children)
                ))
            })?,
            None if children.len() == 1 => children[0].clone(),
            None => {
                return Err(Error::Input(format!(
                    "{}: {} holds transforms to several child frames ({}); choose the \
                     camera's with --pose-frame",
                    ob.path().display(),
                    topic.name,
                    join(&children)
                )));
            }
        };
        let list = by_child.remove(&chosen).unwrap_or_default();
        (chosen, list)
    } else {
        (String::new(), by_child.remove("").unwrap_or_default())
    };
    if n_bad > 0 {
        warnings.push(format!(
            "{n_bad} messages of {} could not be used: {}",
            topic.name,
            bad.join("; ")
        ));
    }
    if zero > 0 {
        warnings.push(format!(
            "{zero} poses on {} have a zero header.stamp: their record time is used",
            topic.name
        ));
    }
    list.sort_by_key(|(t, _)| *t);
    let before = list.len();
    list.dedup_by_key(|(t, _)| *t);
    if list.len() < before {
        warnings.push(format!(
            "{} poses on {} repeat an earlier time stamp and were dropped",
            before - list.len(),
            topic.name
        ));
    }
    let Some(&(t0, _)) = list.first() else {
        return Err(Error::Input(format!(
            "{}: no usable pose on {}{}",
            ob.path().display(),
            topic.name,
            warnings.last().map_or(String::new(), |w| format!(" ({w})"))
        )));
    };
    let epoch = Epoch::at(raw_time(t0));
    let poses = list
        .into_iter()
        .map(|(t, pose)| PoseMeasurement {
            t: epoch.rel(raw_time(t)),
            pose,
            cov: None,
        })
        .collect();
    let source = if child.is_empty() {
        format!("{} ({})", topic.name, topic.type_name())
    } else {
        format!(
            "{} ({}, child frame {child})",
            topic.name,
            topic.type_name()
        )
    };
    Ok(BagPoses {
        epoch,
        poses,
        source,
        warnings,
    })
}

fn join(v: &[&String]) -> String {
    v.iter().map(|s| s.as_str()).collect::<Vec<_>>().join(", ")
}

fn transform_pose(t: &cdr::TransformStamped) -> (String, cdr::Time, cdr::Pose) {
    let tr = &t.transform;
    (
        t.child_frame_id.trim_start_matches('/').to_string(),
        t.header.stamp,
        cdr::Pose {
            position: cdr::Point {
                x: tr.translation.x,
                y: tr.translation.y,
                z: tr.translation.z,
            },
            orientation: tr.rotation,
        },
    )
}

/// Largest departure of a pose's quaternion norm from 1 that is taken for rounding (a TUM
/// file's limit).
const QUATERNION_NORM_TOL: f64 = 1e-3;

fn se3_of(p: &cdr::Pose) -> Option<Se3> {
    let q = [
        p.orientation.x,
        p.orientation.y,
        p.orientation.z,
        p.orientation.w,
    ];
    let t = [p.position.x, p.position.y, p.position.z];
    if q.iter().chain(&t).any(|v| !v.is_finite()) {
        return None;
    }
    let norm = q.iter().map(|c| c * c).sum::<f64>().sqrt();
    if (norm - 1.0).abs() > QUATERNION_NORM_TOL {
        return None;
    }
    let qn = [q[0] / norm, q[1] / norm, q[2] / norm, q[3] / norm];
    Some(Se3::from_quaternion_xyzw(
        &qn,
        nalgebra::Vector3::new(t[0], t[1], t[2]),
    ))
}

/// One topic as `dvlcal bag-info` lists it.
#[derive(Clone, Debug)]
pub struct TopicInfo {
    /// The topic.
    pub topic: Topic,
    /// Messages read.
    pub count: u64,
    /// First and last record time, Unix ns (0 without messages).
    pub first_ns: i64,
    /// Last record time, Unix ns.
    pub last_ns: i64,
    /// The part dvlcal gives it (`images cam0`, `DVL`, ...; `-` for none).
    pub role: String,
}

impl TopicInfo {
    /// Messages per second over the topic's span (0 for fewer than two messages).
    pub fn rate_hz(&self) -> f64 {
        let span = (self.last_ns - self.first_ns) as f64 * 1e-9;
        if self.count < 2 || span <= 0.0 {
            0.0
        } else {
            (self.count - 1) as f64 / span
        }
    }
}

/// What `dvlcal bag-info` prints.
#[derive(Clone, Debug)]
pub struct BagInfo {
    /// The bag.
    pub path: PathBuf,
    /// Its storage's name.
    pub storage: &'static str,
    /// One per topic.
    pub topics: Vec<TopicInfo>,
    /// How the parts were chosen, or why they could not be.
    pub notes: Vec<String>,
    /// Damage met.
    pub problems: Vec<String>,
}

/// Reads every message's record time once and lists the topics with their counts, rates and
/// spans, and the part dvlcal would give each under `options`.
pub fn bag_info(path: &Path, options: &BagOptions) -> Result<BagInfo> {
    let bag = Bag::open(path)?;
    let (roles, mut notes) = match roles::assign(bag.topics(), options) {
        Ok(r) => {
            let notes = r.notes.clone();
            (r, notes)
        }
        Err(e) => (Roles::default(), vec![format!("no roles: {e}")]),
    };
    let n = bag.topics().len();
    let mut count = vec![0u64; n];
    let mut first = vec![i64::MAX; n];
    let mut last = vec![i64::MIN; n];
    let summary = bag.messages(&|_| true, &mut |m| {
        if let Some(c) = count.get_mut(m.topic) {
            *c += 1;
            first[m.topic] = first[m.topic].min(m.log_time_ns);
            last[m.topic] = last[m.topic].max(m.log_time_ns);
        }
        Ok(())
    })?;
    let topics = bag
        .topics()
        .iter()
        .enumerate()
        .map(|(i, t)| TopicInfo {
            topic: t.clone(),
            count: count[i],
            first_ns: if count[i] > 0 { first[i] } else { 0 },
            last_ns: if count[i] > 0 { last[i] } else { 0 },
            role: roles::role_name(&roles, i),
        })
        .collect();
    if roles.images.is_empty() && roles.pose.is_none() {
        notes.push("no image or pose topic: nothing gives the camera's motion".into());
    }
    if roles.dvl.is_none() {
        notes.push("no DVL topic".into());
    }
    let mut problems = bag.problems().to_vec();
    problems.extend(summary.problems);
    Ok(BagInfo {
        path: path.to_path_buf(),
        storage: bag.storage().name(),
        topics,
        notes,
        problems,
    })
}

impl BagInfo {
    /// The listing: one line per topic, then the notes and the damage.
    pub fn render(&self) -> String {
        let mut s = format!("{} ({})\n", self.path.display(), self.storage);
        let _ = writeln!(
            s,
            "{:<40} {:<44} {:>8} {:>9} {:>9}  role",
            "topic", "type", "messages", "rate Hz", "span s"
        );
        for t in &self.topics {
            let span = (t.last_ns - t.first_ns) as f64 * 1e-9;
            let _ = writeln!(
                s,
                "{:<40} {:<44} {:>8} {:>9.2} {:>9.2}  {}",
                t.topic.name,
                t.topic.type_name(),
                t.count,
                t.rate_hz(),
                span,
                t.role
            );
        }
        if let (Some(a), Some(b)) = (
            self.topics
                .iter()
                .filter(|t| t.count > 0)
                .map(|t| t.first_ns)
                .min(),
            self.topics
                .iter()
                .filter(|t| t.count > 0)
                .map(|t| t.last_ns)
                .max(),
        ) {
            let _ = writeln!(
                s,
                "record times {} to {} ({:.2} s)",
                Epoch::at(raw_time(a)).format_abs(raw_frac(a), 3),
                Epoch::at(raw_time(b)).format_abs(raw_frac(b), 3),
                (b - a) as f64 * 1e-9
            );
        }
        for n in &self.notes {
            let _ = writeln!(s, "note: {n}");
        }
        for p in &self.problems {
            let _ = writeln!(s, "damage: {p}");
        }
        s
    }
}

/// The fraction of a second of a nanosecond time, in seconds.
fn raw_frac(t_ns: i64) -> f64 {
    t_ns.rem_euclid(1_000_000_000) as f64 * 1e-9
}
