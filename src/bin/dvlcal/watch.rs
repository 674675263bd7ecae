//! `dvlcal watch`: follows a dataset folder or a bag while it is written, printing each update
//! (or one JSON object per line), then calibrates the finished recording as `calibrate` does.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::{Context, Result, bail};
use dvlcal::calib::options::WeakThresholds;
use dvlcal::io::calib_yaml::read_calibration_guess;
use dvlcal::pipeline::live_dvl::LiveDvl;
use dvlcal::pipeline::watch::{Pace, WatchOptions, Watcher};

use crate::calibrate::{CalibrateArgs, options};

#[derive(clap::Args)]
pub struct WatchArgs {
    /// One JSON object per line per update (`done`, `advice`, `parameters`, `counts`, ...).
    #[arg(long)]
    pub json: bool,
    /// Seconds between updates.
    #[arg(long, default_value = "2", value_name = "S")]
    pub interval: f64,
    /// End when no file has changed for this many seconds.
    #[arg(long, default_value = "30", value_name = "S")]
    pub until_idle: f64,
    /// End as soon as every parameter meets its target.
    #[arg(long)]
    pub stop_when_done: bool,
    /// The updates' std targets instead of the verdict limits: rotation (deg), lever arm (m),
    /// clock offset (s), velocity scale (the final result keeps calibrate's limits).
    #[arg(long, value_delimiter = ',', value_name = "DEG,M,S,SCALE")]
    pub target_std: Option<Vec<f64>>,
    /// A live DVL, HOST:PORT (the A50: port 16171), recorded into DIR/dvl.jsonl as record-dvl
    /// records it; its stream keeps the folder changing: end with Ctrl-C or --stop-when-done.
    #[arg(long, value_name = "HOST:PORT", conflicts_with = "dvl")]
    pub dvl_tcp: Option<String>,
    #[command(flatten)]
    pub calibrate: CalibrateArgs,
}

/// Runs `f` with the standard output going to the standard error, so that `--json` keeps the
/// standard output for the updates alone while the final calibration prints its summary.
fn on_stderr<T>(f: impl FnOnce() -> T) -> T {
    use std::io::Write as _;
    let _ = std::io::stdout().flush();
    // SAFETY: duplicating and restoring the process's own standard descriptors.
    let saved = unsafe { libc::dup(1) };
    if saved < 0 || unsafe { libc::dup2(2, 1) } < 0 {
        return f();
    }
    let out = f();
    let _ = std::io::stdout().flush();
    // SAFETY: as above; `saved` is the descriptor `dup` returned.
    unsafe {
        libc::dup2(saved, 1);
        libc::close(saved);
    }
    out
}

pub fn run(mut a: WatchArgs) -> Result<()> {
    for (v, name) in [(a.interval, "--interval"), (a.until_idle, "--until-idle")] {
        if !(v.is_finite() && v > 0.0) {
            bail!("{name} must be a positive number of seconds, got {v}");
        }
    }
    let c = &a.calibrate;
    let Some(dir) = c.dataset.as_deref() else {
        bail!("dvlcal watch follows a dataset folder or a bag: give it (dvlcal watch DIR|BAG)");
    };
    let guess = c.init.as_deref().map(read_calibration_guess).transpose()?;
    let read = c.dvl_input.read_options(c.strict);
    let mut opts = WatchOptions {
        calib: options(c.method, guess, c.estimate_offset, &c.estimator, c.biased)?,
        vision: c.vision.options(),
        overrides: c.files.overrides(&read),
        read,
        threads: c.vision.detect.threads,
        stretch_s: None,
    };
    if let Some(v) = &a.target_std {
        opts.calib.weak = WeakThresholds::from_values(v, "--target-std")?;
    }
    let stop = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&stop);
    ctrlc::set_handler(move || flag.store(true, Ordering::SeqCst))
        .context("installing the Ctrl-C handler")?;
    let mut watcher = Watcher::new(dir)?;
    let live = match &a.dvl_tcp {
        Some(t) => Some(LiveDvl::start(t, dir, Default::default(), |m| {
            eprintln!("watch: {m}")
        })?),
        None => None,
    };
    let pace = Pace {
        interval: Duration::from_secs_f64(a.interval),
        until_idle: Duration::from_secs_f64(a.until_idle),
        stop_when_done: a.stop_when_done,
    };
    watcher.follow(&opts, &pace, &stop, &mut |u| {
        if a.json {
            println!("{}", serde_json::to_string(u)?);
        } else {
            print!("{}", u.text());
        }
        Ok(())
    })?;
    let (bag, seen, notes) = watcher.finish();
    notes.iter().for_each(|n| eprintln!("watch: {n}"));
    a.calibrate.dataset = bag.or(a.calibrate.dataset);
    drop(watcher);
    if let Some(live) = live {
        eprintln!("watch: {}", live.stop()?);
    }
    let calibrate = || crate::calibrate::run(a.calibrate, Some(seen));
    if a.json {
        on_stderr(calibrate)
    } else {
        calibrate()
    }
}
