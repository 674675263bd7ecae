//! A bag followed while it is recorded (`dvlcal watch BAG`): what is read at each update, and
//! when the recording is over.
//!
//! A bag can be gigabytes of images, so it is never copied: each update reads it in place, up
//! to the length its files had when the update began ([`FixedLengths`]), so that the several
//! reads of one update (topics, image frames, DVL topic, IMU topic) see the same bag. Its last
//! chunk or record is then usually cut: the readers take what precedes the cut, as they do for
//! a recording that was never closed, and the next update reads on.
//!
//! What recorders leave while they record, and how the end is seen:
//!
//! - `rosbag record`: `NAME.bag.active` (no index; its last chunk's header still waiting for
//!   its length), renamed to `NAME.bag` once the index is written. Either name may be given;
//!   the rename ends the watch, and the final calibration reads `NAME.bag`.
//! - A bare `.mcap` file: no summary or footer until it is closed; the watch ends when it has
//!   not changed for the idle time.
//! - `ros2 bag record`: a folder holding the storage file(s) being written, whose
//!   `metadata.yaml` is written at the end; its appearing ends the watch, and the final
//!   calibration reads the folder. Until then the one storage file is read as a bare file (a
//!   recording split into several files waits for `metadata.yaml`, which gives their order).
//! - sqlite3 storage (`.db3`): read through SQLite, which reads a database being written
//!   (its write-ahead log included) as of its last committed transaction.
//!
//! The image messages' detections are kept across updates under the bag's path, topic and
//! message number ([`DetectionCache::message_key`]), moved with the bag when it is renamed.
//! So is the readers' place in each storage file ([`BagMemory`]): an update of a ROS 1 or MCAP
//! bag parses only what was appended since the last one (and its last, unfinished chunk), one
//! of an sqlite3 bag asks SQLite only for the rows written since, and an image's bytes are read
//! again only for a frame not solved yet.

use std::path::{Path, PathBuf};
use std::time::SystemTime;

use crate::io::bag::growing::FixedLengths;
use crate::io::bag::memory::BagMemory;
use crate::io::bag::{Storage, is_bag};
use crate::vision::detect::DetectionCache;

/// The suffix `rosbag record` gives a bag while it records.
const ACTIVE: &str = ".active";

/// What some files looked like at one look: each file's path, size and time.
pub(super) type Signature = Vec<(PathBuf, u64, Option<SystemTime>)>;

/// The signature of `files`, in their order (a file that cannot be read has size 0, no time).
pub(super) fn signature(files: Vec<PathBuf>) -> Signature {
    files
        .into_iter()
        .map(|p| {
            let m = std::fs::metadata(&p).ok();
            let len = m.as_ref().map_or(0, |m| m.len());
            let time = m.and_then(|m| m.modified().ok());
            (p, len, time)
        })
        .collect()
}

/// A bag followed while it is recorded.
#[derive(Debug)]
pub(super) struct FollowedBag {
    /// The path given.
    given: PathBuf,
    /// Where the bag is read now (`None`: nothing to read yet).
    read: Option<PathBuf>,
    /// The files at the last look.
    last: Option<Signature>,
    /// Why the recording is over, once a look saw it end.
    ended: Option<String>,
    /// Where the readers got to in its files, kept across updates.
    memory: BagMemory,
}

/// Whether `name` is a storage file of a ROS 2 bag, or a file SQLite keeps beside one.
fn storage_name(name: &str) -> bool {
    [".mcap", ".db3", ".db3-wal", ".db3-shm", ".db3-journal"]
        .iter()
        .any(|e| name.ends_with(e))
}

/// Whether `name` is a file name a bag is recorded under.
fn bag_name(name: &str) -> bool {
    [".bag", ".bag.active", ".mcap", ".db3"]
        .iter()
        .any(|e| name.ends_with(e))
}

/// The files of `dir` that are not hidden, sorted with their numbers in order (`run_2.mcap`
/// before `run_10.mcap`).
fn listed(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            !p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with('.'))
        })
        .collect();
    // Same prefix, numbers after it: the shorter name is the smaller number.
    let key = |p: &PathBuf| {
        let name = p.file_name().map(|n| n.to_string_lossy().into_owned());
        let name = name.unwrap_or_default();
        (name.len(), name)
    };
    files.sort_by_key(key);
    files
}

/// `path` with `suffix` added to its name.
fn with_suffix(path: &Path, suffix: &str) -> PathBuf {
    let mut s = path.as_os_str().to_owned();
    s.push(suffix);
    PathBuf::from(s)
}

impl FollowedBag {
    /// `source` followed as a bag, when it is one or is named as one: a bag file (there or
    /// still to come, by its name), a ROS 2 bag folder, or a folder holding nothing but ROS 2
    /// storage files (a `ros2 bag record` under way). `None` for a dataset folder.
    pub(super) fn of(source: &Path) -> Option<FollowedBag> {
        let is = if source.is_dir() {
            source.join("metadata.yaml").is_file() || {
                let files = listed(source);
                !files.is_empty()
                    && files.iter().all(|f| {
                        f.is_file()
                            && f.file_name()
                                .is_some_and(|n| storage_name(&n.to_string_lossy()))
                    })
            }
        } else {
            is_bag(source)
                || source
                    .file_name()
                    .is_some_and(|n| bag_name(&n.to_string_lossy()))
        };
        is.then(|| FollowedBag {
            given: source.to_path_buf(),
            read: None,
            last: None,
            ended: None,
            memory: BagMemory::default(),
        })
    }

    /// The files whose size and time tell whether the bag changed.
    fn watched_files(&self) -> Vec<PathBuf> {
        let g = &self.given;
        if g.is_dir() {
            return listed(g);
        }
        let name = g.file_name().map(|n| n.to_string_lossy().into_owned());
        let mut files = vec![g.clone(), with_suffix(g, ACTIVE)];
        if let Some(stem) = name.as_deref().and_then(|n| n.strip_suffix(ACTIVE)) {
            files.push(g.with_file_name(stem));
        }
        files.retain(|f| f.is_file());
        files
    }

    /// Looks at the bag's files: whether they changed since the last look (in number, size or
    /// time), where the bag is to be read now, and whether the recording ended. The
    /// detections in `cache` are moved with the bag when it is read under another path.
    pub(super) fn changed(&mut self, cache: &mut DetectionCache) -> bool {
        let sig = signature(self.watched_files());
        let changed = self.last.as_ref() != Some(&sig);
        self.last = Some(sig);
        self.moved(cache);
        changed
    }

    /// Looks where the bag is to be read now (and whether the recording ended): whether that
    /// is another path than before (a bag renamed, `metadata.yaml` written). The detections
    /// in `cache` are moved with the bag.
    pub(super) fn moved(&mut self, cache: &mut DetectionCache) -> bool {
        let (read, ended) = self.locate();
        let moved = read != self.read;
        if let (Some(old), Some(new)) = (&self.read, &read)
            && old != new
        {
            *cache = cache.rebased(old, new);
            // A file renamed (not a recording folder now read through its metadata.yaml,
            // whose storage file keeps its name).
            if !old.exists() {
                self.memory.rebase(old, new);
            }
        }
        self.read = read;
        if self.ended.is_none() {
            self.ended = ended;
        }
        moved
    }

    /// Where the bag is to be read now, and why the recording is over when it is.
    fn locate(&self) -> (Option<PathBuf>, Option<String>) {
        let g = &self.given;
        if g.is_dir() {
            if g.join("metadata.yaml").is_file() {
                let was_recording = self.read.as_ref().is_some_and(|r| r != g);
                let why = was_recording.then(|| {
                    format!(
                        "{}: metadata.yaml was written, the recording is over",
                        g.display()
                    )
                });
                return (Some(g.clone()), why);
            }
            let storage: Vec<PathBuf> = listed(g)
                .into_iter()
                .filter(|f| f.extension().is_some_and(|e| e == "mcap" || e == "db3"))
                .collect();
            return (storage.first().cloned(), None);
        }
        let active = with_suffix(g, ACTIVE);
        let name = g.file_name().map(|n| n.to_string_lossy().into_owned());
        let stem = name.as_deref().and_then(|n| n.strip_suffix(ACTIVE));
        match stem {
            // NAME.bag.active given: renamed to NAME.bag at the end.
            Some(stem) if !g.exists() && g.with_file_name(stem).is_file() => {
                let done = g.with_file_name(stem);
                let why = format!(
                    "{} was renamed {}: the recording is over",
                    g.display(),
                    done.display()
                );
                (Some(done), Some(why))
            }
            // NAME.bag given while NAME.bag.active is recorded.
            None if !g.exists() && active.is_file() => (Some(active), None),
            None if g.is_file() && self.read.as_ref() == Some(&active) => {
                let why = format!(
                    "{} was renamed {}: the recording is over",
                    active.display(),
                    g.display()
                );
                (Some(g.clone()), Some(why))
            }
            _ => (g.exists().then(|| g.clone()), None),
        }
    }

    /// Why the recording is over, once a look saw it end (a rename, `metadata.yaml`
    /// written); `None` while it may go on.
    pub(super) fn ended(&self) -> Option<&str> {
        self.ended.as_deref()
    }

    /// The bag to read now, with its files' lengths fixed as they are (held until the value
    /// is dropped); or why there is nothing to read yet.
    pub(super) fn snapshot(&self) -> std::result::Result<(PathBuf, FixedLengths), String> {
        let g = &self.given;
        let Some(read) = &self.read else {
            return Err(format!(
                "{}: no bag yet{}",
                g.display(),
                if g.is_dir() {
                    " (no storage file in the folder)"
                } else {
                    ""
                }
            ));
        };
        if g.is_dir() && read != g {
            let storage = listed(g)
                .into_iter()
                .filter(|f| f.extension().is_some_and(|e| e == "mcap" || e == "db3"))
                .count();
            if storage > 1 {
                return Err(format!(
                    "{}: the recording is split into {storage} storage files, read once the \
                     recorder writes metadata.yaml (which gives their order); to follow a \
                     recording while it is written, record it unsplit",
                    g.display()
                ));
            }
        }
        let files = if read.is_dir() {
            listed(read)
        } else {
            vec![read.clone()]
        };
        Ok((
            read.clone(),
            FixedLengths::fix_remembering(&files, &self.memory),
        ))
    }

    /// Words added to why the bag could not be read yet, when its storage explains it.
    pub(super) fn hint(&self, reason: &str) -> Option<&'static str> {
        let db3 = self.read.as_ref().is_some_and(|r| {
            std::fs::File::open(r)
                .ok()
                .and_then(|mut f| {
                    let mut head = [0u8; 16];
                    std::io::Read::read_exact(&mut f, &mut head).ok()?;
                    Storage::of_head(&head)
                })
                .is_some_and(|s| s == Storage::Sqlite3)
        });
        (db3 && reason.contains("locked")).then_some(
            "the recorder holds its sqlite3 database locked while it writes a batch; a later \
             update reads it",
        )
    }

    /// The bag the final calibration reads, with the words that say why, when it is not the
    /// path given (`NAME.bag.active` renamed, a recording folder's storage file read alone).
    pub(super) fn final_dataset(&self) -> Option<(PathBuf, String)> {
        let read = self.read.as_ref().filter(|r| **r != self.given)?;
        let why = self.ended.clone().unwrap_or_else(|| {
            format!(
                "{} is read as the recording {}",
                read.display(),
                self.given.display()
            )
        });
        Some((
            read.clone(),
            format!("{why}; the final calibration reads {}", read.display()),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("dvlcal-wb-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).expect("folder");
        d
    }

    #[test]
    fn an_active_bag_renamed_at_its_end_is_read_under_its_new_name() {
        let d = tmp("rename");
        let active = d.join("run.bag.active");
        let mut b = FollowedBag::of(&active).expect("a bag by its name");
        let mut cache = DetectionCache::default();
        assert!(b.changed(&mut cache));
        assert!(b.snapshot().is_err(), "nothing to read yet");
        std::fs::write(&active, crate::io::bag::ros1::MAGIC).expect("write");
        assert!(b.changed(&mut cache));
        assert!(!b.changed(&mut cache));
        assert_eq!(b.snapshot().expect("bag").0, active);
        assert!(b.ended().is_none());
        std::fs::rename(&active, d.join("run.bag")).expect("rename");
        assert!(b.changed(&mut cache));
        assert!(b.ended().is_some_and(|w| w.contains("renamed")));
        let (path, why) = b.final_dataset().expect("the new name");
        assert_eq!(path, d.join("run.bag"));
        assert!(why.contains("run.bag.active was renamed"), "{why}");
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn the_final_name_given_follows_the_active_file() {
        let d = tmp("final");
        let active = d.join("run.bag.active");
        std::fs::write(&active, crate::io::bag::ros1::MAGIC).expect("write");
        let mut b = FollowedBag::of(&d.join("run.bag")).expect("a bag by its name");
        let mut cache = DetectionCache::default();
        b.changed(&mut cache);
        assert_eq!(b.snapshot().expect("bag").0, active);
        std::fs::rename(&active, d.join("run.bag")).expect("rename");
        assert!(b.changed(&mut cache));
        assert!(b.ended().is_some());
        assert_eq!(b.snapshot().expect("bag").0, d.join("run.bag"));
        assert!(b.final_dataset().is_none());
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn a_ros2_recording_folder_is_read_by_its_file_until_metadata_appears() {
        let d = tmp("ros2");
        assert!(
            FollowedBag::of(&d).is_none(),
            "an empty folder is a dataset folder"
        );
        std::fs::write(d.join("rec_0.mcap"), crate::io::bag::MCAP_MAGIC).expect("write");
        let mut b = FollowedBag::of(&d).expect("a recording folder");
        let mut cache = DetectionCache::default();
        b.changed(&mut cache);
        assert_eq!(b.snapshot().expect("bag").0, d.join("rec_0.mcap"));
        std::fs::write(d.join("rec_1.mcap"), crate::io::bag::MCAP_MAGIC).expect("write");
        b.changed(&mut cache);
        let why = b.snapshot().expect_err("split");
        assert!(why.contains("split into 2 storage files"), "{why}");
        std::fs::write(d.join("metadata.yaml"), "x").expect("write");
        assert!(b.changed(&mut cache));
        assert!(b.ended().is_some_and(|w| w.contains("metadata.yaml")));
        assert_eq!(b.snapshot().expect("bag").0, d);
        std::fs::write(d.join("camchain.yaml"), "x").expect("write");
        assert!(
            FollowedBag::of(&d).is_some(),
            "metadata.yaml makes it a bag"
        );
        std::fs::remove_file(d.join("metadata.yaml")).expect("rm");
        assert!(
            FollowedBag::of(&d).is_none(),
            "a dataset folder holding bags"
        );
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn storage_files_sort_by_their_numbers() {
        let d = tmp("sort");
        for n in ["r_10.mcap", "r_2.mcap", "r_1.mcap"] {
            std::fs::write(d.join(n), b"").expect("write");
        }
        let names: Vec<String> = listed(&d)
            .iter()
            .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
            .collect();
        assert_eq!(names, ["r_1.mcap", "r_2.mcap", "r_10.mcap"]);
        let _ = std::fs::remove_dir_all(&d);
    }
}
