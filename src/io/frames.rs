//! One source of stereo frames for the detection workers, whatever holds the images: a folder
//! of image files ([`crate::io::images`]) or the image topics of a bag
//! ([`crate::io::bag::frames`]). The frames are known before any image is read;
//! [`FrameSource::read`] then hands each frame's images over as the bytes stored (a file, a
//! serialised message) with their names, in one pass, and [`decode`] turns each into the grey
//! image the detector takes.
//!
//! A folder's files are read in frame order. A bag is opened again and read once in record
//! order: each frame's messages are gathered as they pass and the frame is handed over as soon
//! as all of them have come, so memory holds the frames whose images are still arriving, never
//! the bag.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use ::image::GrayImage;

use crate::error::{Error, Result};
use crate::io::bag::frames::BagFrames;
use crate::io::bag::image::message_to_gray;
use crate::io::bag::{Bag, Serialization};
use crate::io::image::decode_gray;
use crate::io::images::{ImageRef, StereoFrame};

/// One image of a frame as it is stored.
#[derive(Clone, Debug, PartialEq)]
pub enum EncodedImage<'a> {
    /// The bytes of an image file.
    File {
        /// The file.
        path: &'a Path,
        /// Its content.
        bytes: Vec<u8>,
    },
    /// A bag's serialised image message.
    Message {
        /// The message's bytes.
        data: Vec<u8>,
        /// How the message is serialised.
        serialization: Serialization,
        /// Its type (`sensor_msgs/Image` or `sensor_msgs/CompressedImage`, either ROS
        /// version's spelling).
        type_name: &'a str,
    },
}

/// The images of one frame, indexed by camera: `None` where none was delivered (the frame has
/// no image from that camera, or a bag cut short never gave it), an error where it could not be
/// read.
pub type FrameImages<'a> = Vec<Option<Result<EncodedImage<'a>>>>;

/// Where a run's frames and their images come from.
#[derive(Clone, Copy, Debug)]
pub enum FrameSource<'a> {
    /// Image files named by the frames ([`ImageRef::File`]).
    Files(&'a [StereoFrame]),
    /// The image topics of the bag at `path`, as `plan` planned them.
    Bag {
        /// The bag (opened again to read the images).
        path: &'a Path,
        /// Its frames.
        plan: &'a BagFrames,
    },
}

impl<'a> FrameSource<'a> {
    /// The frames, in time order.
    pub fn frames(&self) -> &'a [StereoFrame] {
        match self {
            FrameSource::Files(f) => f,
            FrameSource::Bag { plan, .. } => &plan.frames,
        }
    }

    /// Reads the images of the frames in one pass and calls `send(frame index, images)` once
    /// per frame it can deliver (files in frame order, a bag's frames as their last image
    /// passes, then those a bag cut short left incomplete). An error from `send` (the receiver
    /// stopped) ends the pass and is returned.
    pub fn read(&self, send: &mut dyn FnMut(usize, FrameImages<'a>) -> Result<()>) -> Result<()> {
        self.read_some(&|_| true, send)
    }

    /// [`FrameSource::read`], where a bag's frames that `needed` refuses (by index) may be left
    /// out: their images are not read (a frame whose outcome is kept from an earlier update).
    pub fn read_some(
        &self,
        needed: &dyn Fn(usize) -> bool,
        send: &mut dyn FnMut(usize, FrameImages<'a>) -> Result<()>,
    ) -> Result<()> {
        match *self {
            FrameSource::Files(frames) => {
                for (i, f) in frames.iter().enumerate() {
                    let images = f.images.iter().map(|r| r.as_ref().map(read_file)).collect();
                    send(i, images)?;
                }
                Ok(())
            }
            FrameSource::Bag { path, plan } => read_bag(path, plan, needed, send),
        }
    }
}

/// The bytes of the image file `r` names.
fn read_file(r: &ImageRef) -> Result<EncodedImage<'_>> {
    match r {
        ImageRef::File(path) => std::fs::read(path)
            .map(|bytes| EncodedImage::File { path, bytes })
            .map_err(|e| Error::io(path, e)),
        other => Err(Error::Input(format!("{other}: not a file"))),
    }
}

/// Streams the image messages of `plan`'s frames that are `needed` from the bag at `path` in
/// one pass (of a bag followed while recorded, only those messages' bytes are read again).
fn read_bag<'a>(
    path: &Path,
    plan: &'a BagFrames,
    needed: &dyn Fn(usize) -> bool,
    send: &mut dyn FnMut(usize, FrameImages<'a>) -> Result<()>,
) -> Result<()> {
    let cams = plan.topics.len();
    // Where each message goes: (camera, message number) -> frame.
    let mut slot: HashMap<(usize, u64), usize> = HashMap::new();
    let mut expected = vec![0usize; plan.frames.len()];
    for (fi, f) in plan.frames.iter().enumerate() {
        if !needed(fi) {
            continue;
        }
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
    let mut partial: BTreeMap<usize, FrameImages<'a>> = BTreeMap::new();
    let whole = |topic: usize, index: u64| {
        cam_of
            .get(&topic)
            .is_some_and(|&c| slot.contains_key(&(c, index)))
    };
    bag.messages_with(&|i| cam_of.contains_key(&i), &whole, &mut |m| {
        let Some(&c) = cam_of.get(&m.topic) else {
            return Ok(());
        };
        let Some(&fi) = slot.get(&(c, m.index)) else {
            return Ok(());
        };
        if !m.whole {
            return Ok(());
        }
        let topic = &plan.topics[c];
        let entry = partial
            .entry(fi)
            .or_insert_with(|| (0..cams).map(|_| None).collect());
        entry[c] = Some(Ok(EncodedImage::Message {
            data: m.data.to_vec(),
            serialization: topic.serialization,
            type_name: &topic.type_name,
        }));
        if entry.iter().filter(|b| b.is_some()).count() >= expected[fi]
            && let Some(images) = partial.remove(&fi)
        {
            send(fi, images)?;
        }
        Ok(())
    })?;
    // Frames whose images did not all come (a bag cut short): what came is used.
    for (fi, images) in std::mem::take(&mut partial) {
        send(fi, images)?;
    }
    Ok(())
}

/// Decodes one image of a frame to grey; `name` names it in errors (a file's errors name the
/// file already).
pub fn decode(name: &ImageRef, image: &EncodedImage<'_>) -> Result<GrayImage> {
    match image {
        EncodedImage::File { path, bytes } => decode_gray(bytes, path),
        EncodedImage::Message {
            data,
            serialization,
            type_name,
        } => message_to_gray(data, *serialization, type_name)
            .map_err(|e| Error::Input(format!("{name}: {e}"))),
    }
}
