//! Writing the HTML report of `dvlcal calibrate --report`.

use std::path::Path;

use anyhow::{Context, Result};

use dvlcal::calib::CalibrationOutcome;
use dvlcal::io::dvl::DvlLog;
use dvlcal::io::write_atomic;
use dvlcal::report::{FrameStat, ReportInput, render_html};
use dvlcal::types::PoseMeasurement;

/// What the report of one run is made from, besides the outcome.
pub struct RunInfo<'a> {
    pub poses_src: &'a Path,
    pub poses: &'a [PoseMeasurement],
    pub log: &'a DvlLog,
    pub frames: Option<&'a [FrameStat]>,
    /// The result YAML already written.
    pub result: &'a Path,
    pub elapsed_s: f64,
}

/// Renders the report and writes it atomically to `path`.
pub fn write(path: &Path, o: &CalibrationOutcome, run: &RunInfo) -> Result<()> {
    let dataset = format!(
        "camera poses: {}; DVL log: {}",
        run.poses_src.display(),
        run.log.stats.path.display()
    );
    // The result file was just written; a report without it is still useful.
    let yaml = std::fs::read_to_string(run.result).ok();
    let name = run.result.display().to_string();
    let input = ReportInput {
        dataset: &dataset,
        dvl_stats: Some(&run.log.stats),
        frames: run.frames,
        result_name: Some(&name),
        result_yaml: yaml.as_deref(),
        elapsed_s: Some(run.elapsed_s),
        ..ReportInput::new(o, run.poses)
    };
    let html = render_html(&input).context("building the report")?;
    write_atomic(path, html.as_bytes())?;
    Ok(())
}
