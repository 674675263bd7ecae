//! Outputs a user takes as they are: the ready-made boards print on their paper at exact scale,
//! the URDF export is a robot ROS's own parser reads, an export never shows a value the data did
//! not measure without saying so, and `compare-calib` does not pass a failed estimate.

use std::path::{Path, PathBuf};

#[path = "tmp_common/mod.rs"]
mod tmp_common;
use tmp_common::{TmpDir, dvlcal, s};

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

fn text(o: &[u8]) -> String {
    String::from_utf8_lossy(o).into_owned()
}

// ---------------------------------------------------------------------------------------------
// compare-calib

/// An estimate equal to the truth with honest standard deviations passes; the same file marked
/// `status: failed` is reported as failed, with the reason it records, and exits non-zero.
#[test]
fn compare_calib_does_not_pass_a_failed_estimate() {
    let tmp = TmpDir::new("compare-failed");
    let truth = repo("sample_data/poses/truth/calibration.yaml");
    let body = std::fs::read_to_string(&truth).unwrap();
    let std = "std:\n  rotation_deg: [0.1, 0.1, 0.1]\n  lever_arm_m: [0.01, 0.01, 0.01]\n  \
               time_offset_s: 0.002\n  velocity_scale: 0.002\n";
    let ok = tmp.path("ok.yaml");
    std::fs::write(&ok, format!("{body}{std}")).unwrap();
    let r = dvlcal(&["compare-calib", "--estimate", s(&ok), "--truth", s(&truth)]);
    assert!(r.status.success(), "{}", text(&r.stderr));
    assert!(
        text(&r.stdout).contains("within 3 std"),
        "{}",
        text(&r.stdout)
    );

    let reason = "the DVL's velocities do not fit the camera's motion (normalized cost 41.2)";
    let failed = tmp.path("failed.yaml");
    std::fs::write(
        &failed,
        format!("status: failed\nfailure:\n  - \"{reason}\"\n{body}{std}"),
    )
    .unwrap();
    let r = dvlcal(&[
        "compare-calib",
        "--estimate",
        s(&failed),
        "--truth",
        s(&truth),
    ]);
    let (out, err) = (text(&r.stdout), text(&r.stderr));
    assert_eq!(r.status.code(), Some(1), "{out}{err}");
    assert!(!out.contains("within 3 std"), "{out}");
    assert!(
        out.lines().nth(1).unwrap_or_default().contains("FAILED") && out.contains(reason),
        "{out}"
    );
    assert!(
        err.contains("failed.yaml is a failed calibration (status: failed)")
            && err.contains(reason),
        "{err}"
    );

    // A failed file without reasons says it records none.
    std::fs::write(&failed, format!("status: failed\n{body}{std}")).unwrap();
    let r = dvlcal(&[
        "compare-calib",
        "--estimate",
        s(&failed),
        "--truth",
        s(&truth),
    ]);
    assert!(!r.status.success());
    assert!(
        text(&r.stderr).contains("records no reason"),
        "{}",
        text(&r.stderr)
    );
}
