//! Where a result came from: the program's version, the command line, the time of the run, and
//! each input file with its size and SHA-256 digest, so that a result can be traced to the
//! exact data it was computed from.
//!
//! A folder (the images of one camera, a ROS 2 bag folder) gets one digest over its files: the
//! SHA-256 of the lines `<sha256 of the file>  <path relative to the folder>\n`, one per
//! regular file below the folder (recursively, `/` as the separator), sorted by path byte by
//! byte. These are the lines `sha256sum` prints, so the digest can be reproduced with
//!
//! ```sh
//! cd FOLDER && find . -type f -printf '%P\n' | LC_ALL=C sort | xargs -d '\n' sha256sum | sha256sum
//! ```

use std::io::Read as _;
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::error::{Error, Result};

/// One input of a run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct InputDigest {
    /// The part the input played (`dvl_log`, `poses`, `images_cam0`, `camchain`, `target`,
    /// `bag`, ...).
    pub role: String,
    /// The path as given.
    pub path: String,
    /// Size in bytes (for a folder: of all its files).
    pub bytes: u64,
    /// SHA-256 of the file, lower-case hex (for a folder: the digest over its files described
    /// in the module documentation).
    pub sha256: String,
    /// For a folder, the number of files digested.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub files: Option<u64>,
}

/// The provenance section of a result file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Provenance {
    /// The version of dvlcal that wrote the result.
    pub dvlcal_version: String,
    /// The command line of the run (arguments with spaces quoted), when run from the program.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub command_line: Option<String>,
    /// The time the result was written, UTC, ISO 8601 (`2026-01-31T12:00:00Z`).
    pub run_utc: String,
    /// Every input, with its size and digest.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub inputs: Vec<InputDigest>,
}

impl Provenance {
    /// The provenance of a run now: this version, `command_line`, the current UTC time and the
    /// digests of `inputs` (role, path; a folder is digested as a whole).
    pub fn of_run(
        command_line: Option<String>,
        inputs: &[(String, PathBuf)],
    ) -> Result<Provenance> {
        let inputs = inputs
            .iter()
            .map(|(role, p)| digest(role, p))
            .collect::<Result<Vec<_>>>()?;
        Ok(Provenance {
            dvlcal_version: env!("CARGO_PKG_VERSION").to_owned(),
            command_line,
            run_utc: utc_iso8601(SystemTime::now()),
            inputs,
        })
    }
}

/// A command line from its arguments, each quoted for a POSIX shell when it holds anything but
/// plain characters; an argument that is not UTF-8 (a file name in another encoding) is written
/// with its bytes escaped (`$'r\xffx'`, as bash and zsh read it), so the line stays exact.
pub fn command_line<I, S>(args: I) -> String
where
    I: IntoIterator<Item = S>,
    S: AsRef<std::ffi::OsStr>,
{
    args.into_iter()
        .map(|a| match a.as_ref().to_str() {
            Some(a) => {
                let plain = !a.is_empty()
                    && a.chars().all(|c| {
                        c.is_ascii_alphanumeric()
                            || matches!(c, '-' | '_' | '.' | '/' | ',' | ':' | '=' | '+')
                    });
                if plain {
                    a.to_owned()
                } else {
                    format!("'{}'", a.replace('\'', r"'\''"))
                }
            }
            None => escaped_bytes(a.as_ref()),
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// The command line this program was started with (see [`command_line`]); never fails, whatever
/// the bytes of its arguments.
pub fn this_command_line() -> String {
    command_line(std::env::args_os())
}

/// An argument as an ANSI-C quoted word: printable ASCII as it is, every other byte as `\xHH`.
fn escaped_bytes(a: &std::ffi::OsStr) -> String {
    let mut out = String::from("$'");
    for &b in a.as_encoded_bytes() {
        match b {
            b'\'' | b'\\' => {
                out.push('\\');
                out.push(char::from(b));
            }
            0x20..=0x7e => out.push(char::from(b)),
            _ => out.push_str(&format!("\\x{b:02x}")),
        }
    }
    out.push('\'');
    out
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Size and SHA-256 (hex) of one file, read in blocks.
fn file_digest(path: &Path) -> Result<(u64, String)> {
    let mut f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 20];
    let mut n = 0u64;
    loop {
        let k = f.read(&mut buf).map_err(|e| Error::io(path, e))?;
        if k == 0 {
            break;
        }
        h.update(&buf[..k]);
        n += k as u64;
    }
    Ok((n, hex(&h.finalize())))
}

/// Every regular file below `dir`, as (path relative to `dir` with `/` separators, full path).
fn files_below(dir: &Path) -> Result<Vec<(String, PathBuf)>> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).map_err(|e| Error::io(&d, e))? {
            let entry = entry.map_err(|e| Error::io(&d, e))?;
            let path = entry.path();
            let meta = std::fs::metadata(&path).map_err(|e| Error::io(&path, e))?;
            if meta.is_dir() {
                stack.push(path);
            } else if meta.is_file() {
                let rel = path
                    .strip_prefix(dir)
                    .unwrap_or(&path)
                    .components()
                    .map(|c| c.as_os_str().to_string_lossy().into_owned())
                    .collect::<Vec<_>>()
                    .join("/");
                out.push((rel, path));
            }
        }
    }
    out.sort_by(|a, b| a.0.as_bytes().cmp(b.0.as_bytes()));
    Ok(out)
}

/// The digest of a file, or of a folder as a whole (see the module documentation); the files
/// of a folder are digested on all cores.
pub fn digest(role: &str, path: &Path) -> Result<InputDigest> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    let (bytes, sha256, files) = if meta.is_dir() {
        let list = files_below(path)?;
        let digests = list
            .par_iter()
            .map(|(_, p)| file_digest(p))
            .collect::<Result<Vec<_>>>()?;
        let mut h = Sha256::new();
        let mut total = 0u64;
        for ((rel, _), (n, d)) in list.iter().zip(&digests) {
            h.update(format!("{d}  {rel}\n").as_bytes());
            total += n;
        }
        (total, hex(&h.finalize()), Some(list.len() as u64))
    } else {
        let (n, d) = file_digest(path)?;
        (n, d, None)
    };
    Ok(InputDigest {
        role: role.to_owned(),
        path: path.display().to_string(),
        bytes,
        sha256,
        files,
    })
}

/// `t` as ISO 8601 UTC with whole seconds (`1970-01-01T00:00:00Z`); times before 1970 give the
/// epoch.
pub fn utc_iso8601(t: SystemTime) -> String {
    let secs = t.duration_since(UNIX_EPOCH).map_or(0, |d| d.as_secs());
    let (days, rem) = ((secs / 86_400) as i64, secs % 86_400);
    // Civil date from days since 1970-01-01 (proleptic Gregorian; eras of 400 years).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn utc_dates_match_known_calendar_days() {
        let at = |s: u64| utc_iso8601(UNIX_EPOCH + Duration::from_secs(s));
        assert_eq!(at(0), "1970-01-01T00:00:00Z");
        // 2000-02-29 (a leap day of a year divisible by 400), 12:34:56.
        assert_eq!(at(951_827_696), "2000-02-29T12:34:56Z");
        // 2024-12-31T23:59:59 and the second after it.
        assert_eq!(at(1_735_689_599), "2024-12-31T23:59:59Z");
        assert_eq!(at(1_735_689_600), "2025-01-01T00:00:00Z");
        // 2100-03-01: 2100 is not a leap year.
        assert_eq!(at(4_107_542_400), "2100-03-01T00:00:00Z");
    }

    #[test]
    fn digests_match_sha256sum() {
        let dir = std::env::temp_dir().join(format!("dvlcal-prov-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        std::fs::write(dir.join("b.txt"), b"abc").unwrap();
        std::fs::write(dir.join("sub").join("a.txt"), b"").unwrap();
        // The well-known digests of "abc" and of nothing.
        let abc = "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad";
        let empty = "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855";
        let f = digest("x", &dir.join("b.txt")).unwrap();
        assert_eq!((f.bytes, f.sha256.as_str(), f.files), (3, abc, None));
        let d = digest("x", &dir).unwrap();
        let lines = format!("{abc}  b.txt\n{empty}  sub/a.txt\n");
        let expected = hex(&Sha256::digest(lines.as_bytes()));
        assert_eq!((d.bytes, d.files), (3, Some(2)));
        assert_eq!(d.sha256, expected);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn command_lines_quote_what_a_shell_would_split() {
        let line = command_line(
            [
                "dvlcal",
                "calibrate",
                "my run",
                "--offset-range",
                "-1,2",
                "it's",
            ]
            .map(String::from),
        );
        assert_eq!(
            line,
            r"dvlcal calibrate 'my run' --offset-range -1,2 'it'\''s'"
        );
    }

    #[cfg(unix)]
    #[test]
    fn arguments_that_are_not_utf8_keep_their_bytes() {
        use std::os::unix::ffi::OsStrExt;
        let odd = std::ffi::OsStr::from_bytes(b"r\xffx'\\/cal.yaml");
        let line = command_line([std::ffi::OsStr::new("--out"), odd]);
        assert_eq!(line, r"--out $'r\xffx\'\\/cal.yaml'");
    }
}
