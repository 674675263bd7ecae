//! What the ROS, URDF and Kalibr exports say beside their numbers: the [`ExportNotes`] of a
//! calibration run, from its verdicts (a quantity a prior or a given value determined, or that
//! the data constrained poorly) and its status (a failed calibration exported with `--force`).

use crate::calib::outcome::{CalibrationOutcome, DeterminedBy, Status, Verdict};
use crate::io::calib_yaml::Observability;
use crate::io::exports::ExportNotes;

/// The state the result file gives a parameter with verdict `v`.
pub(super) fn state(v: &Verdict) -> Observability {
    match v.by {
        DeterminedBy::Fixed => Observability::Fixed,
        DeterminedBy::Prior => Observability::Prior,
        DeterminedBy::Data if v.ok => Observability::Ok,
        DeterminedBy::Data => Observability::Weak,
    }
}

/// The notes the exports of a calibration with `outcome` carry: one per parameter the data did
/// not determine well, with the verdict's reason, and the failure's reasons when it failed.
pub(crate) fn export_notes(outcome: &CalibrationOutcome) -> ExportNotes {
    let v = &outcome.verdicts;
    let failed = match &outcome.status {
        Status::Ok => None,
        Status::Failed(reasons) => Some(reasons.clone()),
    };
    notes_of(
        [&v.rotation, &v.lever_arm, &v.time_offset, &v.velocity_scale],
        failed,
    )
}

/// The notes of the verdicts on the rotation, lever arm, clock offset and scale (in that
/// order), and of a failure's reasons.
pub(super) fn notes_of(v: [&Verdict; 4], failed: Option<Vec<String>>) -> ExportNotes {
    let note = |v: &Verdict| ExportNotes::note(state(v), &v.reason);
    ExportNotes {
        failed,
        rotation: note(v[0]),
        lever_arm: note(v[1]),
        time_offset: note(v[2]),
        velocity_scale: note(v[3]),
    }
}
