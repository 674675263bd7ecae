//! The pass over a file's data section in file order: records at top level and inside
//! chunks, and the recovery from damage (a record whose length runs past the data section
//! resumes at the next indexed chunk; a cut recording ends the pass, described).

use super::damage::Damaged;
use super::file::{Buffers, McapFile, Walk};
use super::reader::Reader;
use super::records::{
    Cur, MAX_MESSAGE, MAX_META, MESSAGE_HEAD, OP_CHANNEL, OP_CHUNK, OP_DATA_END, OP_FOOTER,
    OP_MESSAGE, OP_MESSAGE_INDEX, OP_SCHEMA, RECORD_HEAD, Rec, inner_meta, op_name,
    parse_message_index,
};
use crate::error::Result;

impl McapFile {
    /// Walks the data section in file order, handing Schema, Channel and (wanted) Message
    /// records to `f`, from top level and inside chunks. Damage is skipped and described in
    /// `problems`; an error from `f` or from the file system stops the walk.
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
}
