//! Twist CSV files.
#![no_main]

use std::path::Path;

use dvlcal::io::twist_csv::parse_twist_csv;
use dvlcal::time::Epoch;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let _ = parse_twist_csv(
        text,
        Path::new("fuzz-twist.csv"),
        Epoch { sec: 1_700_000_000 },
    );
});
