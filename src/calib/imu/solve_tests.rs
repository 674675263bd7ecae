//! The joint problem's normal equations against differences of its whole cost: the gradient
//! `-J^T W e` of every knot variable and every calibration column (the IMU's, the biases' and
//! the DVL's) is half the cost's derivative, and held columns carry none.

use nalgebra::{DVector, Matrix3, Matrix6, Vector3, Vector6};

use super::*;
use crate::calib::imu::bins::ImuBin;
use crate::calib::imu::state::BiasNodes;
use crate::lie::{Se3, so3};
use crate::trajectory::blocktri::BlockTridiagonal;
use crate::types::imu::{ImuBias, STANDARD_GRAVITY};

fn knots(n: usize) -> (Vec<f64>, Vec<Knot>) {
    let times: Vec<f64> = (0..n).map(|i| 0.025 * i as f64).collect();
    let knots = times
        .iter()
        .map(|&t| Knot {
            pose: Se3::exp(&Vector6::new(
                0.3 * t,
                -0.1,
                0.2 * t,
                0.4 * t,
                -0.3 + t,
                0.2,
            )),
            twist: Vector6::new(0.3, 0.1 - t, -0.2, 0.5 * t, -0.4, 0.3 + t),
            rate: Vector6::new(-0.1, 0.3 * t, 0.05, 0.2, 0.1 * t, -0.4),
        })
        .collect();
    (times, knots)
}

fn state(dvl: bool) -> ImuState {
    let mut bias = BiasNodes::spanning(
        0.0,
        0.15,
        0.1,
        ImuBias {
            gyro: Vector3::new(0.01, 0.02, -0.01),
            accel: Vector3::new(0.1, -0.2, 0.05),
        },
    );
    bias.values[1].accel.y = -0.1;
    ImuState {
        t_cam_imu: Se3::new(
            so3::exp(&Vector3::new(0.4, 1.1, -0.3)),
            Vector3::new(0.1, -0.05, 0.2),
        ),
        time_offset_s: 0.004,
        gravity_rotation: so3::exp(&Vector3::new(0.2, -0.1, 0.4)),
        gravity_magnitude: STANDARD_GRAVITY,
        bias,
        dvl: dvl.then(|| {
            CalibrationParams::from_r_dvl_cam(
                so3::exp(&Vector3::new(1.2, -0.3, 0.4)),
                Vector3::new(0.05, 0.25, -0.1),
                1.02,
                0.007,
            )
        }),
    }
}

#[test]
fn the_gradient_matches_differences_of_the_cost_with_a_dvl_and_held_columns() {
    let (times, ks) = knots(7);
    let bins: Vec<ImuBin> = (0..14)
        .map(|j| ImuBin {
            t: 0.003 + 0.011 * j as f64,
            gyro: Vector3::new(0.1, -0.3 + 0.01 * j as f64, 0.2),
            accel: Vector3::new(0.5, 9.0, -2.0 + 0.1 * j as f64),
            n: 2,
        })
        .collect();
    let dvl: Vec<DvlObs> = (0..5)
        .map(|j| DvlObs {
            t: 0.01 + 0.03 * j as f64,
            v: Vector3::new(0.2, -0.1 * j as f64, 0.3),
            cov: Matrix3::identity() * 1e-4,
        })
        .collect();
    let mut poses = vec![None; times.len()];
    poses[0] = Some((
        ks[0].pose * Se3::exp(&Vector6::from_element(0.01)),
        Matrix6::identity() * 1e3,
    ));
    let joint = ImuJoint {
        times: times.clone(),
        poses: SparsePoseFactors { poses },
        density: JerkDensity::constant(Vector6::from_element(1e5)),
        bins: &bins,
        info: vec![Vector6::from_element(50.0); bins.len()],
        noise: ImuNoise {
            accelerometer_noise_density: 4e-3,
            accelerometer_random_walk: 1e-3,
            gyroscope_noise_density: 3e-4,
            gyroscope_random_walk: 4e-5,
            update_rate: 200.0,
        },
        held: vec![3, 6],
        dvl: &dvl,
        dvl_info: dvl.iter().map(|o| o.information().expect("info")).collect(),
    };
    let st = state(true);
    let mut sys = BlockTridiagonal::zeros(ks.len());
    let lin = joint.linearise(&ks, &st, &mut sys);
    assert!((lin.cost - joint.cost(&ks, &st)).abs() < 1e-9 * lin.cost.max(1.0));
    // Round-off in the differences: about the cost times 1e-16 over the step.
    let noise = |h: f64| lin.cost * 1e-15 / h;
    assert!(
        noise(1e-5) < 1e-3,
        "cost {} too large for the differences",
        lin.cost
    );
    // Calibration columns.
    for c in 0..st.dim() {
        let h = 1e-5;
        let mut d = DVector::zeros(st.dim());
        d[c] = h;
        let num =
            -(joint.cost(&ks, &st.retract(&d)) - joint.cost(&ks, &st.retract(&-d))) / (4.0 * h);
        if joint.held.contains(&c) {
            assert_eq!(lin.gth[c], 0.0, "held column {c}");
            assert!(lin.cross.column(c).iter().all(|x| *x == 0.0));
            continue;
        }
        assert!(
            (num - lin.gth[c]).abs() < 1e-4 * num.abs() + noise(h),
            "column {c}: numeric {num} vs {}",
            lin.gth[c]
        );
    }
    // Knot variables.
    for k in 0..ks.len() {
        for i in 0..18 {
            let h = 1e-5;
            let mut dx = vec![V18::zeros(); ks.len()];
            dx[k][i] = h;
            let up = joint.cost(&step(&ks, &dx, 1.0), &st);
            let down = joint.cost(&step(&ks, &dx, -1.0), &st);
            let num = -(up - down) / (4.0 * h);
            let ana = sys.rhs[k][i];
            assert!(
                (num - ana).abs() < 1e-4 * num.abs() + noise(h),
                "knot {k} variable {i}: numeric {num} vs {ana}"
            );
        }
    }
}
