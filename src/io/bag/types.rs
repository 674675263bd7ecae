//! The types shared by the bag readers and [`super::Bag`]: topics, messages, what a pass
//! found, and the magic bytes that tell the storages apart. (A module of their own, so that
//! the storage readers depend on it rather than on the module that uses them.)

/// The first bytes of an MCAP file.
pub const MCAP_MAGIC: &[u8] = b"\x89MCAP0\r\n";
/// The first bytes of an sqlite3 database.
pub const SQLITE_MAGIC: &[u8] = b"SQLite format 3\0";

/// How the messages of a topic are serialised.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Serialization {
    /// ROS 2's CDR (an encapsulation header, aligned primitives).
    Cdr,
    /// ROS 1's serialisation (packed little-endian, `Header` with a `seq`).
    Ros1,
}

/// The storage a bag was read from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Storage {
    /// A ROS 1 bag (format 2.0).
    Ros1,
    /// ROS 2, MCAP storage.
    Mcap,
    /// ROS 2, sqlite3 storage.
    Sqlite3,
}

impl Storage {
    /// The storage's name in summaries.
    pub fn name(self) -> &'static str {
        match self {
            Storage::Ros1 => "ROS 1 bag",
            Storage::Mcap => "ROS 2 bag (MCAP)",
            Storage::Sqlite3 => "ROS 2 bag (sqlite3)",
        }
    }

    /// What one file of this storage is, in messages (`an MCAP file`).
    pub fn file_kind(self) -> &'static str {
        match self {
            Storage::Ros1 => "a ROS 1 bag",
            Storage::Mcap => "an MCAP file",
            Storage::Sqlite3 => "an sqlite3 database",
        }
    }

    /// The bytes every file of this storage starts with.
    pub fn magic(self) -> &'static [u8] {
        match self {
            Storage::Ros1 => ROS1_MAGIC,
            Storage::Mcap => MCAP_MAGIC,
            Storage::Sqlite3 => SQLITE_MAGIC,
        }
    }

    /// The storage a file's first bytes announce, if any.
    pub fn of_head(head: &[u8]) -> Option<Storage> {
        [Storage::Ros1, Storage::Mcap, Storage::Sqlite3]
            .into_iter()
            .find(|s| head.starts_with(s.magic()))
    }

    /// The storage a file's name suggests: `.bag`, `.mcap`, `.db3`.
    pub fn of_extension(path: &std::path::Path) -> Option<Storage> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "bag" => Some(Storage::Ros1),
            "mcap" => Some(Storage::Mcap),
            "db3" => Some(Storage::Sqlite3),
            _ => None,
        }
    }

    /// Why a file starting with `head` (all of it when the file is that short) is not a file
    /// of this storage: cut inside the magic, or other bytes where the magic belongs.
    pub fn magic_mismatch(self, head: &[u8]) -> String {
        let magic = self.magic();
        let shown = &head[..head.len().min(magic.len())];
        if head.len() < magic.len() && magic.starts_with(head) {
            format!(
                "not {}: the file ends after {} bytes, inside the magic bytes {} that open one \
                 (cut at its start)",
                self.file_kind(),
                head.len(),
                show_bytes(magic)
            )
        } else if head.is_empty() {
            format!("not {}: the file is empty", self.file_kind())
        } else {
            format!(
                "not {}: magic bytes {} where {} starts with {}",
                self.file_kind(),
                show_bytes(shown),
                self.file_kind(),
                show_bytes(magic)
            )
        }
    }
}

/// The first bytes of a ROS 1 bag.
const ROS1_MAGIC: &[u8] = super::ros1::MAGIC;

/// Bytes as hex with their printable characters (`89 4d 43 41 (".MCA")`), for messages about
/// a file's first bytes.
pub fn show_bytes(b: &[u8]) -> String {
    let hex: Vec<String> = b.iter().map(|x| format!("{x:02x}")).collect();
    let text: String = b
        .iter()
        .map(|&x| {
            if x.is_ascii_graphic() || x == b' ' {
                x as char
            } else {
                '.'
            }
        })
        .collect();
    format!("{} (\"{text}\")", hex.join(" "))
}

/// One topic of a bag.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Topic {
    /// The topic's name (`/cam0/image_raw`).
    pub name: String,
    /// The message type as the bag stores it (`sensor_msgs/msg/Image` in ROS 2,
    /// `sensor_msgs/Image` in ROS 1); [`Topic::type_name`] gives one spelling for both.
    pub msg_type: String,
    /// How its messages are serialised.
    pub serialization: Serialization,
    /// Messages the bag's index, summary or metadata declares for the topic, when it does.
    pub declared_count: Option<u64>,
}

impl Topic {
    /// The message type without ROS 2's `/msg/` (`sensor_msgs/Image` in both ROS versions).
    pub fn type_name(&self) -> String {
        normalize_type(&self.msg_type)
    }
}

/// `pkg/msg/Type` as `pkg/Type`; any other spelling unchanged.
pub fn normalize_type(t: &str) -> String {
    match t.split('/').collect::<Vec<_>>().as_slice() {
        [pkg, "msg", name] => format!("{pkg}/{name}"),
        _ => t.to_string(),
    }
}

/// One serialised message handed out by [`Bag::messages`](super::Bag::messages).
#[derive(Clone, Copy, Debug)]
pub struct BagMessage<'a> {
    /// The message's topic: an index into [`Bag::topics`](super::Bag::topics).
    pub topic: usize,
    /// The record (log) time: when the recorder received the message, Unix nanoseconds.
    pub log_time_ns: i64,
    /// The serialised message: all of it, or only its first
    /// [`HEAD`](super::memory::HEAD) bytes when `whole` is false.
    pub data: &'a [u8],
    /// The 1-based number of this message among its topic's messages read in this pass.
    pub index: u64,
    /// Whether `data` is the whole message: always, but in a pass of
    /// [`Bag::messages_with`](super::Bag::messages_with) over a bag followed while recorded.
    pub whole: bool,
}

/// What one pass over the messages found.
#[derive(Clone, Debug, Default)]
pub struct BagReadSummary {
    /// Messages handed to the callback.
    pub messages: u64,
    /// Damage met while reading (a chunk that could not be decompressed, a file cut short),
    /// each with what it cost.
    pub problems: Vec<String>,
}
