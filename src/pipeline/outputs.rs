//! The checks of a calibration's output files made before the run starts, so that an output
//! that cannot be written costs no work.

use std::path::Path;

use super::calibration::sibling;
use crate::error::Result;
use crate::files::{prepare_output, refuse_read_only};

/// The suffixes of the exports written beside a result `RESULT.yaml` (`RESULT-tf.txt`, ...; see
/// [`super::write_results`]).
pub const RESULT_EXPORTS: [&str; 3] = ["tf.txt", "urdf.xml", "camchain-imucam.yaml"];

/// Checks that the result `out`, its exports and the `report` can be written (see
/// [`prepare_output`]); an error names the option and the file, e.g. a read-only one.
pub fn check_result_outputs(out: &Path, report: Option<&Path>) -> Result<()> {
    prepare_output("--out", out)?;
    for suffix in RESULT_EXPORTS {
        refuse_read_only("--out", &sibling(out, suffix))?;
    }
    if let Some(r) = report {
        prepare_output("--report", r)?;
    }
    Ok(())
}
