//! One storage file as opened (its channels and the summary's chunk index), and what a pass
//! over its data section is asked for and reuses.

use std::collections::BTreeMap;
use std::path::PathBuf;

use super::records::ChannelRec;

/// A channel of one file, resolved to the bag's topic.
#[derive(Clone, Copy, Debug)]
pub(super) struct Chan {
    /// Index into the bag's topics.
    pub(super) topic: usize,
    /// Whether its messages are handed out (a known encoding agreeing with the topic's).
    pub(super) readable: bool,
}

/// One storage file, opened.
#[derive(Debug)]
pub(super) struct McapFile {
    pub(super) path: PathBuf,
    pub(super) len: u64,
    /// Where the data section starts (after the magic and the Header record).
    pub(super) data_start: u64,
    /// Where the data section ends at the latest (the summary's start, or the file's end).
    pub(super) data_end: u64,
    /// Whether the file ends with a footer (it was closed, not cut).
    pub(super) closed: bool,
    pub(super) channels: BTreeMap<u16, Chan>,
    /// The channels with messages in each chunk (by the chunk record's offset), from the
    /// summary's chunk indexes; chunks it does not list are always read.
    pub(super) chunk_channels: BTreeMap<u64, Vec<u16>>,
    /// Where the reads of a file being recorded keep their place ([`super::kept`]).
    pub(super) slot: Option<crate::io::bag::memory::SlotRef>,
}

/// What the summary section (or a reading of the whole file) tells of one file.
#[derive(Debug, Default)]
pub(super) struct FileInfo {
    pub(super) schemas: BTreeMap<u16, String>,
    pub(super) channels: Vec<ChannelRec>,
    /// Statistics' channel_message_counts, when present and not empty.
    pub(super) counts: Option<BTreeMap<u16, u64>>,
    pub(super) chunk_channels: BTreeMap<u64, Vec<u16>>,
}

/// Reusable buffers of a walk.
#[derive(Default)]
pub(super) struct Buffers {
    pub(super) chunk: Vec<u8>,
    pub(super) record: Vec<u8>,
}

/// Options of a walk.
pub(super) struct Walk<'w> {
    /// The channels whose messages are asked for: only these are handed to the callback,
    /// and losses are counted for them.
    pub(super) want: &'w dyn Fn(u16) -> bool,
    /// Whether a wanted message kept by an earlier read is to be handed over whole (asked
    /// just before it is): else its first bytes are ([`super::kept`]).
    pub(super) whole: &'w dyn Fn(u16) -> bool,
    /// Skip chunks that the summary's index says hold no wanted channel.
    pub(super) use_index: bool,
    /// Messages are being read (damage is described by the messages it cost).
    pub(super) counting: bool,
}
