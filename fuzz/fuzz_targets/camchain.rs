//! Kalibr camchain YAML.
#![no_main]

use std::path::Path;

use dvlcal::io::camchain::parse_camchain;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let _ = parse_camchain(text, Path::new("fuzz-camchain.yaml"));
});
