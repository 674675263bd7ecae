//! An MCAP file (ROS 2 bag storage) of any bytes: opening it through `Bag` and a pass over all
//! its messages must return (an error or a result), never panic, hang or exhaust memory. The
//! input follows the MCAP magic unless it starts with the magic's first byte 0x89 (then it is
//! the whole file).
#![no_main]

use std::path::PathBuf;
use std::sync::OnceLock;

use dvlcal::io::bag::{Bag, MCAP_MAGIC};
use libfuzzer_sys::fuzz_target;

fn scratch() -> &'static PathBuf {
    static P: OnceLock<PathBuf> = OnceLock::new();
    P.get_or_init(|| std::env::temp_dir().join(format!("dvlcal-fuzz-{}.mcap", std::process::id())))
}

fuzz_target!(|data: &[u8]| {
    let mut bytes = MCAP_MAGIC.to_vec();
    // Keep the magic most of the time so the fuzzer spends its effort past it.
    if data.first() == Some(&0x89) {
        bytes.clear();
    }
    bytes.extend_from_slice(data);
    let p = scratch();
    if std::fs::write(p, &bytes).is_err() {
        return;
    }
    if let Ok(bag) = Bag::open(p) {
        let mut n = 0usize;
        let _ = bag.messages(&|_| true, &mut |m| {
            n += m.data.len();
            Ok(())
        });
        // A pass over one topic takes the index's shortcuts.
        let _ = bag.messages(&|t| t == 0, &mut |_| Ok(()));
    }
});
