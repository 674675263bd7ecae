//! One Chunk record: its head checked, its records decompressed (zstd, lz4 or none) into one
//! buffer and checked against the declared size and CRC, and the Schema, Channel and wanted
//! Message records inside handed out; damage is returned, not raised.

use super::damage::Damaged;
use super::file::{Buffers, McapFile, Walk};
use super::kept::{Inside, Meta};
use super::reader::{Reader, decompress};
use super::records::{
    CHUNK_FIXED, Cur, MAX_CHUNK, MAX_COMPRESSION_NAME, OP_CHANNEL, OP_MESSAGE, OP_SCHEMA,
    RECORD_HEAD, Rec, inner_meta, op_name,
};
use crate::error::Result;
use crate::io::bag::memory::Kept;

impl McapFile {
    /// Reads the chunk record at `p` (its content declared `len` bytes long, possibly cut by
    /// the end of the file) and hands its records to `f`. Returns what damaged it, if
    /// anything did. Every Schema, Channel and Message record is added to `keep` when given
    /// (the caller keeps them only when the chunk was whole and undamaged).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn chunk(
        &self,
        r: &mut Reader,
        bufs: &mut Buffers,
        p: u64,
        len: u64,
        opts: &Walk<'_>,
        f: &mut dyn FnMut(Rec<'_>) -> Result<()>,
        mut keep: Option<&mut Vec<Inside>>,
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
        if self.skipped_by_index(p, opts) {
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
                    {
                        // Where the message's data starts in the chunk's records.
                        let at = q as u64 + RECORD_HEAD + m.p as u64;
                        let data = m.rest();
                        if let Some(keep) = keep.as_deref_mut() {
                            keep.push(Inside::Message {
                                channel,
                                log_time,
                                data: Kept::of(data, at),
                            });
                        }
                        if (opts.want)(channel) {
                            delivered += 1;
                            f(Rec::Message {
                                channel,
                                log_time,
                                data,
                                whole: true,
                            })?;
                        }
                    }
                }
                OP_SCHEMA | OP_CHANNEL => {
                    if let Some(rec) = inner_meta(op, content) {
                        if let (Some(keep), Some(m)) = (keep.as_deref_mut(), Meta::of(&rec)) {
                            keep.push(Inside::Meta(m));
                        }
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

    /// Whether the summary's chunk index says the chunk at `p` holds no channel `opts` wants
    /// (the walk then skips it).
    pub(super) fn skipped_by_index(&self, p: u64, opts: &Walk<'_>) -> bool {
        opts.use_index
            && self
                .chunk_channels
                .get(&p)
                .is_some_and(|ids| !ids.is_empty() && !ids.iter().any(|&id| (opts.want)(id)))
    }
}
