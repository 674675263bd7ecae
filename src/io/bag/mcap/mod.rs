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
//!
//! The parts: the records' layout and parsers (`records`), the positioned file reader and the
//! decompression (`reader`), opening a file and reading its summary (`open`), the pass over
//! the data section with its recovery from damage (`walk`), one chunk (`chunk`) and what a
//! damaged one cost (`damage`); this file joins the storage files of a bag and hands out their
//! messages.

mod chunk;
mod damage;
mod file;
mod kept;
mod open;
mod reader;
mod records;
mod walk;

use std::path::PathBuf;

use crate::error::{Error, Result};
use crate::io::bag::types::{BagMessage, BagReadSummary, Serialization, Topic};
use file::{Chan, McapFile, Walk};
use records::Rec;

/// The storage files of one ROS 2 bag, opened.
#[derive(Debug)]
pub struct McapBag {
    files: Vec<McapFile>,
    topics: Vec<Topic>,
    problems: Vec<String>,
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
            let (mut file, info) = open::open_file(path, &mut bag.problems)?;
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

    /// See [`super::Bag::messages_with`].
    pub fn messages(
        &self,
        wanted: &dyn Fn(usize) -> bool,
        whole: &dyn Fn(usize, u64) -> bool,
        f: &mut dyn FnMut(BagMessage<'_>) -> Result<()>,
    ) -> Result<BagReadSummary> {
        let mut summary = BagReadSummary::default();
        let counts = vec![std::cell::Cell::new(0u64); self.topics.len()];
        for file in &self.files {
            let want = |id: u16| {
                file.channels
                    .get(&id)
                    .is_some_and(|c| c.readable && wanted(c.topic))
            };
            // The message about to be handed over is its topic's next.
            let fetch = |id: u16| {
                file.channels.get(&id).is_some_and(|c| {
                    counts
                        .get(c.topic)
                        .is_some_and(|n| whole(c.topic, n.get() + 1))
                })
            };
            let walk = Walk {
                want: &want,
                whole: &fetch,
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
                    whole,
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
                let Some(n) = counts.get(topic) else {
                    return Ok(());
                };
                n.set(n.get() + 1);
                summary.messages += 1;
                f(BagMessage {
                    topic,
                    log_time_ns,
                    data,
                    index: n.get(),
                    whole,
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
