//! CSV of body twists with their standard deviations and derivatives, one row per time.

use std::fmt::Write as _;
use std::path::Path;

use nalgebra::Vector3;

use super::{fmt_f64, non_finite, parse_finite, parse_time};
use crate::error::{Error, Result};
use crate::time::Epoch;

/// The header line of a twist CSV file.
pub const TWIST_CSV_HEADER: &str =
    "t,vx,vy,vz,wx,wy,wz,std_vx,std_vy,std_vz,std_wx,std_wy,std_wz,dvx,dvy,dvz,dwx,dwy,dwz";

/// One row of a twist CSV file.
#[derive(Clone, Debug, PartialEq)]
pub struct TwistRow {
    /// Time, seconds relative to the epoch.
    pub t: f64,
    /// Linear velocity.
    pub v: Vector3<f64>,
    /// Angular velocity.
    pub w: Vector3<f64>,
    /// Standard deviation of `v`.
    pub std_v: Vector3<f64>,
    /// Standard deviation of `w`.
    pub std_w: Vector3<f64>,
    /// Time derivative of `v`.
    pub dv: Vector3<f64>,
    /// Time derivative of `w`.
    pub dw: Vector3<f64>,
}

impl TwistRow {
    fn vectors(&self) -> [&Vector3<f64>; 6] {
        [
            &self.v,
            &self.w,
            &self.std_v,
            &self.std_w,
            &self.dv,
            &self.dw,
        ]
    }
}

/// Writes rows with the header [`TWIST_CSV_HEADER`], absolute times with 9 decimals and the
/// other values with the shortest digits that read back exactly, atomically.
pub fn write_twist_csv(path: &Path, epoch: Epoch, rows: &[TwistRow]) -> Result<()> {
    let mut out = String::with_capacity(64 + rows.len() * 200);
    out.push_str(TWIST_CSV_HEADER);
    out.push('\n');
    for (i, r) in rows.iter().enumerate() {
        if !r.t.is_finite() || r.vectors().iter().any(|v| v.iter().any(|x| !x.is_finite())) {
            return Err(non_finite(path, format!("twist row {i}")));
        }
        out.push_str(&epoch.format_abs(r.t, 9));
        for v in r.vectors() {
            for x in v.iter() {
                let _ = write!(out, ",{}", fmt_f64(*x));
            }
        }
        out.push('\n');
    }
    super::write_atomic(path, out.as_bytes())
}

/// Reads a file written by [`write_twist_csv`]. The first non-blank line must be the header;
/// blank lines are skipped.
pub fn read_twist_csv(path: &Path, epoch: Epoch) -> Result<Vec<TwistRow>> {
    let text = crate::files::read_text(path)?;
    parse_twist_csv(&text, path, epoch)
}

/// Parses the text of a twist CSV file as [`read_twist_csv`] does; `path` names the file in
/// messages.
pub fn parse_twist_csv(text: &str, path: &Path, epoch: Epoch) -> Result<Vec<TwistRow>> {
    let names: Vec<&str> = TWIST_CSV_HEADER.split(',').collect();
    let mut rows = Vec::new();
    let mut seen_header = false;
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let content = raw.trim();
        if content.is_empty() {
            continue;
        }
        if !seen_header {
            if content != TWIST_CSV_HEADER {
                return Err(Error::parse(
                    path,
                    line,
                    format!("expected the header '{TWIST_CSV_HEADER}'"),
                ));
            }
            seen_header = true;
            continue;
        }
        let fields: Vec<&str> = content.split(',').map(str::trim).collect();
        if fields.len() != names.len() {
            return Err(Error::parse(
                path,
                line,
                format!("expected {} fields, found {}", names.len(), fields.len()),
            ));
        }
        let t = epoch.rel(parse_time(path, line, fields[0])?);
        let mut x = [0.0; 18];
        for (k, slot) in x.iter_mut().enumerate() {
            *slot = parse_finite(path, line, names[k + 1], fields[k + 1])?;
        }
        let v3 = |k: usize| Vector3::new(x[3 * k], x[3 * k + 1], x[3 * k + 2]);
        rows.push(TwistRow {
            t,
            v: v3(0),
            w: v3(1),
            std_v: v3(2),
            std_w: v3(3),
            dv: v3(4),
            dw: v3(5),
        });
    }
    if !seen_header {
        return Err(Error::parse(
            path,
            super::last_line(text),
            "empty file: no header",
        ));
    }
    Ok(rows)
}
