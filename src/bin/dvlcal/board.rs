//! `dvlcal board`: an SVG of a board definition, to print at exact scale.

use anyhow::{Context, Result};
use std::path::PathBuf;

use dvlcal::vision::board::Board;
use dvlcal::vision::board_svg::board_svg;

#[derive(clap::Args)]
pub struct BoardArgs {
    /// Board definition (dvlcal grid or list YAML, or Kalibr aprilgrid YAML).
    #[arg(long)]
    pub target: PathBuf,
    /// SVG to write (width and height in millimetres; print at 100 % scale).
    #[arg(long)]
    pub out: PathBuf,
}

pub fn run(a: BoardArgs) -> Result<()> {
    let board = Board::load(&a.target)?;
    let svg = board_svg(&board, &a.target.display().to_string())?;
    std::fs::write(&a.out, svg).with_context(|| format!("writing {}", a.out.display()))?;
    println!("wrote {}: {}", a.out.display(), board.description);
    Ok(())
}
