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

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// The first 13 bytes of every ROS 1 bag of format 2.0.
pub const MAGIC: &[u8] = b"#ROSBAG V2.0\n";

/// The largest record header accepted (real headers are well under 1 kB; a connection record's
/// header holds only op, conn and topic).
const MAX_HEADER: usize = 1 << 16;
/// The largest chunk, compressed or not (rosbag's default is 768 kB; images make them bigger).
const MAX_CHUNK: usize = 1 << 30;

const OP_MESSAGE: u8 = 2;
const OP_BAG_HEADER: u8 = 3;
const OP_INDEX_DATA: u8 = 4;
const OP_CHUNK: u8 = 5;
const OP_CHUNK_INFO: u8 = 6;
const OP_CONNECTION: u8 = 7;
/// Every op a top-level scan may meet (messages only where a chunk header was damaged).
const ANY_OP: [u8; 6] = [
    OP_MESSAGE,
    OP_BAG_HEADER,
    OP_INDEX_DATA,
    OP_CHUNK,
    OP_CHUNK_INFO,
    OP_CONNECTION,
];

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
    /// The serialised message.
    pub data: &'a [u8],
    /// The 1-based number of this message among the messages read (all connections).
    pub number: usize,
    /// The byte offset in the file of the chunk holding the message.
    pub chunk_offset: u64,
}

/// How a chunk's data is stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Compression {
    None,
    Bz2,
    Lz4,
}

#[derive(Clone, Debug)]
struct ChunkLoc {
    /// Offset of the chunk record in the file.
    record: u64,
    /// Offset of the chunk's data.
    data: u64,
    /// Bytes of data present in the file (less than declared when the file is cut).
    len: usize,
    /// Whether the file ends before the chunk's declared end.
    cut: bool,
    compression: Compression,
    /// Declared uncompressed size.
    size: usize,
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
}

/// A parsed record header: its fields, and where the record's data lies.
struct RecordHead<'a> {
    fields: Vec<(&'a [u8], &'a [u8])>,
    op: u8,
}

impl<'a> RecordHead<'a> {
    fn field(&self, name: &str) -> Option<&'a [u8]> {
        self.fields
            .iter()
            .find(|(k, _)| *k == name.as_bytes())
            .map(|(_, v)| *v)
    }
    fn u32(&self, name: &str) -> Option<u32> {
        let v = self.field(name)?;
        Some(u32::from_le_bytes(v.try_into().ok()?))
    }
    fn u64(&self, name: &str) -> Option<u64> {
        let v = self.field(name)?;
        Some(u64::from_le_bytes(v.try_into().ok()?))
    }
    fn time(&self, name: &str) -> Option<(u32, u32)> {
        let v = self.field(name)?;
        if v.len() != 8 {
            return None;
        }
        let sec = u32::from_le_bytes(v[..4].try_into().ok()?);
        let nsec = u32::from_le_bytes(v[4..].try_into().ok()?);
        Some((sec, nsec))
    }
    fn text(&self, name: &str) -> Option<String> {
        self.field(name)
            .map(|v| String::from_utf8_lossy(v).into_owned())
    }
    /// Whether the fields an op needs are present and well formed.
    fn complete(&self) -> bool {
        match self.op {
            OP_MESSAGE => self.u32("conn").is_some() && self.time("time").is_some(),
            OP_BAG_HEADER => self.u64("index_pos").is_some(),
            OP_CHUNK => self.field("compression").is_some() && self.u32("size").is_some(),
            OP_CONNECTION => self.u32("conn").is_some() && self.field("topic").is_some(),
            OP_INDEX_DATA => self.u32("conn").is_some() && self.u32("ver").is_some(),
            OP_CHUNK_INFO => self.u64("chunk_pos").is_some() && self.u32("count").is_some(),
            _ => false,
        }
    }
}

/// Parses the header fields of a record; `None` when they are not a well-formed header.
fn parse_header(h: &[u8]) -> Option<RecordHead<'_>> {
    let mut fields = Vec::new();
    let mut i = 0usize;
    while i < h.len() {
        let n = u32::from_le_bytes(h.get(i..i + 4)?.try_into().ok()?) as usize;
        i += 4;
        let f = h.get(i..i.checked_add(n)?)?;
        i += n;
        let eq = f.iter().position(|&b| b == b'=')?;
        if eq == 0 {
            return None;
        }
        fields.push((&f[..eq], &f[eq + 1..]));
    }
    let op = fields.iter().find(|(k, _)| *k == b"op")?.1;
    if op.len() != 1 {
        return None;
    }
    let head = RecordHead { op: op[0], fields };
    head.complete().then_some(head)
}

/// A record found in a buffer: its header, and the range of its data (which may run past the
/// buffer's end when `cut`).
struct Found<'a> {
    head: RecordHead<'a>,
    data_start: usize,
    data_len: usize,
}

/// Reads the record at `p` of `buf`; `None` when no well-formed record header starts there.
fn record_at(buf: &[u8], p: usize) -> Option<Found<'_>> {
    let hl = u32::from_le_bytes(buf.get(p..p + 4)?.try_into().ok()?) as usize;
    if hl == 0 || hl > MAX_HEADER {
        return None;
    }
    let h_end = p.checked_add(4)?.checked_add(hl)?;
    let head = parse_header(buf.get(p + 4..h_end)?)?;
    let dl = u32::from_le_bytes(buf.get(h_end..h_end + 4)?.try_into().ok()?) as usize;
    Some(Found {
        head,
        data_start: h_end + 4,
        data_len: dl,
    })
}

/// The next offset after `from` where a record of one of `ops` parses and its data fits in
/// `buf` (records cut by the end of `buf` are accepted when `allow_cut`).
fn resync(buf: &[u8], from: usize, ops: &[u8], allow_cut: bool) -> Option<usize> {
    let mut s = from;
    while let Some(k) = find(&buf[s.min(buf.len())..], b"op=") {
        let at = s + k;
        // `op=` is preceded by its field length (4 bytes) and possibly by other fields; the
        // record starts at most a few hundred bytes earlier.
        let lo = at.saturating_sub(512).max(from);
        for start in lo..at.saturating_sub(7).max(lo) {
            if let Some(f) = record_at(buf, start)
                && ops.contains(&f.head.op)
                && (allow_cut || f.data_start + f.data_len <= buf.len())
                && f.data_start > at
            {
                return Some(start);
            }
        }
        s = at + 3;
    }
    None
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

/// Reads up to `len` bytes at `offset`, never past byte `end` (fewer when the file or `end`
/// comes first: `end` is the length the bag is read to, [`super::growing`]).
fn read_at(file: &mut File, offset: u64, len: usize, end: u64) -> std::io::Result<Vec<u8>> {
    file.seek(SeekFrom::Start(offset))?;
    let mut v = Vec::new();
    let len = (len as u64).min(end.saturating_sub(offset));
    file.take(len).read_to_end(&mut v)?;
    Ok(v)
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
        let mut bag = Ros1Bag {
            path: path.to_path_buf(),
            file_len,
            connections: BTreeMap::new(),
            chunks: Vec::new(),
            index_counts: BTreeMap::new(),
            indexed: false,
            problems: Vec::new(),
        };
        let mut index_pos = None;
        let mut declared = (None, None); // (conn_count, chunk_count)
        let mut index_conns = 0u32;
        let mut chunk_infos = 0u32;
        let mut p = MAGIC.len() as u64;
        while p < file_len {
            // A record header is small: read it with its length words.
            let head_buf = read_at(&mut file, p, 4 + MAX_HEADER + 4, file_len).map_err(io_err)?;
            let Some(f) = record_at(&head_buf, 0) else {
                match bag.resync_file(&mut file, p, &ANY_OP)? {
                    Some(q) => {
                        bag.problems.push(format!(
                            "bytes {p}..{q} are not bag records (a damaged stretch): skipped"
                        ));
                        p = q;
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
                    bag.chunks.push(ChunkLoc {
                        record: p,
                        data: p,
                        len: (stop - p) as usize,
                        cut: false,
                        compression: Compression::None,
                        size: (stop - p) as usize,
                    });
                    p = stop;
                    continue;
                }
                OP_BAG_HEADER => {
                    index_pos = f.head.u64("index_pos");
                    declared = (f.head.u32("conn_count"), f.head.u32("chunk_count"));
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
                            bag.chunks.push(ChunkLoc {
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
                    index_conns +=
                        u32::from(bag.add_connection(&f.head, &mut file, data, f.data_len, cut)?);
                }
                OP_CHUNK_INFO if !cut => {
                    let d = read_at(&mut file, data, f.data_len, file_len).map_err(io_err)?;
                    if let Some(pos) = f.head.u64("chunk_pos") {
                        let counts = bag.index_counts.entry(pos).or_default();
                        for e in d.chunks_exact(8) {
                            let id = u32::from_le_bytes([e[0], e[1], e[2], e[3]]);
                            let n = u32::from_le_bytes([e[4], e[5], e[6], e[7]]);
                            counts.insert(id, n);
                        }
                        chunk_infos += 1;
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
            p = end;
        }
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

    /// Adds a connection record; returns whether it was read.
    fn add_connection(
        &mut self,
        head: &RecordHead<'_>,
        file: &mut File,
        data: u64,
        len: usize,
        cut: bool,
    ) -> Result<bool> {
        let (Some(id), Some(topic)) = (head.u32("conn"), head.text("topic")) else {
            return Ok(false);
        };
        let msg_type = if cut || len > MAX_HEADER {
            String::new()
        } else {
            let d = read_at(file, data, len, self.file_len)
                .map_err(|e| Error::Input(format!("{}: {e}", self.path.display())))?;
            connection_type(&d)
        };
        self.insert_connection(id, topic, msg_type);
        Ok(true)
    }

    fn insert_connection(&mut self, id: u32, topic: String, msg_type: String) {
        let c = self.connections.entry(id).or_insert(Connection {
            id,
            topic,
            msg_type: String::new(),
        });
        if c.msg_type.is_empty() {
            c.msg_type = msg_type;
        }
    }

    /// Collects the connections written inside the chunks (every bag has them there, before
    /// the first message of each connection).
    fn connections_from_chunks(&mut self) -> Result<()> {
        let mut found = Vec::new();
        let mut problems = Vec::new();
        self.walk_chunks(&mut problems, &mut |rec| {
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
            self.insert_connection(id, topic, tp);
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
        let mut summary = ReadSummary::default();
        let mut per_chunk: BTreeMap<u64, u64> = BTreeMap::new();
        let mut problems = Vec::new();
        let mut number = 0usize;
        let chunks_read = self.walk_chunks(&mut problems, &mut |rec| {
            if let Inner::Message {
                conn_id,
                sec,
                nsec,
                data,
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
    fn walk_chunks(
        &self,
        problems: &mut Vec<String>,
        f: &mut dyn FnMut(Inner<'_>) -> Result<()>,
    ) -> Result<usize> {
        let mut file = File::open(&self.path)
            .map_err(|e| Error::Input(format!("{}: {e}", self.path.display())))?;
        let mut whole = 0usize;
        for c in &self.chunks {
            let raw = read_at(&mut file, c.data, c.len, self.file_len)
                .map_err(|e| Error::Input(format!("{}: {e}", self.path.display())))?;
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
                        f(Inner::Message {
                            conn_id: r.head.u32("conn").unwrap_or(u32::MAX),
                            sec,
                            nsec,
                            data: body,
                            chunk: c.record,
                        })?;
                    }
                    _ => {
                        if let (Some(id), Some(topic)) = (r.head.u32("conn"), r.head.text("topic"))
                        {
                            f(Inner::Connection {
                                id,
                                topic,
                                msg_type: connection_type(body),
                            })?;
                        }
                    }
                }
                p = r.data_start + r.data_len;
            }
            if clean {
                whole += 1;
            }
        }
        Ok(whole)
    }
}

/// A record inside a chunk.
enum Inner<'a> {
    Message {
        conn_id: u32,
        sec: u32,
        nsec: u32,
        data: &'a [u8],
        chunk: u64,
    },
    Connection {
        id: u32,
        topic: String,
        msg_type: String,
    },
}

/// The `type` field of a connection record's data (itself a header of fields).
fn connection_type(data: &[u8]) -> String {
    let mut i = 0usize;
    while let Some(n) = data
        .get(i..i + 4)
        .and_then(|b| b.try_into().ok())
        .map(u32::from_le_bytes)
    {
        i += 4;
        let Some(f) = i.checked_add(n as usize).and_then(|e| data.get(i..e)) else {
            break;
        };
        i += n as usize;
        if let Some(t) = f.strip_prefix(b"type=") {
            return String::from_utf8_lossy(t).into_owned();
        }
    }
    String::new()
}

/// A chunk's records, decompressed; a cut compressed chunk gives what decompresses.
fn decompress(c: &ChunkLoc, raw: &[u8]) -> std::result::Result<Vec<u8>, String> {
    let limit = c.size as u64;
    let mut out = Vec::new();
    let r = match c.compression {
        Compression::None => return Ok(raw.to_vec()),
        Compression::Bz2 => bzip2::read::BzDecoder::new(raw)
            .take(limit + 1)
            .read_to_end(&mut out),
        Compression::Lz4 => lz4::Decoder::new(raw)
            .map_err(|e| e.to_string())?
            .take(limit + 1)
            .read_to_end(&mut out),
    };
    match r {
        Ok(_) if out.len() as u64 > limit => Err(format!(
            "it decompresses to more than the {limit} bytes it declares"
        )),
        Ok(_) => Ok(out),
        // A cut chunk: keep what came out before the end.
        Err(_) if c.cut && !out.is_empty() => Ok(out),
        Err(e) => Err(format!("{:?} decompression failed: {e}", c.compression)),
    }
}
