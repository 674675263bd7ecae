//! The report of a run with an IMU: a section of the IMU's whose figures are the result file's
//! to the printed digits; a run without one has no such section.

mod tmp_common;

use dvlcal::io::calib_yaml::{Observability, read_calib_yaml};
use dvlcal::lie::Se3;
use dvlcal::report::IMU_SECTION_ID;
use nalgebra::Matrix4;
use tmp_common::{TmpDir, dvlcal_ok, s, simulate_imu_recording};

/// The text of the section `id` of a report.
fn section<'a>(html: &'a str, id: &str) -> Option<&'a str> {
    let start = html.find(&format!("<section id=\"{id}\""))?;
    let len = html[start..].find("</section>").expect("closed section");
    Some(&html[start..start + len])
}

fn triple(v: [f64; 3], scale: f64, decimals: usize) -> String {
    format!(
        "[{:.d$}, {:.d$}, {:.d$}]",
        v[0] * scale,
        v[1] * scale,
        v[2] * scale,
        d = decimals
    )
}

/// `simulate --imu` and `calibrate --report`: the report's IMU section prints the result file's
/// quaternion, lever arm, clock offset, their standard deviations, gravity and noise factors,
/// the verdicts in words and the motion; after the IMU's noise file is removed (the IMU is then
/// not calibrated) the report has no IMU section.
#[test]
fn the_report_shows_the_imu_as_the_result_file_has_it() {
    let tmp = TmpDir::new("report-imu");
    let data = tmp.path("rec");
    simulate_imu_recording(&data);
    let (result, report) = (tmp.path("r.yaml"), tmp.path("r.html"));
    let calibrate = |extra: &[&str]| {
        let mut args = vec![
            "calibrate",
            s(&data),
            "--out",
            s(&result),
            "--report",
            s(&report),
        ];
        args.extend_from_slice(extra);
        dvlcal_ok(&args);
        std::fs::read_to_string(&report).expect("report")
    };
    let html = calibrate(&[]);
    let file = read_calib_yaml(&result).expect("result");
    let sec = section(&html, IMU_SECTION_ID)
        .expect("the IMU's section")
        .replace("&#39;", "'");

    let m = file.t_cam_imu.expect("T_cam_imu");
    let q = Se3::from_matrix(&Matrix4::from_fn(|i, j| m[i][j])).quaternion_xyzw();
    let quat = format!("[{:.5}, {:.5}, {:.5}, {:.5}]", q[0], q[1], q[2], q[3]);
    let lever = triple([m[0][3], m[1][3], m[2][3]], 1.0, 4);
    let offset = format!("{:.5} s", file.imu_time_offset_s.expect("offset"));
    let std = file
        .std
        .as_ref()
        .and_then(|s| s.imu.clone())
        .expect("std.imu");
    let std_rot = format!("{} deg", triple(std.rotation_deg, 1.0, 3));
    let std_lever = format!("{} mm", triple(std.lever_arm_m, 1e3, 2));
    let std_off = format!("{:.2} ms", 1e3 * std.time_offset_s);
    let gravity = triple(file.imu_gravity_world_mps2.expect("gravity"), 1.0, 3);
    let fig = &file.info.as_ref().expect("info").figures;
    let noise = format!(
        "{:.2}, {:.2}",
        fig.imu_noise_factor_gyro.expect("gyro factor"),
        fig.imu_noise_factor_accel.expect("accel factor")
    );
    for want in [
        &quat, &lever, &offset, &std_rot, &std_lever, &std_off, &gravity, &noise,
    ] {
        assert!(sec.contains(want.as_str()), "{want} not in {sec}");
    }
    // The verdicts as the result file gives them, in words, and the motion behind them.
    let obs = file
        .observability
        .as_ref()
        .and_then(|o| o.imu.clone())
        .expect("verdicts");
    for (name, o) in [
        ("The IMU's rotation", obs.rotation),
        ("The IMU's lever arm", obs.lever_arm),
        ("The IMU's clock offset", obs.time_offset),
    ] {
        let words = match o {
            Observability::Ok => format!("{name} is well determined"),
            _ => format!("{name} is weakly observable"),
        };
        assert!(sec.contains(&words), "{words} not in {sec}");
    }
    assert_eq!(obs.rotation, Observability::Ok);
    assert!(
        sec.contains("The rotation R_cam_imu: observed by the rotation about more than one axis"),
        "{sec}"
    );
    assert!(
        sec.contains("id=\"imu-motion\"") && sec.contains("rad/s RMS"),
        "{sec}"
    );
    assert!(sec.contains("id=\"imu-rotation-forms\""), "{sec}");
    // The motion prior's share of the std, as the result file's figures give it.
    let shift = triple(
        fig.imu_prior_shift_lever_arm_m.expect("prior shift"),
        1e3,
        2,
    );
    assert!(
        sec.contains("id=\"imu-prior\"") && sec.contains(&format!("the lever arm by {shift} mm")),
        "{shift} not in {sec}"
    );
    // A simulated IMU's noise is as its noise file says: no factor far above 1 is claimed.
    assert!(!sec.contains("understates"), "{sec}");

    // The stream without its noise file: no IMU result, no IMU section.
    std::fs::remove_file(data.join("imu.yaml")).expect("remove imu.yaml");
    let html = calibrate(&["--force"]);
    assert!(html.contains("<section id=\"results\""));
    assert!(section(&html, IMU_SECTION_ID).is_none());
}
