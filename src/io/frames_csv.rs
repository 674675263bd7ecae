//! The per-frame table written beside a TUM pose file (`POSES.frames.csv`): one row per pose, in
//! the TUM file's order, with the detection statistics and the 6x6 covariance of the pose.
//!
//! `dvlcal detect` writes it; reading a TUM file that has one beside it gives the poses their
//! covariances back, so poses detected in one run and calibrated in another are weighted as
//! they are when images are calibrated directly.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use nalgebra::Matrix6;

use super::tum::{TumPoses, read_tum};
use super::{content_lines, last_line, parse_finite, parse_time};
use crate::error::{Error, Result};
use crate::time::Epoch;

/// The columns before the covariance's 21 upper-triangle values.
const LEADING: [&str; 6] = ["t", "tags", "corners", "rms_px", "rejected", "sigma_px"];

/// Columns of a row: the leading six and the upper triangle of a 6x6 matrix.
const COLUMNS: usize = LEADING.len() + 21;

/// Largest difference between a row's time and its pose's time in the TUM file, s: a time
/// written with six decimals instead of nine still matches; a different frame (at least a
/// millisecond away at any camera rate) does not.
pub const TIME_MATCH_TOL_S: f64 = 1e-6;

/// `POSES.frames.csv` beside the TUM file `POSES`.
pub fn frames_csv_path(tum: &Path) -> PathBuf {
    let mut name = tum.as_os_str().to_owned();
    name.push(".frames.csv");
    PathBuf::from(name)
}

/// One posed frame of the table.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameRow {
    /// Camera-clock time relative to the table's epoch, s.
    pub t: f64,
    /// Tag observations used (a tag seen by both cameras counts twice).
    pub tags: usize,
    /// Board corners used.
    pub corners: usize,
    /// Reprojection RMS of the used corners, px.
    pub rms_px: f64,
    /// Tag observations rejected as outliers.
    pub rejected: usize,
    /// Corner noise the covariance was computed with, px.
    pub sigma_px: f64,
    /// Covariance of the right perturbation `[rho; phi]` of `T_world_cam0` (m, rad).
    pub cov: Matrix6<f64>,
}

/// The table's text: a comment line, the header and one row per entry of `rows` (times with nine
/// decimals on `epoch`, covariances with the shortest digits that read back to the same value).
pub fn format_frames_csv(epoch: &Epoch, rows: &[FrameRow]) -> String {
    let mut s = String::from(
        "# one row per pose of the TUM file: time (s), tag observations used (a tag in both \
         cameras counts twice), corners used, reprojection RMS (px), observations rejected, \
         pixel sigma used for the covariance, then the 21 upper-triangle values (row by row) of \
         the 6x6 covariance of the right perturbation [rho; phi] of T_world_cam0 (m, rad)\n",
    );
    s.push_str(&header());
    s.push('\n');
    for r in rows {
        let _ = write!(
            s,
            "{},{},{},{},{},{}",
            epoch.format_abs(r.t, 9),
            r.tags,
            r.corners,
            r.rms_px,
            r.rejected,
            r.sigma_px
        );
        for i in 0..6 {
            for j in i..6 {
                let _ = write!(s, ",{:e}", r.cov[(i, j)]);
            }
        }
        s.push('\n');
    }
    s
}

fn header() -> String {
    let mut h = LEADING.join(",");
    for i in 0..6 {
        for j in i..6 {
            let _ = write!(h, ",c{i}{j}");
        }
    }
    h
}

/// A table read from a file.
#[derive(Clone, Debug)]
pub struct FramesTable {
    /// The rows, in file order.
    pub rows: Vec<FrameRow>,
    /// The 1-based source line of each row.
    pub lines: Vec<usize>,
    /// The file's last line (for errors about missing rows).
    pub last_line: usize,
}

/// Reads a frames table; times are made relative to `epoch`. Every row must have the 27 columns
/// of the header, finite numbers, non-negative counts and a symmetric positive-definite
/// covariance; the first row that does not is an error naming the file and line.
pub fn read_frames_csv(path: &Path, epoch: &Epoch) -> Result<FramesTable> {
    let text = crate::files::read_text(path)?;
    parse_frames_csv(&text, path, epoch)
}

/// Parses the text of a frames table as [`read_frames_csv`] does; `path` names the file in
/// messages.
pub fn parse_frames_csv(text: &str, path: &Path, epoch: &Epoch) -> Result<FramesTable> {
    let expected = header();
    let mut lines = content_lines(text);
    match lines.next() {
        Some((_, h)) if h.replace(' ', "") == expected => {}
        Some((line, h)) => {
            return Err(Error::parse(
                path,
                line,
                format!("expected the header '{expected}', found '{h}'"),
            ));
        }
        None => return Err(Error::parse(path, last_line(text), "no header and no rows")),
    }
    let mut table = FramesTable {
        rows: Vec::new(),
        lines: Vec::new(),
        last_line: last_line(text),
    };
    for (line, content) in lines {
        let fields: Vec<&str> = content.split(',').map(str::trim).collect();
        if fields.len() != COLUMNS {
            return Err(Error::parse(
                path,
                line,
                format!(
                    "expected {COLUMNS} comma-separated fields, found {}",
                    fields.len()
                ),
            ));
        }
        let t = epoch.rel(parse_time(path, line, fields[0])?);
        let count = |k: usize| -> Result<usize> {
            fields[k].parse::<usize>().map_err(|_| {
                Error::parse(
                    path,
                    line,
                    format!("{}: '{}' is not a count", LEADING[k], fields[k]),
                )
            })
        };
        let number = |k: usize, what: &str| parse_finite(path, line, what, fields[k]);
        let mut cov = Matrix6::zeros();
        let mut k = LEADING.len();
        for i in 0..6 {
            for j in i..6 {
                let v = number(k, &format!("c{i}{j}"))?;
                cov[(i, j)] = v;
                cov[(j, i)] = v;
                k += 1;
            }
        }
        if cov.cholesky().is_none() {
            return Err(Error::parse(
                path,
                line,
                "the pose covariance is not positive definite",
            ));
        }
        table.rows.push(FrameRow {
            t,
            tags: count(1)?,
            corners: count(2)?,
            rms_px: number(3, LEADING[3])?,
            rejected: count(4)?,
            sigma_px: number(5, LEADING[5])?,
            cov,
        });
        table.lines.push(line);
    }
    Ok(table)
}

/// Gives the poses of `tum` (read from `tum_path`) the covariances of `table` (read from
/// `frames_path` on the poses' epoch). The rows must match the poses one for one, in
/// order, each time within [`TIME_MATCH_TOL_S`] of its pose's; a missing, extra or mismatched
/// row is an error naming the table's line (and the TUM file's line it should match), and the
/// poses are left untouched.
pub fn attach_covariances(
    tum: &mut TumPoses,
    tum_path: &Path,
    table: &FramesTable,
    frames_path: &Path,
) -> Result<()> {
    let n = tum.poses.len();
    for (k, (row, line)) in table.rows.iter().zip(&table.lines).enumerate() {
        if k >= n {
            return Err(Error::parse(
                frames_path,
                *line,
                format!(
                    "row {} has no pose: {} holds {n} poses (the table must have one row per \
                     pose, in order)",
                    k + 1,
                    tum_path.display()
                ),
            ));
        }
        let pose_t = tum.own_time(k);
        if (row.t - pose_t).abs() > TIME_MATCH_TOL_S {
            return Err(Error::parse(
                frames_path,
                *line,
                format!(
                    "row {} is at time {}, but pose {} ({}:{}) is at {} (the table must have one \
                     row per pose, in order)",
                    k + 1,
                    tum.epoch.format_abs(row.t, 9),
                    k + 1,
                    tum_path.display(),
                    tum.lines[k],
                    tum.epoch.format_abs(pose_t, 9)
                ),
            ));
        }
    }
    if table.rows.len() < n {
        let k = table.rows.len();
        return Err(Error::parse(
            frames_path,
            table.last_line,
            format!(
                "{} rows for the {n} poses of {}: pose {} ({}:{}) has no row",
                table.rows.len(),
                tum_path.display(),
                k + 1,
                tum_path.display(),
                tum.lines[k]
            ),
        ));
    }
    for (pose, row) in tum.poses.iter_mut().zip(&table.rows) {
        pose.cov = Some(row.cov);
    }
    Ok(())
}

/// Reads a TUM pose file and, when `POSES.frames.csv` sits beside it, the poses' covariances
/// from that table ([`attach_covariances`]). Returns the poses and the table's path when one
/// was read.
pub fn read_tum_with_covariances(
    path: &Path,
    epoch: Option<Epoch>,
) -> Result<(TumPoses, Option<PathBuf>)> {
    let mut tum = read_tum(path, epoch)?;
    let frames = frames_csv_path(path);
    if frames.is_file() {
        let table = read_frames_csv(&frames, &tum.epoch)?;
        attach_covariances(&mut tum, path, &table, &frames)?;
        Ok((tum, Some(frames)))
    } else {
        Ok((tum, None))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::tum::parse_tum;
    use crate::time::RawTime;

    fn cov(scale: f64) -> Matrix6<f64> {
        let mut c = Matrix6::from_diagonal_element(scale);
        c[(0, 1)] = 0.1 * scale;
        c[(1, 0)] = 0.1 * scale;
        c
    }

    fn table(epoch: &Epoch, times: &[f64]) -> String {
        let rows: Vec<FrameRow> = times
            .iter()
            .enumerate()
            .map(|(k, t)| FrameRow {
                t: *t,
                tags: 40 + k,
                corners: 160,
                rms_px: 0.123,
                rejected: 0,
                sigma_px: 0.2,
                cov: cov(1e-6 * (k + 1) as f64),
            })
            .collect();
        format_frames_csv(epoch, &rows)
    }

    const TUM: &str = "# t x y z qx qy qz qw\n\
        1700000000.100000000 0 0 1 0 0 0 1\n\
        1700000000.200000000 0 0 1 0 0 0 1\n\
        1700000000.300000000 0 0 1 0 0 0 1\n";

    fn tum() -> TumPoses {
        parse_tum(TUM, Path::new("p.txt"), None).unwrap()
    }

    #[test]
    fn rows_round_trip_exactly() {
        let epoch = Epoch::at(RawTime::parse("1700000000").unwrap());
        let text = table(&epoch, &[0.1, 0.2, 0.3]);
        let t = parse_frames_csv(&text, Path::new("f.csv"), &epoch).unwrap();
        assert_eq!(t.rows.len(), 3);
        assert_eq!(t.lines, vec![3, 4, 5]);
        assert_eq!(t.rows[1].cov, cov(2e-6));
        assert_eq!(t.rows[2].tags, 42);
        assert_eq!(t.rows[0].t, 0.1);
    }

    fn attach_text(frames: &str) -> Result<TumPoses> {
        let f = Path::new("p.txt.frames.csv");
        let mut poses = tum();
        let table = parse_frames_csv(frames, f, &poses.epoch)?;
        attach_covariances(&mut poses, Path::new("p.txt"), &table, f).map(|()| poses)
    }

    #[test]
    fn covariances_attach_to_their_poses() {
        let p = attach_text(&table(&tum().epoch, &[0.1, 0.2, 0.3])).unwrap();
        assert_eq!(p.poses[0].cov, Some(cov(1e-6)));
        assert_eq!(p.poses[2].cov, Some(cov(3e-6)));
    }

    #[test]
    fn a_missing_row_names_the_pose_without_one() {
        let e = attach_text(&table(&tum().epoch, &[0.1, 0.2]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("p.txt.frames.csv:4"), "{e}");
        assert!(e.contains("2 rows for the 3 poses"), "{e}");
        assert!(e.contains("pose 3 (p.txt:4)"), "{e}");
    }

    #[test]
    fn an_extra_row_is_an_error_at_its_line() {
        let e = attach_text(&table(&tum().epoch, &[0.1, 0.2, 0.3, 0.4]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("p.txt.frames.csv:6"), "{e}");
        assert!(e.contains("row 4 has no pose"), "{e}");
    }

    #[test]
    fn a_shifted_row_names_both_lines() {
        let e = attach_text(&table(&tum().epoch, &[0.1, 0.25, 0.3]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("p.txt.frames.csv:4"), "{e}");
        assert!(e.contains("(p.txt:3)"), "{e}");
        // Times rounded to fewer decimals match within the tolerance, not beyond it.
        let good = table(&tum().epoch, &[0.1, 0.2, 0.3]);
        let near = good.replace(".200000000,", ".2000004,");
        assert!(near.contains("1700000000.2000004,"));
        assert!(attach_text(&near).is_ok());
        let far = good.replace(".200000000,", ".200002,");
        let e = attach_text(&far).unwrap_err().to_string();
        assert!(
            e.contains("p.txt.frames.csv:4: row 2 is at time 1700000000.200002000"),
            "{e}"
        );
    }

    #[test]
    fn bad_numbers_name_the_line_and_column() {
        let good = table(&tum().epoch, &[0.1, 0.2, 0.3]);
        let mut lines: Vec<String> = good.lines().map(str::to_owned).collect();
        lines[3] = lines[3].replacen(",0.123,", ",0.1x3,", 1);
        let e = attach_text(&lines.join("\n")).unwrap_err().to_string();
        assert!(e.contains("p.txt.frames.csv:4"), "{e}");
        assert!(e.contains("rms_px: '0.1x3' is not a number"), "{e}");

        let mut lines: Vec<String> = good.lines().map(str::to_owned).collect();
        lines[4] = lines[4].replacen(",42,", ",-4,", 1);
        let e = attach_text(&lines.join("\n")).unwrap_err().to_string();
        assert!(
            e.contains("p.txt.frames.csv:5: tags: '-4' is not a count"),
            "{e}"
        );

        let short = good.replace(",0.2,", ",0.2,,");
        let e = attach_text(&short).unwrap_err().to_string();
        assert!(e.contains("p.txt.frames.csv:3: expected 27"), "{e}");
    }

    #[test]
    fn a_covariance_that_is_not_positive_definite_is_refused() {
        let good = table(&tum().epoch, &[0.1, 0.2, 0.3]);
        let mut lines: Vec<String> = good.lines().map(str::to_owned).collect();
        // The first covariance value (c00) of the second row, made negative.
        let mut f: Vec<String> = lines[3].split(',').map(str::to_owned).collect();
        f[6] = "-2e-6".into();
        lines[3] = f.join(",");
        let e = attach_text(&lines.join("\n")).unwrap_err().to_string();
        assert!(e.contains("p.txt.frames.csv:4"), "{e}");
        assert!(e.contains("not positive definite"), "{e}");
    }

    #[test]
    fn a_wrong_header_is_named() {
        let e = attach_text("t,x,y\n1700000000.1,1,2\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("p.txt.frames.csv:1: expected the header"), "{e}");
    }
}
