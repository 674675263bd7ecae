//! What the camera calibration's report is told besides the result.

/// What the report says about the run besides the result itself.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CamCalReportInput {
    /// The folder (or bag) the images came from.
    pub images: String,
    /// The calibration target: its file or a description.
    pub target: String,
    /// The text of the camchain YAML written (shown at the end; empty: none written).
    pub camchain_yaml: String,
    /// Where the camchain was written, if it was.
    pub camchain_path: Option<String>,
    /// The command line of the run.
    pub command: Option<String>,
}
