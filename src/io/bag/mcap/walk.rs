//! The pass over a file's data section in file order: records at top level and inside
//! chunks, and the recovery from damage (a record whose length runs past the data section
//! resumes at the next indexed chunk; a cut recording ends the pass, described).

use std::sync::Arc;

use super::damage::Damaged;
use super::file::{Buffers, McapFile, Walk};
use super::kept::{Meta, Top};
use super::reader::Reader;
use super::records::{
    Cur, MAX_MESSAGE, MAX_META, MESSAGE_HEAD, OP_CHANNEL, OP_CHUNK, OP_DATA_END, OP_FOOTER,
    OP_MESSAGE, OP_MESSAGE_INDEX, OP_SCHEMA, RECORD_HEAD, Rec, inner_meta, op_name,
    parse_message_index,
};
use crate::error::Result;
use crate::io::bag::memory::Kept;

impl McapFile {
    /// Walks the data section in file order, handing Schema, Channel and (wanted) Message
    /// records to `f`, from top level and inside chunks. Damage is skipped and described in
    /// `problems`; an error from `f` or from the file system stops the walk.
    ///
    /// A file followed while recorded ([`super::kept`]) has its records kept up to the first
    /// that is cut or damaged: they are handed over as kept, and the file is parsed from there;
    /// what is then parsed whole is kept in turn.
    pub(super) fn walk(
        &self,
        opts: &Walk<'_>,
        problems: &mut Vec<String>,
        f: &mut dyn FnMut(Rec<'_>) -> Result<()>,
    ) -> Result<()> {
        let mut r = Reader::open(&self.path)?;
        let mut bufs = Buffers::default();
        let mut damaged: Option<Damaged> = None;
        let limit = self.data_end;
        let (from, kept) = self.kept_items();
        for item in &kept {
            self.replay(&mut r, &mut bufs, item, opts, f)?;
        }
        let mut p = from;
        // What is parsed whole and undamaged from `from` on, and where it ends (`None` once a
        // record is not kept: nothing after it is).
        let mut keeping = self.slot.is_some().then(Vec::new);
        let mut kept_to = from;
        let clean_before = problems.len();
        // Chunk offsets to resume at after damage (known when the file has a summary).
        let resume: Vec<u64> = self.chunk_channels.keys().copied().collect();
        loop {
            if keeping.is_some() && (problems.len() > clean_before || damaged.is_some()) {
                keeping = None;
            }
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
                        self.count_decoded(p);
                        let d = self.chunk(&mut r, &mut bufs, p, len, opts, f, None)?;
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
            let mut top = Top::Other;
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
                            Some(rec) => {
                                if let Some(m) = Meta::of(&rec) {
                                    top = Top::Meta(m);
                                }
                                f(rec)?
                            }
                            None => problems.push(format!(
                                "the {} record at byte {p} is malformed: skipped",
                                op_name(op)
                            )),
                        }
                    }
                }
                OP_MESSAGE => {
                    let keep = keeping.is_some();
                    match self.top_message(&mut r, &mut bufs, p, len, opts, problems, f, keep)? {
                        Some(t) => top = t,
                        // Skipped for its length: a walk wanting it would say so.
                        None if len > MAX_MESSAGE => keeping = None,
                        None => {}
                    }
                }
                OP_CHUNK => {
                    if keeping.is_some() && self.skipped_by_index(p, opts) {
                        // Not parsed, so not kept: nor is anything after it.
                        keeping = None;
                    }
                    let mut records = keeping.is_some().then(Vec::new);
                    if !self.skipped_by_index(p, opts) {
                        self.count_decoded(p);
                    }
                    match self.chunk(&mut r, &mut bufs, p, len, opts, f, records.as_mut())? {
                        Some(d) => damaged = Some(d),
                        None => {
                            if let Some(records) = records {
                                top = Top::Chunk { p, len, records };
                            }
                        }
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
            if let Some(items) = &mut keeping
                && problems.len() == clean_before
                && damaged.is_none()
            {
                items.push(Arc::new(top));
                kept_to = p;
            }
        }
        if let Some(d) = damaged.take() {
            problems.push(d.describe(opts.counting));
        }
        if let Some(items) = keeping {
            self.keep(from, kept_to, items);
        }
        Ok(())
    }

    /// A message outside any chunk; with `keep`, what a later walk hands over for it.
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
        keep: bool,
    ) -> Result<Option<Top>> {
        let body = p + RECORD_HEAD;
        if len < MESSAGE_HEAD as u64 {
            problems.push(format!(
                "the Message record at byte {p} is shorter than a message's head: skipped"
            ));
            return Ok(None);
        }
        let head: [u8; MESSAGE_HEAD] = r.read_array(body)?;
        let mut c = Cur::new(&head);
        let (Some(channel), Some(_seq), Some(log_time)) = (c.u16(), c.u32(), c.u64()) else {
            return Ok(None);
        };
        let wanted = (opts.want)(channel);
        if !wanted && !keep {
            return Ok(None);
        }
        if len > MAX_MESSAGE {
            if wanted {
                problems.push(format!(
                    "the message at byte {p} declares {len} bytes, more than this reader \
                     accepts: skipped"
                ));
            }
            return Ok(None);
        }
        let at = body + MESSAGE_HEAD as u64;
        r.read_into(at, len - MESSAGE_HEAD as u64, &mut bufs.record)?;
        let top = keep.then(|| Top::Message {
            channel,
            log_time,
            data: Kept::of(&bufs.record, at),
        });
        if wanted {
            f(Rec::Message {
                channel,
                log_time,
                data: &bufs.record,
                whole: true,
            })?;
        }
        Ok(top)
    }
}
