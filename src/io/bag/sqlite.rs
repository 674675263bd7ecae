//! sqlite3 storage (ROS 2): tables `topics` and `messages`.
//!
//! rosbag2's sqlite3 storage holds `topics(id, name, type, serialization_format, ...)` and
//! `messages(id, topic_id, timestamp, data)`, with `timestamp` the record time in nanoseconds
//! and an index on it; newer versions add `schema`, `metadata` and `message_definitions`
//! tables, which are not needed here. The database is opened read-only and the messages are
//! streamed row by row from one statement in record order (`timestamp`, then `id`), so memory
//! holds one message at a time. SQLite itself checks the file's structure: a damaged page
//! gives an error, after which the file's remaining rows are read one at a time by id, stepping
//! past each row that cannot be read, and the loss is counted in the summary.
//!
//! While the bag is followed as it is recorded ([`super::memory`]), each file's slot keeps its
//! `topics` rows, the message counts per topic up to a row id, and the messages read so far
//! (a long one as its head and its row id) up to the largest row id read: an opening counts
//! only the rows above the counted id, and a pass asks SQLite only for the rows above the
//! largest id kept, merges them into what is kept in record order and hands over the lot. A
//! database whose topics, first row or last kept row are no longer what was kept (replaced,
//! shortened) is read from the start; a damaged one, or one with a row of unexpected types, is
//! read as without the memory.

use std::collections::{BTreeMap, HashSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use rusqlite::types::ValueRef;
use rusqlite::{Connection, OpenFlags};

use super::memory::{self, Kept, SlotRef};
use super::types::{BagMessage, BagReadSummary, Serialization, Topic};
use crate::error::{Error, Result};

/// One storage file: its topic ids resolved to the bag's topics.
#[derive(Debug)]
struct DbFile {
    path: PathBuf,
    /// topic id → (index into the bag's topics, whether its messages are read).
    topics: BTreeMap<i64, (usize, bool)>,
    /// Where the reads of a bag followed while recorded keep their place ([`memory`]).
    slot: Option<SlotRef>,
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
#[derive(Clone, Debug, PartialEq, Eq)]
struct TopicRow {
    id: i64,
    name: String,
    msg_type: String,
    format: String,
}

/// The message counts per topic id, or why they could not be counted.
type Counts = std::result::Result<BTreeMap<i64, u64>, String>;

/// The rows of `topics` and the number of messages per topic id.
fn read_tables(
    path: &Path,
    db: &Connection,
    slot: Option<&SlotRef>,
) -> Result<(Vec<TopicRow>, Counts)> {
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
    // One pass over the table's rows (the message data is not read), or over those above the
    // rows counted before when the file is followed. A damaged table fails here; the messages
    // are still read past the damage, so the counts are left unknown.
    let counts = match slot {
        Some(slot) => remembered_counts(db, &rows, slot),
        None => count_rows(db, None).map(|(c, _)| c),
    }
    .map_err(|e| {
        format!(
            "{}: the messages table could not be counted ({e}): it is damaged, and its \
             messages are read row by row past the damage",
            path.display()
        )
    });
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
        // Whether every file's messages could be counted.
        let mut counted = true;
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
            let slot = super::growing::slot_of(path);
            let (rows, counts) = read_tables(path, &db, slot.as_ref())?;
            let counts = match counts {
                Ok(c) => Some(c),
                Err(problem) => {
                    bag.problems.push(problem);
                    counted = false;
                    None
                }
            };
            let count_of = |id: &i64| counts.as_ref().and_then(|c| c.get(id)).copied();
            let mut file = DbFile {
                path: path.clone(),
                topics: BTreeMap::new(),
                slot,
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
                    *d = d.saturating_add(count_of(&row.id).unwrap_or(0));
                }
                file.topics.insert(row.id, (i, readable));
            }
            let orphans: u64 = counts
                .iter()
                .flatten()
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
            t.declared_count = counted.then_some(n);
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

    /// See [`super::Bag::messages`]. Each file is read in one pass in record order; when SQLite
    /// meets a damaged page, the file's remaining rows are read one by one past it (see
    /// [`salvage_keys`]), and what could not be read is counted in the summary. While the bag
    /// is followed ([`memory`]), only the rows above those kept are read, and a long message
    /// kept from before is read again only when `whole(topic, index)` says so (see
    /// [`super::Bag::messages_with`]).
    pub fn messages(
        &self,
        wanted: &dyn Fn(usize) -> bool,
        whole: &dyn Fn(usize, u64) -> bool,
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
            if let Some(kept) = file.slot.as_ref().and_then(|s| read_on(&db, s)) {
                let mut pass = Pass::new(file, &mut counts, &mut *f);
                pass.replay(&db, &kept, wanted, whole)?;
                summary.messages += pass.read;
                continue;
            }
            // The ids are integers read from the database, so they can be written into the
            // statement; the filter keeps SQLite from loading other topics' data.
            let sql = format!(
                "SELECT id, topic_id, timestamp, data FROM messages WHERE topic_id IN ({}) \
                 ORDER BY timestamp, id",
                ids.join(", ")
            );
            let mut pass = Pass::new(file, &mut counts, &mut *f);
            let failure = match db.prepare(&sql) {
                Ok(mut stmt) => pass.stream(&mut stmt)?,
                Err(e) => Some(e),
            };
            if let Some(e) = failure {
                let before = pass.read;
                match salvage_keys(&db) {
                    Ok(keys) => {
                        let lost = pass.read_by_id(&db, keys.keys)?;
                        summary.problems.push(salvage_note(
                            path,
                            &e,
                            before,
                            &pass,
                            &lost,
                            keys.lost,
                            &self.topics,
                        ));
                    }
                    Err(e2) => summary.problems.push(format!(
                        "{}: reading stopped after {before} messages ({e}), and the rows past \
                         the damage could not be found ({e2}): the rest of the file's messages \
                         are lost",
                        path.display()
                    )),
                }
            }
            summary.messages += pass.read;
            if pass.bad_rows > 0 {
                summary.problems.push(format!(
                    "{}: {} rows of the messages table are not (integer topic id, integer time \
                     stamp, blob of data): skipped",
                    path.display(),
                    pass.bad_rows
                ));
            }
        }
        Ok(summary)
    }
}

/// A row's key: (row id, topic id, time stamp).
type RowKey = (i64, i64, i64);

/// One message kept of a database followed while recorded.
#[derive(Clone, Debug)]
struct KeptRow {
    t: i64,
    id: i64,
    topic: i64,
    /// Its data; a long message's place is its row id.
    data: Kept,
}

/// What the reads of an sqlite3 database being recorded keep ([`memory`]).
#[derive(Debug)]
pub(crate) struct SqliteKept {
    /// The `topics` table.
    topics: Vec<TopicRow>,
    /// The first row of `messages` when this was begun.
    first: Option<RowKey>,
    /// Messages per topic id of the rows up to `counted_to`.
    counts: BTreeMap<i64, u64>,
    counted_to: Option<RowKey>,
    /// The rows up to `read_to`, in record order (time stamp, then row id).
    messages: Arc<Vec<KeptRow>>,
    read_to: Option<RowKey>,
}

/// The key of the row `id`, if there is one.
fn key_of(db: &Connection, id: i64) -> rusqlite::Result<Option<RowKey>> {
    db.prepare_cached("SELECT id, topic_id, timestamp FROM messages WHERE id = ?1")?
        .query([id])?
        .next()?
        .map(|r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)))
        .transpose()
}

/// The key of the first row of `messages`, if there is one.
fn first_row(db: &Connection) -> rusqlite::Result<Option<RowKey>> {
    db.prepare("SELECT id, topic_id, timestamp FROM messages ORDER BY id LIMIT 1")?
        .query([])?
        .next()?
        .map(|r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)))
        .transpose()
}

/// The messages per topic id of the rows above `above` (all when `None`), and the largest
/// row id counted.
fn count_rows(
    db: &Connection,
    above: Option<i64>,
) -> rusqlite::Result<(BTreeMap<i64, u64>, Option<i64>)> {
    let sql = match above {
        Some(_) => {
            "SELECT topic_id, COUNT(*), MAX(id) FROM messages WHERE id > ?1 GROUP BY topic_id"
        }
        None => "SELECT topic_id, COUNT(*), MAX(id) FROM messages GROUP BY topic_id",
    };
    let mut stmt = db.prepare(sql)?;
    let rows = match above {
        Some(a) => stmt.query([a])?,
        None => stmt.query([])?,
    };
    let c = rows
        .mapped(|r| {
            Ok((
                r.get::<_, i64>(0)?,
                r.get::<_, i64>(1)?,
                r.get::<_, i64>(2)?,
            ))
        })
        .collect::<rusqlite::Result<Vec<(i64, i64, i64)>>>()?;
    let last = c.iter().map(|&(_, _, m)| m).max();
    let counts = c
        .into_iter()
        .map(|(id, n, _)| (id, u64::try_from(n).unwrap_or(0)))
        .collect();
    Ok((counts, last))
}

impl SqliteKept {
    /// Whether the database `db`, whose topics are `topics` and first row `first`, still
    /// holds what is kept.
    fn holds(&self, db: &Connection, topics: &[TopicRow], first: Option<RowKey>) -> bool {
        self.topics == topics
            && self.first == first
            && [self.counted_to, self.read_to]
                .into_iter()
                .flatten()
                .all(|k| key_of(db, k.0).is_ok_and(|now| now == Some(k)))
    }
}

/// The message counts per topic id of a database followed while recorded, kept in `slot`:
/// only the rows above those counted before are counted (all of them when the database is
/// new to the slot or no longer holds what it kept, which then empties it).
fn remembered_counts(
    db: &Connection,
    topics: &[TopicRow],
    slot: &SlotRef,
) -> rusqlite::Result<BTreeMap<i64, u64>> {
    let mut slot = memory::lock(slot);
    let first = first_row(db);
    let held = first.as_ref().is_ok_and(|first| {
        slot.kept::<SqliteKept>()
            .is_some_and(|k| k.holds(db, topics, *first))
    });
    if !held {
        slot.take::<SqliteKept>();
        slot.keep(
            SqliteKept {
                topics: topics.to_vec(),
                first: first.as_ref().ok().copied().flatten(),
                counts: BTreeMap::new(),
                counted_to: None,
                messages: Arc::new(Vec::new()),
                read_to: None,
            },
            0,
        );
    }
    let at = slot
        .kept::<SqliteKept>()
        .and_then(|k| k.read_to)
        .map_or(0, |k| k.0 as u64);
    slot.resumed(at);
    let counted = first.and_then(|_| {
        let above = slot.kept::<SqliteKept>().and_then(|k| k.counted_to);
        let (more, last) = count_rows(db, above.map(|k| k.0))?;
        let to = match last {
            Some(id) => key_of(db, id)?,
            None => above,
        };
        Ok((more, to))
    });
    let Some(k) = slot.kept_mut::<SqliteKept>() else {
        return counted.map(|(c, _)| c);
    };
    match counted {
        Ok((more, to)) => {
            for (id, n) in more {
                *k.counts.entry(id).or_insert(0) += n;
            }
            k.counted_to = to;
            Ok(k.counts.clone())
        }
        Err(e) => {
            // Damaged: read as without the memory.
            slot.take::<SqliteKept>();
            Err(e)
        }
    }
}

/// A `messages` row selected as (id, topic id, time stamp, data); `None` when a column is not of
/// its type.
fn message_row<'r>(row: &'r rusqlite::Row<'_>) -> Option<(i64, i64, i64, &'r [u8])> {
    match (
        row.get_ref(0),
        row.get_ref(1),
        row.get_ref(2),
        row.get_ref(3),
    ) {
        (
            Ok(ValueRef::Integer(id)),
            Ok(ValueRef::Integer(topic)),
            Ok(ValueRef::Integer(t)),
            Ok(ValueRef::Blob(data)),
        ) => Some((id, topic, t, data)),
        _ => None,
    }
}

/// The rows above `above` (all when `None`) of `messages`, in row id order; `None` when one
/// cannot be read or is not (integer topic id, integer time stamp, blob of data).
fn read_rows(db: &Connection, above: Option<i64>) -> Option<Vec<KeptRow>> {
    let sql = match above {
        Some(_) => "SELECT id, topic_id, timestamp, data FROM messages WHERE id > ?1 ORDER BY id",
        None => "SELECT id, topic_id, timestamp, data FROM messages ORDER BY id",
    };
    let mut stmt = db.prepare(sql).ok()?;
    let mut rows = match above {
        Some(a) => stmt.query([a]),
        None => stmt.query([]),
    }
    .ok()?;
    let mut out = Vec::new();
    while let Some(row) = rows.next().ok()? {
        let (id, topic, t, data) = message_row(row)?;
        out.push(KeptRow {
            t,
            id,
            topic,
            data: Kept::of(data, id as u64),
        });
    }
    Some(out)
}

/// The rows of the database followed in `slot`, read on from those kept: SQLite is asked only
/// for the rows above the largest id kept, which are added to what is kept. `None` when the
/// slot keeps nothing, or the rows could not be read (then it is emptied, and the database is
/// read as without the memory).
fn read_on(db: &Connection, slot: &SlotRef) -> Option<Arc<Vec<KeptRow>>> {
    let mut slot = memory::lock(slot);
    let above = slot.kept::<SqliteKept>()?.read_to;
    let Some(new) = read_rows(db, above.map(|k| k.0)) else {
        slot.take::<SqliteKept>();
        return None;
    };
    let n = new.len() as u64;
    let first = new.first().map(|r| r.id);
    let k = slot.kept_mut::<SqliteKept>()?;
    if let Some(last) = new.last() {
        k.read_to = Some((last.id, last.topic, last.t));
        let m = Arc::make_mut(&mut k.messages);
        m.extend(new);
        m.sort_by_key(|r| (r.t, r.id));
    }
    let (kept, to) = (k.messages.clone(), k.read_to.map_or(0, |r| r.0 as u64));
    slot.rows_read(n, first);
    slot.kept_to(to);
    Some(kept)
}

/// Largest number of row ids in a row that cannot be read before the rest of a damaged table
/// is given up (each costs one lookup; a destroyed interior page can hide many rows).
const MAX_UNREADABLE_IN_A_ROW: u64 = 100_000;

/// One pass over the messages of one storage file.
struct Pass<'a> {
    file: &'a DbFile,
    /// Messages handed out so far, per topic of the bag (they number the messages).
    counts: &'a mut [u64],
    f: &'a mut dyn FnMut(BagMessage<'_>) -> Result<()>,
    /// Messages of this file handed out.
    read: u64,
    /// Rows whose columns are not of the expected types.
    bad_rows: u64,
    /// Row ids handed out (so that a second pass past damage skips them).
    delivered: HashSet<i64>,
}

impl<'a> Pass<'a> {
    /// A pass over `file` that has handed out nothing yet.
    fn new(
        file: &'a DbFile,
        counts: &'a mut [u64],
        f: &'a mut dyn FnMut(BagMessage<'_>) -> Result<()>,
    ) -> Pass<'a> {
        Pass {
            file,
            counts,
            f,
            read: 0,
            bad_rows: 0,
            delivered: HashSet::new(),
        }
    }

    /// Hands one row to the callback, numbered within its topic.
    fn deliver(&mut self, row_id: i64, topic_id: i64, t: i64, data: &[u8]) -> Result<()> {
        let Some(&(topic, _)) = self.file.topics.get(&topic_id) else {
            return Ok(());
        };
        let Some(n) = self.counts.get_mut(topic) else {
            return Ok(());
        };
        *n += 1;
        self.read += 1;
        self.delivered.insert(row_id);
        (self.f)(BagMessage {
            topic,
            log_time_ns: t,
            data,
            index: *n,
            whole: true,
        })
    }

    /// Hands over the kept rows `kept` (in record order) of the topics read and `wanted`; a
    /// long message is read again by its row id when `whole` asks for it.
    fn replay(
        &mut self,
        db: &Connection,
        kept: &[KeptRow],
        wanted: &dyn Fn(usize) -> bool,
        whole: &dyn Fn(usize, u64) -> bool,
    ) -> Result<()> {
        let path = &self.file.path;
        let mut fetch = None;
        for row in kept {
            let Some(&(topic, true)) = self.file.topics.get(&row.topic) else {
                continue;
            };
            if !wanted(topic) {
                continue;
            }
            let Some(n) = self.counts.get(topic).map(|n| n + 1) else {
                continue;
            };
            let again;
            let (data, is_whole) = match &row.data {
                Kept::Whole(b) => (b.as_slice(), true),
                Kept::Head { len, .. } if whole(topic, n) => {
                    let stmt = match &mut fetch {
                        Some(s) => s,
                        None => fetch.insert(
                            db.prepare("SELECT data FROM messages WHERE id = ?1")
                                .map_err(|e| db_err(path, e))?,
                        ),
                    };
                    again = stmt
                        .query_row([row.id], |r| r.get::<_, Vec<u8>>(0))
                        .ok()
                        .filter(|d| d.len() == *len)
                        .ok_or_else(|| {
                            Error::Input(format!(
                                "{}: the message in row {} changed while the database was \
                                 followed",
                                path.display(),
                                row.id
                            ))
                        })?;
                    (again.as_slice(), true)
                }
                Kept::Head { head, .. } => (head.as_slice(), false),
            };
            if let Some(c) = self.counts.get_mut(topic) {
                *c = n;
            }
            self.read += 1;
            (self.f)(BagMessage {
                topic,
                log_time_ns: row.t,
                data,
                index: n,
                whole: is_whole,
            })?;
        }
        Ok(())
    }

    /// Streams the rows of `stmt` (id, topic id, time stamp, data); returns SQLite's error when
    /// it stops early.
    fn stream(&mut self, stmt: &mut rusqlite::Statement<'_>) -> Result<Option<rusqlite::Error>> {
        let mut rows = match stmt.query([]) {
            Ok(r) => r,
            Err(e) => return Ok(Some(e)),
        };
        loop {
            let row = match rows.next() {
                Ok(Some(row)) => row,
                Ok(None) => return Ok(None),
                Err(e) => return Ok(Some(e)),
            };
            match message_row(row) {
                Some((row_id, id, t, data)) => self.deliver(row_id, id, t, data)?,
                None => self.bad_rows += 1,
            }
        }
    }

    /// Reads the rows `keys` (time stamp, row id, topic id) not yet handed out, of the topics
    /// read, one by one in record order; returns the number per topic id that could not be read.
    fn read_by_id(
        &mut self,
        db: &Connection,
        mut keys: Vec<(i64, i64, i64)>,
    ) -> Result<BTreeMap<i64, u64>> {
        let path = &self.file.path;
        let mut lost = BTreeMap::new();
        keys.retain(|(_, row_id, topic_id)| {
            !self.delivered.contains(row_id)
                && self.file.topics.get(topic_id).is_some_and(|(_, r)| *r)
        });
        keys.sort_unstable();
        let mut stmt = db
            .prepare("SELECT data FROM messages WHERE id = ?1")
            .map_err(|e| db_err(path, e))?;
        for (t, row_id, topic_id) in keys {
            let mut rows = match stmt.query([row_id]) {
                Ok(r) => r,
                Err(_) => {
                    *lost.entry(topic_id).or_insert(0) += 1;
                    continue;
                }
            };
            match rows.next() {
                Ok(Some(row)) => match row.get_ref(0) {
                    Ok(ValueRef::Blob(data)) => self.deliver(row_id, topic_id, t, data)?,
                    _ => self.bad_rows += 1,
                },
                Ok(None) | Err(_) => *lost.entry(topic_id).or_insert(0) += 1,
            }
        }
        Ok(lost)
    }
}

/// The keys of the rows of a damaged messages table, and the row ids that could not be read.
struct Salvage {
    /// (time stamp, row id, topic id) of every row read.
    keys: Vec<(i64, i64, i64)>,
    /// Row ids at which reading failed (rosbag2 numbers its rows without gaps, so each is a
    /// message lost; its topic is unknown).
    lost: u64,
}

/// The keys of every row of the messages table that SQLite can still reach: the table is read
/// in row id order, and wherever a read fails it starts again at the next row id, so one
/// damaged page costs only the rows it holds. Row ids up to the largest are tried, at most
/// [`MAX_UNREADABLE_IN_A_ROW`] failing ones in a row (the rest are then counted as lost).
fn salvage_keys(db: &Connection) -> rusqlite::Result<Salvage> {
    let bound = |sql: &str| db.query_row(sql, [], |r| r.get::<_, Option<i64>>(0));
    let mut out = Salvage {
        keys: Vec::new(),
        lost: 0,
    };
    let (Some(mut next), Some(last)) = (
        bound("SELECT min(id) FROM messages")?,
        bound("SELECT max(id) FROM messages")?,
    ) else {
        return Ok(out);
    };
    let mut stmt =
        db.prepare("SELECT id, topic_id, timestamp FROM messages WHERE id >= ?1 ORDER BY id")?;
    let mut failing = 0u64;
    while next <= last {
        if let Ok(mut rows) = stmt.query([next]) {
            loop {
                match rows.next() {
                    Ok(Some(row)) => {
                        let id: i64 = row.get(0)?;
                        if let (Ok(ValueRef::Integer(topic)), Ok(ValueRef::Integer(t))) =
                            (row.get_ref(1), row.get_ref(2))
                        {
                            out.keys.push((t, id, topic));
                        }
                        failing = 0;
                        match id.checked_add(1) {
                            Some(n) => next = n,
                            None => return Ok(out),
                        }
                    }
                    Ok(None) => return Ok(out),
                    Err(_) => break,
                }
            }
        }
        // The row at `next` cannot be read: step past it.
        out.lost += 1;
        failing += 1;
        if failing >= MAX_UNREADABLE_IN_A_ROW {
            out.lost += u64::try_from(last - next).unwrap_or(0);
            return Ok(out);
        }
        next += 1;
    }
    Ok(out)
}

/// What a damaged file cost: `e` stopped the pass in record order after `before` messages;
/// the rows past the damage were read one by one.
fn salvage_note(
    path: &Path,
    e: &rusqlite::Error,
    before: u64,
    pass: &Pass<'_>,
    lost: &BTreeMap<i64, u64>,
    unreachable: u64,
    topics: &[Topic],
) -> String {
    let lost_known: u64 = lost.values().sum();
    let mut s = format!(
        "{}: damaged ({e}): reading in record order stopped after {before} messages; reading \
         row by row past the damage gave {} more. Lost: {}",
        path.display(),
        pass.read - before,
        plural(lost_known + unreachable, "message")
    );
    let mut parts: Vec<String> = lost
        .iter()
        .map(|(id, n)| {
            let name = pass
                .file
                .topics
                .get(id)
                .and_then(|(t, _)| topics.get(*t))
                .map_or_else(|| format!("topic id {id}"), |t| t.name.clone());
            format!("{n} of {name}")
        })
        .collect();
    if unreachable > 0 {
        parts.push(format!(
            "{} of unknown topic that could not be read",
            plural(unreachable, "row")
        ));
    }
    if !parts.is_empty() {
        s.push_str(&format!(" ({})", parts.join(", ")));
    }
    s
}

/// `n` and `what`, with an `s` unless `n` is 1.
fn plural(n: u64, what: &str) -> String {
    format!("{n} {what}{}", if n == 1 { "" } else { "s" })
}
