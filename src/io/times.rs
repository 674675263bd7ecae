//! Lists of time stamps, one per line (for example the times at which to evaluate a trajectory).

use std::path::Path;

use super::{content_lines, parse_time};
use crate::error::{Error, Result};
use crate::time::Epoch;

/// Reads one time stamp per line (`#` comments and blank lines skipped) and returns each with
/// its 1-based line number, as seconds relative to `epoch`, in file order (not necessarily
/// sorted).
pub fn read_times(path: &Path, epoch: Epoch) -> Result<Vec<(usize, f64)>> {
    let text = crate::files::read_text(path)?;
    parse_times(&text, path, epoch)
}

/// Parses the text of a time stamp list as [`read_times`] does; `path` names the file in
/// messages.
pub fn parse_times(text: &str, path: &Path, epoch: Epoch) -> Result<Vec<(usize, f64)>> {
    let mut out = Vec::new();
    for (line, content) in content_lines(text) {
        let fields: Vec<&str> = content
            .split(|c: char| c.is_whitespace() || c == ',')
            .filter(|s| !s.is_empty())
            .collect();
        if fields.len() != 1 {
            return Err(Error::parse(
                path,
                line,
                format!("expected one time stamp, found {} fields", fields.len()),
            ));
        }
        let t = parse_time(path, line, fields[0])?;
        out.push((line, epoch.rel(t)));
    }
    Ok(out)
}
