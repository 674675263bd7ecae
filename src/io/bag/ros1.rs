//! The ROS 1 bag container (format 2.0): records, chunks, connections and messages, read in file
//! order so that a bag whose index is missing (a recording that was never closed, `.bag.active`)
//! or whose end is cut off (a full disk, a killed recorder) still gives every message it holds.
//!
//! A record is `header_len: u32`, a header of `field_len: u32, name=value` fields, `data_len:
//! u32` and the data. The top level holds the bag header (op 3), chunks (op 5) each followed by
//! index data (op 4) and, after `index_pos`, connections (op 7) and chunk infos (op 6). A chunk's
//! data (uncompressed, bz2 or lz4) holds connections and message data (op 2). Nothing here
//! trusts a length: every read is bounds-checked, every loop moves forward, a decompressed chunk
//! is bounded by its declared size, and a damaged stretch is skipped to the next record that
//! parses. What could not be read is described in [`Ros1Bag::problems`] and in the
//! [`ReadSummary`] of a pass over the messages.

use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::Arc;

mod records;

use super::memory::{self, Kept, Prefix, SlotRef};
use crate::error::{Error, Result};
use records::{
    ANY_OP, ChunkLoc, Compression, MAX_CHUNK, MAX_HEADER, OP_BAG_HEADER, OP_CHUNK, OP_CHUNK_INFO,
    OP_CONNECTION, OP_INDEX_DATA, OP_MESSAGE, RecordHead, connection_type, decompress, read_at,
    record_at, resync,
};

/// The first 13 bytes of every ROS 1 bag of format 2.0.
pub const MAGIC: &[u8] = b"#ROSBAG V2.0\n";

/// One connection of a bag: a topic with its message type.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Connection {
    /// The connection id messages refer to.
    pub id: u32,
    /// The topic name.
    pub topic: String,
    /// The message type (`package/Type`); empty when the record did not say.
    pub msg_type: String,
}

/// One message handed to [`Ros1Bag::messages`].
#[derive(Clone, Copy, Debug)]
pub struct Message<'a> {
    /// The connection the message belongs to.
    pub conn_id: u32,
    /// The record time: seconds.
    pub sec: u32,
    /// The record time: nanoseconds.
    pub nsec: u32,
    /// The serialised message: all of it, or its first [`memory::HEAD`] bytes when `whole`
    /// is false.
    pub data: &'a [u8],
    /// Whether `data` is the whole message (it is unless the message was kept from an earlier
    /// read of a bag followed while recorded, and not asked for whole).
    pub whole: bool,
    /// The 1-based number of this message among the messages read (all connections).
    pub number: usize,
    /// The byte offset in the file of the chunk holding the message.
    pub chunk_offset: u64,
}

/// What one pass over the messages found.
#[derive(Clone, Debug, Default)]
pub struct ReadSummary {
    /// Messages handed to the callback.
    pub messages: usize,
    /// Chunks read whole.
    pub chunks_read: usize,
    /// Damage met while reading the chunks, each with what it cost.
    pub problems: Vec<String>,
    /// Messages of the wanted connections the index lists but that could not be read, when the
    /// index survives to tell; `None` when it does not.
    pub lost_messages: Option<u64>,
}

/// A ROS 1 bag opened for reading: its connections and where its chunks are.
#[derive(Debug)]
pub struct Ros1Bag {
    path: PathBuf,
    file_len: u64,
    connections: BTreeMap<u32, Connection>,
    chunks: Vec<ChunkLoc>,
    /// Messages per connection per chunk (by chunk record offset), from the index section.
    index_counts: BTreeMap<u64, BTreeMap<u32, u32>>,
    indexed: bool,
    problems: Vec<String>,
    /// Where the reads of a bag followed while recorded keep their place ([`memory`]).
    slot: Option<SlotRef>,
}

/// The walk over the top-level records, as far as it got: where it is and what it found.
#[derive(Clone, Debug, Default)]
pub(crate) struct Scan {
    /// The next record's offset.
    p: u64,
    /// The connections of the index section.
    connections: BTreeMap<u32, Connection>,
    chunks: Vec<ChunkLoc>,
    index_counts: BTreeMap<u64, BTreeMap<u32, u32>>,
    index_pos: Option<u64>,
    /// The bag header's conn_count and chunk_count.
    declared: (Option<u32>, Option<u32>),
    index_conns: u32,
    chunk_infos: u32,
}

/// A record of a chunk, kept.
#[derive(Debug)]
pub(crate) enum Item {
    Connection {
        id: u32,
        topic: String,
        msg_type: String,
    },
    Message {
        conn_id: u32,
        sec: u32,
        nsec: u32,
        /// Its bytes, or their head and offset in the chunk's decompressed records.
        data: Kept,
    },
}

/// What the reads of a ROS 1 bag being recorded keep ([`memory`]): the top-level walk up to
/// the first record that was cut or damaged, and the records of every whole, undamaged chunk
/// before it, by the chunk's offset.
#[derive(Debug)]
pub(crate) struct Ros1Kept {
    prefix: Prefix,
    scan: Scan,
    chunks: HashMap<u64, Arc<Vec<Item>>>,
}

impl Ros1Bag {
    /// Opens a bag: checks the magic, then walks the top-level records in file order, noting
    /// the chunks and the connections (from the index section when it is whole, otherwise from
    /// the chunks themselves). Damage is skipped and described in [`Ros1Bag::problems`]; only
    /// a file that is not a ROS 1 bag at all, or holds no chunk, is an error.
    pub fn open(path: &Path) -> Result<Ros1Bag> {
        let io_err = |e: std::io::Error| Error::Input(format!("{}: {e}", path.display()));
        let mut file = File::open(path).map_err(io_err)?;
        // A bag still being recorded is read to the length fixed for this read, if any.
        let file_len = super::growing::readable_len(path, file.metadata().map_err(io_err)?.len());
        let magic = read_at(&mut file, 0, MAGIC.len(), file_len).map_err(io_err)?;
        if magic != MAGIC {
            return Err(Error::Input(format!(
                "{}: not a ROS 1 bag (it does not start with \"#ROSBAG V2.0\")",
                path.display()
            )));
        }
        let slot = super::growing::slot_of(path);
        let mut s = slot
            .as_ref()
            .and_then(|slot| resumed(slot, path, file_len))
            .unwrap_or(Scan {
                p: MAGIC.len() as u64,
                ..Scan::default()
            });
        let mut bag = Ros1Bag {
            path: path.to_path_buf(),
            file_len,
            connections: BTreeMap::new(),
            chunks: Vec::new(),
            index_counts: BTreeMap::new(),
            indexed: false,
            problems: Vec::new(),
            slot,
        };
        // The walk as it was before the first record that is cut or damaged: where a later
        // read of a bag being recorded takes it up.
        let mut checkpoint: Option<Scan> = None;
        while s.p < file_len {
            let p = s.p;
            // A record header is small: read it with its length words.
            let head_buf = read_at(&mut file, p, 4 + MAX_HEADER + 4, file_len).map_err(io_err)?;
            let Some(f) = record_at(&head_buf, 0) else {
                if bag.problems.is_empty() {
                    checkpoint = Some(s.clone());
                }
                match bag.resync_file(&mut file, p, &ANY_OP)? {
                    Some(q) => {
                        bag.problems.push(format!(
                            "bytes {p}..{q} are not bag records (a damaged stretch): skipped"
                        ));
                        s.p = q;
                        continue;
                    }
                    None => {
                        bag.problems.push(format!(
                            "bytes {p}..{file_len} (the last {} bytes) are not bag records: \
                             the file is damaged or was cut there",
                            file_len - p
                        ));
                        break;
                    }
                }
            };
            let data = p + f.data_start as u64;
            let end = data + f.data_len as u64;
            let cut = end > file_len;
            if bag.problems.is_empty() && (cut || f.head.op == OP_MESSAGE) {
                checkpoint = Some(s.clone());
            }
            match f.head.op {
                OP_MESSAGE => {
                    // Messages outside a chunk: a chunk whose header was damaged. They are read
                    // as an uncompressed chunk up to the next top-level record.
                    let stop = bag
                        .resync_file(&mut file, p, &[OP_CHUNK, OP_INDEX_DATA, OP_CHUNK_INFO])?
                        .unwrap_or(file_len);
                    bag.problems.push(format!(
                        "bytes {p}..{stop} are messages outside any chunk (a damaged chunk \
                         header): read as they are"
                    ));
                    s.chunks.push(ChunkLoc {
                        record: p,
                        data: p,
                        len: (stop - p) as usize,
                        cut: false,
                        compression: Compression::None,
                        size: (stop - p) as usize,
                    });
                    s.p = stop;
                    continue;
                }
                OP_BAG_HEADER => {
                    s.index_pos = f.head.u64("index_pos");
                    s.declared = (f.head.u32("conn_count"), f.head.u32("chunk_count"));
                }
                OP_CHUNK => {
                    let compression = match f.head.field("compression") {
                        Some(b"none") => Some(Compression::None),
                        Some(b"bz2") => Some(Compression::Bz2),
                        Some(b"lz4") => Some(Compression::Lz4),
                        _ => None,
                    };
                    let size = f.head.u32("size").unwrap_or(0) as usize;
                    match compression {
                        Some(c) if f.data_len <= MAX_CHUNK && size <= MAX_CHUNK => {
                            s.chunks.push(ChunkLoc {
                                record: p,
                                data,
                                len: (end.min(file_len) - data) as usize,
                                cut,
                                compression: c,
                                size,
                            });
                        }
                        Some(_) => bag.problems.push(format!(
                            "the chunk at byte {p} declares {} bytes (compressed {}): more than \
                             this reader accepts ({MAX_CHUNK}); skipped",
                            size, f.data_len
                        )),
                        None => bag.problems.push(format!(
                            "the chunk at byte {p} uses compression \"{}\", which is not none, \
                             bz2 or lz4; skipped",
                            f.head.text("compression").unwrap_or_default()
                        )),
                    }
                }
                OP_CONNECTION => {
                    if let Some((id, topic, tp)) =
                        bag.connection(&f.head, &mut file, data, f.data_len, cut)?
                    {
                        insert_connection(&mut s.connections, id, topic, tp);
                        s.index_conns += 1;
                    }
                }
                OP_CHUNK_INFO if !cut => {
                    let d = read_at(&mut file, data, f.data_len, file_len).map_err(io_err)?;
                    if let Some(pos) = f.head.u64("chunk_pos") {
                        let counts = s.index_counts.entry(pos).or_default();
                        for e in d.chunks_exact(8) {
                            let id = u32::from_le_bytes([e[0], e[1], e[2], e[3]]);
                            let n = u32::from_le_bytes([e[4], e[5], e[6], e[7]]);
                            counts.insert(id, n);
                        }
                        s.chunk_infos += 1;
                    }
                }
                _ => {} // index data: the chunks are read in order instead
            }
            if cut {
                bag.problems.push(format!(
                    "the file ends at byte {file_len}, inside a record that starts at byte {p} \
                     and declares {} bytes: the recording was cut short",
                    f.data_len
                ));
                break;
            }
            s.p = end;
        }
        if bag.problems.is_empty() {
            checkpoint = Some(s.clone());
        }
        bag.keep(checkpoint);
        let Scan {
            connections,
            chunks,
            index_counts,
            index_pos,
            declared,
            index_conns,
            chunk_infos,
            ..
        } = s;
        bag.connections = connections;
        bag.chunks = chunks;
        bag.index_counts = index_counts;
        let chunk_count = declared.1;
        // The index is whole when it lists as many chunks as the bag header declares.
        bag.indexed = match (index_pos, chunk_count) {
            (Some(ip), Some(n)) => ip > 0 && ip < file_len && chunk_infos == n,
            _ => false,
        };
        if index_pos == Some(0) {
            bag.problems.push(
                "the bag has no index (the recording was not closed, as in a .bag.active file): \
                 its chunks were read in order; `rosbag reindex` rebuilds the index for other \
                 tools"
                    .to_string(),
            );
        } else if !bag.indexed {
            let found = bag.chunks.len();
            let expected =
                chunk_count.map_or("an unknown number of".to_string(), |n| n.to_string());
            bag.problems.push(format!(
                "the bag's index is missing or damaged ({found} chunks found, the bag header \
                 declares {expected}): the chunks were read in order; `rosbag reindex` on a copy \
                 rebuilds the index for other tools"
            ));
        } else if let Some(n) = chunk_count.filter(|&n| n as usize > bag.chunks.len()) {
            bag.problems.push(format!(
                "{} of the {n} chunks the index lists could not be found (damaged)",
                n as usize - bag.chunks.len()
            ));
        }
        if !bag.indexed || declared.0.is_some_and(|n| n != index_conns) {
            bag.connections_from_chunks()?;
        }
        if bag.chunks.is_empty() {
            return Err(Error::Input(format!(
                "{}: a ROS 1 bag with no readable chunk (no messages){}",
                path.display(),
                bag.problem_suffix()
            )));
        }
        Ok(bag)
    }

    fn problem_suffix(&self) -> String {
        if self.problems.is_empty() {
            String::new()
        } else {
            format!(": {}", self.problems.join("; "))
        }
    }

    /// Scans the file from `p` for the next top-level record that parses.
    fn resync_file(&self, file: &mut File, p: u64, ops: &[u8]) -> Result<Option<u64>> {
        const WINDOW: usize = 1 << 20;
        let mut at = p + 1;
        while at < self.file_len {
            let buf = read_at(file, at, WINDOW + MAX_HEADER, self.file_len)
                .map_err(|e| Error::Input(format!("{}: {e}", self.path.display())))?;
            if let Some(k) = resync(&buf, 0, ops, true) {
                return Ok(Some(at + k as u64));
            }
            at += WINDOW as u64;
        }
        Ok(None)
    }

    /// A connection record's id, topic and type (`None`: it names no id or topic).
    fn connection(
        &self,
        head: &RecordHead<'_>,
        file: &mut File,
        data: u64,
        len: usize,
        cut: bool,
    ) -> Result<Option<(u32, String, String)>> {
        let (Some(id), Some(topic)) = (head.u32("conn"), head.text("topic")) else {
            return Ok(None);
        };
        let msg_type = if cut || len > MAX_HEADER {
            String::new()
        } else {
            let d = read_at(file, data, len, self.file_len)
                .map_err(|e| Error::Input(format!("{}: {e}", self.path.display())))?;
            connection_type(&d)
        };
        Ok(Some((id, topic, msg_type)))
    }

    /// Keeps the top-level walk as it was at `checkpoint` in the bag's slot, when it has one;
    /// the chunks kept before stay when the file still starts as it did.
    fn keep(&self, checkpoint: Option<Scan>) {
        let (Some(slot), Some(scan)) = (&self.slot, checkpoint) else {
            return;
        };
        let Ok(prefix) = Prefix::of(&self.path, scan.p) else {
            return;
        };
        let mut slot = memory::lock(slot);
        let chunks = slot
            .take::<Ros1Kept>()
            .map_or_else(HashMap::new, |k| k.chunks);
        let to = prefix.len;
        slot.keep(
            Ros1Kept {
                prefix,
                scan,
                chunks,
            },
            to,
        );
    }

    /// Collects the connections written inside the chunks (every bag has them there, before
    /// the first message of each connection).
    fn connections_from_chunks(&mut self) -> Result<()> {
        let mut found = Vec::new();
        let mut problems = Vec::new();
        self.walk_chunks(&mut problems, &|_| false, &mut |rec| {
            if let Inner::Connection {
                id,
                topic,
                msg_type,
            } = rec
            {
                found.push((id, topic, msg_type));
            }
            Ok(())
        })?;
        for (id, topic, tp) in found {
            insert_connection(&mut self.connections, id, topic, tp);
        }
        Ok(())
    }

    /// The file the bag was opened from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The connections, by id.
    pub fn connections(&self) -> impl Iterator<Item = &Connection> {
        self.connections.values()
    }

    /// Whether the bag's index section was found whole.
    pub fn indexed(&self) -> bool {
        self.indexed
    }

    /// Damage found while opening: what it was and what it cost.
    pub fn problems(&self) -> &[String] {
        &self.problems
    }

    /// Hands every message of the connections `wanted` accepts to `f`, in file order. A chunk
    /// that cannot be decompressed is skipped; inside a damaged chunk the reader skips to the
    /// next record that parses. An error from `f` stops the pass.
    pub fn messages(
        &self,
        wanted: &dyn Fn(u32) -> bool,
        f: &mut dyn FnMut(Message<'_>) -> Result<()>,
    ) -> Result<ReadSummary> {
        self.messages_with(wanted, &|_| true, f)
    }

    /// [`Ros1Bag::messages`], where a message kept from an earlier read of a bag being
    /// recorded ([`memory`]) is handed over whole only when `whole` says so for its connection
    /// (asked just before it is handed over), else as its first bytes ([`Message::whole`]).
    pub fn messages_with(
        &self,
        wanted: &dyn Fn(u32) -> bool,
        whole: &dyn Fn(u32) -> bool,
        f: &mut dyn FnMut(Message<'_>) -> Result<()>,
    ) -> Result<ReadSummary> {
        let mut summary = ReadSummary::default();
        let mut per_chunk: BTreeMap<u64, u64> = BTreeMap::new();
        let mut problems = Vec::new();
        let mut number = 0usize;
        let fetch = |id: u32| wanted(id) && whole(id);
        let chunks_read = self.walk_chunks(&mut problems, &fetch, &mut |rec| {
            if let Inner::Message {
                conn_id,
                sec,
                nsec,
                data,
                whole,
                chunk,
            } = rec
                && wanted(conn_id)
            {
                number += 1;
                *per_chunk.entry(chunk).or_default() += 1;
                f(Message {
                    conn_id,
                    sec,
                    nsec,
                    data,
                    whole,
                    number,
                    chunk_offset: chunk,
                })?;
            }
            Ok(())
        })?;
        summary.messages = number;
        summary.chunks_read = chunks_read;
        summary.problems = problems;
        if self.indexed {
            let mut lost = 0u64;
            for (chunk, counts) in &self.index_counts {
                let listed: u64 = counts
                    .iter()
                    .filter(|(id, _)| wanted(**id))
                    .map(|(_, n)| *n as u64)
                    .sum();
                lost += listed.saturating_sub(per_chunk.get(chunk).copied().unwrap_or(0));
            }
            summary.lost_messages = Some(lost);
        }
        Ok(summary)
    }

    /// Decompresses each chunk and hands its records to `f`; returns the chunks read whole.
    /// The chunks kept by earlier reads ([`memory`]) are not read again: their records are
    /// handed over as kept, a long message whole only when `fetch` says so for its connection.
    fn walk_chunks(
        &self,
        problems: &mut Vec<String>,
        fetch: &dyn Fn(u32) -> bool,
        f: &mut dyn FnMut(Inner<'_>) -> Result<()>,
    ) -> Result<usize> {
        let mut file = File::open(&self.path)
            .map_err(|e| Error::Input(format!("{}: {e}", self.path.display())))?;
        let (kept, keep_to) = self.kept_chunks();
        let mut whole = 0usize;
        for (c, kept) in self.chunks.iter().zip(kept) {
            if let Some(items) = kept {
                whole += 1;
                self.replay(&mut file, c, &items, fetch, f)?;
                continue;
            }
            let raw = read_at(&mut file, c.data, c.len, self.file_len)
                .map_err(|e| Error::Input(format!("{}: {e}", self.path.display())))?;
            self.count_decoded(c.record);
            // The chunk's records are kept when it lies whole before the kept offset.
            let mut items = (!c.cut && c.data + c.len as u64 <= keep_to).then(Vec::<Item>::new);
            let data = match decompress(c, &raw) {
                Ok(d) => d,
                Err(why) => {
                    problems.push(format!(
                        "the chunk at byte {} could not be read ({why}); its messages are lost",
                        c.record
                    ));
                    continue;
                }
            };
            let mut p = 0usize;
            let mut clean = !c.cut;
            while p < data.len() {
                let Some(r) = record_at(&data, p).filter(|r| {
                    matches!(r.head.op, OP_MESSAGE | OP_CONNECTION)
                        && r.data_start + r.data_len <= data.len()
                }) else {
                    clean = false;
                    // One scan for the next record that parses: none after the last record
                    // of a chunk the file cuts means the cut is the only damage.
                    match resync(&data, p + 1, &[OP_MESSAGE, OP_CONNECTION], false) {
                        Some(q) => {
                            problems.push(format!(
                                "bytes {}..{} inside the chunk at byte {} are damaged: skipped",
                                c.data + p as u64,
                                c.data + q as u64,
                                c.record
                            ));
                            p = q;
                            continue;
                        }
                        None if c.cut => {
                            problems.push(format!(
                                "the chunk at byte {} is cut by the end of the file: its \
                                 messages after byte {} are lost",
                                c.record,
                                c.data + p as u64
                            ));
                            break;
                        }
                        None => {
                            problems.push(format!(
                                "the chunk at byte {} is damaged or cut from byte {}: the rest \
                                 of it is lost",
                                c.record,
                                c.data + p as u64
                            ));
                            break;
                        }
                    }
                };
                let body = &data[r.data_start..r.data_start + r.data_len];
                match r.head.op {
                    OP_MESSAGE => {
                        let (sec, nsec) = r.head.time("time").unwrap_or((0, 0));
                        let conn_id = r.head.u32("conn").unwrap_or(u32::MAX);
                        if let Some(items) = &mut items {
                            items.push(Item::Message {
                                conn_id,
                                sec,
                                nsec,
                                data: Kept::of(body, r.data_start as u64),
                            });
                        }
                        f(Inner::Message {
                            conn_id,
                            sec,
                            nsec,
                            data: body,
                            whole: true,
                            chunk: c.record,
                        })?;
                    }
                    _ => {
                        if let (Some(id), Some(topic)) = (r.head.u32("conn"), r.head.text("topic"))
                        {
                            let msg_type = connection_type(body);
                            if let Some(items) = &mut items {
                                items.push(Item::Connection {
                                    id,
                                    topic: topic.clone(),
                                    msg_type: msg_type.clone(),
                                });
                            }
                            f(Inner::Connection {
                                id,
                                topic,
                                msg_type,
                            })?;
                        }
                    }
                }
                p = r.data_start + r.data_len;
            }
            if clean {
                whole += 1;
                if let Some(items) = items {
                    self.keep_chunk(c.record, items);
                }
            }
        }
        Ok(whole)
    }

    /// The records kept of each chunk (`None`: read it), and the offset up to which the file
    /// is kept (0 when nothing is).
    fn kept_chunks(&self) -> (Vec<Option<Arc<Vec<Item>>>>, u64) {
        let none = || vec![None; self.chunks.len()];
        let Some(slot) = &self.slot else {
            return (none(), 0);
        };
        let slot = memory::lock(slot);
        let Some(k) = slot.kept::<Ros1Kept>() else {
            return (none(), 0);
        };
        let kept = self
            .chunks
            .iter()
            .map(|c| {
                (!c.cut && c.data + c.len as u64 <= k.prefix.len)
                    .then(|| k.chunks.get(&c.record).cloned())
                    .flatten()
            })
            .collect();
        (kept, k.prefix.len)
    }

    /// Counts the chunk at `at` decoded, in the bag's slot.
    fn count_decoded(&self, at: u64) {
        if let Some(slot) = &self.slot {
            memory::lock(slot).decoded(at);
        }
    }

    /// Keeps the records of the whole chunk at `record`.
    fn keep_chunk(&self, record: u64, items: Vec<Item>) {
        let Some(slot) = &self.slot else { return };
        if let Some(k) = memory::lock(slot).kept_mut::<Ros1Kept>() {
            k.chunks.insert(record, Arc::new(items));
        }
    }

    /// Hands over the kept records of chunk `c`; a long message whose connection `fetch`
    /// accepts is read again whole (the chunk decompressed once for all of them).
    fn replay(
        &self,
        file: &mut File,
        c: &ChunkLoc,
        items: &[Item],
        fetch: &dyn Fn(u32) -> bool,
        f: &mut dyn FnMut(Inner<'_>) -> Result<()>,
    ) -> Result<()> {
        let mut records: Option<Vec<u8>> = None;
        for item in items {
            match item {
                Item::Connection {
                    id,
                    topic,
                    msg_type,
                } => f(Inner::Connection {
                    id: *id,
                    topic: topic.clone(),
                    msg_type: msg_type.clone(),
                })?,
                Item::Message {
                    conn_id,
                    sec,
                    nsec,
                    data,
                } => {
                    let (bytes, whole) = match data {
                        Kept::Head { at, len, .. } if fetch(*conn_id) => {
                            if records.is_none() {
                                let raw = read_at(file, c.data, c.len, self.file_len)
                                    .map_err(|e| Error::io(&self.path, e))?;
                                self.count_decoded(c.record);
                                records = Some(decompress(c, &raw).map_err(|why| {
                                    Error::Input(format!(
                                        "{}: the chunk at byte {} could not be read again \
                                         ({why}): the file changed while it was followed",
                                        self.path.display(),
                                        c.record
                                    ))
                                })?);
                            }
                            let at = *at as usize;
                            let bytes = records
                                .as_deref()
                                .and_then(|r| r.get(at..at.checked_add(*len)?))
                                .ok_or_else(|| {
                                    Error::Input(format!(
                                        "{}: the chunk at byte {} changed while the file was \
                                         followed",
                                        self.path.display(),
                                        c.record
                                    ))
                                })?;
                            (bytes, true)
                        }
                        Kept::Head { head, .. } => (head.as_slice(), false),
                        Kept::Whole(b) => (b.as_slice(), true),
                    };
                    f(Inner::Message {
                        conn_id: *conn_id,
                        sec: *sec,
                        nsec: *nsec,
                        data: bytes,
                        whole,
                        chunk: c.record,
                    })?;
                }
            }
        }
        Ok(())
    }
}

/// A record inside a chunk.
enum Inner<'a> {
    Message {
        conn_id: u32,
        sec: u32,
        nsec: u32,
        data: &'a [u8],
        whole: bool,
        chunk: u64,
    },
    Connection {
        id: u32,
        topic: String,
        msg_type: String,
    },
}

/// Adds a connection (its type filled in when it was not known).
fn insert_connection(
    map: &mut BTreeMap<u32, Connection>,
    id: u32,
    topic: String,
    msg_type: String,
) {
    let c = map.entry(id).or_insert(Connection {
        id,
        topic,
        msg_type: String::new(),
    });
    if c.msg_type.is_empty() {
        c.msg_type = msg_type;
    }
}

/// The top-level walk kept in `slot` for the file at `path` (readable to `len`), when the file
/// still starts as it did; else the slot is emptied (the file is read from its start).
fn resumed(slot: &SlotRef, path: &Path, len: u64) -> Option<Scan> {
    let mut slot = memory::lock(slot);
    let scan = slot
        .kept::<Ros1Kept>()
        .filter(|k| k.prefix.holds(path, len))
        .map(|k| k.scan.clone());
    if scan.is_none() {
        slot.take::<Ros1Kept>();
    }
    slot.resumed(scan.as_ref().map_or(0, |s| s.p));
    scan
}
