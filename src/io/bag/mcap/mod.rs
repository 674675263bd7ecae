//! MCAP storage (ROS 2): the container, chunks compressed with zstd or lz4 or not at all.
//!
//! An MCAP file is the magic `\x89MCAP0\r\n`, a Header record, the data section (Schema,
//! Channel, Message, Chunk, Message Index, Attachment, Metadata records, ending with Data
//! End), an optional summary section (copies of the Schema and Channel records, a Chunk Index
//! per chunk, Statistics), an optional summary offset section, a Footer and the magic again.
//! Every record is `opcode: u8, length: u64 LE, content`; all integers are little-endian and
//! strings, maps and arrays carry a u32 byte length. A Chunk holds Schema, Channel and Message
//! records, compressed as a whole.
//!
//! Opening reads the topics from the summary section (found through the footer) without
//! touching the data; a file without a summary (a recording that was never closed) is read
//! from start to end instead. The pass over the messages reads the data section in file order
//! through a buffered reader, holding one decompressed chunk at a time. Nothing here trusts a
//! length: each is checked against the file and against a maximum before anything is
//! allocated, a chunk decompresses to at most its declared size and is checked against its
//! CRC when it has one, and damage is skipped and described with what it cost.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use super::types::{BagMessage, BagReadSummary, MCAP_MAGIC, Serialization, Topic};
use crate::error::{Error, Result};

const OP_HEADER: u8 = 0x01;
const OP_FOOTER: u8 = 0x02;
const OP_SCHEMA: u8 = 0x03;
const OP_CHANNEL: u8 = 0x04;
const OP_MESSAGE: u8 = 0x05;
const OP_CHUNK: u8 = 0x06;
const OP_MESSAGE_INDEX: u8 = 0x07;
const OP_CHUNK_INDEX: u8 = 0x08;
const OP_STATISTICS: u8 = 0x0B;
const OP_DATA_END: u8 = 0x0F;

/// Opcode and length in front of every record.
const RECORD_HEAD: u64 = 9;
/// The Footer's content: summary_start, summary_offset_start, summary_crc.
const FOOTER_CONTENT: u64 = 20;
/// The Footer record and the closing magic.
const TAIL: u64 = RECORD_HEAD + FOOTER_CONTENT + 8;
/// The largest record read whole that is not a message or a chunk (headers, schemas with
/// their message definitions, channels, statistics, indexes are far smaller).
const MAX_META: u64 = 64 << 20;
/// The largest message (an uncompressed 4K colour image is 25 MB).
const MAX_MESSAGE: u64 = 1 << 30;
/// The largest chunk, decompressed (rosbag2 writes about 1 MB; single large images make
/// bigger ones).
const MAX_CHUNK: u64 = 1 << 30;
/// The longest compression name taken for a real one.
const MAX_COMPRESSION_NAME: u32 = 64;
/// Message: channel_id u16, sequence u32, log_time u64, publish_time u64.
const MESSAGE_HEAD: usize = 22;
/// Chunk: message_start_time, message_end_time, uncompressed_size (u64 each), uncompressed_crc
/// (u32), then the compression string and the records' u64 length.
const CHUNK_FIXED: u64 = 28;

/// A channel of one file, resolved to the bag's topic.
#[derive(Clone, Copy, Debug)]
struct Chan {
    /// Index into the bag's topics.
    topic: usize,
    /// Whether its messages are handed out (a known encoding agreeing with the topic's).
    readable: bool,
}

/// One storage file, opened.
#[derive(Debug)]
struct McapFile {
    path: PathBuf,
    len: u64,
    /// Where the data section starts (after the magic and the Header record).
    data_start: u64,
    /// Where the data section ends at the latest (the summary's start, or the file's end).
    data_end: u64,
    /// Whether the file ends with a footer (it was closed, not cut).
    closed: bool,
    channels: BTreeMap<u16, Chan>,
    /// The channels with messages in each chunk (by the chunk record's offset), from the
    /// summary's chunk indexes; chunks it does not list are always read.
    chunk_channels: BTreeMap<u64, Vec<u16>>,
}

/// The storage files of one ROS 2 bag, opened.
#[derive(Debug)]
pub struct McapBag {
    files: Vec<McapFile>,
    topics: Vec<Topic>,
    problems: Vec<String>,
}

/// A Schema or Channel record as read.
#[derive(Clone, Debug)]
struct ChannelRec {
    id: u16,
    schema_id: u16,
    topic: String,
    encoding: String,
}

/// What the summary section (or a reading of the whole file) tells of one file.
#[derive(Debug, Default)]
struct FileInfo {
    schemas: BTreeMap<u16, String>,
    channels: Vec<ChannelRec>,
    /// Statistics' channel_message_counts, when present and not empty.
    counts: Option<BTreeMap<u16, u64>>,
    chunk_channels: BTreeMap<u64, Vec<u16>>,
}

/// A bounds-checked cursor over a record's content.
struct Cur<'a> {
    b: &'a [u8],
    p: usize,
}

impl<'a> Cur<'a> {
    fn new(b: &'a [u8]) -> Self {
        Cur { b, p: 0 }
    }
    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let s = self.b.get(self.p..self.p.checked_add(n)?)?;
        self.p += n;
        Some(s)
    }
    fn u16(&mut self) -> Option<u16> {
        Some(u16::from_le_bytes(self.take(2)?.try_into().ok()?))
    }
    fn u32(&mut self) -> Option<u32> {
        Some(u32::from_le_bytes(self.take(4)?.try_into().ok()?))
    }
    fn u64(&mut self) -> Option<u64> {
        Some(u64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }
    /// A u32-length-prefixed byte string (strings, maps, arrays).
    fn prefixed(&mut self) -> Option<&'a [u8]> {
        let n = self.u32()?;
        self.take(usize::try_from(n).ok()?)
    }
    fn string(&mut self) -> Option<String> {
        self.prefixed()
            .map(|s| String::from_utf8_lossy(s).into_owned())
    }
    fn rest(&mut self) -> &'a [u8] {
        let s = self.b.get(self.p..).unwrap_or(&[]);
        self.p = self.b.len();
        s
    }
}

fn parse_schema(b: &[u8]) -> Option<(u16, String)> {
    let mut c = Cur::new(b);
    let id = c.u16()?;
    let name = c.string()?;
    Some((id, name))
}

fn parse_channel(b: &[u8]) -> Option<ChannelRec> {
    let mut c = Cur::new(b);
    Some(ChannelRec {
        id: c.u16()?,
        schema_id: c.u16()?,
        topic: c.string()?,
        encoding: c.string()?,
    })
}

/// Statistics' channel_message_counts (`None` when malformed).
fn parse_statistics(b: &[u8]) -> Option<BTreeMap<u16, u64>> {
    let mut c = Cur::new(b);
    // message_count, schema_count, channel_count, attachment_count, metadata_count,
    // chunk_count, message_start_time, message_end_time.
    c.take(8 + 2 + 4 + 4 + 4 + 4 + 8 + 8)?;
    let mut m = Cur::new(c.prefixed()?);
    let mut out = BTreeMap::new();
    while m.p < m.b.len() {
        out.insert(m.u16()?, m.u64()?);
    }
    Some(out)
}

/// A Chunk Index: the chunk's record offset and the channels its messages are on.
fn parse_chunk_index(b: &[u8]) -> Option<(u64, Vec<u16>)> {
    let mut c = Cur::new(b);
    c.take(16)?; // message_start_time, message_end_time
    let offset = c.u64()?;
    c.u64()?; // chunk_length
    let mut m = Cur::new(c.prefixed()?);
    let mut ids = Vec::new();
    while m.p < m.b.len() {
        ids.push(m.u16()?);
        m.u64()?;
    }
    Some((offset, ids))
}

/// A Message Index: its channel and how many messages it lists.
fn parse_message_index(b: &[u8]) -> Option<(u16, u64)> {
    let mut c = Cur::new(b);
    let id = c.u16()?;
    let records = c.prefixed()?;
    Some((id, records.len() as u64 / 16))
}

fn op_name(op: u8) -> String {
    match op {
        OP_HEADER => "Header".into(),
        OP_FOOTER => "Footer".into(),
        OP_SCHEMA => "Schema".into(),
        OP_CHANNEL => "Channel".into(),
        OP_MESSAGE => "Message".into(),
        OP_CHUNK => "Chunk".into(),
        OP_MESSAGE_INDEX => "Message Index".into(),
        OP_CHUNK_INDEX => "Chunk Index".into(),
        OP_STATISTICS => "Statistics".into(),
        OP_DATA_END => "Data End".into(),
        _ => format!("opcode 0x{op:02x}"),
    }
}

/// A buffered reader that knows its position, so that forward skips keep the buffer.
struct Reader {
    inner: BufReader<File>,
    pos: u64,
    path: PathBuf,
}

impl Reader {
    fn open(path: &Path) -> Result<Reader> {
        let f = File::open(path).map_err(|e| Error::io(path, e))?;
        Ok(Reader {
            inner: BufReader::with_capacity(1 << 16, f),
            pos: 0,
            path: path.to_path_buf(),
        })
    }
    fn err(&self, e: std::io::Error) -> Error {
        Error::io(&self.path, e)
    }
    fn goto(&mut self, to: u64) -> Result<()> {
        if to == self.pos {
            return Ok(());
        }
        let r = match i64::try_from(to.wrapping_sub(self.pos)) {
            Ok(d) if to > self.pos => self.inner.seek_relative(d),
            _ => self.inner.seek(SeekFrom::Start(to)).map(|_| ()),
        };
        r.map_err(|e| self.err(e))?;
        self.pos = to;
        Ok(())
    }
    /// Reads exactly `n` bytes at `at` into `buf` (replacing its content). The caller has
    /// checked that they lie inside the file.
    fn read_into(&mut self, at: u64, n: u64, buf: &mut Vec<u8>) -> Result<()> {
        self.goto(at)?;
        buf.clear();
        let got = (&mut self.inner)
            .take(n)
            .read_to_end(buf)
            .map_err(|e| Error::io(&self.path, e))?;
        self.pos += got as u64;
        if (got as u64) < n {
            return Err(Error::Input(format!(
                "{}: the file ended at byte {} while {} bytes were expected there (it was \
                 shortened while being read?)",
                self.path.display(),
                self.pos,
                n
            )));
        }
        Ok(())
    }
    fn read_array<const N: usize>(&mut self, at: u64) -> Result<[u8; N]> {
        self.goto(at)?;
        let mut b = [0u8; N];
        self.inner.read_exact(&mut b).map_err(|e| self.err(e))?;
        self.pos += N as u64;
        Ok(b)
    }
    /// A record's opcode and length at `at` (the caller has checked 9 bytes are there).
    fn record_head(&mut self, at: u64) -> Result<(u8, u64)> {
        let h: [u8; 9] = self.read_array(at)?;
        let mut len = [0u8; 8];
        len.copy_from_slice(&h[1..]);
        Ok((h[0], u64::from_le_bytes(len)))
    }
}

/// A record met while walking a file's data section.
enum Rec<'a> {
    Schema(u16, String),
    Channel(ChannelRec),
    Message {
        channel: u16,
        log_time: u64,
        data: &'a [u8],
    },
}

/// A chunk that was damaged: the Message Index records after it tell what it cost.
struct Damaged {
    offset: u64,
    why: String,
    /// Messages of the wanted channels handed out before the damage.
    delivered: u64,
    /// Messages the index after the chunk lists: all, and of the wanted channels.
    listed: u64,
    listed_wanted: u64,
    indexed: bool,
}

impl Damaged {
    /// What the damage cost; `counting` when messages were being read (not only topics).
    fn describe(&self, counting: bool) -> String {
        let before = if self.delivered > 0 {
            format!(" ({} read before the damage)", self.delivered)
        } else {
            String::new()
        };
        if !counting {
            let listed = if self.indexed {
                format!(" (its index lists {} messages)", self.listed)
            } else {
                String::new()
            };
            format!(
                "the chunk at byte {} {}{listed}: topics declared only in it are missing",
                self.offset, self.why
            )
        } else if self.indexed {
            format!(
                "the chunk at byte {} {}: {} messages of the topics read are lost{before} (its \
                 index lists {} messages in all)",
                self.offset,
                self.why,
                self.listed_wanted.saturating_sub(self.delivered),
                self.listed
            )
        } else {
            format!(
                "the chunk at byte {} {}: its messages are lost{before} (no index after it says \
                 how many)",
                self.offset, self.why
            )
        }
    }
}

/// Reusable buffers of a walk.
#[derive(Default)]
struct Buffers {
    chunk: Vec<u8>,
    record: Vec<u8>,
}

/// Decompresses (`zstd`, otherwise lz4) the `stored` bytes of a chunk's records at the
/// reader's position into `out`,
/// at most `size + 1` bytes; a panic of the third-party decompressor is an error.
fn decompress(
    r: &mut Reader,
    compression: &str,
    stored: u64,
    size: u64,
    out: &mut Vec<u8>,
) -> std::result::Result<(), String> {
    out.clear();
    out.reserve(
        usize::try_from(size.min(stored.saturating_mul(8).saturating_add(1 << 16))).unwrap_or(0),
    );
    let src = (&mut r.inner).take(stored);
    let res = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| match compression {
        "zstd" => {
            zstd::stream::read::Decoder::new(src).and_then(|d| d.take(size + 1).read_to_end(out))
        }
        _ => lz4::Decoder::new(src).and_then(|d| d.take(size + 1).read_to_end(out)),
    }));
    // The reader's position is unknown after the decoder; the caller moves it.
    r.pos = u64::MAX;
    match res {
        Ok(Ok(_)) => Ok(()),
        Ok(Err(e)) => Err(format!("{compression} decompression failed: {e}")),
        Err(_) => Err(format!("the {compression} decompressor failed")),
    }
}

/// Options of a walk.
struct Walk<'w> {
    /// The channels whose messages are asked for: only these are handed to the callback,
    /// and losses are counted for them.
    want: &'w dyn Fn(u16) -> bool,
    /// Skip chunks that the summary's index says hold no wanted channel.
    use_index: bool,
    /// Messages are being read (damage is described by the messages it cost).
    counting: bool,
}

impl McapFile {
    /// Walks the data section in file order, handing Schema, Channel and (wanted) Message
    /// records to `f`, from top level and inside chunks. Damage is skipped and described in
    /// `problems`; an error from `f` or from the file system stops the walk.
    fn walk(
        &self,
        opts: &Walk<'_>,
        problems: &mut Vec<String>,
        f: &mut dyn FnMut(Rec<'_>) -> Result<()>,
    ) -> Result<()> {
        let mut r = Reader::open(&self.path)?;
        let mut bufs = Buffers::default();
        let mut damaged: Option<Damaged> = None;
        let limit = self.data_end;
        let mut p = self.data_start;
        // Chunk offsets to resume at after damage (known when the file has a summary).
        let resume: Vec<u64> = self.chunk_channels.keys().copied().collect();
        loop {
            if p >= limit {
                break;
            }
            if limit - p < RECORD_HEAD {
                if !self.closed {
                    problems.push(format!(
                        "the file ends at byte {}, inside the head of a record at byte {p}: the \
                         recording was cut",
                        self.len
                    ));
                } else {
                    problems.push(format!(
                        "bytes {p}..{limit} before the summary are not a whole record: skipped"
                    ));
                }
                break;
            }
            let (op, len) = r.record_head(p)?;
            let body = p + RECORD_HEAD;
            let rec_end = body.checked_add(len).filter(|&e| e <= limit);
            if op != OP_MESSAGE_INDEX
                && let Some(d) = damaged.take()
            {
                problems.push(d.describe(opts.counting));
            }
            let Some(rec_end) = rec_end else {
                if !self.closed {
                    // A recording cut inside this record.
                    if op == OP_CHUNK {
                        let d = self.chunk(&mut r, &mut bufs, p, len, opts, f)?;
                        problems.push(d.map_or_else(
                            || {
                                format!(
                                    "the file ends at byte {} inside the chunk at byte {p}: the \
                                     recording was cut there",
                                    self.len
                                )
                            },
                            |d| d.describe(opts.counting),
                        ));
                    } else {
                        problems.push(format!(
                            "the file ends at byte {}, inside a {} record that starts at byte \
                             {p} and declares {len} bytes: the recording was cut there",
                            self.len,
                            op_name(op)
                        ));
                    }
                    break;
                }
                // The file was closed, so this length is damage: go on at the next chunk.
                match resume.iter().find(|&&q| q > p) {
                    Some(&q) => {
                        problems.push(format!(
                            "the {} record at byte {p} declares {len} bytes, past the data \
                             section's end at byte {limit}: bytes {p}..{q} skipped",
                            op_name(op)
                        ));
                        p = q;
                        continue;
                    }
                    None => {
                        problems.push(format!(
                            "the {} record at byte {p} declares {len} bytes, past the data \
                             section's end at byte {limit}: the rest of the data section \
                             ({} bytes) is skipped",
                            op_name(op),
                            limit - p
                        ));
                        break;
                    }
                }
            };
            match op {
                OP_FOOTER | OP_DATA_END => break,
                OP_SCHEMA | OP_CHANNEL => {
                    if len > MAX_META {
                        problems.push(format!(
                            "the {} record at byte {p} declares {len} bytes, more than this \
                             reader accepts: skipped",
                            op_name(op)
                        ));
                    } else {
                        r.read_into(body, len, &mut bufs.record)?;
                        match inner_meta(op, &bufs.record) {
                            Some(rec) => f(rec)?,
                            None => problems.push(format!(
                                "the {} record at byte {p} is malformed: skipped",
                                op_name(op)
                            )),
                        }
                    }
                }
                OP_MESSAGE => {
                    self.top_message(&mut r, &mut bufs, p, len, opts, problems, f)?;
                }
                OP_CHUNK => {
                    if let Some(d) = self.chunk(&mut r, &mut bufs, p, len, opts, f)? {
                        damaged = Some(d);
                    }
                }
                OP_MESSAGE_INDEX => {
                    if let Some(d) = damaged.as_mut()
                        && len <= MAX_META
                    {
                        r.read_into(body, len, &mut bufs.record)?;
                        if let Some((id, n)) = parse_message_index(&bufs.record) {
                            d.indexed = true;
                            d.listed += n;
                            if (opts.want)(id) {
                                d.listed_wanted += n;
                            }
                        }
                    }
                }
                _ => {}
            }
            p = rec_end;
        }
        if let Some(d) = damaged.take() {
            problems.push(d.describe(opts.counting));
        }
        Ok(())
    }

    /// A message outside any chunk.
    #[allow(clippy::too_many_arguments)]
    fn top_message(
        &self,
        r: &mut Reader,
        bufs: &mut Buffers,
        p: u64,
        len: u64,
        opts: &Walk<'_>,
        problems: &mut Vec<String>,
        f: &mut dyn FnMut(Rec<'_>) -> Result<()>,
    ) -> Result<()> {
        let body = p + RECORD_HEAD;
        if len < MESSAGE_HEAD as u64 {
            problems.push(format!(
                "the Message record at byte {p} is shorter than a message's head: skipped"
            ));
            return Ok(());
        }
        let head: [u8; MESSAGE_HEAD] = r.read_array(body)?;
        let mut c = Cur::new(&head);
        let (Some(channel), Some(_seq), Some(log_time)) = (c.u16(), c.u32(), c.u64()) else {
            return Ok(());
        };
        if !(opts.want)(channel) {
            return Ok(());
        }
        if len > MAX_MESSAGE {
            problems.push(format!(
                "the message at byte {p} declares {len} bytes, more than this reader accepts: \
                 skipped"
            ));
            return Ok(());
        }
        let n = len - MESSAGE_HEAD as u64;
        r.read_into(body + MESSAGE_HEAD as u64, n, &mut bufs.record)?;
        f(Rec::Message {
            channel,
            log_time,
            data: &bufs.record,
        })
    }

    /// Reads the chunk record at `p` (its content declared `len` bytes long, possibly cut by
    /// the end of the file) and hands its records to `f`. Returns what damaged it, if
    /// anything did.
    fn chunk(
        &self,
        r: &mut Reader,
        bufs: &mut Buffers,
        p: u64,
        len: u64,
        opts: &Walk<'_>,
        f: &mut dyn FnMut(Rec<'_>) -> Result<()>,
    ) -> Result<Option<Damaged>> {
        let body = p + RECORD_HEAD;
        let present = len.min(self.len.saturating_sub(body));
        let cut = present < len;
        let damage = |why: String| Damaged {
            offset: p,
            why,
            delivered: 0,
            listed: 0,
            listed_wanted: 0,
            indexed: false,
        };
        if opts.use_index
            && let Some(ids) = self.chunk_channels.get(&p)
            && !ids.is_empty()
            && !ids.iter().any(|&id| (opts.want)(id))
        {
            return Ok(None);
        }
        // The fixed fields and the compression name's length.
        if present < CHUNK_FIXED + 4 {
            return Ok(Some(damage(if cut {
                "is cut by the end of the file before its records".into()
            } else {
                "is too short for a chunk's head".into()
            })));
        }
        let fixed: [u8; 32] = r.read_array(body)?;
        let mut c = Cur::new(&fixed);
        let (Some(_start), Some(_end), Some(size), Some(crc), Some(name_len)) =
            (c.u64(), c.u64(), c.u64(), c.u32(), c.u32())
        else {
            return Ok(Some(damage("has a malformed head".into())));
        };
        if name_len > MAX_COMPRESSION_NAME {
            return Ok(Some(damage(format!(
                "names a compression of {name_len} bytes (a damaged head)"
            ))));
        }
        let head_len = CHUNK_FIXED + 4 + u64::from(name_len) + 8;
        if present < head_len {
            return Ok(Some(damage(if cut {
                "is cut by the end of the file before its records".into()
            } else {
                "is too short for its head".into()
            })));
        }
        r.read_into(
            body + CHUNK_FIXED + 4,
            u64::from(name_len) + 8,
            &mut bufs.record,
        )?;
        let mut c = Cur::new(&bufs.record);
        let name = c
            .take(name_len as usize)
            .map(|s| String::from_utf8_lossy(s).into_owned())
            .unwrap_or_default();
        let records_len = c.u64().unwrap_or(u64::MAX);
        if records_len > len - head_len {
            return Ok(Some(damage(format!(
                "declares {records_len} bytes of records, more than its record holds"
            ))));
        }
        if size > MAX_CHUNK {
            return Ok(Some(damage(format!(
                "declares {size} bytes decompressed, more than this reader accepts"
            ))));
        }
        if !matches!(name.as_str(), "" | "zstd" | "lz4") {
            return Ok(Some(damage(format!(
                "uses compression {name:?}, which is not zstd, lz4 or none"
            ))));
        }
        let stored = records_len.min(present - head_len);
        let records_at = body + head_len;
        let mut damaged: Option<Damaged> = None;
        if name.is_empty() {
            if records_len != size {
                damaged = Some(damage(format!(
                    "is uncompressed but holds {records_len} bytes of records, not the {size} \
                     it declares"
                )));
            }
            r.read_into(records_at, stored, &mut bufs.chunk)?;
        } else {
            r.goto(records_at)?;
            // A cut chunk gives what decompressed before the cut (the cut is told below).
            if let Err(why) = decompress(r, &name, stored, size, &mut bufs.chunk)
                && !cut
            {
                return Ok(Some(damage(format!("could not be read ({why})"))));
            }
            if bufs.chunk.len() as u64 > size {
                return Ok(Some(damage(format!(
                    "decompresses to more than the {size} bytes it declares"
                ))));
            }
        }
        if cut {
            damaged = Some(damage(format!(
                "is cut by the end of the file at byte {}",
                self.len
            )));
        } else if (bufs.chunk.len() as u64) < size && damaged.is_none() {
            return Ok(Some(damage(format!(
                "decompresses to {} bytes, not the {size} it declares",
                bufs.chunk.len()
            ))));
        } else if crc != 0 && damaged.is_none() && crc32fast::hash(&bufs.chunk) != crc {
            return Ok(Some(damage(
                "does not match its CRC (its records are damaged)".into(),
            )));
        }
        // The records: Schema, Channel and Message.
        let data = &bufs.chunk;
        let mut q = 0usize;
        let mut delivered = 0u64;
        while q < data.len() {
            let mut c = Cur::new(data.get(q..).unwrap_or(&[]));
            let (Some(op), Some(n)) = (c.take(1).and_then(|b| b.first().copied()), c.u64()) else {
                if damaged.is_none() {
                    damaged = Some(damage(format!(
                        "ends with {} bytes that are not a whole record",
                        data.len() - q
                    )));
                }
                break;
            };
            let Some(content) = usize::try_from(n).ok().and_then(|n| c.take(n)) else {
                if damaged.is_none() {
                    damaged = Some(damage(format!(
                        "has a damaged record at byte {q} of its records (a {} record of {n} \
                         bytes in {} bytes left)",
                        op_name(op),
                        data.len() - q
                    )));
                }
                break;
            };
            match op {
                OP_MESSAGE => {
                    let mut m = Cur::new(content);
                    if let (Some(channel), Some(_), Some(log_time), Some(_)) =
                        (m.u16(), m.u32(), m.u64(), m.u64())
                        && (opts.want)(channel)
                    {
                        delivered += 1;
                        f(Rec::Message {
                            channel,
                            log_time,
                            data: m.rest(),
                        })?;
                    }
                }
                OP_SCHEMA | OP_CHANNEL => {
                    if let Some(rec) = inner_meta(op, content) {
                        f(rec)?;
                    }
                }
                _ => {}
            }
            q += c.p;
        }
        Ok(damaged.map(|mut d| {
            d.delivered = delivered;
            d
        }))
    }
}

/// A Schema or Channel record's content, parsed.
fn inner_meta(op: u8, b: &[u8]) -> Option<Rec<'static>> {
    match op {
        OP_SCHEMA => parse_schema(b).map(|(id, name)| Rec::Schema(id, name)),
        OP_CHANNEL => parse_channel(b).map(Rec::Channel),
        _ => None,
    }
}

/// Opens one file: checks the magic and the Header, finds the footer and reads the summary,
/// or reads the whole data section when there is no usable summary.
fn open_file(path: &Path, problems: &mut Vec<String>) -> Result<(McapFile, FileInfo)> {
    let bad = |msg: String| Error::Input(format!("{}: {msg}", path.display()));
    let len = std::fs::metadata(path)
        .map_err(|e| Error::io(path, e))?
        .len();
    let mut r = Reader::open(path)?;
    let magic_len = MCAP_MAGIC.len() as u64;
    if len < magic_len + RECORD_HEAD {
        return Err(bad(format!(
            "{len} bytes: too short for an MCAP file (the magic and a header)"
        )));
    }
    let magic: [u8; 8] = r.read_array(0)?;
    if magic != MCAP_MAGIC {
        return Err(bad(
            "not an MCAP file (it does not start with the MCAP magic)".into(),
        ));
    }
    let (op, hlen) = r.record_head(magic_len)?;
    if op != OP_HEADER {
        return Err(bad(format!(
            "the MCAP magic is followed by a {} record, not a Header: not an MCAP file, or \
             damaged at its start",
            op_name(op)
        )));
    }
    let data_start = (magic_len + RECORD_HEAD)
        .checked_add(hlen)
        .filter(|&e| e <= len)
        .ok_or_else(|| {
            bad(format!(
                "the Header record declares {hlen} bytes, more than the file holds: damaged, \
                 or cut before any data"
            ))
        })?;
    let mut file = McapFile {
        path: path.to_path_buf(),
        len,
        data_start,
        data_end: len,
        closed: false,
        channels: BTreeMap::new(),
        chunk_channels: BTreeMap::new(),
    };
    // The footer, when the file was closed.
    let mut summary = None;
    if len >= data_start + TAIL {
        let footer_at = len - TAIL;
        let tail: [u8; TAIL as usize] = r.read_array(footer_at)?;
        let mut c = Cur::new(&tail);
        let head_ok = c.take(1) == Some(&[OP_FOOTER][..]) && c.u64() == Some(FOOTER_CONTENT);
        let (start, offsets) = (c.u64(), c.u64());
        c.u32();
        if head_ok && c.take(8) == Some(MCAP_MAGIC) {
            file.closed = true;
            file.data_end = footer_at;
            if let (Some(start), Some(offsets)) = (start, offsets)
                && start != 0
            {
                if (data_start..=footer_at).contains(&start) {
                    let end = if (start..=footer_at).contains(&offsets) && offsets != 0 {
                        offsets
                    } else {
                        footer_at
                    };
                    file.data_end = start;
                    summary = Some((start, end));
                } else {
                    problems.push(format!(
                        "{}: the footer puts the summary at byte {start}, outside the file's \
                         records: the file was read whole for its topics",
                        path.display()
                    ));
                }
            }
        }
    }
    if let Some((start, end)) = summary {
        match read_summary(&mut r, start, end) {
            Ok(mut info) if !info.channels.is_empty() => {
                file.chunk_channels = std::mem::take(&mut info.chunk_channels);
                return Ok((file, info));
            }
            Ok(_) => {} // No channel copies in the summary: look in the data.
            Err(why) => problems.push(format!(
                "{}: the summary section is damaged ({why}): the file was read whole for its \
                 topics",
                path.display()
            )),
        }
    } else if !file.closed {
        problems.push(format!(
            "{}: the file does not end with an MCAP footer (the recording was not closed, or \
             the file was cut): it was read whole for its topics",
            path.display()
        ));
    }
    let info = scan(&file, problems)?;
    Ok((file, info))
}

/// Reads the Schema, Channel, Statistics and Chunk Index records of the summary section.
fn read_summary(r: &mut Reader, start: u64, end: u64) -> std::result::Result<FileInfo, String> {
    let mut info = FileInfo::default();
    let mut buf = Vec::new();
    let mut p = start;
    while p < end {
        if end - p < RECORD_HEAD {
            return Err(format!("bytes {p}..{end} are not a whole record"));
        }
        let (op, len) = r.record_head(p).map_err(|e| e.to_string())?;
        let body = p + RECORD_HEAD;
        let rec_end = body
            .checked_add(len)
            .filter(|&e| e <= end)
            .ok_or_else(|| format!("the record at byte {p} runs past the summary's end"))?;
        if matches!(op, OP_SCHEMA | OP_CHANNEL | OP_STATISTICS | OP_CHUNK_INDEX) {
            if len > MAX_META {
                return Err(format!("the record at byte {p} declares {len} bytes"));
            }
            r.read_into(body, len, &mut buf)
                .map_err(|e| e.to_string())?;
            let malformed = || format!("the {} record at byte {p} is malformed", op_name(op));
            match op {
                OP_SCHEMA => {
                    let (id, name) = parse_schema(&buf).ok_or_else(malformed)?;
                    info.schemas.insert(id, name);
                }
                OP_CHANNEL => info
                    .channels
                    .push(parse_channel(&buf).ok_or_else(malformed)?),
                OP_STATISTICS => {
                    let counts = parse_statistics(&buf).ok_or_else(malformed)?;
                    info.counts = (!counts.is_empty()).then_some(counts);
                }
                _ => {
                    let (offset, ids) = parse_chunk_index(&buf).ok_or_else(malformed)?;
                    info.chunk_channels.insert(offset, ids);
                }
            }
        }
        p = rec_end;
    }
    Ok(info)
}

/// Reads the whole data section for its Schema and Channel records.
fn scan(file: &McapFile, problems: &mut Vec<String>) -> Result<FileInfo> {
    let mut info = FileInfo::default();
    let mut found = Vec::new();
    let walk = Walk {
        want: &|_| false,
        use_index: false,
        counting: false,
    };
    file.walk(&walk, &mut found, &mut |rec| {
        match rec {
            Rec::Schema(id, name) => {
                info.schemas.insert(id, name);
            }
            Rec::Channel(c) => {
                if !info.channels.iter().any(|k| k.id == c.id) {
                    info.channels.push(c);
                }
            }
            Rec::Message { .. } => {}
        }
        Ok(())
    })?;
    problems.extend(
        found
            .into_iter()
            .map(|p| format!("{}: while looking for topics: {p}", file.path.display())),
    );
    Ok(info)
}

/// The topic (an index into `topics`) a channel's messages belong to, added when new.
fn topic_of(topics: &mut Vec<Topic>, name: &str, msg_type: &str, ser: Serialization) -> usize {
    match topics
        .iter()
        .position(|t| t.name == name && t.msg_type == msg_type)
    {
        Some(i) => i,
        None => {
            topics.push(Topic {
                name: name.to_string(),
                msg_type: msg_type.to_string(),
                serialization: ser,
                declared_count: None,
            });
            topics.len() - 1
        }
    }
}

impl McapBag {
    /// Opens the storage files of one bag (in order) and reads their topics.
    pub fn open(files: &[PathBuf]) -> Result<McapBag> {
        if files.is_empty() {
            return Err(Error::Input("an MCAP bag needs at least one file".into()));
        }
        let mut bag = McapBag {
            files: Vec::new(),
            topics: Vec::new(),
            problems: Vec::new(),
        };
        // Messages declared per topic; None once a file holding it declares none.
        let mut declared: Vec<Option<u64>> = Vec::new();
        for path in files {
            let (mut file, info) = open_file(path, &mut bag.problems)?;
            for c in &info.channels {
                let msg_type = match c.schema_id {
                    0 => String::new(),
                    id => info.schemas.get(&id).cloned().unwrap_or_default(),
                };
                if msg_type.is_empty() {
                    bag.problems.push(format!(
                        "{}: channel {} ({}) has no schema naming its message type",
                        path.display(),
                        c.id,
                        c.topic
                    ));
                }
                let ser = match c.encoding.as_str() {
                    "cdr" => Some(Serialization::Cdr),
                    "ros1" => Some(Serialization::Ros1),
                    _ => None,
                };
                let topic = topic_of(
                    &mut bag.topics,
                    &c.topic,
                    &msg_type,
                    ser.unwrap_or(Serialization::Cdr),
                );
                let mut readable = ser.is_some();
                match ser {
                    None => bag.problems.push(format!(
                        "{}: topic {} ({msg_type}) has message encoding {:?}, which is neither \
                         cdr nor ros1: it is listed but its messages are not read",
                        path.display(),
                        c.topic,
                        c.encoding
                    )),
                    Some(s) if bag.topics.get(topic).is_some_and(|t| t.serialization != s) => {
                        readable = false;
                        bag.problems.push(format!(
                            "{}: channel {} of topic {} has message encoding {:?}, unlike the \
                             topic's other channels: its messages are not read",
                            path.display(),
                            c.id,
                            c.topic,
                            c.encoding
                        ));
                    }
                    Some(_) => {}
                }
                file.channels.insert(c.id, Chan { topic, readable });
            }
            // Declared counts: a file's statistics count its channels' messages.
            declared.resize(bag.topics.len(), Some(0));
            for (id, ch) in &file.channels {
                let n = info
                    .counts
                    .as_ref()
                    .map(|m| m.get(id).copied().unwrap_or(0));
                if let Some(d) = declared.get_mut(ch.topic) {
                    *d = match (*d, n) {
                        (Some(a), Some(b)) => Some(a.saturating_add(b)),
                        _ => None,
                    };
                }
            }
            bag.files.push(file);
        }
        for (t, d) in bag.topics.iter_mut().zip(declared) {
            t.declared_count = d;
        }
        Ok(bag)
    }

    /// The topics of all files, each once.
    pub fn topics(&self) -> &[Topic] {
        &self.topics
    }

    /// Damage found while opening.
    pub fn problems(&self) -> &[String] {
        &self.problems
    }

    /// See [`super::Bag::messages`].
    pub fn messages(
        &self,
        wanted: &dyn Fn(usize) -> bool,
        f: &mut dyn FnMut(BagMessage<'_>) -> Result<()>,
    ) -> Result<BagReadSummary> {
        let mut summary = BagReadSummary::default();
        let mut counts = vec![0u64; self.topics.len()];
        for file in &self.files {
            let want = |id: u16| {
                file.channels
                    .get(&id)
                    .is_some_and(|c| c.readable && wanted(c.topic))
            };
            let walk = Walk {
                want: &want,
                use_index: true,
                counting: true,
            };
            let mut late = 0u64;
            let mut problems = Vec::new();
            file.walk(&walk, &mut problems, &mut |rec| {
                let Rec::Message {
                    channel,
                    log_time,
                    data,
                } = rec
                else {
                    return Ok(());
                };
                let Some(topic) = file.channels.get(&channel).map(|c| c.topic) else {
                    return Ok(());
                };
                let Ok(log_time_ns) = i64::try_from(log_time) else {
                    late += 1;
                    return Ok(());
                };
                let Some(n) = counts.get_mut(topic) else {
                    return Ok(());
                };
                *n += 1;
                summary.messages += 1;
                f(BagMessage {
                    topic,
                    log_time_ns,
                    data,
                    index: *n,
                })
            })?;
            if late > 0 {
                problems.push(format!(
                    "{late} messages have record times past the year 2262 (beyond signed 64-bit \
                     nanoseconds): skipped"
                ));
            }
            summary.problems.extend(
                problems
                    .into_iter()
                    .map(|p| format!("{}: {p}", file.path.display())),
            );
        }
        Ok(summary)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cursor_never_reads_past_the_end() {
        let b = [1u8, 0, 3, 0, 0, 0, b'a', b'b'];
        let mut c = Cur::new(&b);
        assert_eq!(c.u16(), Some(1));
        assert_eq!(c.prefixed(), None); // declares 3 bytes, 2 left
        let mut c = Cur::new(&b);
        c.take(2);
        c.u32();
        assert_eq!(c.u64(), None);
        assert_eq!(c.rest(), b"ab");
        assert_eq!(c.rest(), b"");
    }

    #[test]
    fn statistics_and_indexes_parse() {
        let mut s = vec![0u8; 42];
        s.extend_from_slice(&20u32.to_le_bytes());
        for (id, n) in [(1u16, 5u64), (2, 7)] {
            s.extend_from_slice(&id.to_le_bytes());
            s.extend_from_slice(&n.to_le_bytes());
        }
        let m = parse_statistics(&s).expect("statistics");
        assert_eq!(m.get(&2), Some(&7));
        // A map whose length cuts an entry is malformed.
        s.truncate(s.len() - 1);
        assert!(parse_statistics(&s).is_none());
        let mut mi = 3u16.to_le_bytes().to_vec();
        mi.extend_from_slice(&32u32.to_le_bytes());
        mi.extend_from_slice(&[0u8; 32]);
        assert_eq!(parse_message_index(&mi), Some((3, 2)));
    }
}
