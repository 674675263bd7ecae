//! The image topics of a bag as stereo frames, planned in a first pass that reads only the
//! header stamp of each image message (a few bytes, whatever the image's size) and pairs the
//! cameras by stamp exactly as image folders are paired ([`pair_frames`]). The images
//! themselves are streamed in a second pass (`io::frames`).

use std::collections::HashMap;

use crate::error::{Error, Result};
use crate::io::bag::cdr;
use crate::io::bag::image::message_to_gray;
use crate::io::bag::open::{LISTED, OpenBag, message_time};
use crate::io::bag::{BagMessage, Serialization};
use crate::io::images::{ImageRef, Layout, ScanStats, StereoFrame, pair_frames};

/// One camera's image topic.
#[derive(Clone, Debug)]
pub(crate) struct ImageTopic {
    /// The topic's index in the bag.
    pub(crate) topic: usize,
    /// The topic's name.
    pub(crate) name: String,
    /// How its messages are serialised.
    pub(crate) serialization: Serialization,
    /// Its message type.
    pub(crate) type_name: String,
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
    pub(crate) topics: Vec<ImageTopic>,
}

/// The first pass over the image topics: stamps, pairing, sizes. An image message is read
/// whole only until its camera's size is known; of the others the first bytes do (their header),
/// which spares a bag followed while recorded the reading of the images it kept
/// ([`crate::io::bag::memory`]).
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
    let need_size: Vec<std::cell::Cell<bool>> = vec![std::cell::Cell::new(true); cams];
    let whole = |topic: usize, _| cam_of.get(&topic).is_some_and(|&c| need_size[c].get());
    let summary = ob.bag.messages_with(
        &|i| cam_of.contains_key(&i),
        &whole,
        &mut |m: BagMessage<'_>| {
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
            if sizes[c].is_none() && m.whole {
                match message_to_gray(m.data, t.serialization, &t.type_name) {
                    Ok(img) => {
                        sizes[c] = Some((img.width(), img.height()));
                        need_size[c].set(false);
                    }
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
        },
    )?;
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
