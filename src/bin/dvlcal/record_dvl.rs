//! `dvlcal record-dvl`: record a DVL's TCP JSON stream to a log.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::Context;
use clap::Args;
use dvlcal::io::dvl::{RecordOptions, record_tcp};

#[derive(Args, Debug)]
pub struct RecordDvlArgs {
    /// The DVL's JSON stream, HOST:PORT (the A50 serves it on port 16171).
    #[arg(long, value_name = "HOST:PORT")]
    pub tcp: String,
    /// Log to append to: one JSON object per line, each with `host_time_us` added.
    #[arg(long, value_name = "LOG")]
    pub out: PathBuf,
    /// Stop after this many seconds (default: until Ctrl-C).
    #[arg(long, value_name = "S")]
    pub duration: Option<f64>,
    /// Seconds between reconnection attempts.
    #[arg(long, value_name = "S", default_value_t = 1.0)]
    pub reconnect_delay: f64,
}

fn seconds(s: f64, what: &str) -> anyhow::Result<Duration> {
    Duration::try_from_secs_f64(s).with_context(|| format!("{what}: {s} is not a duration"))
}

pub fn run(args: RecordDvlArgs) -> anyhow::Result<()> {
    dvlcal::files::prepare_output("--out", &args.out)?;
    let stop = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&stop);
    ctrlc::set_handler(move || flag.store(true, Ordering::SeqCst))
        .context("installing the Ctrl-C handler")?;
    let opts = RecordOptions {
        duration: args
            .duration
            .map(|d| seconds(d, "--duration"))
            .transpose()?,
        reconnect_delay: seconds(args.reconnect_delay, "--reconnect-delay")?,
        ..RecordOptions::default()
    };
    let stats = record_tcp(&args.tcp, &args.out, &opts, &stop, &mut |m| {
        eprintln!("record-dvl: {m}")
    })?;
    if stats.lines == 0 {
        anyhow::bail!("{}", stats.nothing_recorded(&args.tcp));
    }
    eprintln!("record-dvl: {}", stats.summary(&args.out));
    Ok(())
}
