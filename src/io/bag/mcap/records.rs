//! The layout of MCAP records: opcodes and sizes, a bounds-checked cursor over a record's
//! content, and the parsers of the records this reader uses (Schema, Channel, Statistics, Chunk
//! Index, Message Index).

use std::collections::BTreeMap;

pub(super) const OP_HEADER: u8 = 0x01;
pub(super) const OP_FOOTER: u8 = 0x02;
pub(super) const OP_SCHEMA: u8 = 0x03;
pub(super) const OP_CHANNEL: u8 = 0x04;
pub(super) const OP_MESSAGE: u8 = 0x05;
pub(super) const OP_CHUNK: u8 = 0x06;
pub(super) const OP_MESSAGE_INDEX: u8 = 0x07;
pub(super) const OP_CHUNK_INDEX: u8 = 0x08;
pub(super) const OP_STATISTICS: u8 = 0x0B;
pub(super) const OP_DATA_END: u8 = 0x0F;

/// Opcode and length in front of every record.
pub(super) const RECORD_HEAD: u64 = 9;
/// The Footer's content: summary_start, summary_offset_start, summary_crc.
pub(super) const FOOTER_CONTENT: u64 = 20;
/// The Footer record and the closing magic.
pub(super) const TAIL: u64 = RECORD_HEAD + FOOTER_CONTENT + 8;
/// The largest record read whole that is not a message or a chunk (headers, schemas with
/// their message definitions, channels, statistics, indexes are far smaller).
pub(super) const MAX_META: u64 = 64 << 20;
/// The largest message (an uncompressed 4K colour image is 25 MB).
pub(super) const MAX_MESSAGE: u64 = 1 << 30;
/// The largest chunk, decompressed (rosbag2 writes about 1 MB; single large images make
/// bigger ones).
pub(super) const MAX_CHUNK: u64 = 1 << 30;
/// The longest compression name taken for a real one.
pub(super) const MAX_COMPRESSION_NAME: u32 = 64;
/// Message: channel_id u16, sequence u32, log_time u64, publish_time u64.
pub(super) const MESSAGE_HEAD: usize = 22;
/// Chunk: message_start_time, message_end_time, uncompressed_size (u64 each), uncompressed_crc
/// (u32), then the compression string and the records' u64 length.
pub(super) const CHUNK_FIXED: u64 = 28;

/// A Schema or Channel record as read.
#[derive(Clone, Debug)]
pub(super) struct ChannelRec {
    pub(super) id: u16,
    pub(super) schema_id: u16,
    pub(super) topic: String,
    pub(super) encoding: String,
}

/// A bounds-checked cursor over a record's content.
pub(super) struct Cur<'a> {
    b: &'a [u8],
    pub(super) p: usize,
}

impl<'a> Cur<'a> {
    pub(super) fn new(b: &'a [u8]) -> Self {
        Cur { b, p: 0 }
    }
    pub(super) fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let s = self.b.get(self.p..self.p.checked_add(n)?)?;
        self.p += n;
        Some(s)
    }
    pub(super) fn u16(&mut self) -> Option<u16> {
        Some(u16::from_le_bytes(self.take(2)?.try_into().ok()?))
    }
    pub(super) fn u32(&mut self) -> Option<u32> {
        Some(u32::from_le_bytes(self.take(4)?.try_into().ok()?))
    }
    pub(super) fn u64(&mut self) -> Option<u64> {
        Some(u64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }
    /// A u32-length-prefixed byte string (strings, maps, arrays).
    pub(super) fn prefixed(&mut self) -> Option<&'a [u8]> {
        let n = self.u32()?;
        self.take(usize::try_from(n).ok()?)
    }
    pub(super) fn string(&mut self) -> Option<String> {
        self.prefixed()
            .map(|s| String::from_utf8_lossy(s).into_owned())
    }
    pub(super) fn rest(&mut self) -> &'a [u8] {
        let s = self.b.get(self.p..).unwrap_or(&[]);
        self.p = self.b.len();
        s
    }
}

pub(super) fn parse_schema(b: &[u8]) -> Option<(u16, String)> {
    let mut c = Cur::new(b);
    let id = c.u16()?;
    let name = c.string()?;
    Some((id, name))
}

pub(super) fn parse_channel(b: &[u8]) -> Option<ChannelRec> {
    let mut c = Cur::new(b);
    Some(ChannelRec {
        id: c.u16()?,
        schema_id: c.u16()?,
        topic: c.string()?,
        encoding: c.string()?,
    })
}

/// Statistics' channel_message_counts (`None` when malformed).
pub(super) fn parse_statistics(b: &[u8]) -> Option<BTreeMap<u16, u64>> {
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
pub(super) fn parse_chunk_index(b: &[u8]) -> Option<(u64, Vec<u16>)> {
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
pub(super) fn parse_message_index(b: &[u8]) -> Option<(u16, u64)> {
    let mut c = Cur::new(b);
    let id = c.u16()?;
    let records = c.prefixed()?;
    Some((id, records.len() as u64 / 16))
}

pub(super) fn op_name(op: u8) -> String {
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

/// A record met while walking a file's data section.
pub(super) enum Rec<'a> {
    Schema(u16, String),
    Channel(ChannelRec),
    Message {
        channel: u16,
        log_time: u64,
        data: &'a [u8],
        /// Whether `data` is the whole message, not only its first bytes.
        whole: bool,
    },
}

/// A Schema or Channel record's content, parsed.
pub(super) fn inner_meta(op: u8, b: &[u8]) -> Option<Rec<'static>> {
    match op {
        OP_SCHEMA => parse_schema(b).map(|(id, name)| Rec::Schema(id, name)),
        OP_CHANNEL => parse_channel(b).map(Rec::Channel),
        _ => None,
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
