//! Opening one storage file: the magic and the Header checked, the footer found, and the
//! topics read from the summary section, or from the whole data section when there is no
//! usable summary.

use std::collections::BTreeMap;
use std::path::Path;

use super::file::{FileInfo, McapFile, Walk};
use super::reader::Reader;
use super::records::{
    Cur, FOOTER_CONTENT, MAX_META, OP_CHANNEL, OP_CHUNK_INDEX, OP_FOOTER, OP_HEADER, OP_SCHEMA,
    OP_STATISTICS, RECORD_HEAD, Rec, TAIL, op_name, parse_channel, parse_chunk_index, parse_schema,
    parse_statistics,
};
use crate::error::{Error, Result};
use crate::io::bag::types::{MCAP_MAGIC, Storage};

/// Opens one file: checks the magic and the Header, finds the footer and reads the summary,
/// or reads the whole data section when there is no usable summary.
pub(super) fn open_file(path: &Path, problems: &mut Vec<String>) -> Result<(McapFile, FileInfo)> {
    let bad = |msg: String| Error::Input(format!("{}: {msg}", path.display()));
    // A file still being recorded is read to the length fixed for this read, if any.
    let len = crate::io::bag::growing::readable_len(
        path,
        std::fs::metadata(path)
            .map_err(|e| Error::io(path, e))?
            .len(),
    );
    let mut r = Reader::open(path)?;
    let magic_len = MCAP_MAGIC.len() as u64;
    if len < magic_len {
        let head = std::fs::read(path).map_err(|e| Error::io(path, e))?;
        return Err(bad(Storage::Mcap.magic_mismatch(&head)));
    }
    let magic: [u8; 8] = r.read_array(0)?;
    if magic != MCAP_MAGIC {
        return Err(bad(Storage::Mcap.magic_mismatch(&magic)));
    }
    if len < magic_len + RECORD_HEAD {
        return Err(bad(format!(
            "{len} bytes: too short for an MCAP file (the magic and a header)"
        )));
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
        slot: crate::io::bag::growing::slot_of(path),
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
    // What earlier reads kept, checked once the data section's end is known.
    file.check_kept();
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
        whole: &|_| false,
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
