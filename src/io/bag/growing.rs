//! A bag still being recorded, read as it was at one moment.
//!
//! A recorder appends to its file while a reader goes through it, and one dataset read opens
//! the same bag several times (its topics, the image frames, the DVL topic, the IMU topic). So
//! that every one of these reads sees the same bag, a caller fixes the length of the bag's
//! files with [`FixedLengths::fix`]: until the guard is dropped, the ROS 1 and MCAP readers
//! read each of those files up to the length it had then, whatever was appended since. The
//! last chunk or record is then usually cut, which the readers take as the end of a recording
//! (they read what precedes it and say so). sqlite3 storage is read through SQLite, which
//! gives each read a consistent database of its own; it is not fixed, but its reader keeps its
//! place in the memory attached all the same ([`FixedLengths::fix_remembering`]).

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use super::memory::{BagMemory, SlotRef};

/// The lengths fixed now, by canonical path (a path fixed twice holds both entries; the
/// shorter wins).
static FIXED: Mutex<Vec<(PathBuf, u64)>> = Mutex::new(Vec::new());

/// The memories attached to fixed files, by canonical path ([`FixedLengths::fix_remembering`]).
static REMEMBERED: Mutex<Vec<(PathBuf, SlotRef)>> = Mutex::new(Vec::new());

/// The lengths of some files, fixed until this is dropped.
#[derive(Debug)]
pub struct FixedLengths {
    held: Vec<(PathBuf, u64)>,
    slots: Vec<(PathBuf, SlotRef)>,
}

impl FixedLengths {
    /// Fixes each of `files` at its present length (a file that cannot be read is left out:
    /// the readers then report it as they would).
    pub fn fix(files: &[PathBuf]) -> FixedLengths {
        let held: Vec<(PathBuf, u64)> = files
            .iter()
            .filter_map(|f| {
                let len = std::fs::metadata(f).ok()?.len();
                Some((std::fs::canonicalize(f).ok()?, len))
            })
            .collect();
        FIXED
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .extend(held.iter().cloned());
        FixedLengths {
            held,
            slots: Vec::new(),
        }
    }

    /// Fixes `files` as [`FixedLengths::fix`] does, and until this is dropped lets their
    /// readers keep their place in `memory` (each file's slot under its path as given) and
    /// read on from it ([`super::memory`]).
    pub fn fix_remembering(files: &[PathBuf], memory: &BagMemory) -> FixedLengths {
        let mut fixed = FixedLengths::fix(files);
        fixed.slots = files
            .iter()
            .filter_map(|f| Some((std::fs::canonicalize(f).ok()?, memory.slot(f))))
            .collect();
        REMEMBERED
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .extend(fixed.slots.iter().cloned());
        fixed
    }

    /// The files and the lengths they were fixed at.
    pub fn lengths(&self) -> &[(PathBuf, u64)] {
        &self.held
    }
}

impl Drop for FixedLengths {
    fn drop(&mut self) {
        let mut fixed = FIXED.lock().unwrap_or_else(|p| p.into_inner());
        for h in &self.held {
            if let Some(i) = fixed.iter().position(|f| f == h) {
                fixed.swap_remove(i);
            }
        }
        drop(fixed);
        let mut slots = REMEMBERED.lock().unwrap_or_else(|p| p.into_inner());
        for (p, s) in &self.slots {
            if let Some(i) = slots.iter().position(|(q, t)| q == p && Arc::ptr_eq(s, t)) {
                slots.swap_remove(i);
            }
        }
    }
}

/// How much of `path`, whose length is `len` now, a reader reads: `len`, or less when the
/// file's length was fixed shorter ([`FixedLengths`]).
pub(crate) fn readable_len(path: &Path, len: u64) -> u64 {
    let fixed = FIXED.lock().unwrap_or_else(|p| p.into_inner());
    if fixed.is_empty() {
        return len;
    }
    let Ok(canonical) = std::fs::canonicalize(path) else {
        return len;
    };
    fixed
        .iter()
        .filter(|(p, _)| *p == canonical)
        .map(|&(_, l)| l)
        .fold(len, u64::min)
}

/// The memory the reads of `path` keep their place in, while one is attached
/// ([`FixedLengths::fix_remembering`]).
pub(crate) fn slot_of(path: &Path) -> Option<SlotRef> {
    let slots = REMEMBERED.lock().unwrap_or_else(|p| p.into_inner());
    if slots.is_empty() {
        return None;
    }
    let canonical = std::fs::canonicalize(path).ok()?;
    slots
        .iter()
        .find(|(p, _)| *p == canonical)
        .map(|(_, s)| s.clone())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fixed_length_holds_until_dropped_whatever_is_appended() {
        let dir = std::env::temp_dir().join(format!("dvlcal-growing-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("folder");
        let f = dir.join("run.mcap");
        std::fs::write(&f, b"0123456789").expect("write");
        assert_eq!(readable_len(&f, 10), 10);
        let fixed = FixedLengths::fix(std::slice::from_ref(&f));
        assert_eq!(fixed.lengths().len(), 1);
        std::fs::write(&f, b"0123456789abcdef").expect("grow");
        // Through another spelling of the same path too.
        assert_eq!(readable_len(&dir.join(".").join("run.mcap"), 16), 10);
        drop(fixed);
        assert_eq!(readable_len(&f, 16), 16);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
