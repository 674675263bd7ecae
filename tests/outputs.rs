//! The outputs of `dvlcal calibrate` as other tools and users read them: held parameters
//! labelled as held (result file, summary, compare-calib), the Kalibr camchain-imucam file read
//! back through the crate's camchain reader, `--frames`, the provenance section, and every
//! `info` key documented in docs/formats.md.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use dvlcal::io::calib_yaml::{Observability, read_calib_yaml};
use dvlcal::io::camchain::read_camchain;
use nalgebra::Matrix4;

#[path = "tmp_common/mod.rs"]
mod tmp_common;
use tmp_common::{TmpDir as TempDir, dvlcal, s};

fn sample(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("sample_data")
        .join(name)
}

/// The truth of sample_data/poses with its clock offset moved by 530 ms: a guess that is wrong
/// in the clock alone.
fn wrong_clock_guess(tmp: &TempDir) -> PathBuf {
    let truth = std::fs::read_to_string(sample("poses").join("truth/calibration.yaml")).unwrap();
    assert!(truth.contains("time_offset_s: 0.07\n"), "{truth}");
    let guess = tmp.path("guess.yaml");
    std::fs::write(
        &guess,
        truth.replace("time_offset_s: 0.07\n", "time_offset_s: 0.6\n"),
    )
    .unwrap();
    guess
}

#[test]
fn a_fixed_run_says_fixed_in_the_result_the_summary_and_the_comparison() {
    let tmp = TempDir::new("fixed");
    let guess = wrong_clock_guess(&tmp);
    let out = tmp.path("fixed.yaml");
    let data = sample("poses");
    let r = dvlcal(&[
        "calibrate",
        s(&data),
        "--method",
        "fixed",
        "--init",
        s(&guess),
        "--out",
        s(&out),
    ]);
    let stdout = String::from_utf8_lossy(&r.stdout);
    // A 530 ms error does not fit: the run fails, and says the guess is the likely cause.
    assert!(!r.status.success(), "{stdout}");
    assert_eq!(stdout.matches("fixed (from --init)").count(), 4, "{stdout}");
    assert!(!stdout.contains("std 0.0"), "{stdout}");
    assert!(stdout.contains("--estimate-offset"), "{stdout}");
    assert!(!stdout.contains("set --dvl-sigma"), "{stdout}");

    let text = std::fs::read_to_string(&out).unwrap();
    let f = read_calib_yaml(&out).unwrap();
    let st = f.std.clone().unwrap();
    assert_eq!(
        (
            st.rotation_deg,
            st.lever_arm_m,
            st.time_offset_s,
            st.velocity_scale
        ),
        (None, None, None, None),
        "{text}"
    );
    let o = f.observability.clone().unwrap();
    for state in [o.rotation, o.lever_arm, o.time_offset, o.velocity_scale] {
        assert_eq!(state, Observability::Fixed, "{text}");
    }
    assert!(text.contains("  time_offset: fixed"), "{text}");
    // The guess is an input of the run.
    let prov = f.provenance.clone().expect("provenance");
    assert!(prov.inputs.iter().any(|i| i.role == "init"), "{text}");

    let truth = data.join("truth/calibration.yaml");
    let c = dvlcal(&["compare-calib", "--estimate", s(&out), "--truth", s(&truth)]);
    let cmp = String::from_utf8_lossy(&c.stdout);
    // The run failed: the comparison says so and exits non-zero.
    assert!(!c.status.success(), "{cmp}");
    assert!(cmp.contains("FAILED calibration"), "{cmp}");
    let clock = cmp
        .lines()
        .find(|l| l.starts_with("clock"))
        .unwrap_or_default();
    assert!(clock.contains("+530.00 ms"), "{cmp}");
    assert!(clock.contains("held fixed"), "{cmp}");
    assert!(!cmp.contains("in std"), "{cmp}");
    assert!(!cmp.contains("standard deviations ("), "{cmp}");
    assert!(cmp.contains("nothing was estimated"), "{cmp}");

    // With --estimate-offset the clock and scale are estimated, the extrinsics still held.
    let out2 = tmp.path("offset.yaml");
    let r = dvlcal(&[
        "calibrate",
        s(&data),
        "--method",
        "fixed",
        "--estimate-offset",
        "--init",
        s(&guess),
        "--out",
        s(&out2),
    ]);
    let stdout = String::from_utf8_lossy(&r.stdout);
    assert!(r.status.success(), "{stdout}");
    assert_eq!(stdout.matches("fixed (from --init)").count(), 2, "{stdout}");
    let f = read_calib_yaml(&out2).unwrap();
    let st = f.std.clone().unwrap();
    assert!(st.rotation_deg.is_none() && st.lever_arm_m.is_none());
    let sd = st.time_offset_s.expect("estimated offset has a std");
    assert!(sd > 0.0 && sd < 0.01, "{sd}");
    assert!(
        (f.time_offset_s - 0.07).abs() < 4.0 * sd,
        "{}",
        f.time_offset_s
    );
    let c = dvlcal(&[
        "compare-calib",
        "--estimate",
        s(&out2),
        "--truth",
        s(&truth),
    ]);
    let cmp = String::from_utf8_lossy(&c.stdout);
    let clock = cmp
        .lines()
        .find(|l| l.starts_with("clock"))
        .unwrap_or_default();
    assert!(clock.contains("in std"), "{cmp}");
    let rot = cmp
        .lines()
        .find(|l| l.starts_with("rotation"))
        .unwrap_or_default();
    assert!(rot.contains("held fixed"), "{cmp}");
    assert!(
        cmp.contains("held parameters are compared in units only"),
        "{cmp}"
    );
}

fn matrix(v: &serde_yaml::Value) -> Matrix4<f64> {
    let mut m = Matrix4::from_element(f64::NAN);
    for (r, row) in v.as_sequence().into_iter().flatten().enumerate() {
        for (k, x) in row.as_sequence().into_iter().flatten().enumerate() {
            m[(r, k)] = x.as_f64().unwrap_or(f64::NAN);
        }
    }
    m
}

#[test]
fn stereo_outputs_are_a_kalibr_camchain_imucam_a_urdf_joint_and_a_traced_result() {
    let tmp = TempDir::new("stereo");
    let out = tmp.path("res/cal.yaml");
    let data = sample("stereo");
    let r = dvlcal(&[
        "calibrate",
        s(&data),
        "--out",
        s(&out),
        "--frames",
        "camera_link,dvl_link",
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let result = read_calib_yaml(&out).unwrap();
    let calib = result.to_params().unwrap();

    // The camchain-imucam file reads as the camchain it was made from.
    let imucam = tmp.path("res/cal-camchain-imucam.yaml");
    let given = read_camchain(&data.join("camchain.yaml")).unwrap();
    let back = read_camchain(&imucam).expect("the crate's camchain reader reads it");
    assert_eq!(back.cams, given.cams);
    assert_eq!(back.topics, given.topics);
    for (a, b) in back.t_cn_c0.iter().zip(&given.t_cn_c0) {
        assert!((a.to_matrix() - b.to_matrix()).abs().max() < 1e-12);
    }
    // Kalibr's keys: T_cam_imu per camera, consistent along the chain with T_cn_cnm1.
    let text = std::fs::read_to_string(&imucam).unwrap();
    let v: serde_yaml::Value = serde_yaml::from_str(&text).unwrap();
    let top: Vec<&str> = v
        .as_mapping()
        .unwrap()
        .keys()
        .filter_map(|k| k.as_str())
        .collect();
    assert_eq!(top, ["cam0", "cam1"], "{text}");
    let t0 = matrix(&v["cam0"]["T_cam_imu"]);
    let t1 = matrix(&v["cam1"]["T_cam_imu"]);
    let t10 = matrix(&v["cam1"]["T_cn_cnm1"]);
    assert!(
        (t0 - calib.t_cam_dvl.to_matrix()).abs().max() < 1e-11,
        "{text}"
    );
    let chained = (t10 * t0 - t1).abs().max();
    assert!(
        chained < 1e-11,
        "T_cn_cnm1 T_cam_imu(cam0) - T_cam_imu(cam1): {chained}"
    );
    for cam in ["cam0", "cam1"] {
        let shift = v[cam]["timeshift_cam_imu"].as_f64().unwrap();
        assert!((shift + calib.time_offset_s).abs() < 1e-11, "{shift}");
        assert_eq!(v[cam]["T_cam_dvl"], v[cam]["T_cam_imu"]);
        assert_eq!(v[cam]["dvl_frame_id"].as_str(), Some("dvl_link"));
    }
    assert_eq!(v["cam0"]["cam_overlaps"][0].as_u64(), Some(1));

    // The frame names reach the ROS lines and the URDF joint.
    let tf = std::fs::read_to_string(tmp.path("res/cal-tf.txt")).unwrap();
    assert!(tf.contains(" camera_link dvl_link\n"), "{tf}");
    assert!(
        tf.contains("--frame-id camera_link --child-frame-id dvl_link"),
        "{tf}"
    );
    let urdf = std::fs::read_to_string(tmp.path("res/cal-urdf.xml")).unwrap();
    assert!(urdf.contains("<parent link=\"camera_link\"/>"), "{urdf}");
    assert!(urdf.contains("<child link=\"dvl_link\"/>"), "{urdf}");
    let origin = urdf
        .lines()
        .find(|l| l.trim_start().starts_with("<origin"))
        .unwrap_or_default();
    let xyz: Vec<f64> = origin
        .split('"')
        .nth(1)
        .unwrap_or_default()
        .split(' ')
        .filter_map(|x| x.parse().ok())
        .collect();
    let arm = calib.lever_arm_cam_m();
    assert_eq!(xyz.len(), 3, "{origin}");
    assert!((0..3).all(|k| (xyz[k] - arm[k]).abs() < 1e-11), "{origin}");

    // Provenance: version, command line, time, and the digests of every input.
    let prov = result.provenance.clone().expect("provenance");
    assert_eq!(prov.dvlcal_version, env!("CARGO_PKG_VERSION"));
    assert!(
        prov.command_line
            .as_deref()
            .unwrap_or_default()
            .contains("--frames camera_link,dvl_link"),
        "{prov:?}"
    );
    assert!(
        prov.run_utc.len() == 20 && prov.run_utc.ends_with('Z'),
        "{}",
        prov.run_utc
    );
    let roles: Vec<&str> = prov.inputs.iter().map(|i| i.role.as_str()).collect();
    assert_eq!(
        roles,
        [
            "camchain",
            "target",
            "dvl_log",
            "images_cam0",
            "images_cam1"
        ]
    );
    for i in &prov.inputs {
        assert_eq!(i.sha256.len(), 64, "{i:?}");
        let size: u64 = if i.role.starts_with("images") {
            let n = std::fs::read_dir(&i.path).unwrap().count() as u64;
            assert_eq!(i.files, Some(n), "{i:?}");
            std::fs::read_dir(&i.path)
                .unwrap()
                .map(|e| e.unwrap().metadata().unwrap().len())
                .sum()
        } else {
            std::fs::metadata(&i.path).unwrap().len()
        };
        assert_eq!(i.bytes, size, "{i:?}");
    }
    info_keys_are_documented(&result);
}

#[test]
fn bad_frame_names_are_refused_before_the_run() {
    let tmp = TempDir::new("frames");
    for bad in ["cam0", "cam 0,dvl", ",dvl", "dvl,dvl"] {
        let r = dvlcal(&[
            "calibrate",
            s(&sample("poses")),
            "--out",
            s(&tmp.path("x.yaml")),
            "--frames",
            bad,
        ]);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(!r.status.success(), "{bad}");
        assert!(err.contains("--frames"), "{bad}: {err}");
        assert!(!tmp.path("x.yaml").exists(), "{bad}: a result was written");
    }
}

/// The keys of the `info` table in docs/formats.md.
fn documented_info_keys() -> BTreeSet<String> {
    let doc =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/formats.md"))
            .unwrap();
    let start = doc
        .find("### The `info` keys")
        .expect("the info table's heading");
    doc[start..]
        .lines()
        .skip(1)
        .skip_while(|l| !l.starts_with('|'))
        .take_while(|l| l.starts_with('|'))
        .filter_map(|l| l.strip_prefix("| `"))
        .filter_map(|l| l.split('`').next())
        .map(str::to_owned)
        .collect()
}

/// Every key the result writer can put into `info`: the named fields and every figure of
/// `RunFigures`.
fn written_info_keys() -> BTreeSet<String> {
    let mut keys: BTreeSet<String> = ["method", "iterations", "warnings", "notes"]
        .map(String::from)
        .into();
    keys.extend(
        dvlcal::io::calib_yaml::RunFigures::KEYS
            .iter()
            .map(|k| k.to_string()),
    );
    keys
}

fn info_keys_are_documented(result: &dvlcal::io::calib_yaml::CalibrationFile) {
    let documented = documented_info_keys();
    let written = written_info_keys();
    // The source scan finds the keys (a guard against a scan that finds nothing).
    assert!(written.len() > 40, "{written:?}");
    let missing: Vec<&String> = written.difference(&documented).collect();
    assert!(
        missing.is_empty(),
        "info keys not in docs/formats.md: {missing:?}"
    );
    // And the keys a real run wrote, nested lists' keys aside.
    let info = result.info.clone().expect("info");
    let yaml = serde_yaml::to_value(&info).unwrap();
    let run_keys: Vec<String> = yaml
        .as_mapping()
        .unwrap()
        .keys()
        .filter_map(|k| k.as_str().map(str::to_owned))
        .collect();
    assert!(run_keys.len() > 30, "{run_keys:?}");
    let missing: Vec<&String> = run_keys
        .iter()
        .filter(|k| !documented.contains(*k))
        .collect();
    assert!(
        missing.is_empty(),
        "info keys of a run not in docs/formats.md: {missing:?}"
    );
}

#[test]
fn the_info_table_lists_every_key_the_writer_emits() {
    let documented = documented_info_keys();
    let written = written_info_keys();
    let missing: Vec<&String> = written.difference(&documented).collect();
    assert!(
        missing.is_empty(),
        "info keys not in docs/formats.md: {missing:?}"
    );
    // No stale rows either: each documented key is one the writer emits.
    let stale: Vec<&String> = documented.difference(&written).collect();
    assert!(
        stale.is_empty(),
        "docs/formats.md documents keys never written: {stale:?}"
    );
}

/// The speed of the input digests (run with `--ignored --nocapture`): sample_data/stereo, and
/// the file or folder named by DVLCAL_HASH_INPUT if set.
#[test]
#[ignore]
fn digest_speed() {
    let mut inputs = vec![sample("stereo")];
    if let Ok(p) = std::env::var("DVLCAL_HASH_INPUT") {
        inputs.push(PathBuf::from(p));
    }
    for p in inputs {
        let t = std::time::Instant::now();
        let d = dvlcal::io::provenance::digest("x", &p).unwrap();
        let dt = t.elapsed().as_secs_f64();
        println!(
            "{}: {} bytes in {:.3} s ({:.0} MB/s)",
            p.display(),
            d.bytes,
            dt,
            d.bytes as f64 / dt / 1e6
        );
    }
}
