//! The `dvlcal` command line: a thin layer over the library, one module per subcommand.

mod calibrate;
mod eval;
mod fit;
mod simulate;

use clap::{Parser, Subcommand};

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
    /// Estimate the DVL's rotation, lever arm, clock offset and velocity scale.
    Calibrate(calibrate::CalibrateArgs),
    /// Compare a twist CSV with a truth twist CSV (RMS errors and normalised errors).
    EvalTwist(eval::EvalTwistArgs),
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Simulate(a) => simulate::run(a),
        Command::FitTrajectory(a) => fit::run(a),
        Command::EvalTwist(a) => eval::run(a),
        Command::Calibrate(a) => calibrate::run(a),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
