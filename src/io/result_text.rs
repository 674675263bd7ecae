//! What the result files of the IMU's modes (camera + IMU, DVL + IMU) share: the layout of
//! their text (a comment header, `status` and `failure`, the main keys as the caller writes
//! them, then the sections as YAML) and their reading with errors that name the line.

use std::path::Path;

use serde::Serialize;
use serde::de::DeserializeOwned;

use super::calib_yaml::ResultStatus;
use crate::error::{Error, Result};

/// A YAML flow sequence of numbers (shortest digits that read back exactly).
pub(crate) fn flow(v: &[f64]) -> String {
    let items: Vec<String> = v.iter().map(|x| format!("{x:?}")).collect();
    format!("[{}]", items.join(", "))
}

/// Writes `header`, then `status` and `failure` (when given), then `main` (the main keys, as
/// text), then `tail` serialised (its empty sections left out by its own attributes), to
/// `path` atomically.
pub(crate) fn write_result_text(
    path: &Path,
    header: &str,
    status: &Option<ResultStatus>,
    failure: &[String],
    main: &str,
    tail: &impl Serialize,
) -> Result<()> {
    #[derive(Serialize)]
    struct Head<'a> {
        #[serde(skip_serializing_if = "Option::is_none")]
        status: &'a Option<ResultStatus>,
        #[serde(skip_serializing_if = "<[String]>::is_empty")]
        failure: &'a [String],
    }
    let yaml_err = |e: serde_yaml::Error| Error::Input(format!("{}: {e}", path.display()));
    let mut s = String::from(header);
    if status.is_some() || !failure.is_empty() {
        s.push_str(&serde_yaml::to_string(&Head { status, failure }).map_err(yaml_err)?);
    }
    s.push_str(main);
    let tail = serde_yaml::to_string(tail).map_err(yaml_err)?;
    if tail.trim() != "{}" {
        s.push_str(&tail);
    }
    super::write_atomic(path, s.as_bytes())
}

/// Reads a YAML result file into `T`; errors name the file, and the line where the parser
/// reports one.
pub(crate) fn read_result_text<T: DeserializeOwned>(path: &Path) -> Result<T> {
    let text = crate::files::read_text(path)?;
    serde_yaml::from_str(&text).map_err(|e| match e.location() {
        Some(loc) => Error::parse(path, loc.line(), format!("column {}: {e}", loc.column())),
        None => Error::Input(format!("{}: {e}", path.display())),
    })
}
