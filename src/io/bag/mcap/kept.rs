//! What the reads of an MCAP file being recorded keep between updates
//! ([`crate::io::bag::memory`]): the data section's records up to the first one that was cut or
//! damaged, decoded (the records of each whole chunk too), so that a later walk hands them
//! over again and parses the file only from there.

use std::sync::Arc;

use super::file::{Buffers, McapFile, Walk};
use super::reader::Reader;
use super::records::{ChannelRec, Rec};
use crate::error::{Error, Result};
use crate::io::bag::memory::{self, Kept, Prefix};

/// A Schema or Channel record, kept.
#[derive(Clone, Debug)]
pub(super) enum Meta {
    Schema(u16, String),
    Channel(ChannelRec),
}

impl Meta {
    /// The record as a walk hands it over.
    fn rec(&self) -> Rec<'static> {
        match self {
            Meta::Schema(id, name) => Rec::Schema(*id, name.clone()),
            Meta::Channel(c) => Rec::Channel(c.clone()),
        }
    }

    /// `rec` kept, when it is a Schema or Channel record.
    pub(super) fn of(rec: &Rec<'_>) -> Option<Meta> {
        match rec {
            Rec::Schema(id, name) => Some(Meta::Schema(*id, name.clone())),
            Rec::Channel(c) => Some(Meta::Channel(c.clone())),
            Rec::Message { .. } => None,
        }
    }
}

/// A record inside a chunk, kept (a message's place is its offset in the chunk's records).
#[derive(Debug)]
pub(super) enum Inside {
    Meta(Meta),
    Message {
        channel: u16,
        log_time: u64,
        data: Kept,
    },
}

/// A top-level record of the data section, kept (a message's place is its offset in the file).
#[derive(Debug)]
pub(super) enum Top {
    Meta(Meta),
    Message {
        channel: u16,
        log_time: u64,
        data: Kept,
    },
    Chunk {
        /// The chunk record's offset and its content's declared length.
        p: u64,
        len: u64,
        records: Vec<Inside>,
    },
    /// A record that hands nothing over (a Message Index, an Attachment).
    Other,
}

/// What the reads of one MCAP file keep: its data section's records up to `prefix.len`.
#[derive(Debug)]
pub(crate) struct McapKept {
    prefix: Prefix,
    items: Vec<Arc<Top>>,
}

impl McapFile {
    /// Checks what the file's slot keeps against the file as it is now (readable to
    /// `self.len`): kept when the file still starts as it did and what is kept lies in its
    /// data section (a file closed since has its summary after it), else emptied.
    pub(super) fn check_kept(&self) {
        let Some(slot) = &self.slot else { return };
        let mut slot = memory::lock(slot);
        let held = slot
            .kept::<McapKept>()
            .filter(|k| k.prefix.len <= self.data_end && k.prefix.holds(&self.path, self.len))
            .map(|k| k.prefix.len);
        if held.is_none() {
            slot.take::<McapKept>();
        }
        slot.resumed(held.unwrap_or(0));
    }

    /// Where a walk starts parsing, and the records kept before it.
    pub(super) fn kept_items(&self) -> (u64, Vec<Arc<Top>>) {
        let Some(slot) = &self.slot else {
            return (self.data_start, Vec::new());
        };
        match memory::lock(slot).kept::<McapKept>() {
            Some(k) if k.prefix.len >= self.data_start => (k.prefix.len, k.items.clone()),
            _ => (self.data_start, Vec::new()),
        }
    }

    /// Adds `items`, the records parsed whole from `from` (where the walk began parsing) to
    /// `to`, to what the slot keeps, unless another walk got further meanwhile.
    pub(super) fn keep(&self, from: u64, to: u64, items: Vec<Arc<Top>>) {
        let Some(slot) = &self.slot else { return };
        if to <= from {
            return;
        }
        let Ok(prefix) = Prefix::of(&self.path, to) else {
            return;
        };
        let mut slot = memory::lock(slot);
        let to = prefix.len;
        match slot.kept_mut::<McapKept>() {
            Some(k) if k.prefix.len == from => {
                k.items.extend(items);
                k.prefix = prefix;
                slot.kept_to(to);
            }
            Some(_) => {}
            None if from == self.data_start => slot.keep(McapKept { prefix, items }, to),
            None => {}
        }
    }

    /// Counts the chunk at `p` decoded, in the file's slot.
    pub(super) fn count_decoded(&self, p: u64) {
        if let Some(slot) = &self.slot {
            memory::lock(slot).decoded(p);
        }
    }

    /// Hands over a kept record as the walk would: its Schema and Channel records, and the
    /// messages `opts` wants (a long one read again whole when `opts.whole` says so).
    pub(super) fn replay(
        &self,
        r: &mut Reader,
        bufs: &mut Buffers,
        item: &Top,
        opts: &Walk<'_>,
        f: &mut dyn FnMut(Rec<'_>) -> Result<()>,
    ) -> Result<()> {
        match item {
            Top::Meta(m) => f(m.rec()),
            Top::Other => Ok(()),
            Top::Message {
                channel,
                log_time,
                data,
            } => {
                if !(opts.want)(*channel) {
                    return Ok(());
                }
                let (bytes, whole) = match data {
                    Kept::Head { at, len, .. } if (opts.whole)(*channel) => {
                        r.read_into(*at, *len as u64, &mut bufs.record)?;
                        (bufs.record.as_slice(), true)
                    }
                    Kept::Head { head, .. } => (head.as_slice(), false),
                    Kept::Whole(b) => (b.as_slice(), true),
                };
                f(Rec::Message {
                    channel: *channel,
                    log_time: *log_time,
                    data: bytes,
                    whole,
                })
            }
            Top::Chunk {
                p,
                len: chunk_len,
                records,
            } => {
                if self.skipped_by_index(*p, opts) {
                    return Ok(());
                }
                let mut loaded = false;
                for rec in records {
                    match rec {
                        Inside::Meta(m) => f(m.rec())?,
                        Inside::Message {
                            channel,
                            log_time,
                            data,
                        } => {
                            if !(opts.want)(*channel) {
                                continue;
                            }
                            let (bytes, whole) = match data {
                                Kept::Head { at, len, .. } if (opts.whole)(*channel) => {
                                    if !loaded {
                                        self.reload(r, bufs, *p, *chunk_len)?;
                                        loaded = true;
                                    }
                                    let at = *at as usize;
                                    let b = bufs
                                        .chunk
                                        .get(at..at.saturating_add(*len))
                                        .ok_or_else(|| self.changed(*p))?;
                                    (b, true)
                                }
                                Kept::Head { head, .. } => (head.as_slice(), false),
                                Kept::Whole(b) => (b.as_slice(), true),
                            };
                            f(Rec::Message {
                                channel: *channel,
                                log_time: *log_time,
                                data: bytes,
                                whole,
                            })?;
                        }
                    }
                }
                Ok(())
            }
        }
    }

    /// Decompresses the kept chunk at `p` again into `bufs.chunk`.
    fn reload(&self, r: &mut Reader, bufs: &mut Buffers, p: u64, len: u64) -> Result<()> {
        let none = Walk {
            want: &|_| false,
            whole: &|_| false,
            use_index: false,
            counting: false,
        };
        self.count_decoded(p);
        match self.chunk(r, bufs, p, len, &none, &mut |_| Ok(()), None)? {
            None => Ok(()),
            Some(_) => Err(self.changed(p)),
        }
    }

    /// The error for a kept chunk that no longer reads as it did.
    fn changed(&self, p: u64) -> Error {
        Error::Input(format!(
            "{}: the chunk at byte {p} changed while the file was followed",
            self.path.display()
        ))
    }
}
