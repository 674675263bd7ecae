//! A ROS 1 bag of any bytes: opening it, a pass over all its messages, and the DVL reader on it
//! must return (an error or a result), never panic, hang or exhaust memory. The input follows
//! the bag magic unless it starts with `#` (then it is the whole file).
#![no_main]

use std::path::PathBuf;
use std::sync::OnceLock;

use dvlcal::io::bag::ros1::Ros1Bag;
use dvlcal::io::dvl::{DvlReadOptions, read_dvl_log};
use libfuzzer_sys::fuzz_target;

fn scratch() -> &'static PathBuf {
    static P: OnceLock<PathBuf> = OnceLock::new();
    P.get_or_init(|| std::env::temp_dir().join(format!("dvlcal-fuzz-{}.bag", std::process::id())))
}

fuzz_target!(|data: &[u8]| {
    let mut bag = b"#ROSBAG V2.0\n".to_vec();
    // Keep the magic most of the time so the fuzzer spends its effort past it.
    if data.first() == Some(&b'#') {
        bag.clear();
    }
    bag.extend_from_slice(data);
    let p = scratch();
    if std::fs::write(p, &bag).is_err() {
        return;
    }
    if let Ok(b) = Ros1Bag::open(p) {
        let mut n = 0usize;
        let _ = b.messages(&|_| true, &mut |m| {
            n += m.data.len();
            Ok(())
        });
    }
    let _ = read_dvl_log(p, &DvlReadOptions::default());
});
