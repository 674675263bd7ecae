//! Bags as users record them: ROS 1 bags ([`ros1`]) and ROS 2 bags in either storage (MCAP,
//! [`mcap`]; sqlite3, [`sqlite`]), behind one [`Bag`] that lists the topics and streams the
//! serialised messages of the ones asked for, in record order, one chunk at a time. Decoding
//! the messages is left to [`cdr`] (both serialisations) and to the formats that need them.
//!
//! A ROS 2 bag is a folder with `metadata.yaml` and its storage files, or one bare `.mcap` or
//! `.db3` file; [`Bag::open`] takes any of these, and a ROS 1 `.bag`.
//!
//! A bag as a dataset: [`open`] gives its topics their parts ([`roles`]), [`frames`] plans its
//! image topics as stereo frames, [`poses`] reads a pose topic, [`imu`] an IMU topic,
//! [`camera_info`] a camera model, [`image`] turns image messages into grey images, and
//! [`info`] lists it for `dvlcal bag-info`.

pub mod camera_info;
pub mod cdr;
pub mod frames;
pub mod growing;
pub mod image;
pub mod imu;
pub mod info;
pub mod mcap;
pub mod memory;
pub mod open;
pub mod poses;
pub mod roles;
pub mod ros1;
pub mod sqlite;
mod types;

use std::path::{Path, PathBuf};

pub use types::{
    BagMessage, BagReadSummary, MCAP_MAGIC, SQLITE_MAGIC, Serialization, Storage, Topic,
    normalize_type,
};

use crate::error::{Error, Result};

/// A bag opened for reading: its topics and how to stream its messages.
#[derive(Debug)]
pub struct Bag {
    path: PathBuf,
    storage: Storage,
    topics: Vec<Topic>,
    problems: Vec<String>,
    notes: Vec<String>,
    inner: Inner,
}

#[derive(Debug)]
enum Inner {
    Ros1 {
        bag: ros1::Ros1Bag,
        /// The topic index of each connection id.
        conn_topic: std::collections::BTreeMap<u32, usize>,
    },
    Mcap(mcap::McapBag),
    Sqlite(sqlite::SqliteBag),
}

/// The first bytes of a file (all of it when it is shorter), enough to tell the storages apart.
fn head_of_file(path: &Path) -> std::io::Result<Vec<u8>> {
    let mut head = Vec::with_capacity(16);
    std::io::Read::read_to_end(
        &mut std::io::Read::take(std::fs::File::open(path)?, 16),
        &mut head,
    )?;
    Ok(head)
}

/// The storage a file's first bytes announce, if any.
fn storage_of_file(path: &Path) -> std::io::Result<Option<Storage>> {
    Ok(Storage::of_head(&head_of_file(path)?))
}

/// The error for a file that is no bag: named after the storage its extension promises
/// (`not an MCAP file: magic bytes ...`), or after all of them.
fn not_a_bag(path: &Path) -> Error {
    let head = match head_of_file(path) {
        Ok(h) => h,
        Err(e) => return Error::io(path, e),
    };
    match Storage::of_extension(path) {
        Some(storage) => Error::Input(format!(
            "{}: {}",
            path.display(),
            storage.magic_mismatch(&head)
        )),
        None => Error::Input(format!(
            "{}: not a bag (neither a ROS 1 bag, an MCAP file, an sqlite3 database, nor a \
             ROS 2 bag folder with metadata.yaml): it starts with {}",
            path.display(),
            if head.is_empty() {
                "nothing (it is empty)".to_string()
            } else {
                types::show_bytes(&head)
            }
        )),
    }
}

/// Whether `path` looks like a bag: a folder holding `metadata.yaml`, or a file starting like
/// a ROS 1 bag, an MCAP file or an sqlite3 database.
pub fn is_bag(path: &Path) -> bool {
    if path.is_dir() {
        return path.join("metadata.yaml").is_file();
    }
    storage_of_file(path).ok().flatten().is_some()
}

impl Bag {
    /// Opens a bag: a ROS 2 bag folder (`metadata.yaml` and its `.mcap` or `.db3` files, read
    /// in the order the metadata lists them), a bare `.mcap` or `.db3` file, or a ROS 1 bag.
    /// Damage that leaves messages to read is described in [`Bag::problems`]; a file that is
    /// none of these, or that holds nothing readable, is an error naming it.
    pub fn open(path: &Path) -> Result<Bag> {
        if path.is_dir() {
            return open_ros2_folder(path);
        }
        match storage_of_file(path).map_err(|e| Error::io(path, e))? {
            Some(Storage::Ros1) => open_ros1(path),
            Some(storage) => open_ros2(path, storage, &[path.to_path_buf()]),
            None => Err(not_a_bag(path)),
        }
    }

    /// The bag's path as given.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The storage the bag was read from.
    pub fn storage(&self) -> Storage {
        self.storage
    }

    /// The topics, in the order the bag declares them; [`BagMessage::topic`] indexes this.
    pub fn topics(&self) -> &[Topic] {
        &self.topics
    }

    /// Damage found while opening: what it was and what it cost.
    pub fn problems(&self) -> &[String] {
        &self.problems
    }

    /// What a user should know about the bag that is not damage (a `metadata.yaml` naming
    /// another storage than its files hold).
    pub fn notes(&self) -> &[String] {
        &self.notes
    }

    /// Hands every message of the topics `wanted` accepts (by index into [`Bag::topics`]) to
    /// `f`, in record order within each storage file, files in order. Memory stays bounded by
    /// one chunk, whatever the bag's size. Damage is skipped and described in the summary; an
    /// error from `f` stops the pass and is returned.
    pub fn messages(
        &self,
        wanted: &dyn Fn(usize) -> bool,
        f: &mut dyn FnMut(BagMessage<'_>) -> Result<()>,
    ) -> Result<BagReadSummary> {
        self.messages_with(wanted, &|_, _| true, f)
    }

    /// [`Bag::messages`], for a reader that needs some messages only in part: while the bag
    /// is followed as it is recorded ([`memory`]), a long message (an image) kept from an
    /// earlier update is handed over whole only when `whole(topic, index)` says so (asked
    /// just before it is handed over), else as its first [`memory::HEAD`] bytes
    /// ([`BagMessage::whole`] false), so that its bytes are not read again. Otherwise every
    /// message is whole.
    pub fn messages_with(
        &self,
        wanted: &dyn Fn(usize) -> bool,
        whole: &dyn Fn(usize, u64) -> bool,
        f: &mut dyn FnMut(BagMessage<'_>) -> Result<()>,
    ) -> Result<BagReadSummary> {
        match &self.inner {
            Inner::Ros1 { bag, conn_topic } => {
                let counts = vec![std::cell::Cell::new(0u64); self.topics.len()];
                let want = |id: u32| conn_topic.get(&id).is_some_and(|&t| wanted(t));
                // The message about to be handed over is its topic's next.
                let fetch = |id: u32| {
                    conn_topic
                        .get(&id)
                        .is_some_and(|&t| whole(t, counts[t].get() + 1))
                };
                let s = bag.messages_with(&want, &fetch, &mut |m| {
                    let Some(&topic) = conn_topic.get(&m.conn_id) else {
                        return Ok(());
                    };
                    let n = counts[topic].get() + 1;
                    counts[topic].set(n);
                    f(BagMessage {
                        topic,
                        log_time_ns: i64::from(m.sec) * 1_000_000_000 + i64::from(m.nsec),
                        data: m.data,
                        index: n,
                        whole: m.whole,
                    })
                })?;
                let mut problems = s.problems;
                if let Some(n) = s.lost_messages.filter(|&n| n > 0) {
                    problems.push(format!(
                        "{n} messages that the bag's index lists could not be read"
                    ));
                }
                Ok(BagReadSummary {
                    messages: s.messages as u64,
                    problems,
                })
            }
            Inner::Mcap(b) => b.messages(wanted, whole, f),
            Inner::Sqlite(b) => b.messages(wanted, whole, f),
        }
    }
}

/// A ROS 1 bag: one topic per (name, type), whatever the number of connections.
fn open_ros1(path: &Path) -> Result<Bag> {
    let bag = ros1::Ros1Bag::open(path)?;
    let mut topics: Vec<Topic> = Vec::new();
    let mut conn_topic = std::collections::BTreeMap::new();
    for c in bag.connections() {
        let i = match topics
            .iter()
            .position(|t| t.name == c.topic && t.msg_type == c.msg_type)
        {
            Some(i) => i,
            None => {
                topics.push(Topic {
                    name: c.topic.clone(),
                    msg_type: c.msg_type.clone(),
                    serialization: Serialization::Ros1,
                    declared_count: None,
                });
                topics.len() - 1
            }
        };
        conn_topic.insert(c.id, i);
    }
    Ok(Bag {
        path: path.to_path_buf(),
        storage: Storage::Ros1,
        topics,
        problems: bag.problems().to_vec(),
        notes: Vec::new(),
        inner: Inner::Ros1 { bag, conn_topic },
    })
}

/// The ROS 2 storage files `files` (in order) of the bag at `path`.
fn open_ros2(path: &Path, storage: Storage, files: &[PathBuf]) -> Result<Bag> {
    let (inner, topics, problems) = match storage {
        Storage::Mcap => {
            let b = mcap::McapBag::open(files)?;
            let (t, p) = (b.topics().to_vec(), b.problems().to_vec());
            (Inner::Mcap(b), t, p)
        }
        Storage::Sqlite3 => {
            let b = sqlite::SqliteBag::open(files)?;
            let (t, p) = (b.topics().to_vec(), b.problems().to_vec());
            (Inner::Sqlite(b), t, p)
        }
        Storage::Ros1 => return open_ros1(path),
    };
    Ok(Bag {
        path: path.to_path_buf(),
        storage,
        topics,
        problems,
        notes: Vec::new(),
        inner,
    })
}

/// A ROS 2 bag folder: its `metadata.yaml` names the storage and the files.
fn open_ros2_folder(dir: &Path) -> Result<Bag> {
    let meta_path = dir.join("metadata.yaml");
    if !meta_path.is_file() {
        return Err(Error::Input(format!(
            "{}: a folder without metadata.yaml is not a ROS 2 bag",
            dir.display()
        )));
    }
    let meta = crate::files::read_text(&meta_path)?;
    let info = parse_metadata(&meta, &meta_path)?;
    let files: Vec<PathBuf> = info.files.iter().map(|f| dir.join(f)).collect();
    for f in &files {
        if !f.is_file() {
            return Err(Error::Input(format!(
                "{}: lists {}, which is missing",
                meta_path.display(),
                f.display()
            )));
        }
    }
    let (storage, note) = folder_storage(&meta_path, &info.storage, &files)?;
    let mut bag = open_ros2(dir, storage, &files)?;
    bag.notes.extend(note);
    for t in &mut bag.topics {
        if t.declared_count.is_none() {
            t.declared_count = info.counts.get(&t.name).copied();
        }
    }
    Ok(bag)
}

/// The storage of a ROS 2 bag folder's files (`files`, listed by `meta_path`, whose
/// `storage_identifier` is `declared`), with a note when `declared` says otherwise.
///
/// The files' first bytes decide: every MCAP file opens with the MCAP magic and every
/// sqlite3 database with SQLite's, so they cannot be mistaken for each other, while
/// `storage_identifier` is a label that a copied or hand-edited `metadata.yaml` can get wrong.
/// Files that are neither, or of both storages, are an error naming them.
fn folder_storage(
    meta_path: &Path,
    declared: &str,
    files: &[PathBuf],
) -> Result<(Storage, Option<String>)> {
    let named = match declared {
        "mcap" => Some(Storage::Mcap),
        "sqlite3" => Some(Storage::Sqlite3),
        _ => None,
    };
    let mut found: Vec<(&PathBuf, Storage)> = Vec::new();
    for f in files {
        let head = head_of_file(f).map_err(|e| Error::io(f, e))?;
        match Storage::of_head(&head) {
            Some(s @ (Storage::Mcap | Storage::Sqlite3)) => found.push((f, s)),
            other => {
                // Compared with what the metadata says it is, else what its name says.
                let expected = named
                    .or_else(|| Storage::of_extension(f))
                    .filter(|&s| s != Storage::Ros1)
                    .unwrap_or(Storage::Mcap);
                let what = if other == Some(Storage::Ros1) {
                    format!(
                        "not {}: it is a ROS 1 bag (read it by its own path, not through \
                         metadata.yaml)",
                        expected.file_kind()
                    )
                } else {
                    expected.magic_mismatch(&head)
                };
                return Err(Error::Input(format!(
                    "{}: {what} ({} lists it, storage_identifier {declared:?})",
                    f.display(),
                    meta_path.display()
                )));
            }
        }
    }
    let Some(&(first, storage)) = found.first() else {
        return Err(Error::Input(format!(
            "{}: relative_file_paths lists no storage file",
            meta_path.display()
        )));
    };
    if let Some((other, s)) = found.iter().find(|(_, s)| *s != storage) {
        return Err(Error::Input(format!(
            "{}: its files are of two storages: {} is {} and {} is {}",
            meta_path.display(),
            first.display(),
            storage.file_kind(),
            other.display(),
            s.file_kind()
        )));
    }
    if named == Some(storage) {
        return Ok((storage, None));
    }
    let kind = match storage {
        Storage::Sqlite3 => "sqlite3",
        _ => "mcap",
    };
    let files_word = if found.len() == 1 {
        format!("{} starts", first.display())
    } else {
        format!("its {} files start", found.len())
    };
    Ok((
        storage,
        Some(format!(
            "{}: storage_identifier is {declared:?}, but {files_word} with the magic bytes of \
             {}: read as {kind} (the magic bytes say what a file holds; ROS 2's own tools go by \
             storage_identifier, so set it to {kind})",
            meta_path.display(),
            storage.file_kind()
        )),
    ))
}

/// What dvlcal reads of a ROS 2 bag's `metadata.yaml`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Metadata {
    /// `storage_identifier`: `mcap` or `sqlite3`.
    pub storage: String,
    /// `relative_file_paths`, in order.
    pub files: Vec<String>,
    /// `message_count` of each topic in `topics_with_message_count`.
    pub counts: std::collections::BTreeMap<String, u64>,
}

/// Parses a ROS 2 bag's `metadata.yaml` (`rosbag2_bagfile_information`).
pub fn parse_metadata(text: &str, path: &Path) -> Result<Metadata> {
    let v: serde_yaml::Value = serde_yaml::from_str(text)
        .map_err(|e| Error::Input(format!("{}: not readable as YAML ({e})", path.display())))?;
    let Some(info) = v.get("rosbag2_bagfile_information") else {
        return Err(Error::Input(format!(
            "{}: no rosbag2_bagfile_information: not a ROS 2 bag's metadata",
            path.display()
        )));
    };
    let storage = info
        .get("storage_identifier")
        .and_then(|s| s.as_str())
        .unwrap_or("")
        .to_string();
    let files: Vec<String> = info
        .get("relative_file_paths")
        .and_then(|s| s.as_sequence())
        .map(|s| {
            s.iter()
                .filter_map(|f| f.as_str().map(str::to_string))
                .collect()
        })
        .unwrap_or_default();
    if files.is_empty() {
        return Err(Error::Input(format!(
            "{}: relative_file_paths lists no storage file",
            path.display()
        )));
    }
    let mut counts = std::collections::BTreeMap::new();
    if let Some(list) = info
        .get("topics_with_message_count")
        .and_then(|s| s.as_sequence())
    {
        for t in list {
            let name = t
                .get("topic_metadata")
                .and_then(|m| m.get("name"))
                .and_then(|n| n.as_str());
            let n = t.get("message_count").and_then(|n| n.as_u64());
            if let (Some(name), Some(n)) = (name, n) {
                counts.insert(name.to_string(), n);
            }
        }
    }
    Ok(Metadata {
        storage,
        files,
        counts,
    })
}
