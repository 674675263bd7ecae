//! The camera-IMU calibration of the two real recordings in `tests/fixtures/real_imu` (EuRoC's
//! and MoCap2GT's) against their published extrinsics, with the motion prior's density
//! multiplied by a factor: the lever arm's difference from the published one over its std,
//! the std with and without the motion prior's share, and that share over the data's std.
//! `cargo run --release --example imu_real -- [DENSITY_FACTOR]`

use std::path::Path;

use dvlcal::calib::imu::{ImuOptions, calibrate_camera_imu};
use dvlcal::io::frames_csv::read_tum_with_covariances;
use dvlcal::io::imu::noise::read_imu_noise;
use dvlcal::io::imu::read_imu_csv;
use dvlcal::lie::so3;
use nalgebra::{Matrix3, Vector3};

/// The four rows of the 4x4 matrix under `key` in a published.yaml.
fn matrix(text: &str, key: &str) -> Option<[[f64; 4]; 4]> {
    let mut rows = text
        .lines()
        .skip_while(|l| !l.starts_with(key))
        .skip(1)
        .take(4)
        .map(|l| {
            l.trim()
                .trim_start_matches('-')
                .trim()
                .trim_matches(|c| c == '[' || c == ']')
                .split(',')
                .map(|x| x.trim().parse::<f64>().ok())
                .collect::<Option<Vec<f64>>>()
        });
    let mut out = [[0.0; 4]; 4];
    for row in &mut out {
        let r = rows.next()??;
        if r.len() != 4 {
            return None;
        }
        row.copy_from_slice(&r);
    }
    Some(out)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let factor: f64 = std::env::args()
        .nth(1)
        .map(|s| s.parse())
        .transpose()?
        .unwrap_or(1.0);
    let root = Path::new("tests/fixtures/real_imu");
    for (name, poses, key) in [
        ("euroc_imu_april", "cam0_poses.txt", "T_cam_imu"),
        ("mocap2gt_imu_mocap", "marker_poses.txt", "T_marker_imu"),
    ] {
        let dir = root.join(name);
        let (tum, _) = read_tum_with_covariances(&dir.join(poses), None)?;
        let imu = read_imu_csv(&dir.join("imu0/data.csv"), Some(tum.epoch))?;
        let noise = read_imu_noise(&dir.join("imu.yaml"))?.noise;
        let opts = ImuOptions {
            density_factor: factor,
            ..ImuOptions::default()
        };
        let est = calibrate_camera_imu(&tum.poses, &imu.samples, &noise, &opts)?;
        let published = std::fs::read_to_string(dir.join("published.yaml"))?;
        let m = matrix(&published, key).ok_or(format!("no {key} in {name}'s published.yaml"))?;
        let r_pub = Matrix3::from_fn(|i, j| m[i][j]);
        let p_pub = Vector3::new(m[0][3], m[1][3], m[2][3]);
        let (s_rot, s_lever, _) = est.std();
        let (_, d_lever, _) = est.data_std();
        let angle = so3::log(&(r_pub.transpose() * est.state.t_cam_imu.rot))
            .norm()
            .to_degrees();
        let d = est.state.t_cam_imu.trans - p_pub;
        let over = est.prior_shift.map(|p| p.over_data_std(&est));
        println!(
            "{name} (density x{factor}): rotation {angle:.3} deg from the published (std {:.3}); \
             lever arm {:.1} mm from it, err/std {:.2} {:.2} {:.2}; std {:.2} {:.2} {:.2} mm, \
             the data's alone {:.2} {:.2} {:.2} mm; prior shift over the data's std: {}; \
             noise factors {:.1} {:.1}",
            s_rot.norm().to_degrees(),
            d.norm() * 1e3,
            d.x / s_lever.x,
            d.y / s_lever.y,
            d.z / s_lever.z,
            s_lever.x * 1e3,
            s_lever.y * 1e3,
            s_lever.z * 1e3,
            d_lever.x * 1e3,
            d_lever.y * 1e3,
            d_lever.z * 1e3,
            over.map_or("none".into(), |o| format!(
                "rotation {:.1} {:.1} {:.1}, lever arm {:.1} {:.1} {:.1}, offset {:.1}",
                o[0], o[1], o[2], o[3], o[4], o[5], o[6]
            )),
            est.noise_factor.0,
            est.noise_factor.1
        );
    }
    Ok(())
}
