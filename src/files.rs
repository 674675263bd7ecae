//! Reading input files: whole texts, with the byte-order mark some editors put first removed, and
//! errors that name the file; and the checks of output paths made before a run starts.

use std::path::Path;

use crate::error::{Error, Result};

/// The UTF-8 byte-order mark (`EF BB BF`), which Windows editors write at the start of text files.
pub const BOM: &[u8] = b"\xef\xbb\xbf";

/// A file's name for messages that name it briefly (`target.yaml`), its whole path when it has
/// no name.
pub fn file_name_of(path: &Path) -> String {
    path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

/// Reads a whole text file without its byte-order mark, naming the file on failure.
pub fn read_text(path: &Path) -> Result<String> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    Ok(match text.strip_prefix('\u{feff}') {
        Some(rest) => rest.to_string(),
        None => text,
    })
}

/// Reads a whole file's bytes without a leading byte-order mark, naming the file on failure.
pub fn read_bytes(path: &Path) -> Result<Vec<u8>> {
    let mut bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    if bytes.starts_with(BOM) {
        bytes.drain(..BOM.len());
    }
    Ok(bytes)
}

/// Whether `a` and `b` name the same existing file (after following links).
pub fn same_file(a: &Path, b: &Path) -> bool {
    match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    }
}

/// An error when the output `out` is one of the `inputs` (writing it would destroy the input);
/// `option` names the output's option.
pub fn refuse_input<'a>(
    option: &'static str,
    out: &Path,
    inputs: impl IntoIterator<Item = &'a Path>,
) -> Result<()> {
    for input in inputs {
        if same_file(out, input) {
            return Err(Error::option(
                option,
                format!(
                    "{} is an input of this run; refusing to overwrite it",
                    out.display()
                ),
            ));
        }
    }
    Ok(())
}

/// The permission bits of `path` when it is an existing file (a link is followed) that its
/// owner may not write (`chmod a-w` or `u-w`): a file someone protected, which dvlcal never
/// replaces. The bits themselves are read, since root may write any file.
pub fn read_only_mode(path: &Path) -> Option<u32> {
    let meta = std::fs::metadata(path).ok().filter(|m| m.is_file())?;
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = meta.permissions().mode() & 0o7777;
        (mode & 0o200 == 0).then_some(mode)
    }
    #[cfg(not(unix))]
    {
        meta.permissions().readonly().then_some(0o444)
    }
}

/// Why an output that is read-only (permission bits `mode`) is not replaced.
pub fn read_only_reason(mode: u32) -> String {
    format!(
        "is read-only (mode {mode:04o}): refusing to replace it; make it writable (chmod u+w) or \
         choose another name"
    )
}

/// An error naming the option when the output `out` exists read-only (see [`read_only_mode`]).
pub fn refuse_read_only(option: &'static str, out: &Path) -> Result<()> {
    match read_only_mode(out) {
        Some(mode) => Err(Error::option(
            option,
            format!("{} {}", out.display(), read_only_reason(mode)),
        )),
        None => Ok(()),
    }
}

/// Makes `out` writable before the work that produces it starts: its folder is created when
/// missing, and a probe file is created and removed in it. An error names the option and the
/// path when `out` is a folder, a read-only file (see [`read_only_mode`]), or when its folder
/// cannot be created or written.
pub fn prepare_output(option: &'static str, out: &Path) -> Result<()> {
    if out.is_dir() {
        return Err(Error::option(
            option,
            format!("{} is a folder; give a file name", out.display()),
        ));
    }
    refuse_read_only(option, out)?;
    let dir = match out.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let cannot =
        |e: std::io::Error| Error::option(option, format!("cannot write {}: {e}", out.display()));
    std::fs::create_dir_all(dir).map_err(cannot)?;
    let probe = dir.join(format!(".dvlcal-probe.{}", std::process::id()));
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
        .map_err(cannot)?;
    std::fs::remove_file(&probe).map_err(cannot)
}

/// Removes the files `paths` an earlier run left, so that none can be taken for this run's; a
/// file that is not there is no error.
pub fn remove_stale(paths: &[&Path]) -> Result<()> {
    for p in paths {
        match std::fs::remove_file(p) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => return Err(Error::io(p, e)),
            _ => {}
        }
    }
    Ok(())
}
