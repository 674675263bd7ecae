//! `dvlcal board` as a library call: a board file printed as an SVG at exact scale, on the paper
//! the file or the caller names.

use std::path::Path;

use crate::error::Result;
use crate::io::target::{paper_option, read_board};
use crate::vision::board_svg::board_svg;

/// Reads the board `target`, lays it out on `paper` (a `--paper` value; `None`: the file's own
/// `paper`, if any) and writes its SVG to `out` atomically; `out` may not be `target`. Returns
/// what was printed, in words: the board's description and the paper.
pub fn write_board_svg(target: &Path, out: &Path, paper: Option<&str>) -> Result<String> {
    crate::files::refuse_input("--out", out, [target])?;
    crate::files::prepare_output("--out", out)?;
    let mut board = read_board(target)?;
    if let Some(p) = paper {
        board.paper = Some(paper_option(p)?);
    }
    let svg = board_svg(&board, &target.display().to_string())
        .map_err(|e| e.during(target.display().to_string()))?;
    crate::io::write_atomic(out, svg.as_bytes())?;
    Ok(match &board.paper {
        Some(p) => format!("{} on {p}; print at 100 % (actual size)", board.description),
        None => board.description,
    })
}
