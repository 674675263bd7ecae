//! The IMU's biases' random walks as factors of the joint problem ([`super::solve`]): each
//! knot's biases tied to the next knot's, on the bias rows of the knots' blocks.

use nalgebra::Vector3;

use super::block::KB;
use super::solve::ImuJoint;
use super::state::ImuState;
use crate::trajectory::blocktri::BlockTridiagonal;

impl ImuJoint<'_> {
    /// The information of the biases' random walks (gyro, accelerometer) between knots `k`
    /// and `k + 1`.
    fn walk_information(&self, k: usize) -> (f64, f64) {
        let dt = self.times[k + 1] - self.times[k];
        let g = self.noise.gyroscope_random_walk.max(1e-12);
        let a = self.noise.accelerometer_random_walk.max(1e-12);
        (1.0 / (g * g * dt), 1.0 / (a * a * dt))
    }

    /// The random walk from knot `k` to the next: its information (gyro, accelerometer), its
    /// residuals (the biases' change) and its cost.
    fn walk(&self, st: &ImuState, k: usize) -> ((f64, f64), [Vector3<f64>; 2], f64) {
        let (wg, wa) = self.walk_information(k);
        let (b0, b1) = (&st.bias.values[k], &st.bias.values[k + 1]);
        let r = [b1.gyro - b0.gyro, b1.accel - b0.accel];
        let cost = wg * r[0].norm_squared() + wa * r[1].norm_squared();
        ((wg, wa), r, cost)
    }

    /// The random walks' cost: the biases' change from each knot to the next.
    pub(super) fn walk_cost(&self, st: &ImuState) -> f64 {
        (0..st.bias.values.len() - 1)
            .map(|k| self.walk(st, k).2)
            .sum()
    }

    /// The random walks' share of the normal equations, on the knots' bias rows; returns
    /// their cost.
    pub(super) fn linearise_walks(&self, st: &ImuState, sys: &mut BlockTridiagonal<KB>) -> f64 {
        let mut cost = 0.0;
        for k in 0..st.bias.values.len() - 1 {
            let ((wg, wa), r, c) = self.walk(st, k);
            cost += c;
            for (part, (w, d)) in [(wg, &r[0]), (wa, &r[1])].into_iter().enumerate() {
                for (x, dx) in d.iter().enumerate() {
                    let c = 18 + 3 * part + x;
                    sys.diag[k][(c, c)] += w;
                    sys.diag[k + 1][(c, c)] += w;
                    sys.upper[k][(c, c)] -= w;
                    sys.rhs[k][c] += w * dx;
                    sys.rhs[k + 1][c] -= w * dx;
                }
            }
        }
        cost
    }
}
