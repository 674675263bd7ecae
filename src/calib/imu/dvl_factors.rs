//! The DVL's velocities as factors of the joint problem ([`super::solve`]), with the DVL's
//! parameters at the end of `theta`: where each lies on the trajectory, its residual and
//! Jacobians (the twist interpolated between the two knots around it), its share of the normal
//! equations and of the cost.

use std::ops::{AddAssign, SubAssign};

use nalgebra::{DMatrix, DVector, SMatrix};

use super::block::KB;
use super::coupling::Coupling;
use super::solve::ImuJoint;
use super::state::ImuState;
use crate::calib::model::{NPARAM, d_predict_d_params, d_predict_d_twist, predict};
use crate::trajectory::KnotView;
use crate::trajectory::blocktri::{BlockTridiagonal, M18, V18};
use crate::trajectory::gp::{Knot, LocalState, local_gamma, local_state};
use crate::types::CalibrationParams;

/// One DVL velocity's residual and Jacobians.
pub(super) struct DvlTerms {
    pub(super) e: nalgebra::Vector3<f64>,
    pub(super) j1: SMatrix<f64, 3, 18>,
    pub(super) j2: SMatrix<f64, 3, 18>,
    pub(super) jth: SMatrix<f64, 3, NPARAM>,
}

/// A DVL velocity's share of the normal equations (see [`BinNormal`]), on the DVL's columns.
#[derive(Clone, Default)]
struct DvlNormal {
    k: usize,
    cost: f64,
    d1: M18,
    d2: M18,
    up: M18,
    r1: V18,
    r2: V18,
    c1: SMatrix<f64, 18, NPARAM>,
    c2: SMatrix<f64, 18, NPARAM>,
    ht: SMatrix<f64, NPARAM, NPARAM>,
    gt: SMatrix<f64, NPARAM, 1>,
}

impl ImuJoint<'_> {
    /// For each DVL velocity inside the span at the DVL's clock offset: its index, the
    /// interval and its time on the trajectory's clock.
    pub(super) fn placed_dvl(&self, st: &ImuState) -> Vec<(usize, usize, f64)> {
        let Some(p) = &st.dvl else {
            return Vec::new();
        };
        let view = KnotView {
            times: &self.times,
            knots: &[],
        };
        let mut out: Vec<_> = self
            .dvl
            .iter()
            .enumerate()
            .filter_map(|(i, o)| {
                let tau = o.t + p.time_offset_s;
                view.interval(tau).map(|k| (i, k, tau))
            })
            .collect();
        out.sort_by(|a, b| a.2.total_cmp(&b.2));
        out
    }

    /// The residual and Jacobians of DVL velocity `i` at `tau`, in interval `k`.
    pub(super) fn dvl_terms(
        &self,
        knots: &[Knot],
        k: usize,
        tau: f64,
        ls: &LocalState,
        i: usize,
        p: &CalibrationParams,
    ) -> DvlTerms {
        let view = KnotView {
            times: &self.times,
            knots,
        };
        let m = d_predict_d_twist(p);
        let (motion, j1, j2) = view.projected_twist_jacobian_in(k, tau, ls, &m);
        DvlTerms {
            e: predict(p, &motion.twist) - self.dvl[i].v,
            j1,
            j2,
            jth: d_predict_d_params(p, &motion.twist, &motion.rate),
        }
    }

    /// The DVL's part of the cost.
    pub(super) fn dvl_cost(&self, knots: &[Knot], st: &ImuState) -> f64 {
        let Some(p) = &st.dvl else { return 0.0 };
        let view = KnotView {
            times: &self.times,
            knots,
        };
        let mut cost = 0.0;
        let gamma2 = |k: usize| local_gamma(&knots[k], &knots[k + 1]);
        let term = |g2: &V18, i: usize, k: usize, tau: f64| {
            let e = predict(p, &view.motion_in(k, tau, g2).twist) - self.dvl[i].v;
            (e.transpose() * self.dvl_info[i] * e)[0]
        };
        self.map_factors(&self.placed_dvl(st), 0.0, gamma2, term, |c| cost += c);
        cost
    }

    /// The DVL's share of the normal equations at `knots` and `st` (DVL parameters `p`): its
    /// blocks on the knots into `sys` and `cross`, on the DVL's columns of `theta` into `hth`
    /// and `gth`; returns its cost. The terms are computed in parallel and summed in the
    /// velocities' order.
    pub(super) fn linearise_dvl(
        &self,
        knots: &[Knot],
        st: &ImuState,
        p: &CalibrationParams,
        sys: &mut BlockTridiagonal<KB>,
        cross: &mut Coupling,
        (hth, gth): (&mut DMatrix<f64>, &mut DVector<f64>),
    ) -> f64 {
        let mut cost = 0.0;
        let c0 = st.dvl_start();
        let local = |k: usize| local_state(&knots[k], &knots[k + 1]);
        let normal = |l: &LocalState, i: usize, k: usize, tau: f64| {
            let t = self.dvl_terms(knots, k, tau, l, i, p);
            let w = &self.dvl_info[i];
            let we = w * t.e;
            let (wj1, wj2, wjt) = (w * t.j1, w * t.j2, w * t.jth);
            DvlNormal {
                k,
                cost: t.e.dot(&we),
                d1: t.j1.transpose() * wj1,
                d2: t.j2.transpose() * wj2,
                up: t.j1.transpose() * wj2,
                r1: t.j1.transpose() * we,
                r2: t.j2.transpose() * we,
                c1: t.j1.transpose() * wjt,
                c2: t.j2.transpose() * wjt,
                ht: t.jth.transpose() * wjt,
                gt: t.jth.transpose() * we,
            }
        };
        let add = |b: &DvlNormal| {
            let k = b.k;
            cost += b.cost;
            // On the knots' trajectory rows (the DVL does not see the biases).
            sys.diag[k].fixed_view_mut::<18, 18>(0, 0).add_assign(&b.d1);
            sys.diag[k + 1]
                .fixed_view_mut::<18, 18>(0, 0)
                .add_assign(&b.d2);
            sys.upper[k]
                .fixed_view_mut::<18, 18>(0, 0)
                .add_assign(&b.up);
            sys.rhs[k].fixed_rows_mut::<18>(0).sub_assign(&b.r1);
            sys.rhs[k + 1].fixed_rows_mut::<18>(0).sub_assign(&b.r2);
            cross.add_dvl(k, &b.c1);
            cross.add_dvl(k + 1, &b.c2);
            hth.view_mut((c0, c0), (NPARAM, NPARAM)).add_assign(&b.ht);
            gth.rows_mut(c0, NPARAM).sub_assign(&b.gt);
        };
        self.map_factors(
            &self.placed_dvl(st),
            DvlNormal::default(),
            local,
            normal,
            add,
        );
        cost
    }
}
