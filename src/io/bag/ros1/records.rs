//! The ROS 1 bag format's records: the ops, a record's header and its fields, finding a
//! record in a buffer (and the next one after damage), a chunk's place and its decompression.
//! Nothing here trusts a length.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};

/// The largest record header accepted (real headers are well under 1 kB; a connection record's
/// header holds only op, conn and topic).
pub(super) const MAX_HEADER: usize = 1 << 16;
/// The largest chunk, compressed or not (rosbag's default is 768 kB; images make them bigger).
pub(super) const MAX_CHUNK: usize = 1 << 30;

pub(super) const OP_MESSAGE: u8 = 2;
pub(super) const OP_BAG_HEADER: u8 = 3;
pub(super) const OP_INDEX_DATA: u8 = 4;
pub(super) const OP_CHUNK: u8 = 5;
pub(super) const OP_CHUNK_INFO: u8 = 6;
pub(super) const OP_CONNECTION: u8 = 7;
/// Every op a top-level scan may meet (messages only where a chunk header was damaged).
pub(super) const ANY_OP: [u8; 6] = [
    OP_MESSAGE,
    OP_BAG_HEADER,
    OP_INDEX_DATA,
    OP_CHUNK,
    OP_CHUNK_INFO,
    OP_CONNECTION,
];

/// How a chunk's data is stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Compression {
    None,
    Bz2,
    Lz4,
}

#[derive(Clone, Debug)]
pub(super) struct ChunkLoc {
    /// Offset of the chunk record in the file.
    pub(super) record: u64,
    /// Offset of the chunk's data.
    pub(super) data: u64,
    /// Bytes of data present in the file (less than declared when the file is cut).
    pub(super) len: usize,
    /// Whether the file ends before the chunk's declared end.
    pub(super) cut: bool,
    pub(super) compression: Compression,
    /// Declared uncompressed size.
    pub(super) size: usize,
}

/// A parsed record header: its fields, and where the record's data lies.
pub(super) struct RecordHead<'a> {
    pub(super) fields: Vec<(&'a [u8], &'a [u8])>,
    pub(super) op: u8,
}

impl<'a> RecordHead<'a> {
    pub(super) fn field(&self, name: &str) -> Option<&'a [u8]> {
        self.fields
            .iter()
            .find(|(k, _)| *k == name.as_bytes())
            .map(|(_, v)| *v)
    }
    pub(super) fn u32(&self, name: &str) -> Option<u32> {
        let v = self.field(name)?;
        Some(u32::from_le_bytes(v.try_into().ok()?))
    }
    pub(super) fn u64(&self, name: &str) -> Option<u64> {
        let v = self.field(name)?;
        Some(u64::from_le_bytes(v.try_into().ok()?))
    }
    pub(super) fn time(&self, name: &str) -> Option<(u32, u32)> {
        let v = self.field(name)?;
        if v.len() != 8 {
            return None;
        }
        let sec = u32::from_le_bytes(v[..4].try_into().ok()?);
        let nsec = u32::from_le_bytes(v[4..].try_into().ok()?);
        Some((sec, nsec))
    }
    pub(super) fn text(&self, name: &str) -> Option<String> {
        self.field(name)
            .map(|v| String::from_utf8_lossy(v).into_owned())
    }
    /// Whether the fields an op needs are present and well formed.
    pub(super) fn complete(&self) -> bool {
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
pub(super) fn parse_header(h: &[u8]) -> Option<RecordHead<'_>> {
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
pub(super) struct Found<'a> {
    pub(super) head: RecordHead<'a>,
    pub(super) data_start: usize,
    pub(super) data_len: usize,
}

/// Reads the record at `p` of `buf`; `None` when no well-formed record header starts there.
pub(super) fn record_at(buf: &[u8], p: usize) -> Option<Found<'_>> {
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
pub(super) fn resync(buf: &[u8], from: usize, ops: &[u8], allow_cut: bool) -> Option<usize> {
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

pub(super) fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

/// Reads up to `len` bytes at `offset`, never past byte `end` (fewer when the file or `end`
/// comes first: `end` is the length the bag is read to, `io::bag::growing`).
pub(super) fn read_at(
    file: &mut File,
    offset: u64,
    len: usize,
    end: u64,
) -> std::io::Result<Vec<u8>> {
    file.seek(SeekFrom::Start(offset))?;
    let mut v = Vec::new();
    let len = (len as u64).min(end.saturating_sub(offset));
    file.take(len).read_to_end(&mut v)?;
    Ok(v)
}

/// The `type` field of a connection record's data (itself a header of fields).
pub(super) fn connection_type(data: &[u8]) -> String {
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
pub(super) fn decompress(c: &ChunkLoc, raw: &[u8]) -> std::result::Result<Vec<u8>, String> {
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
