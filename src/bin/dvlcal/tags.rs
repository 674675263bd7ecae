//! `dvlcal tags`: AprilTag detections of images as CSV (corners in the OpenCV pixel convention;
//! the last column is the border width in bits: 1 as libapriltag prints tags, 2 as Kalibr does).

use std::io::Write as _;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;
use dvlcal::io::image::load_gray;
use dvlcal::types::board::TagFamily;
use dvlcal::vision::detect::{Detector, DetectorSettings};

#[derive(Args, Debug)]
pub struct TagsArgs {
    /// Images to read (PNG, JPEG, PGM/PPM); colour images are converted to grey.
    #[arg(required = true, value_name = "IMAGE")]
    pub images: Vec<PathBuf>,
    /// Tag family, as libapriltag names it (tag36h11, tag25h9, tag16h5, tagCircle21h7, ...).
    #[arg(long, value_name = "F", default_value = "tag36h11")]
    pub family: String,
    /// Decimation factor of the image for quad detection (no unit; corners are refined at full
    /// resolution).
    #[arg(long, value_name = "X", default_value_t = 2.0)]
    pub decimate: f32,
    /// Gaussian blur sigma (pixels) for quad detection; negative sharpens.
    #[arg(long, value_name = "S", default_value_t = 0.0)]
    pub sigma: f32,
    /// Sharpening of the decoded bits (no unit; libapriltag's decode_sharpening).
    #[arg(long, value_name = "S", default_value_t = 0.25)]
    pub sharpening: f64,
    /// Do not snap quad edges to the image gradients (libapriltag's own refinement).
    #[arg(long)]
    pub no_refine_edges: bool,
    /// Report libapriltag's corners as they are, without the line-fit refinement of each side.
    #[arg(long)]
    pub no_refine_corners: bool,
    /// Detector threads (at most 4 per core, 256 in all).
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub threads: usize,
    /// Largest number of corrected bits of an accepted tag (0..=3).
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub max_hamming: u32,
}

pub fn run(a: TagsArgs) -> Result<()> {
    let family = TagFamily::from_name(&a.family).with_context(|| {
        format!(
            "unknown tag family {:?} (known: {})",
            a.family,
            TagFamily::ALL
                .iter()
                .map(|f| f.name())
                .collect::<Vec<_>>()
                .join(", ")
        )
    })?;
    let settings = DetectorSettings {
        family,
        decimate: a.decimate,
        sigma: a.sigma,
        sharpening: a.sharpening,
        refine_edges: !a.no_refine_edges,
        refine_corners: !a.no_refine_corners,
        threads: dvlcal::parallel::capped_threads("--threads", a.threads).0,
        max_hamming: a.max_hamming,
        ..DetectorSettings::default()
    };
    let mut det = Detector::new(&settings)?;
    let stdout = std::io::stdout();
    let mut out = std::io::BufWriter::new(stdout.lock());
    writeln!(
        out,
        "file,id,hamming,decision_margin,x0,y0,x1,y1,x2,y2,x3,y3,border_bits"
    )?;
    let mut failed = 0usize;
    for path in &a.images {
        let gray = match load_gray(path) {
            Ok(g) => g,
            Err(e) => {
                eprintln!("error: {e:#}");
                failed += 1;
                continue;
            }
        };
        let name = csv_field(&path.display().to_string());
        for d in det.detect(&gray) {
            write!(out, "{name},{},{},{}", d.id, d.hamming, d.decision_margin)?;
            for c in &d.corners {
                write!(out, ",{},{}", c.x, c.y)?;
            }
            writeln!(out, ",{}", d.border_bits)?;
        }
    }
    out.flush()?;
    if failed > 0 {
        eprintln!("{failed} of {} images could not be read", a.images.len());
    }
    if failed == a.images.len() {
        bail!("no image could be read");
    }
    Ok(())
}

/// A CSV field, quoted when it holds a comma, quote or line break.
fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}
