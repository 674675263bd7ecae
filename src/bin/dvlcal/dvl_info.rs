//! `dvlcal dvl-info`: what is in a DVL log (formats, counts, time span, rate, velocity
//! statistics, problems with file:line).

use std::io::Write as _;
use std::path::PathBuf;

use clap::Args;
use dvlcal::io::dvl::{DvlFormat, DvlReadOptions, DvlTimeSource, read_dvl_log};

/// Options of every subcommand that reads a DVL log (flatten into its arguments).
#[derive(Args, Clone, Debug, Default)]
pub struct DvlInputArgs {
    /// Format of the DVL log: json, serial or rosbag (default: detected from the content).
    #[arg(long = "dvl-format", value_name = "F")]
    pub dvl_format: Option<DvlFormat>,
    /// Time stamp of each DVL sample: validity (time_of_validity), transmission
    /// (time_of_transmission) or host (receive time: bag record time or record-dvl's host_time_us).
    #[arg(long = "dvl-time", value_name = "T", default_value = "validity")]
    pub dvl_time: DvlTimeSource,
    /// Topic to read from a ROS bag (default: /dvl/json_data, else the driver's DVL topic).
    #[arg(long = "dvl-topic", value_name = "TOPIC")]
    pub dvl_topic: Option<String>,
}

impl DvlInputArgs {
    /// The library's read options for these arguments.
    pub fn read_options(&self, strict: bool) -> DvlReadOptions {
        DvlReadOptions {
            format: self.dvl_format,
            time_source: self.dvl_time,
            strict,
            topic: self.dvl_topic.clone(),
            epoch: None,
            include_invalid: false,
        }
    }
}

#[derive(Args, Debug)]
pub struct DvlInfoArgs {
    /// The DVL log: JSON lines, serial capture or ROS1 bag.
    pub log: PathBuf,
    /// Print one JSON object instead of a summary.
    #[arg(long)]
    pub json: bool,
    /// Stop at the first malformed line with an error naming file:line.
    #[arg(long)]
    pub strict: bool,
    #[command(flatten)]
    pub input: DvlInputArgs,
}

pub fn run(args: DvlInfoArgs) -> anyhow::Result<()> {
    dvlcal::pipeline::unused::dvl_topic_option(&args.log, &crate::given())?;
    let opts = args.input.read_options(args.strict);
    let log = read_dvl_log(&args.log, &opts)?;
    let mut text = if args.json {
        serde_json::to_string_pretty(&log.summary_json())?
    } else {
        log.summary_text()
    };
    if !text.ends_with('\n') {
        text.push('\n');
    }
    // A closed pipe (`dvlcal dvl-info LOG | head`) is not an error.
    match std::io::stdout().lock().write_all(text.as_bytes()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(e.into()),
        _ => Ok(()),
    }
}
