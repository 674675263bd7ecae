//! Kalibr camchain YAML.
#![no_main]

use std::path::Path;

use dvlcal::vision::camera::Camchain;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let _ = Camchain::parse(text, Path::new("fuzz-camchain.yaml"));
});
