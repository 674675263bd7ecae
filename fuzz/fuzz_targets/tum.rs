//! TUM pose files, with the epoch chosen from the file and given.
#![no_main]

use std::path::Path;

use dvlcal::io::tum::parse_tum;
use dvlcal::time::Epoch;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let name = Path::new("fuzz.tum");
    let _ = parse_tum(text, name, None);
    let _ = parse_tum(text, name, Some(Epoch { sec: 1_700_000_000 }));
});
