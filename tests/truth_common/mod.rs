//! A calibration result against the truth of the simulated dataset it came from.
#![allow(dead_code)]

use std::path::Path;

use dvlcal::eval::calibration_error;
use dvlcal::io::calib_yaml::{CalibrationFile, read_calib_yaml};

/// The eight parameters in the estimator's order.
pub const NAMES: [&str; 8] = [
    "rot x", "rot y", "rot z", "lever x", "lever y", "lever z", "scale", "offset",
];

/// Errors and standard deviations of a result file against `dataset/truth/calibration.yaml`,
/// with a table of them (printed to stderr), and the result file itself.
pub struct AgainstTruth {
    pub err: [f64; 8],
    pub std: [f64; 8],
    pub table: String,
    pub file: CalibrationFile,
}

pub fn against_truth(dataset: &Path, result: &Path) -> AgainstTruth {
    let file = read_calib_yaml(result).expect("result file");
    let truth_file = dataset.join("truth").join("calibration.yaml");
    let truth = read_calib_yaml(&truth_file)
        .expect("truth file")
        .to_params()
        .expect("truth parameters");
    let ce = calibration_error(&file, &truth).expect("comparable");
    let std = ce.std.expect("std in the result");
    let mut out = AgainstTruth {
        err: [0.0; 8],
        std: [0.0; 8],
        table: String::new(),
        file,
    };
    for k in 0..8 {
        out.err[k] = ce.error[k];
        out.std[k] = std[k];
        out.table.push_str(&format!(
            "{}: err {:.3e} std {:.3e} z {:+.2}\n",
            NAMES[k],
            ce.error[k],
            std[k],
            ce.error[k] / std[k]
        ));
    }
    eprintln!("{}", out.table);
    out
}

/// Every error within `z` of its standard deviations (and every deviation positive and finite).
pub fn assert_within(a: &AgainstTruth, z: f64) {
    for ((name, e), s) in NAMES.iter().zip(&a.err).zip(&a.std) {
        assert!(*s > 0.0 && s.is_finite(), "{}", a.table);
        assert!((e / s).abs() < z, "{name}:\n{}", a.table);
    }
}
