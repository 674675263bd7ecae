//! Time stamp lists.
#![no_main]

use std::path::Path;

use dvlcal::io::times::parse_times;
use dvlcal::time::Epoch;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let _ = parse_times(
        text,
        Path::new("fuzz-times.txt"),
        Epoch { sec: 1_700_000_000 },
    );
});
