//! The `dvlcal` command line: a thin layer over the library, one module per subcommand.

mod bag;
mod board;
mod calibrate;
mod cameras;
#[cfg(test)]
mod cli_rules;
mod compare;
mod dataset;
mod detect;
mod dvl_info;
mod eval;
mod evaluate;
mod fit;
mod record_dvl;
mod simulate;
mod tags;
mod watch;

use std::sync::OnceLock;

use clap::parser::ValueSource;
use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "dvlcal",
    version,
    about = "Calibrate a Doppler velocity log against a camera"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Write a synthetic dataset with known truth (camera poses, A50 log, truth files).
    Simulate(simulate::SimulateArgs),
    /// Fit the continuous-time trajectory to camera poses and write body twists with their
    /// standard deviations.
    FitTrajectory(fit::FitArgs),
    /// Camera poses (TUM, board frame as world) with covariances from stereo images of an
    /// AprilTag board.
    Detect(detect::DetectArgs),
    /// Calibrate the cameras (intrinsics, distortion, stereo extrinsics) from images of a board
    /// and write a Kalibr camchain.
    CalibrateCameras(cameras::CalibrateCamerasArgs),
    /// Estimate the DVL's rotation, lever arm, clock offset and velocity scale.
    Calibrate(calibrate::CalibrateArgs),
    /// Follow a dataset folder while it is recorded: update the calibration, say what motion is
    /// still missing, and calibrate the finished recording as `calibrate` does.
    Watch(watch::WatchArgs),
    /// Check calibrations by DVL dead reckoning against the camera (ATE, RPE), and
    /// cross-validate over several datasets.
    Evaluate(evaluate::EvaluateArgs),
    /// Compare a calibration with a reference (e.g. a simulation's truth), in units and in
    /// standard deviations.
    CompareCalib(compare::CompareArgs),
    /// Compare a twist CSV with a truth twist CSV (RMS errors and normalised errors).
    EvalTwist(eval::EvalTwistArgs),
    /// List a bag's topics (types, counts, rates, spans) and the part dvlcal gives each.
    BagInfo(bag::BagInfoArgs),
    /// Summarise a DVL log (any format): counts, time span, rate, velocity statistics, problems.
    DvlInfo(dvl_info::DvlInfoArgs),
    /// Record a DVL's TCP JSON stream to a log, adding the host receive time to each line.
    RecordDvl(record_dvl::RecordDvlArgs),
    /// Draw a board definition as an SVG to print at exact scale.
    Board(board::BoardArgs),
    /// Detect AprilTags in images and print them as CSV (corners in the OpenCV pixel convention).
    Tags(tags::TagsArgs),
}

/// Whether an option takes numbers (one, a list, or numbers with a sigma): its value parser makes
/// one of these types.
fn numeric(a: &clap::Arg) -> bool {
    use std::any::TypeId;
    let t = a.get_value_parser().type_id();
    [
        TypeId::of::<f64>(),
        TypeId::of::<f32>(),
        TypeId::of::<u8>(),
        TypeId::of::<u32>(),
        TypeId::of::<u64>(),
        TypeId::of::<usize>(),
        TypeId::of::<dvlcal::calib::prior::VectorSigma>(),
        TypeId::of::<dvlcal::calib::prior::SigmaOrNone>(),
    ]
    .iter()
    .any(|id| t == *id)
}

/// The command line of [`Cli`], with every numeric option taking a value that starts with '-': a
/// negative number, or a list that starts with one (`--offset-range -0.5,0.5`).
fn command() -> clap::Command {
    let mut cmd = Cli::command();
    for sub in cmd.get_subcommands_mut() {
        *sub = std::mem::take(sub).mut_args(|a| match !a.is_positional() && numeric(&a) {
            true => a.allow_hyphen_values(true),
            false => a,
        });
    }
    cmd
}

/// The options written on the command line (`--init`), not those left at their defaults.
static GIVEN: OnceLock<Vec<String>> = OnceLock::new();

/// The flags written on the command line, for the library's checks of unused options.
pub fn given() -> Vec<&'static str> {
    GIVEN
        .get()
        .map_or(Vec::new(), |g| g.iter().map(String::as_str).collect())
}

fn main() {
    // Rust ignores SIGPIPE, so printing to a closed pipe (`dvlcal calibrate ... | head -1`)
    // would panic; with the default action the program ends quietly, as Unix tools do.
    #[cfg(unix)]
    // SAFETY: setting a signal's disposition to its default before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let matches = command().get_matches();
    if let Some((name, sub)) = matches.subcommand()
        && let Some(def) = command().find_subcommand(name)
    {
        let typed = |a: &&clap::Arg| {
            sub.value_source(a.get_id().as_str()) == Some(ValueSource::CommandLine)
        };
        let flags = def
            .get_arguments()
            .filter(typed)
            .filter_map(|a| a.get_long());
        let _ = GIVEN.set(flags.map(|l| format!("--{l}")).collect());
        if let Ok(Some(&n)) = sub.try_get_one::<usize>("threads")
            && let (_, Some(note)) = dvlcal::parallel::capped_threads("--threads", n)
        {
            eprintln!("note: {note}");
        }
    }
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    let result = match cli.command {
        Command::Simulate(a) => simulate::run(a),
        Command::FitTrajectory(a) => fit::run(a),
        Command::EvalTwist(a) => eval::run(a),
        Command::Evaluate(a) => evaluate::run(a),
        Command::CompareCalib(a) => compare::run(a),
        Command::DvlInfo(a) => dvl_info::run(a),
        Command::BagInfo(a) => bag::run(a),
        Command::RecordDvl(a) => record_dvl::run(a),
        Command::Board(a) => board::run(a),
        Command::Calibrate(a) => calibrate::run(a, None),
        Command::Watch(a) => watch::run(a),
        Command::CalibrateCameras(a) => cameras::run(a),
        Command::Detect(a) => detect::run(a),
        Command::Tags(a) => tags::run(a),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        let usage = e.chain().any(|c| {
            matches!(
                c.downcast_ref(),
                Some(dvlcal::error::Error::UnusedOption(_))
            )
        });
        std::process::exit(if usage { 2 } else { 1 });
    }
}
