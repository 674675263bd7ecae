//! What the camera-IMU calibration estimates besides the trajectory, and how a step moves it.
//!
//! The parameter vector `theta` is laid out as:
//!
//! | index | quantity | step |
//! |---|---|---|
//! | 0..3 | rotation `R_cam_imu` | `R <- R Exp(d)` (IMU frame) |
//! | 3..6 | lever arm `p_cam_imu`, m | added |
//! | 6 | clock offset, s (`t_cam = t_imu + offset`) | added |
//! | 7..9 | gravity direction | `R_g <- R_g Exp([d0, d1, 0])`, `g_world = R_g [0, 0, -|g|]` |
//! | 9..17, with a DVL | the DVL's `[dphi; dp; dkappa; ddelta]` | as `CalibrationParams::updated` |
//!
//! The biases are not in `theta`: in the joint problem they are states of the knots (one gyro
//! and one accelerometer bias per knot, linear between knots, consecutive knots tied by the
//! random walks of the noise file), stepped with the knots ([`ImuState::with_bias_step`]).

use nalgebra::{DVector, Matrix3, Vector3, Vector6};

use crate::calib::model::NPARAM;
use crate::lie::{Se3, so3};
use crate::types::CalibrationParams;
use crate::types::imu::ImuBias;

/// Parameters before the DVL's.
pub const NFIXED: usize = 9;

/// The biases, linear between nodes.
#[derive(Clone, Debug, PartialEq)]
pub struct BiasNodes {
    /// Node times, seconds, strictly increasing (at least two): the knots' times (camera clock)
    /// in the joint problem, the IMU's clock in its first estimate.
    pub times: Vec<f64>,
    /// The biases at the nodes.
    pub values: Vec<ImuBias>,
}

impl BiasNodes {
    /// Nodes spaced at most `spacing` apart over `[t0, t1]` (at least two), all at `bias`.
    pub fn spanning(t0: f64, t1: f64, spacing: f64, bias: ImuBias) -> BiasNodes {
        let n = (((t1 - t0) / spacing).ceil() as usize).max(1) + 1;
        let times = (0..n)
            .map(|i| t0 + (t1 - t0) * i as f64 / (n - 1) as f64)
            .collect();
        BiasNodes {
            times,
            values: vec![bias; n],
        }
    }

    /// The node `i` and weight `u` of time `t`: the bias is `(1 - u) b_i + u b_{i+1}` (constant
    /// beyond the ends).
    pub fn weights(&self, t: f64) -> (usize, f64) {
        let n = self.times.len();
        let i = self
            .times
            .partition_point(|&x| x <= t)
            .saturating_sub(1)
            .min(n - 2);
        let (a, b) = (self.times[i], self.times[i + 1]);
        (i, ((t - a) / (b - a)).clamp(0.0, 1.0))
    }

    /// The bias at `t`.
    pub fn at(&self, t: f64) -> ImuBias {
        let (i, u) = self.weights(t);
        self.between(i, u)
    }

    /// `(1 - u) b_i + u b_{i+1}`.
    pub fn between(&self, i: usize, u: f64) -> ImuBias {
        let (a, b) = (&self.values[i], &self.values[i + 1]);
        ImuBias {
            gyro: a.gyro * (1.0 - u) + b.gyro * u,
            accel: a.accel * (1.0 - u) + b.accel * u,
        }
    }

    /// Nodes at `times` with the biases of `self` there (`self`'s times shifted by `shift`:
    /// from the IMU's clock to the camera's, the clock offset).
    pub fn resampled(&self, times: &[f64], shift: f64) -> BiasNodes {
        BiasNodes {
            times: times.to_vec(),
            values: times.iter().map(|t| self.at(t - shift)).collect(),
        }
    }
}

/// The IMU's calibration and biases at one iterate.
#[derive(Clone, Debug, PartialEq)]
pub struct ImuState {
    /// `T_cam_imu`: maps IMU-frame points into the camera frame.
    pub t_cam_imu: Se3,
    /// `t_cam = t_imu + time_offset_s`.
    pub time_offset_s: f64,
    /// `R_g`: gravity is `R_g [0, 0, -|g|]` in the world (board) frame.
    pub gravity_rotation: Matrix3<f64>,
    /// `|g|`, m/s^2 (held).
    pub gravity_magnitude: f64,
    /// The biases.
    pub bias: BiasNodes,
    /// A DVL calibrated against the trajectory in the same problem (the DVL + IMU mode): its
    /// `T_cam_dvl` then maps DVL points into the trajectory's body frame, and its clock offset
    /// is `t_body = t_dvl + time_offset_s`.
    pub dvl: Option<CalibrationParams>,
}

impl ImuState {
    /// Gravity in the world frame (pointing down).
    pub fn gravity_world(&self) -> Vector3<f64> {
        self.gravity_rotation * Vector3::new(0.0, 0.0, -self.gravity_magnitude)
    }

    /// The length of `theta`.
    pub fn dim(&self) -> usize {
        self.dvl_start() + if self.dvl.is_some() { NPARAM } else { 0 }
    }

    /// The first column of the DVL's parameters (the length of `theta` without them).
    pub fn dvl_start(&self) -> usize {
        NFIXED
    }

    /// The state moved by the step `d` (length [`ImuState::dim`]).
    pub fn retract(&self, d: &DVector<f64>) -> ImuState {
        let v3 = |i: usize| Vector3::new(d[i], d[i + 1], d[i + 2]);
        let mut out = self.clone();
        out.t_cam_imu = Se3::new(
            self.t_cam_imu.rot * so3::exp(&v3(0)),
            self.t_cam_imu.trans + v3(3),
        )
        .renormalized();
        out.time_offset_s += d[6];
        out.gravity_rotation = self.gravity_rotation * so3::exp(&Vector3::new(d[7], d[8], 0.0));
        if let Some(p) = &self.dvl {
            let c = self.dvl_start();
            let dp = nalgebra::SMatrix::<f64, NPARAM, 1>::from_fn(|r, _| d[c + r]);
            out.dvl = Some(p.updated(&dp));
        }
        out
    }

    /// The state with `scale` times the knots' bias steps `db` added (one per node: gyro, then
    /// accelerometer).
    pub fn with_bias_step(mut self, db: &[Vector6<f64>], scale: f64) -> ImuState {
        for (b, d) in self.bias.values.iter_mut().zip(db) {
            b.gyro += d.fixed_rows::<3>(0) * scale;
            b.accel += d.fixed_rows::<3>(3) * scale;
        }
        self
    }

    /// The rotation `R_g` that takes `[0, 0, -1]` to the direction of `g_world`.
    pub fn gravity_rotation_of(g_world: &Vector3<f64>) -> Matrix3<f64> {
        let down = Vector3::new(0.0, 0.0, -1.0);
        let to = g_world.normalize();
        let axis = down.cross(&to);
        let s = axis.norm();
        let c = down.dot(&to);
        if s < 1e-12 {
            return if c > 0.0 {
                Matrix3::identity()
            } else {
                so3::exp(&Vector3::new(std::f64::consts::PI, 0.0, 0.0))
            };
        }
        so3::exp(&(axis / s * s.atan2(c)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn biases_are_linear_between_nodes_and_held_beyond() {
        let mut b = BiasNodes::spanning(0.0, 25.0, 10.0, ImuBias::default());
        assert_eq!(b.times.len(), 4);
        b.values[1].gyro = Vector3::new(1.0, 0.0, 0.0);
        let dt = b.times[1];
        assert!((b.at(dt * 0.5).gyro.x - 0.5).abs() < 1e-12);
        assert!((b.at(dt * 1.5).gyro.x - 0.5).abs() < 1e-12);
        assert_eq!(b.at(-5.0).gyro.x, 0.0);
        assert_eq!(b.at(99.0).gyro.x, 0.0);
    }

    #[test]
    fn the_gravity_rotation_points_down_along_g() {
        for g in [
            Vector3::new(0.3, -2.0, -9.0),
            Vector3::new(0.0, 0.0, 9.8),
            Vector3::new(0.0, 0.0, -9.8),
        ] {
            let r = ImuState::gravity_rotation_of(&g);
            let got = r * Vector3::new(0.0, 0.0, -g.norm());
            assert!((got - g).norm() < 1e-9, "{got} vs {g}");
        }
    }
}
