//! `dvlcal board`: an SVG of a board definition, to print at exact scale.

use anyhow::Result;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct BoardArgs {
    /// Board definition (dvlcal grid or list YAML, or Kalibr aprilgrid YAML).
    #[arg(long)]
    pub target: PathBuf,
    /// SVG to write (width and height in millimetres; print at 100 % scale).
    #[arg(long)]
    pub out: PathBuf,
    /// Paper (A0-A5, letter, legal, tabloid [landscape], or WxH mm): the SVG is that size, the
    /// board centred 10 mm or more from each edge. Default: the board file's `paper`, if any.
    #[arg(long, value_name = "PAPER")]
    pub paper: Option<String>,
}

pub fn run(a: BoardArgs) -> Result<()> {
    let what = dvlcal::pipeline::write_board_svg(&a.target, &a.out, a.paper.as_deref())?;
    println!("wrote {}: {what}", a.out.display());
    Ok(())
}
