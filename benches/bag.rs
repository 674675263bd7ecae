//! Images from a bag against the same images from a folder, and the memory a long bag needs.
//!
//! `cargo bench --bench bag [-- DIR]` (default DIR `/tmp/dvlcal-bench`), with the bags made by
//! the independent writer first:
//!
//! ```sh
//! python3 -m venv /tmp/rb && /tmp/rb/bin/pip install rosbags numpy pillow
//! /tmp/rb/bin/python scripts/make_bench_bag.py --jpeg-sample --out /tmp/dvlcal-bench/stereo_jpeg
//! /tmp/rb/bin/python scripts/make_bench_bag.py --gb 1 --out /tmp/dvlcal-bench/raw_1gb
//! /tmp/rb/bin/python scripts/make_bench_bag.py --gb 5 --out /tmp/dvlcal-bench/raw_5gb
//! ```
//!
//! 1. Throughput: `sample_data/stereo` (251 JPEG stereo frames) read from its folder, and the
//!    same JPEG files as `sensor_msgs/CompressedImage` in an MCAP bag, through the same
//!    detection and PnP (`poses_from_images` against `poses_from_bag`), best of three.
//! 2. Memory: the peak resident memory of detecting every frame of raw `mono8` bags of 1 and
//!    5 GB (the process's high-water mark, reset before each run through
//!    `/proc/self/clear_refs`).
//!
//! Missing bags are skipped with the command that makes them.

use std::path::{Path, PathBuf};
use std::time::Instant;

use dvlcal::io::bag::frames::plan_frames;
use dvlcal::io::bag::open::OpenBag;
use dvlcal::io::bag::roles::BagOptions;
use dvlcal::io::camchain::read_camchain;
use dvlcal::pipeline::{VisionOptions, poses_from_bag, poses_from_images};

fn sample(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("sample_data")
        .join(rel)
}

/// The process's peak resident memory since the last reset, MB.
fn peak_rss_mb() -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.split_whitespace().next())
        .and_then(|kb| kb.parse::<f64>().ok())
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

/// Resets the peak resident memory to the current one.
fn reset_peak() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

fn opts(threads: usize) -> VisionOptions {
    VisionOptions {
        threads: Some(threads),
        ..VisionOptions::default()
    }
}

/// Detects every frame of `bag`; (frames, posed, seconds).
fn run_bag(bag: &Path, threads: usize) -> (usize, usize, f64) {
    let start = Instant::now();
    let ob = OpenBag::open(bag, &BagOptions::default()).expect("open bag");
    let o = opts(threads);
    let plan = plan_frames(&ob, (o.pair_tolerance_ms * 1e6) as i64).expect("plan");
    let chain = read_camchain(&sample("stereo/camchain.yaml")).expect("camchain");
    let run = poses_from_bag(&ob, &plan, chain, &sample("stereo/target.yaml"), &o).expect("run");
    (
        run.stats.frames,
        run.stats.poses,
        start.elapsed().as_secs_f64(),
    )
}

fn run_folder(threads: usize) -> (usize, usize, f64) {
    let start = Instant::now();
    let run = poses_from_images(
        &sample("stereo"),
        &sample("stereo/camchain.yaml"),
        &sample("stereo/target.yaml"),
        &opts(threads),
    )
    .expect("run");
    (
        run.stats.frames,
        run.stats.poses,
        start.elapsed().as_secs_f64(),
    )
}

/// The bytes of a bag: a file, or the files of a ROS 2 bag folder.
fn bag_bytes(path: &Path) -> Option<u64> {
    let meta = std::fs::metadata(path).ok()?;
    if meta.is_file() {
        return Some(meta.len());
    }
    let mut n = 0;
    for e in std::fs::read_dir(path).ok()? {
        n += e.ok()?.metadata().ok()?.len();
    }
    Some(n)
}

fn best<F: FnMut() -> (usize, usize, f64)>(mut f: F) -> (usize, usize, f64) {
    let mut out = f();
    for _ in 0..2 {
        let r = f();
        if r.2 < out.2 {
            out = r;
        }
    }
    out
}

fn main() {
    let dir = std::env::args()
        .skip(1)
        .find(|a| !a.starts_with('-'))
        .map_or_else(|| PathBuf::from("/tmp/dvlcal-bench"), PathBuf::from);
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    println!("| input | frames | posed | threads | seconds | images/s |");
    println!("|---|---|---|---|---|---|");
    let jpeg = dir.join("stereo_jpeg");
    let mut rates = Vec::new();
    for t in [1, threads] {
        let (n, p, s) = best(|| run_folder(t));
        println!(
            "| sample_data/stereo folder (JPEG) | {n} | {p} | {t} | {s:.2} | {:.1} |",
            2.0 * n as f64 / s
        );
        if jpeg.exists() {
            let (nb, pb, sb) = best(|| run_bag(&jpeg, t));
            println!(
                "| same JPEGs, MCAP CompressedImage | {nb} | {pb} | {t} | {sb:.2} | {:.1} |",
                2.0 * nb as f64 / sb
            );
            rates.push((t, s / sb));
        } else {
            eprintln!(
                "skipped {}: make it with scripts/make_bench_bag.py --jpeg-sample",
                jpeg.display()
            );
        }
    }
    for (t, r) in rates {
        println!("bag / folder images per second, {t} threads: {r:.3}");
    }
    println!();
    println!(
        "| raw mono8 MCAP bag | size GB | frames | posed | seconds | images/s | peak RSS MB |"
    );
    println!("|---|---|---|---|---|---|---|");
    for name in ["raw_1gb", "raw_5gb"] {
        let bag = dir.join(name);
        let Some(bytes) = bag_bytes(&bag) else {
            eprintln!(
                "skipped {}: make it with scripts/make_bench_bag.py --gb N",
                bag.display()
            );
            continue;
        };
        reset_peak();
        let (n, p, s) = run_bag(&bag, threads);
        println!(
            "| {name} | {:.2} | {n} | {p} | {s:.1} | {:.1} | {:.0} |",
            bytes as f64 / 1e9,
            2.0 * n as f64 / s,
            peak_rss_mb()
        );
    }
}
