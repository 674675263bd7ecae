//! `dvlcal detect` against Debian's `apriltag` CLI on the same rendered 752x480 stereo frames,
//! for both prints of the board (libapriltag's and Kalibr's).
//!
//! [`Frames::render`] writes the frames once, as PNG (what `detect` reads) and as binary PGM
//! (what the CLI reads); [`Frames::dvlcal_seconds`] times `detect`'s pipeline (PNG decode,
//! detection, corner refinement, stereo PnP) on a rayon pool of N threads, and
//! [`Frames::cli_seconds`] the CLI as N processes of `apriltag -t 1`, each on its share of the
//! PGM files (its fastest use of N cores). [`compare`] does all of it for one board print and
//! the thread counts asked for; [`detect_vs_cli`] is the one-line summary another bench prints.
//!
//! Include it with `#[path = "common/detect_compare.rs"] mod detect_compare;`.

#![allow(dead_code)]

#[path = "../../tests/vision_seq/mod.rs"]
mod vision_seq;

use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::Instant;

use dvlcal::io::image::load_gray;
use dvlcal::io::images::{StereoFrame, scan_images};
use dvlcal::sim::render::RenderSettings;
use dvlcal::types::board::Board;
use dvlcal::types::camera::Camchain;
use dvlcal::vision::detect::DetectorSettings;
use dvlcal::vision::frames::detect_frames;
use dvlcal::vision::pnp::PnpOptions;

/// Quad decimation of both detectors (the default of both).
pub const DECIMATE: f32 = 2.0;

/// The detector settings `dvlcal detect` uses for `board` at [`DECIMATE`].
pub fn pipeline_settings(board: &Board) -> DetectorSettings {
    dvlcal::pipeline::detector_settings(
        board,
        &dvlcal::pipeline::VisionOptions {
            decimate: DECIMATE,
            ..Default::default()
        },
    )
}

/// How the board's tags are printed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Print {
    /// As libapriltag draws them (one-bit border, white ring): dvlcal's own board YAML.
    Apriltag,
    /// As Kalibr prints an aprilgrid (two-bit border, corner squares).
    Kalibr,
}

impl Print {
    /// A short label for tables.
    pub fn label(self) -> &'static str {
        match self {
            Print::Apriltag => "libapriltag print",
            Print::Kalibr => "Kalibr print",
        }
    }
}

/// Rendered frames on disk, as PNG and as PGM; removed when dropped.
pub struct Frames {
    /// The board print.
    pub print: Print,
    /// Stereo frames.
    pub n: usize,
    /// Where they are.
    pub dir: PathBuf,
    /// The frames as `scan_images` lists them (PNG).
    pub frames: Vec<StereoFrame>,
    /// The same images as binary PGM, in frame order, cam0 then cam1.
    pub pgm: Vec<PathBuf>,
    /// The board the frames show.
    pub board: Board,
    /// The stereo camera chain.
    pub chain: Camchain,
}

impl Frames {
    /// Renders `n` stereo frames of the 6x6 tag36h11 grid (88 mm tags, 0.9-1.3 m away) with the
    /// default render settings, and writes them as PNG and PGM.
    pub fn render(print: Print, n: usize) -> Frames {
        let name = match print {
            Print::Apriltag => "cmp-apriltag",
            Print::Kalibr => "cmp-kalibr",
        };
        let dir = vision_seq::fresh_dir(name);
        let board = match print {
            Print::Apriltag => vision_seq::board(),
            Print::Kalibr => vision_seq::board().printed_by_kalibr(),
        };
        let (_, times) =
            vision_seq::write_sequence_of(&dir, n, &RenderSettings::default(), 7, &board);
        let chain = vision_seq::chain();
        let (frames, _) = scan_images(&dir, 2, 1_000_000).expect("scan");
        let pgm_dir = dir.join("pgm");
        std::fs::create_dir_all(&pgm_dir).expect("pgm folder");
        let mut pgm = Vec::new();
        for &t in &times {
            for c in 0..2 {
                let img = load_gray(&vision_seq::image_path(&dir, c, t)).expect("png");
                let p = pgm_dir.join(format!("cam{c}_{t}.pgm"));
                // Binary PGM (P5) with a minimal header, as libapriltag's reader wants it.
                let mut bytes = format!("P5\n{} {}\n255\n", img.width(), img.height()).into_bytes();
                bytes.extend_from_slice(img.as_raw());
                std::fs::write(&p, bytes).expect("pgm");
                pgm.push(p);
            }
        }
        Frames {
            print,
            n,
            dir,
            frames,
            pgm,
            board,
            chain,
        }
    }

    /// Images (two per frame).
    pub fn images(&self) -> usize {
        2 * self.frames.len()
    }

    /// Best of `reps` wall times of `detect`'s pipeline on a pool of `threads` threads (one
    /// single-threaded detector per thread, as `dvlcal detect --threads N` runs).
    pub fn dvlcal_seconds(&self, threads: usize, reps: usize) -> f64 {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool");
        let settings = pipeline_settings(&self.board);
        let opts = PnpOptions::default();
        best_of(reps, || {
            let s = Instant::now();
            let (_, st) = pool
                .install(|| {
                    detect_frames(
                        &self.frames,
                        &self.board,
                        &self.chain,
                        &settings,
                        &opts,
                        false,
                    )
                })
                .expect("detect");
            let secs = s.elapsed().as_secs_f64();
            assert_eq!(st.poses, self.frames.len(), "every frame posed");
            Some(secs)
        })
        .unwrap_or(f64::NAN)
    }

    /// Best of `reps` wall times of the CLI over the PGM files as `procs` processes of
    /// `apriltag -t threads`, each on a contiguous share of the files (process start and PGM
    /// reading included). `None` when the CLI is not installed or fails.
    pub fn cli_seconds(&self, procs: usize, threads: usize, reps: usize) -> Option<f64> {
        best_of(reps, || cli_once(&self.pgm, procs, threads))
    }
}

impl Drop for Frames {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// Whether Debian's `apriltag` CLI can be run.
pub fn have_cli() -> bool {
    Command::new("apriltag")
        .arg("-h")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok()
}

fn cli_once(files: &[PathBuf], procs: usize, threads: usize) -> Option<f64> {
    let chunk = files.len().div_ceil(procs.max(1)).max(1);
    let start = Instant::now();
    let children: Vec<_> = files
        .chunks(chunk)
        .map(|c| {
            Command::new("apriltag")
                .args([
                    "-q",
                    "-t",
                    &threads.to_string(),
                    "-x",
                    &DECIMATE.to_string(),
                ])
                .args(c)
                .stdout(Stdio::null())
                .spawn()
        })
        .collect::<Result<_, _>>()
        .ok()?;
    let mut ok = true;
    for mut ch in children {
        ok &= ch.wait().is_ok_and(|s| s.success());
    }
    ok.then(|| start.elapsed().as_secs_f64())
}

/// The smallest of `reps` timings (`None` if any fails).
pub fn best_of<F: FnMut() -> Option<f64>>(reps: usize, mut f: F) -> Option<f64> {
    let mut best: Option<f64> = None;
    for _ in 0..reps.max(1) {
        let s = f()?;
        best = Some(best.map_or(s, |b: f64| b.min(s)));
    }
    best
}

/// Throughput with one number of cores.
#[derive(Clone, Copy, Debug)]
pub struct Row {
    /// Threads of dvlcal's pool, and processes of the CLI.
    pub threads: usize,
    /// `dvlcal detect`, images per second.
    pub dvlcal: f64,
    /// The CLI as `threads` processes of `-t 1`, images per second (`None`: no CLI).
    pub cli: Option<f64>,
}

impl Row {
    /// dvlcal's throughput over the CLI's (above 1: dvlcal is faster).
    pub fn ratio(&self) -> Option<f64> {
        self.cli.map(|c| self.dvlcal / c)
    }
}

/// Renders `n` frames of the board printed as `print` and times both on each thread count,
/// best of `reps`; the two are timed one after the other for each thread count, so that a change
/// of the machine's load hits both alike.
pub fn compare(print: Print, n: usize, threads: &[usize], reps: usize) -> Vec<Row> {
    let frames = Frames::render(print, n);
    let cli = have_cli();
    let images = frames.images() as f64;
    threads
        .iter()
        .map(|&t| {
            let ours = frames.dvlcal_seconds(t, reps);
            let theirs = if cli {
                frames.cli_seconds(t, 1, reps)
            } else {
                None
            };
            Row {
                threads: t,
                dvlcal: images / ours,
                cli: theirs.map(|s| images / s),
            }
        })
        .collect()
}

/// `dvlcal detect` over the CLI's fastest use of all the machine's cores, per board print, on
/// `n` rendered stereo frames: the line a bench prints. `None` in place of a ratio when the CLI
/// is not installed.
pub fn detect_vs_cli(n: usize) -> Vec<(Print, Option<f64>)> {
    let cores = std::thread::available_parallelism().map_or(1, |c| c.get());
    [Print::Apriltag, Print::Kalibr]
        .into_iter()
        .map(|p| (p, compare(p, n, &[cores], 3)[0].ratio()))
        .collect()
}
