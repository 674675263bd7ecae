//! The seam's interval path, which camera poses leave unused: a co-sensor kind measured between
//! knots (here the body twist at times inside the intervals, as a gyro and a velocity sensor
//! would see it) is assembled by the solver into the blocks its numeric Jacobians give, and a
//! Gauss-Newton run on it reaches the minimum of its cost.

use nalgebra::{Matrix6, SMatrix, Vector6};

use super::*;
use crate::rng::Rng;
use crate::trajectory::JerkDensity;
use crate::trajectory::blocktri::BlockTridiagonal;
use crate::trajectory::gp::local_gamma;
use crate::trajectory::solver::{GaussNewtonOptions, Problem, gauss_newton, step};

/// Camera poses at the knots and body twists measured between them.
pub(crate) struct PosesAndTwists {
    pub poses: PoseFactors,
    pub times: Vec<f64>,
    /// Sample times, twists measured, and their information.
    samples: Vec<(f64, Vector6<f64>)>,
    info: Matrix6<f64>,
}

impl PosesAndTwists {
    fn in_interval(&self, view: KnotView, k: usize) -> impl Iterator<Item = &(f64, Vector6<f64>)> {
        let (a, b) = (view.times[k], view.times[k + 1]);
        self.samples.iter().filter(move |(t, _)| *t >= a && *t < b)
    }
}

impl CoSensorFactors for PosesAndTwists {
    fn knot_terms(&self, knots: &[Knot], k: usize, diag: &mut M18, rhs: &mut V18) -> f64 {
        self.poses.knot_terms(knots, k, diag, rhs)
    }

    fn knot_cost(&self, knots: &[Knot], k: usize) -> f64 {
        self.poses.knot_cost(knots, k)
    }

    fn has_interval_terms(&self) -> bool {
        true
    }

    fn interval_terms(
        &self,
        view: KnotView,
        k: usize,
        ls: &LocalState,
        out: &mut IntervalNormal,
    ) -> bool {
        *out = IntervalNormal::zeros();
        let mut any = false;
        for (t, meas) in self.in_interval(view, k) {
            let tj = view.twist_jacobian_in(k, *t, ls);
            let e = tj.state.twist - meas;
            let j1: SMatrix<f64, 6, 18> = tj.jacobian.fixed_columns::<18>(0).into_owned();
            let j2: SMatrix<f64, 6, 18> = tj.jacobian.fixed_columns::<18>(18).into_owned();
            out.d1 += j1.transpose() * self.info * j1;
            out.upper += j1.transpose() * self.info * j2;
            out.d2 += j2.transpose() * self.info * j2;
            out.r1 -= j1.transpose() * self.info * e;
            out.r2 -= j2.transpose() * self.info * e;
            out.cost += (e.transpose() * self.info * e)[0];
            any = true;
        }
        any
    }

    fn interval_cost(&self, view: KnotView, k: usize, gamma2: &V18) -> f64 {
        self.in_interval(view, k)
            .map(|(t, meas)| {
                let e = view.twist_in(k, *t, gamma2) - meas;
                (e.transpose() * self.info * e)[0]
            })
            .sum()
    }

    fn dimension(&self) -> usize {
        self.poses.dimension() + 6 * self.samples.len()
    }

    fn restricted(&self, range: Range<usize>) -> Box<dyn CoSensorFactors + '_> {
        let (a, b) = (self.times[range.start], self.times[range.end - 1]);
        Box::new(PosesAndTwists {
            poses: PoseFactors {
                meas: self.poses.meas[range.clone()].to_vec(),
                info: self.poses.info[range.clone()].to_vec(),
            },
            times: self.times[range].to_vec(),
            samples: self
                .samples
                .iter()
                .filter(|(t, _)| *t >= a && *t < b)
                .cloned()
                .collect(),
            info: self.info,
        })
    }
}

/// Twelve knots 0.1 s apart on a turning, accelerating motion, with noisy poses and twists
/// measured three times per interval.
pub(crate) fn setup(seed: u64) -> (Vec<Knot>, PosesAndTwists) {
    let mut rng = Rng::new(seed);
    let n = 12;
    let times: Vec<f64> = (0..n).map(|k| 0.1 * k as f64).collect();
    let base = Vector6::new(0.4, -0.1, 0.2, 0.3, -0.5, 0.8);
    let rate = Vector6::new(0.5, 0.2, -0.3, 1.0, 0.4, -0.6);
    let knots: Vec<Knot> = times
        .iter()
        .map(|&t| Knot {
            pose: Se3::exp(&(base * t + rate * (0.5 * t * t))),
            twist: base + rate * t + rng.normal_vec6() * 0.05,
            rate: rate + rng.normal_vec6() * 0.2,
        })
        .collect();
    let meas: Vec<Se3> = knots
        .iter()
        .map(|k| k.pose * Se3::exp(&(rng.normal_vec6() * 0.003)))
        .collect();
    let info = vec![Matrix6::identity() * 1e5; n];
    let mut samples = Vec::new();
    for k in 0..n - 1 {
        for f in [0.2, 0.5, 0.8] {
            let t = times[k] + f * (times[k + 1] - times[k]);
            let truth = base + rate * t;
            samples.push((t, truth + rng.normal_vec6() * 0.01));
        }
    }
    let cos = PosesAndTwists {
        poses: PoseFactors::new(meas, info),
        times,
        samples,
        info: Matrix6::identity() * 1e4,
    };
    (knots, cos)
}

/// The twist factors' residuals at `knots`, stacked.
fn residuals(cos: &PosesAndTwists, knots: &[Knot]) -> Vec<Vector6<f64>> {
    let view = KnotView {
        times: &cos.times,
        knots,
    };
    cos.samples
        .iter()
        .map(|(t, meas)| {
            let k = view.interval(*t).expect("inside");
            let g = local_gamma(&knots[k], &knots[k + 1]);
            view.twist_in(k, *t, &g) - meas
        })
        .collect()
}

#[test]
fn interval_factors_are_assembled_into_the_blocks_their_jacobians_give() {
    let (knots, cos) = setup(3);
    let n = knots.len();
    let density = JerkDensity::constant(Vector6::from_element(0.05));
    let with = Problem {
        times: &cos.times,
        cosensor: &cos,
        density: &density,
    };
    let without = Problem {
        times: &cos.times,
        cosensor: &cos.poses,
        density: &density,
    };
    let mut sys = BlockTridiagonal::zeros(n);
    let cost = with.assemble_into(&knots, &mut sys);
    // The cost alone sums the same terms in the same order.
    assert_eq!(cost, with.cost(&knots));
    let mut base = BlockTridiagonal::zeros(n);
    let base_cost = without.assemble_into(&knots, &mut base);
    let r0 = residuals(&cos, &knots);
    let twist_cost: f64 = r0.iter().map(|e| (e.transpose() * cos.info * e)[0]).sum();
    assert!(
        ((cost - base_cost) - twist_cost).abs() < 1e-9 * cost,
        "{cost} {base_cost} {twist_cost}"
    );

    // Numeric Jacobian of the stacked twist residuals against every knot variable.
    let h = 1e-6;
    let m = cos.samples.len();
    let mut jac = vec![vec![Vector6::zeros(); 18 * n]; m];
    for col in 0..18 * n {
        let mut dx = vec![V18::zeros(); n];
        dx[col / 18][col % 18] = h;
        let plus = residuals(&cos, &step(&knots, &dx, 1.0));
        let minus = residuals(&cos, &step(&knots, &dx, -1.0));
        for ((row, p), q) in jac.iter_mut().zip(&plus).zip(&minus) {
            row[col] = (p - q) / (2.0 * h);
        }
    }
    // J^T W J and -J^T W e of the twist factors, by knot blocks.
    let block = |a: usize, b: usize| -> M18 {
        let mut out = M18::zeros();
        for row in &jac {
            for i in 0..18 {
                for j in 0..18 {
                    out[(i, j)] += (row[18 * a + i].transpose() * cos.info * row[18 * b + j])[0];
                }
            }
        }
        out
    };
    let mut worst = 0.0f64;
    for k in 0..n {
        let d = block(k, k);
        let got = sys.diag[k] - base.diag[k];
        worst = worst.max((got - d).amax() / d.amax().max(1.0));
        let mut g = V18::zeros();
        for s in 0..m {
            for i in 0..18 {
                g[i] -= (jac[s][18 * k + i].transpose() * cos.info * r0[s])[0];
            }
        }
        let got = sys.rhs[k] - base.rhs[k];
        worst = worst.max((got - g).amax() / g.amax().max(1.0));
        if k + 1 < n {
            let u = block(k, k + 1);
            let got = sys.upper[k] - base.upper[k];
            worst = worst.max((got - u).amax() / u.amax().max(1.0));
        }
    }
    assert!(worst < 1e-5, "largest relative block error {worst:e}");
}

#[test]
fn the_solver_minimises_a_cost_with_interval_factors() {
    let (knots, cos) = setup(5);
    let density = JerkDensity::constant(Vector6::from_element(0.05));
    let problem = Problem {
        times: &cos.times,
        cosensor: &cos,
        density: &density,
    };
    let start = problem.cost(&knots);
    let solved = gauss_newton(
        &problem,
        knots,
        GaussNewtonOptions {
            max_iterations: 20,
            stop_decrement: 1e-10,
            factor: false,
            storage: None,
        },
    )
    .expect("solve");
    assert!(
        solved.converged && solved.cost < 0.5 * start,
        "{start} -> {}",
        solved.cost
    );
    // At the minimum the gradient vanishes: the right-hand side is zero to the solver's
    // tolerance, relative to its size at the start.
    let n = solved.knots.len();
    let mut sys = BlockTridiagonal::zeros(n);
    problem.assemble_into(&solved.knots, &mut sys);
    let g = sys.rhs.iter().map(|r| r.amax()).fold(0.0, f64::max);
    let mut sys0 = BlockTridiagonal::zeros(n);
    problem.assemble_into(&setup(5).0, &mut sys0);
    let g0 = sys0.rhs.iter().map(|r| r.amax()).fold(0.0, f64::max);
    assert!(g < 1e-6 * g0, "gradient {g:e} against {g0:e} at the start");
    // A part of the problem keeps the interval factors of its knots.
    let part = cos.restricted(2..8);
    let sub = &solved.knots[2..8];
    let view = KnotView {
        times: &cos.times[2..8],
        knots: sub,
    };
    let g2 = local_gamma(&sub[0], &sub[1]);
    assert!(part.has_interval_terms());
    assert_eq!(
        part.interval_cost(view, 0, &g2),
        cos.interval_cost(
            KnotView {
                times: &cos.times,
                knots: &solved.knots
            },
            2,
            &g2
        )
    );
}
