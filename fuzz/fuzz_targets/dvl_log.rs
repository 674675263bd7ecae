//! DVL log text: format detection, A50 JSON lines, serial sentences and the whole-log checks,
//! once with the format detected and once forced to each text format.
#![no_main]

use std::path::Path;

use dvlcal::io::dvl::{DvlFormat, DvlReadOptions, read_dvl_text};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let name = Path::new("fuzz.log");
    let _ = read_dvl_text(name, data, &DvlReadOptions::default());
    for format in [DvlFormat::JsonLines, DvlFormat::Serial] {
        let opts = DvlReadOptions {
            format: Some(format),
            ..DvlReadOptions::default()
        };
        let _ = read_dvl_text(name, data, &opts);
    }
});
