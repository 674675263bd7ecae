//! The output files of a calibration that are checked or chosen before the run starts, so that
//! an output that cannot be written costs no work and no file of the user's is replaced.

use std::path::{Path, PathBuf};

use super::calibration::sibling;
use super::cameras::CameraCalRun;
use crate::error::{Error, Result};
use crate::files::{file_name_of, prepare_output, read_only_mode, refuse_input, same_file};
use crate::io::dataset::DatasetFiles;
use crate::io::write_atomic;

/// The suffixes of the exports written beside a result `RESULT.yaml` (`RESULT-tf.txt`, ...; see
/// [`super::write_results`]).
pub const RESULT_EXPORTS: [&str; 3] = ["tf.txt", "urdf.xml", "camchain-imucam.yaml"];

/// Checks that the result `out`, its exports and the `report` can be written (see
/// [`prepare_output`]); an error names the option and the file, e.g. a read-only one.
pub fn check_result_outputs(out: &Path, report: Option<&Path>) -> Result<()> {
    prepare_output("--out", out)?;
    for suffix in RESULT_EXPORTS {
        crate::files::refuse_read_only("--out", &sibling(out, suffix))?;
    }
    if let Some(r) = report {
        prepare_output("--report", r)?;
    }
    Ok(())
}

/// Where `dvlcal calibrate` writes the cameras it calibrated from a dataset's images (a dataset
/// without a camchain): `camchain.yaml` beside the result, or `RESULT-camchain.yaml` when
/// `camchain.yaml` there is a file of someone else's (see [`CameraOutputs::plan`]); and with a
/// DVL report `R.html` the camera report `R-cameras.html` beside it.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraOutputs {
    /// The camchain YAML.
    pub camchain: PathBuf,
    /// Why the camchain is not `camchain.yaml` beside the result, when it is not (a note for the
    /// user).
    pub renamed: Option<String>,
    /// The camera calibration report, when a DVL report is written.
    pub report: Option<PathBuf>,
}

/// The first line of the camchain `dvlcal calibrate` writes for the result `out`: it marks the
/// file as that result's, which a later run for the same result may replace.
fn camchain_mark(out: &Path) -> String {
    format!(
        "# camchain of result {}: the cameras calibrated by dvlcal calibrate from its images",
        file_name_of(out)
    )
}

/// Whether the camchain of the result `out` may be written to `path`: nothing is there, or the
/// camchain an earlier run wrote for the same result, not read-only.
fn free_for(path: &Path, out: &Path) -> bool {
    if path == out || same_file(path, out) || read_only_mode(path).is_some() {
        return false;
    }
    match std::fs::read(path) {
        Err(e) => e.kind() == std::io::ErrorKind::NotFound,
        Ok(bytes) => bytes.starts_with(format!("{}\n", camchain_mark(out)).as_bytes()),
    }
}

impl CameraOutputs {
    /// The outputs for the result `out` and the DVL report `report`, when `files` have images
    /// without a camchain (`None` otherwise). The camchain goes to `camchain.yaml` beside the
    /// result when that name is free or holds this result's camchain from an earlier run, else
    /// to `RESULT-camchain.yaml` under the same condition; a file not written for this result
    /// (the user's own camchain, one of `calibrate-cameras`) or a read-only one is never
    /// replaced. Errors, before anything is run, when neither name is free or when an output
    /// would overwrite an input of the run or the result.
    pub fn plan(
        out: &Path,
        report: Option<&Path>,
        files: &DatasetFiles,
    ) -> Result<Option<CameraOutputs>> {
        // A bag without a camchain may need its cameras calibrated too (a stereo pair, or no
        // CameraInfo): the paths are reserved, and used only if it does.
        let bag_may = files.bag.is_some() && files.camchain.is_none();
        if !files.calibrates_cameras() && !bag_may {
            return Ok(None);
        }
        let beside = out.with_file_name("camchain.yaml");
        if beside == out || same_file(&beside, out) {
            return Err(Error::option(
                "--out",
                format!(
                    "{}: the camchain calibrated from the images is written to {} beside the \
                     result; name the result otherwise",
                    out.display(),
                    beside.display()
                ),
            ));
        }
        let named = sibling(out, "camchain.yaml");
        let (camchain, renamed) = if free_for(&beside, out) {
            (beside, None)
        } else if free_for(&named, out) {
            let why = format!(
                "{} is not a camchain written for this result{}: it is kept, and the cameras \
                 calibrated from the images go to {}",
                beside.display(),
                if read_only_mode(&beside).is_some() {
                    " (or it is read-only)"
                } else {
                    ""
                },
                named.display()
            );
            (named, Some(why))
        } else {
            return Err(Error::option(
                "--out",
                format!(
                    "the cameras calibrated from the images have no file to go to: {} and {} \
                     beside the result hold files not written for it (or read-only), which are \
                     not replaced; move one of them or name the result otherwise",
                    beside.display(),
                    named.display()
                ),
            ));
        };
        let inputs = files.inputs();
        let inputs = || inputs.iter().map(|p| p.as_path());
        refuse_input("--out", &camchain, inputs())?;
        let report = report.map(|r| sibling(r, "cameras.html"));
        if let Some(r) = &report {
            refuse_input("--report", r, inputs().chain([out, camchain.as_path()]))?;
            crate::files::refuse_read_only("--report", r)?;
        }
        Ok(Some(CameraOutputs {
            camchain,
            renamed,
            report,
        }))
    }

    /// Writes the camchain (marked as the result `out`'s) and the report (with `command`, the
    /// command line) of `cams`; returns the lines that tell the user what was written where
    /// (and why the camchain is not `camchain.yaml`, when it is not).
    pub fn write(
        &self,
        out: &Path,
        cams: &CameraCalRun,
        command: Option<String>,
    ) -> Result<Vec<String>> {
        let text = format!("{}\n{}", camchain_mark(out), cams.camchain_yaml());
        write_atomic(&self.camchain, text.as_bytes())?;
        let mut lines: Vec<String> = self.renamed.iter().map(|w| format!("note: {w}")).collect();
        let mut wrote = |p: &Path| {
            lines.push(format!(
                "wrote {} (cameras calibrated from the same images)",
                p.display()
            ))
        };
        wrote(&self.camchain);
        if let Some(r) = &self.report {
            cams.write_report(r, &self.camchain, command)?;
            wrote(r);
        }
        Ok(lines)
    }
}
