//! `dvlcal board`: an SVG of a board definition, to print at exact scale.

use anyhow::Result;
use std::path::PathBuf;

use dvlcal::io::target::read_board;
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
    dvlcal::files::refuse_input("--out", &a.out, [a.target.as_path()])?;
    dvlcal::files::prepare_output("--out", &a.out)?;
    let board = read_board(&a.target)?;
    let svg = board_svg(&board, &a.target.display().to_string())?;
    dvlcal::io::write_atomic(&a.out, svg.as_bytes())?;
    println!("wrote {}: {}", a.out.display(), board.description);
    Ok(())
}
