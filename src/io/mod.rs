//! File formats in and out. Nothing here estimates anything.
//!
//! Every reader names the file and the 1-based line of the first thing it cannot use. Every
//! writer goes through [`write_atomic`], so an interrupted or failed write never leaves a
//! half-written file behind.

pub mod bag;
pub mod calib_yaml;
pub mod camchain;
pub mod dataset;
pub mod dvl;
pub mod dvl_imu_result;
pub mod exports;
pub mod frames;
pub mod frames_csv;
pub mod image;
pub mod images;
pub mod imu;
pub mod imu_result;
pub mod provenance;
mod result_text;
pub mod target;
pub mod times;
pub mod tum;
pub mod twist_csv;

use std::fs::{self, File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::{Error, Result};
use crate::time::RawTime;

/// Writes `bytes` to `path` atomically: the data go to a temporary file in the same directory,
/// which is flushed to disk and then renamed over `path`. On failure the temporary file is
/// removed and `path` is left as it was. A read-only `path` ([`crate::files::read_only_mode`])
/// is not replaced: an error names it.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    // Replace regular files only: a symbolic link is written through (its target is replaced),
    // and a device, folder or other special file is never replaced by a regular file.
    let resolved;
    let path = match fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_symlink() => {
            resolved = match fs::canonicalize(path) {
                Ok(p) => p,
                Err(_) => {
                    let link = fs::read_link(path).map_err(|e| Error::io(path, e))?;
                    path.parent().unwrap_or(Path::new(".")).join(link)
                }
            };
            match fs::metadata(&resolved) {
                Ok(t) if !t.is_file() => return Err(not_regular(path)),
                _ => resolved.as_path(),
            }
        }
        Ok(m) if !m.is_file() => return Err(not_regular(path)),
        _ => path,
    };
    if let Some(mode) = crate::files::read_only_mode(path) {
        return Err(Error::io(
            path,
            std::io::Error::new(
                std::io::ErrorKind::PermissionDenied,
                crate::files::read_only_reason(mode),
            ),
        ));
    }
    let file_name = path.file_name().ok_or_else(|| {
        Error::io(
            path,
            std::io::Error::new(std::io::ErrorKind::InvalidInput, "not a file path"),
        )
    })?;
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(file_name);
    tmp_name.push(format!(
        ".tmp.{}.{}",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let tmp = dir.join(tmp_name);

    let result = (|| -> std::io::Result<()> {
        let mut f = OpenOptions::new().write(true).create_new(true).open(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        drop(f);
        fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        let _ = fs::remove_file(&tmp);
        return Err(Error::io(path, e));
    }
    // Make the rename itself durable where the platform allows syncing a directory.
    if let Ok(d) = File::open(&dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

/// The error for an output that exists and is not a regular file.
fn not_regular(path: &Path) -> Error {
    Error::io(
        path,
        std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "exists and is not a regular file (a device, folder or other special file); refusing \
             to replace it",
        ),
    )
}

/// The content lines of a text file with their 1-based line numbers: `\r` line ends removed,
/// `#` comments cut off, surrounding white space trimmed, blank lines dropped.
pub(crate) fn content_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines().enumerate().filter_map(|(i, line)| {
        let line = line.split('#').next().unwrap_or("").trim();
        (!line.is_empty()).then_some((i + 1, line))
    })
}

/// Number of lines in `text` (at least 1), for errors about the file as a whole.
pub(crate) fn last_line(text: &str) -> usize {
    text.lines().count().max(1)
}

/// Parses a finite number, or says what is wrong with it (`what` names the field).
pub(crate) fn parse_finite(path: &Path, line: usize, what: &str, s: &str) -> Result<f64> {
    let v: f64 = s
        .parse()
        .map_err(|_| Error::parse(path, line, format!("{what}: '{s}' is not a number")))?;
    if !v.is_finite() {
        return Err(Error::parse(
            path,
            line,
            format!("{what}: '{s}' is not finite"),
        ));
    }
    Ok(v)
}

/// Parses a decimal time stamp exactly, or says what is wrong with it.
pub(crate) fn parse_time(path: &Path, line: usize, s: &str) -> Result<RawTime> {
    RawTime::parse(s).ok_or_else(|| {
        Error::parse(
            path,
            line,
            format!("time stamp '{s}' is not a number of seconds (finite, within +-9.2e18)"),
        )
    })
}

/// Formats a finite f64 with the shortest digits that read back to the same value, without an
/// exponent.
pub(crate) fn fmt_f64(v: f64) -> String {
    format!("{v}")
}

/// Error for a value a writer cannot represent.
pub(crate) fn non_finite(path: &Path, what: String) -> Error {
    Error::Input(format!("{}: {what} is not finite", path.display()))
}
