//! Calibration result files and calibration guesses (the same text through both readers).
#![no_main]

use std::path::Path;

use dvlcal::io::calib_yaml::{parse_calib_yaml, parse_calibration_guess};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let name = Path::new("fuzz-calibration.yaml");
    let _ = parse_calib_yaml(text, name);
    let _ = parse_calibration_guess(text, name);
});
