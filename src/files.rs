//! Reading input files: whole texts, with the byte-order mark some editors put first removed, and
//! errors that name the file.

use std::path::Path;

use crate::error::{Error, Result};

/// The UTF-8 byte-order mark (`EF BB BF`), which Windows editors write at the start of text files.
pub const BOM: &[u8] = b"\xef\xbb\xbf";

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
