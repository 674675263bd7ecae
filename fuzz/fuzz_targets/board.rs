//! Board YAML: dvlcal's grid and list forms and Kalibr aprilgrid targets.
#![no_main]

use std::path::Path;

use dvlcal::io::target::parse_board;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let _ = parse_board(text, Path::new("fuzz-board.yaml"));
});
