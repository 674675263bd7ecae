//! sqlite3 storage (ROS 2): tables `topics` and `messages`.
//!
//! rosbag2's sqlite3 storage holds `topics(id, name, type, serialization_format, ...)` and
//! `messages(id, topic_id, timestamp, data)`, with `timestamp` the record time in nanoseconds
//! and an index on it; newer versions add `schema`, `metadata` and `message_definitions`
//! tables, which are not needed here. The database is opened read-only and the messages are
//! streamed row by row from one statement in record order (`timestamp`, then `id`), so memory
//! holds one message at a time. SQLite itself checks the file's structure: a damaged database
//! gives errors, which end the pass over that file with a description of what was read.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use rusqlite::types::ValueRef;
use rusqlite::{Connection, OpenFlags};

use super::types::{BagMessage, BagReadSummary, Serialization, Topic};
use crate::error::{Error, Result};

/// One storage file: its topic ids resolved to the bag's topics.
#[derive(Debug)]
struct DbFile {
    path: PathBuf,
    /// topic id → (index into the bag's topics, whether its messages are read).
    topics: BTreeMap<i64, (usize, bool)>,
}

/// The storage files of one ROS 2 bag, opened.
#[derive(Debug)]
pub struct SqliteBag {
    files: Vec<DbFile>,
    topics: Vec<Topic>,
    problems: Vec<String>,
}

/// An error of SQLite on `path`, naming the file.
fn db_err(path: &Path, e: rusqlite::Error) -> Error {
    Error::Input(format!("{}: {e}", path.display()))
}

fn open_db(path: &Path) -> Result<Connection> {
    Connection::open_with_flags(
        path,
        OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX,
    )
    .map_err(|e| db_err(path, e))
}

/// A column as text, whatever SQLite stored in it.
fn text(v: ValueRef<'_>) -> String {
    match v {
        ValueRef::Text(t) | ValueRef::Blob(t) => String::from_utf8_lossy(t).into_owned(),
        ValueRef::Integer(i) => i.to_string(),
        ValueRef::Real(r) => r.to_string(),
        ValueRef::Null => String::new(),
    }
}

/// One row of the `topics` table.
struct TopicRow {
    id: i64,
    name: String,
    msg_type: String,
    format: String,
}

/// The rows of `topics` and the number of messages per topic id.
fn read_tables(path: &Path, db: &Connection) -> Result<(Vec<TopicRow>, BTreeMap<i64, u64>)> {
    let tables: Vec<String> = db
        .prepare("SELECT name FROM sqlite_master WHERE type = 'table'")
        .and_then(|mut s| {
            s.query_map([], |r| r.get_ref(0).map(text))?
                .collect::<rusqlite::Result<Vec<String>>>()
        })
        .map_err(|e| db_err(path, e))?;
    let missing: Vec<&str> = ["topics", "messages"]
        .into_iter()
        .filter(|t| !tables.iter().any(|n| n == t))
        .collect();
    if !missing.is_empty() {
        return Err(Error::Input(format!(
            "{}: an sqlite3 database without the table{} {}: not a ROS 2 bag",
            path.display(),
            if missing.len() > 1 { "s" } else { "" },
            missing.join(" and ")
        )));
    }
    let rows = db
        .prepare("SELECT id, name, type, serialization_format FROM topics ORDER BY id")
        .and_then(|mut s| {
            s.query_map([], |r| {
                Ok(TopicRow {
                    id: r.get(0)?,
                    name: r.get_ref(1).map(text)?,
                    msg_type: r.get_ref(2).map(text)?,
                    format: r.get_ref(3).map(text)?,
                })
            })?
            .collect::<rusqlite::Result<Vec<TopicRow>>>()
        })
        .map_err(|e| db_err(path, e))?;
    // One pass over the table's rows (the message data is not read).
    let counts = db
        .prepare("SELECT topic_id, COUNT(*) FROM messages GROUP BY topic_id")
        .and_then(|mut s| {
            s.query_map([], |r| Ok((r.get::<_, i64>(0)?, r.get::<_, i64>(1)?)))?
                .collect::<rusqlite::Result<Vec<(i64, i64)>>>()
        })
        .map_err(|e| db_err(path, e))?
        .into_iter()
        .map(|(id, n)| (id, u64::try_from(n).unwrap_or(0)))
        .collect();
    Ok((rows, counts))
}

/// How much shorter the file is than its header declares (page size times page count), when
/// the header's page count is valid: a database cut short.
fn missing_bytes(path: &Path) -> Result<Option<(u64, u64)>> {
    use std::io::Read;
    let mut head = [0u8; 100];
    let mut f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let len = f.metadata().map_err(|e| Error::io(path, e))?.len();
    if f.read_exact(&mut head).is_err() {
        return Ok(None);
    }
    let be32 = |at: usize| {
        head.get(at..at + 4)
            .and_then(|b| b.try_into().ok())
            .map(u32::from_be_bytes)
    };
    let page_size = match head.get(16..18).map(|b| u16::from_be_bytes([b[0], b[1]])) {
        Some(1) => 65536u64,
        Some(n) => u64::from(n),
        None => return Ok(None),
    };
    // The page count is valid when "version-valid-for" equals the change counter.
    let (Some(pages), Some(changes), Some(valid_for)) = (be32(28), be32(24), be32(92)) else {
        return Ok(None);
    };
    let declared = page_size * u64::from(pages);
    Ok((changes == valid_for && pages > 0 && len < declared).then_some((len, declared)))
}

impl SqliteBag {
    /// Opens the storage files of one bag (in order) and reads their topics.
    pub fn open(files: &[PathBuf]) -> Result<SqliteBag> {
        if files.is_empty() {
            return Err(Error::Input(
                "an sqlite3 bag needs at least one file".into(),
            ));
        }
        let mut bag = SqliteBag {
            files: Vec::new(),
            topics: Vec::new(),
            problems: Vec::new(),
        };
        let mut declared: Vec<u64> = Vec::new();
        for path in files {
            // SQLite reads the missing pages of a cut database as zeros, which can give
            // messages of zeros rather than an error: such a file is refused.
            if let Some((len, declared)) = missing_bytes(path)? {
                return Err(Error::Input(format!(
                    "{}: the database is {len} bytes, shorter than the {declared} its header \
                     declares: the file was cut (copied in part?), and SQLite would read its \
                     missing pages as zeros; `sqlite3 {} .recover` saves what it can",
                    path.display(),
                    path.display()
                )));
            }
            let db = open_db(path)?;
            let (rows, counts) = read_tables(path, &db)?;
            let mut file = DbFile {
                path: path.clone(),
                topics: BTreeMap::new(),
            };
            for row in rows {
                let ser = match row.format.as_str() {
                    "cdr" => Some(Serialization::Cdr),
                    "ros1" => Some(Serialization::Ros1),
                    _ => None,
                };
                let i = match bag
                    .topics
                    .iter()
                    .position(|t| t.name == row.name && t.msg_type == row.msg_type)
                {
                    Some(i) => i,
                    None => {
                        bag.topics.push(Topic {
                            name: row.name.clone(),
                            msg_type: row.msg_type.clone(),
                            serialization: ser.unwrap_or(Serialization::Cdr),
                            declared_count: None,
                        });
                        declared.push(0);
                        bag.topics.len() - 1
                    }
                };
                let readable = match ser {
                    None => {
                        bag.problems.push(format!(
                            "{}: topic {} ({}) has serialization format {:?}, which is \
                             neither cdr nor ros1: it is listed but its messages are not read",
                            path.display(),
                            row.name,
                            row.msg_type,
                            row.format
                        ));
                        false
                    }
                    Some(s) if bag.topics.get(i).is_some_and(|t| t.serialization != s) => {
                        bag.problems.push(format!(
                            "{}: topic {} is stored as {:?}, unlike in an earlier file: its \
                             messages in this file are not read",
                            path.display(),
                            row.name,
                            row.format
                        ));
                        false
                    }
                    Some(_) => true,
                };
                if let Some(d) = declared.get_mut(i) {
                    *d = d.saturating_add(counts.get(&row.id).copied().unwrap_or(0));
                }
                file.topics.insert(row.id, (i, readable));
            }
            let orphans: u64 = counts
                .iter()
                .filter(|(id, _)| !file.topics.contains_key(id))
                .map(|(_, n)| *n)
                .sum();
            if orphans > 0 {
                bag.problems.push(format!(
                    "{}: {orphans} messages belong to no topic of the topics table: they are \
                     not read",
                    path.display()
                ));
            }
            bag.files.push(file);
        }
        for (t, n) in bag.topics.iter_mut().zip(declared) {
            t.declared_count = Some(n);
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
            let ids: Vec<String> = file
                .topics
                .iter()
                .filter(|(_, (t, readable))| *readable && wanted(*t))
                .map(|(id, _)| id.to_string())
                .collect();
            if ids.is_empty() {
                continue;
            }
            let path = &file.path;
            let db = open_db(path)?;
            // The ids are integers read from the database, so they can be written into the
            // statement; the filter keeps SQLite from loading other topics' data.
            let sql = format!(
                "SELECT topic_id, timestamp, data FROM messages WHERE topic_id IN ({}) \
                 ORDER BY timestamp, id",
                ids.join(", ")
            );
            let mut read = 0u64;
            let mut bad_rows = 0u64;
            let mut stmt = match db.prepare(&sql) {
                Ok(s) => s,
                Err(e) => {
                    summary.problems.push(format!(
                        "{}: its messages could not be read ({e}): all are lost",
                        path.display()
                    ));
                    continue;
                }
            };
            let mut rows = match stmt.query([]) {
                Ok(r) => r,
                Err(e) => {
                    summary.problems.push(format!(
                        "{}: its messages could not be read ({e}): all are lost",
                        path.display()
                    ));
                    continue;
                }
            };
            loop {
                let row = match rows.next() {
                    Ok(Some(row)) => row,
                    Ok(None) => break,
                    Err(e) => {
                        summary.problems.push(format!(
                            "{}: reading stopped after {read} messages ({e}): the rest of the \
                             file's messages are lost",
                            path.display()
                        ));
                        break;
                    }
                };
                let (Ok(ValueRef::Integer(id)), Ok(ValueRef::Integer(t)), Ok(ValueRef::Blob(data))) =
                    (row.get_ref(0), row.get_ref(1), row.get_ref(2))
                else {
                    bad_rows += 1;
                    continue;
                };
                let Some(&(topic, _)) = file.topics.get(&id) else {
                    continue;
                };
                let Some(n) = counts.get_mut(topic) else {
                    continue;
                };
                *n += 1;
                read += 1;
                summary.messages += 1;
                f(BagMessage {
                    topic,
                    log_time_ns: t,
                    data,
                    index: *n,
                })?;
            }
            if bad_rows > 0 {
                summary.problems.push(format!(
                    "{}: {bad_rows} rows of the messages table are not (integer topic id, \
                     integer time stamp, blob of data): skipped",
                    path.display()
                ));
            }
        }
        Ok(summary)
    }
}
