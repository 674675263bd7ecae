//! What the reads of a bag being recorded keep between updates (`dvlcal watch BAG`), so that an
//! update reads only what was appended since the last one.
//!
//! A [`BagMemory`] is held by the watcher for the whole watch, one slot per storage file. While
//! an update reads the bag, its files' lengths are fixed with the memory attached
//! ([`super::growing::FixedLengths::fix_remembering`]); the ROS 1 and MCAP readers then find
//! their file's slot and:
//!
//! - check that the file still starts with the bytes they consumed before ([`Prefix`]: its
//!   length did not shrink, and its first and last few kB before the saved offset are the
//!   same); if not (a file replaced, `rosbag` rewriting its header when it closes the bag),
//!   the slot is emptied and the file read from its start;
//! - replay what they kept of the records up to the saved offset (the top-level records, the
//!   records of every whole chunk, decoded) and parse the file only from there;
//! - keep what they parsed whole and undamaged, up to the last complete record.
//!
//! A message longer than [`HEAD`] bytes (an image) is kept as its first [`HEAD`] bytes and its
//! place in the file (or in its chunk); its bytes are read again only when a reader asks for the
//! whole message ([`super::Bag::messages_with`]), which the image readers do only for the
//! frames whose detections are not kept yet. The last chunk, which a recorder has not finished,
//! is never kept: each read decodes it again, as before.
//!
//! The sqlite3 reader ([`super::sqlite`]) keeps here, per database, its `topics` rows, the
//! message counts per topic and the messages read (a long one as its [`HEAD`] and its row id,
//! [`Kept::Head`]'s `at`), and asks SQLite only for the rows above the largest row id kept
//! (SQLite reads a database being written as of its last commit); a database whose topics,
//! first row or last kept row changed is read from its start. Its [`SlotStats::kept_to`] and
//! [`SlotStats::resumed_at`] are row ids, and [`SlotStats::rows_read`] counts the rows read.

use std::collections::HashMap;
use std::fs::File;
use std::hash::{Hash, Hasher};
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// Messages longer than this are kept as their first `HEAD` bytes and their place; a message
/// header (stamp, frame id) fits in it.
pub const HEAD: usize = 4096;

/// How many bytes at a file's start, and before the saved offset, are compared.
const CHECKED: u64 = 4096;

/// A kept message's bytes: all of them, or the first [`HEAD`] with the message's place.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Kept {
    /// The whole message.
    Whole(Vec<u8>),
    /// The first [`HEAD`] bytes of a longer message, `len` bytes long, starting at byte `at`
    /// of its chunk's records (or of the file, for a message outside any chunk; for an sqlite3
    /// database, `at` is the message's row id).
    Head {
        /// The first [`HEAD`] bytes.
        head: Vec<u8>,
        /// Where the message's bytes start.
        at: u64,
        /// The message's length.
        len: usize,
    },
}

impl Kept {
    /// `data`, starting at `at`, kept.
    pub(crate) fn of(data: &[u8], at: u64) -> Kept {
        if data.len() <= HEAD {
            Kept::Whole(data.to_vec())
        } else {
            Kept::Head {
                head: data[..HEAD].to_vec(),
                at,
                len: data.len(),
            }
        }
    }
}

/// What a file looked like up to the offset its reader got to.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct Prefix {
    /// The offset.
    pub(crate) len: u64,
    /// A hash of the file's first bytes and of those before `len`.
    hash: u64,
}

/// A hash of `file`'s first [`CHECKED`] bytes and the [`CHECKED`] before `len`.
fn prefix_hash(file: &mut File, len: u64) -> std::io::Result<u64> {
    let mut h = std::hash::DefaultHasher::new();
    for (at, n) in [
        (0, len.min(CHECKED)),
        (len.saturating_sub(CHECKED), len.min(CHECKED)),
    ] {
        let mut buf = Vec::with_capacity(n as usize);
        file.seek(SeekFrom::Start(at))?;
        let got = file.by_ref().take(n).read_to_end(&mut buf)?;
        if got as u64 != n {
            return Err(std::io::ErrorKind::UnexpectedEof.into());
        }
        buf.hash(&mut h);
    }
    Ok(h.finish())
}

impl Prefix {
    /// `path` as it is now up to `len`.
    pub(crate) fn of(path: &Path, len: u64) -> std::io::Result<Prefix> {
        let mut f = File::open(path)?;
        Ok(Prefix {
            len,
            hash: prefix_hash(&mut f, len)?,
        })
    }

    /// Whether `path`, readable to `file_len`, still starts as it did.
    pub(crate) fn holds(&self, path: &Path, file_len: u64) -> bool {
        file_len >= self.len
            && File::open(path)
                .and_then(|mut f| prefix_hash(&mut f, self.len))
                .is_ok_and(|h| h == self.hash)
    }
}

/// One file's slot: what is kept, and what the reads cost.
#[derive(Debug, Default)]
pub(crate) struct Slot {
    /// What the file's reader keeps (its own type: the ROS 1 reader's, the MCAP reader's).
    kept: Option<Box<dyn std::any::Any + Send>>,
    pub(crate) stats: SlotStats,
}

/// What the reads of one file with a [`BagMemory`] cost.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SlotStats {
    /// The offset the last opening of the file began parsing at: 0 when it read the file
    /// from its start, the end of what was kept when it read on from there.
    pub resumed_at: u64,
    /// Chunks decompressed (or read whole) since the memory was made.
    pub chunks_decoded: u64,
    /// The offset of the first chunk decoded since the last opening (`None`: none was).
    pub first_decoded: Option<u64>,
    /// The offset up to which the file is kept now (for an sqlite3 database, the largest
    /// row id kept; `resumed_at` is the one kept before the last opening).
    pub kept_to: u64,
    /// Rows of an sqlite3 database that SQLite handed over since the memory was made.
    pub rows_read: u64,
    /// The smallest row id SQLite handed over since the last opening (`None`: none).
    pub first_row_read: Option<i64>,
}

impl Slot {
    /// What is kept, when it is a `T`.
    pub(crate) fn kept<T: 'static>(&self) -> Option<&T> {
        self.kept.as_ref()?.downcast_ref()
    }

    /// What is kept, when it is a `T`, to change.
    pub(crate) fn kept_mut<T: 'static>(&mut self) -> Option<&mut T> {
        self.kept.as_mut()?.downcast_mut()
    }

    /// What is kept, taken out when it is a `T` (the slot is then empty either way).
    pub(crate) fn take<T: 'static>(&mut self) -> Option<T> {
        self.stats.kept_to = 0;
        self.kept.take()?.downcast().ok().map(|b| *b)
    }

    /// Keeps `kept`, which holds the file up to `to`.
    pub(crate) fn keep<T: Send + 'static>(&mut self, kept: T, to: u64) {
        self.kept = Some(Box::new(kept));
        self.stats.kept_to = to;
    }

    /// Notes that what is kept now holds the file up to `to`.
    pub(crate) fn kept_to(&mut self, to: u64) {
        self.stats.kept_to = to;
    }

    /// Notes an opening that parses the file from `at`.
    pub(crate) fn resumed(&mut self, at: u64) {
        self.stats.resumed_at = at;
        self.stats.first_decoded = None;
        self.stats.first_row_read = None;
    }

    /// Counts `n` rows of an sqlite3 database read, the first with row id `first`.
    pub(crate) fn rows_read(&mut self, n: u64, first: Option<i64>) {
        self.stats.rows_read += n;
        if let Some(f) = first {
            self.stats.first_row_read = Some(self.stats.first_row_read.map_or(f, |g| g.min(f)));
        }
    }

    /// Counts the chunk at `at` decoded.
    pub(crate) fn decoded(&mut self, at: u64) {
        self.stats.chunks_decoded += 1;
        self.stats.first_decoded = Some(self.stats.first_decoded.map_or(at, |f| f.min(at)));
    }
}

/// A shared handle on one file's slot.
pub(crate) type SlotRef = Arc<Mutex<Slot>>;

/// Locks a slot (a reader that panicked left it whole enough: at worst it is read again).
pub(crate) fn lock(slot: &SlotRef) -> std::sync::MutexGuard<'_, Slot> {
    slot.lock().unwrap_or_else(|p| p.into_inner())
}

/// What the reads of one bag keep between updates: a slot per storage file, by its path.
/// Clones share one memory.
#[derive(Clone, Debug, Default)]
pub struct BagMemory(Arc<Mutex<HashMap<PathBuf, SlotRef>>>);

impl BagMemory {
    /// The slot of `path` (made empty when new).
    pub(crate) fn slot(&self, path: &Path) -> SlotRef {
        let mut map = self.0.lock().unwrap_or_else(|p| p.into_inner());
        map.entry(path.to_path_buf()).or_default().clone()
    }

    /// The slot kept for `from` moved to `to` (a bag renamed: `NAME.bag.active` to
    /// `NAME.bag`; the reader checks the bytes before it uses what was kept).
    pub fn rebase(&self, from: &Path, to: &Path) {
        let mut map = self.0.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(s) = map.remove(from) {
            map.insert(to.to_path_buf(), s);
        }
    }

    /// What the reads of `path` cost (`None`: it was never read with this memory).
    pub fn stats(&self, path: &Path) -> Option<SlotStats> {
        let map = self.0.lock().unwrap_or_else(|p| p.into_inner());
        let s = lock(map.get(path)?);
        Some(s.stats)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::bag::Bag;
    use crate::io::bag::growing::FixedLengths;

    /// One message as a pass hands it over: topic, number, time, bytes, whether whole.
    type Seen = (usize, u64, i64, Vec<u8>, bool);

    /// The topics, the problems of opening and of a pass, and the messages of `path` (each
    /// whole when `whole`, else only when a reader must read it again).
    fn read(path: &Path, whole: bool) -> (Vec<String>, Vec<String>, Vec<Seen>) {
        let bag = Bag::open(path).expect("bag");
        let mut seen = Vec::new();
        let s = bag
            .messages_with(&|_| true, &|_, _| whole, &mut |m| {
                seen.push((m.topic, m.index, m.log_time_ns, m.data.to_vec(), m.whole));
                Ok(())
            })
            .expect("pass");
        let topics = bag.topics().iter().map(|t| t.name.clone()).collect();
        let mut problems = bag.problems().to_vec();
        problems.extend(s.problems);
        (topics, problems, seen)
    }

    /// `path` read with `memory` attached, as an update reads it.
    fn read_remembering(
        path: &Path,
        memory: &BagMemory,
        whole: bool,
    ) -> (Vec<String>, Vec<String>, Vec<Seen>) {
        let fixed = FixedLengths::fix_remembering(&[path.to_path_buf()], memory);
        let r = read(path, whole);
        drop(fixed);
        r
    }

    /// Writes `bytes` to `path`, appended: the file holds `bytes[..to]` after.
    fn grow_to(path: &Path, bytes: &[u8], to: usize) {
        use std::io::Write;
        let now = std::fs::metadata(path).map_or(0, |m| m.len() as usize);
        let mut f = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .expect("open");
        f.write_all(&bytes[now..to]).expect("append");
    }

    /// A read with the memory hands over what a read of the file alone does: the same topics,
    /// problems and messages; a long message left unread is its first bytes.
    fn same_as_alone(path: &Path, memory: &BagMemory) {
        let alone = read(path, true);
        assert_eq!(read_remembering(path, memory, true), alone);
        let (topics, problems, seen) = read_remembering(path, memory, false);
        assert_eq!((&topics, &problems), (&alone.0, &alone.1));
        assert_eq!(seen.len(), alone.2.len());
        for (s, a) in seen.iter().zip(&alone.2) {
            assert_eq!((s.0, s.1, s.2), (a.0, a.1, a.2));
            if s.4 {
                assert_eq!(s.3, a.3);
            } else {
                assert!(a.3.len() > HEAD && s.3 == a.3[..HEAD], "a head");
            }
        }
    }

    /// A bag appended to in three pieces and read with a memory after each: every read equals
    /// a read of the file alone, the second and third parse only from where the one before
    /// stopped (no chunk before it decoded), and a changed start is read from the start.
    fn follows(sample: &str, tag: &str, change_at: usize) {
        let src = Path::new(env!("CARGO_MANIFEST_DIR")).join(sample);
        let bytes = std::fs::read(&src).expect("sample");
        let dir = std::env::temp_dir().join(format!("dvlcal-mem-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("folder");
        let f = dir.join(src.file_name().expect("name"));
        let memory = BagMemory::default();
        let mut kept_to = 0;
        for (k, frac) in [0.4, 0.7, 1.0].into_iter().enumerate() {
            grow_to(&f, &bytes, (bytes.len() as f64 * frac) as usize);
            let before = memory.stats(&f).map_or(0, |s| s.chunks_decoded);
            // The first read after the append: its open and one pass.
            read_remembering(&f, &memory, false);
            let s = memory.stats(&f).expect("read with the memory");
            if k == 0 {
                assert_eq!(s.resumed_at, 0);
            } else {
                assert!(
                    kept_to > 0 && s.resumed_at == kept_to,
                    "{s:?} after {kept_to}"
                );
                assert!(s.first_decoded.is_none_or(|at| at >= kept_to), "{s:?}");
            }
            assert!(s.kept_to > kept_to && s.chunks_decoded > before, "{s:?}");
            same_as_alone(&f, &memory);
            kept_to = memory.stats(&f).expect("read").kept_to;
        }
        // Its start rewritten (as rosbag rewrites a bag's header when it closes it): read from
        // the start, and the same as alone.
        let mut changed = bytes.clone();
        changed[change_at] ^= 0x01;
        std::fs::write(&f, &changed).expect("write");
        read_remembering(&f, &memory, false);
        assert_eq!(memory.stats(&f).expect("read").resumed_at, 0);
        same_as_alone(&f, &memory);
        // Shortened: read from the start.
        std::fs::write(&f, &bytes[..bytes.len() / 2]).expect("write");
        read_remembering(&f, &memory, false);
        assert_eq!(memory.stats(&f).expect("read").resumed_at, 0);
        same_as_alone(&f, &memory);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_ros1_bag_appended_to_is_read_on_from_where_the_last_read_stopped() {
        // Byte 0x28: inside the bag header's index_pos (rosbag writes it at the end).
        follows("sample_data/bags/stereo_ros1.bag", "ros1", 0x28);
    }

    #[test]
    fn an_mcap_file_appended_to_is_read_on_from_where_the_last_read_stopped() {
        // Byte 0x1c: inside the Header record's library string.
        follows(
            "sample_data/bags/stereo_mcap/stereo_mcap.mcap",
            "mcap",
            0x1c,
        );
    }

    /// `f` made a copy of the database `src` holding only its rows up to id `upto`.
    fn db_upto(src: &Path, f: &Path, upto: i64) {
        std::fs::copy(src, f).expect("copy");
        let db = rusqlite::Connection::open(f).expect("open");
        db.execute("DELETE FROM messages WHERE id > ?1", [upto])
            .expect("delete");
    }

    /// The rows of `src` above id `from` up to `to` written into `f`, as a recorder commits
    /// a batch.
    fn db_append(src: &Path, f: &Path, from: i64, to: i64) {
        let db = rusqlite::Connection::open(f).expect("open");
        db.execute("ATTACH DATABASE ?1 AS src", [src.to_str().expect("utf-8")])
            .expect("attach");
        db.execute(
            "INSERT INTO messages SELECT * FROM src.messages WHERE id > ?1 AND id <= ?2",
            [from, to],
        )
        .expect("insert");
    }

    /// The topics' message counts of `path`, read with `memory` when given.
    fn declared(path: &Path, memory: Option<&BagMemory>) -> Vec<Option<u64>> {
        let fixed = memory.map(|m| FixedLengths::fix_remembering(&[path.to_path_buf()], m));
        let bag = Bag::open(path).expect("bag");
        drop(fixed);
        bag.topics().iter().map(|t| t.declared_count).collect()
    }

    /// A read with the memory after a database was written to: what a read of it alone gives
    /// (messages and counts), with `rows` rows asked of SQLite, from `resumed` on.
    fn db_read(f: &Path, memory: &BagMemory, resumed: u64, rows: u64, first: i64, to: u64) {
        let before = memory.stats(f).map_or(0, |s| s.rows_read);
        read_remembering(f, memory, false);
        let s = memory.stats(f).expect("read with the memory");
        assert_eq!(
            (
                s.resumed_at,
                s.rows_read - before,
                s.first_row_read,
                s.kept_to
            ),
            (resumed, rows, Some(first), to),
            "{s:?}"
        );
        same_as_alone(f, memory);
        assert_eq!(declared(f, Some(memory)), declared(f, None));
        // The reads after it asked for nothing more.
        assert_eq!(memory.stats(f).expect("read").rows_read - before, rows);
    }

    #[test]
    fn an_sqlite3_database_written_to_is_read_on_from_the_last_row_kept() {
        let src = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("sample_data/bags/stereo_sqlite3/stereo_sqlite3.db3");
        let dir = std::env::temp_dir().join(format!("dvlcal-mem-db3-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("folder");
        let f = dir.join("run.db3");
        let memory = BagMemory::default();
        // 392 rows, ids 1 to 392, images longer than HEAD among them: written in three
        // batches, each read with the memory asks SQLite only for the rows above those kept.
        db_upto(&src, &f, 150);
        db_read(&f, &memory, 0, 150, 1, 150);
        db_append(&src, &f, 150, 270);
        db_read(&f, &memory, 150, 120, 151, 270);
        db_append(&src, &f, 270, 392);
        db_read(&f, &memory, 270, 122, 271, 392);
        // Fewer rows (the last one kept is gone): read from the start.
        db_upto(&src, &f, 100);
        db_read(&f, &memory, 0, 100, 1, 100);
        // Its topics changed: read from the start.
        std::fs::copy(&src, &f).expect("copy");
        db_read(&f, &memory, 100, 292, 101, 392);
        let db = rusqlite::Connection::open(&f).expect("open");
        db.execute("UPDATE topics SET name = name || '_2' WHERE id = 2", [])
            .expect("update");
        drop(db);
        db_read(&f, &memory, 0, 392, 1, 392);
        // Its first row differs: read from the start.
        let db = rusqlite::Connection::open(&f).expect("open");
        db.execute("DELETE FROM messages WHERE id = 1", [])
            .expect("delete");
        drop(db);
        db_read(&f, &memory, 0, 391, 2, 392);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_renamed_file_keeps_its_slot() {
        let m = BagMemory::default();
        let s = m.slot(Path::new("/x/run.bag.active"));
        lock(&s).resumed(7);
        m.rebase(Path::new("/x/run.bag.active"), Path::new("/x/run.bag"));
        assert_eq!(
            m.stats(Path::new("/x/run.bag")).map(|s| s.resumed_at),
            Some(7)
        );
        assert!(m.stats(Path::new("/x/run.bag.active")).is_none());
    }
}
