//! The joint problem: what it takes besides the knot states, set up once per calibration, and
//! the storage its systems reuse.

use std::sync::Mutex;

use nalgebra::{Matrix3, SMatrix};

use crate::calib::model::{DvlObs, NPARAM};
use crate::calib::prior::Priors;
use crate::error::Result;
use crate::trajectory::blocktri::BlockTridiagonal;
use crate::trajectory::factors::CoSensorFactors;
use crate::trajectory::solver::Problem;
use crate::trajectory::{JerkDensity, Knot, KnotView, Trajectory};

/// What the joint problem needs besides the knot states: the co-sensor's factors (camera poses:
/// with the weights and Qc of the trajectory's fit), the DVL terms and the calibration's
/// priors.
pub struct JointProblem<'a> {
    /// The DVL observations (all of them; the problem uses those of `idx`).
    pub obs: &'a [DvlObs],
    /// DVL samples used.
    pub idx: &'a [usize],
    /// DVL information matrices, one per observation.
    pub dvl_info: Vec<Matrix3<f64>>,
    /// Priors on the calibration, factors of the joint problem beside the DVL's.
    pub priors: Priors,
    pub(super) times: Vec<f64>,
    /// The co-sensor's measurements as factors on the knots.
    pub(super) cosensor: Box<dyn CoSensorFactors + 'a>,
    pub(super) density: JerkDensity,
    /// Storage kept from one system to the next.
    storage: Mutex<JointStorage>,
}

/// What a joint problem keeps from one system to the next: the storage of the trajectory's
/// system (a system of 100k knots takes half a gigabyte, which is slow to allocate, and whose
/// pages are slow to fault in, every time) and of the calibration's coupling blocks `H_x theta`
/// (an eighth of a gigabyte more).
#[derive(Default)]
pub(crate) struct JointStorage {
    pub(super) system: Option<BlockTridiagonal>,
    pub(super) cross: Vec<CrossBlock>,
}

/// The 18 x 8 block `H_x theta` of one knot: how the knot's variables and the calibration
/// parameters are coupled through the DVL factors.
pub(super) type CrossBlock = SMatrix<f64, 18, NPARAM>;

impl<'a> JointProblem<'a> {
    /// The joint problem of `traj` (fitted to the co-sensor's measurements, whose factors are
    /// `cosensor`) and the DVL samples `idx` of `obs`.
    pub fn new(
        cosensor: Box<dyn CoSensorFactors + 'a>,
        traj: &Trajectory,
        obs: &'a [DvlObs],
        idx: &'a [usize],
    ) -> Result<Self> {
        let dvl_info = obs.iter().map(DvlObs::information).collect::<Result<_>>()?;
        Ok(JointProblem {
            obs,
            idx,
            dvl_info,
            priors: Priors::default(),
            times: traj.times().to_vec(),
            cosensor,
            density: traj.density().clone(),
            storage: Mutex::new(JointStorage::default()),
        })
    }

    /// A problem of the given parts (the DVL information `dvl_info` per observation, the knot
    /// times, the co-sensor's factors and `Qc^-1`), for tests that set them directly.
    #[cfg(test)]
    pub(super) fn from_parts(
        obs: &'a [DvlObs],
        idx: &'a [usize],
        dvl_info: Vec<Matrix3<f64>>,
        times: Vec<f64>,
        cosensor: Box<dyn CoSensorFactors + 'a>,
        qc_inv: nalgebra::Vector6<f64>,
    ) -> Self {
        JointProblem {
            obs,
            idx,
            dvl_info,
            priors: Priors::default(),
            times,
            cosensor,
            density: JerkDensity::constant(qc_inv.map(|q| 1.0 / q)),
            storage: Mutex::new(JointStorage::default()),
        }
    }

    /// The same problem with the motion prior's jerk density `qc_factor` times this one's.
    pub fn with_qc_factor(mut self, qc_factor: f64) -> Self {
        self.density = self.density.scaled(qc_factor);
        self
    }

    /// The problem of the samples `idx` (a subset of this one's) on the knots `range` alone:
    /// this problem's co-sensor terms, weights and DVL information restricted to them, without
    /// computing any of them again.
    pub fn part<'p>(&'p self, idx: &'p [usize], range: std::ops::Range<usize>) -> JointProblem<'p> {
        JointProblem {
            obs: self.obs,
            idx,
            dvl_info: self.dvl_info.clone(),
            priors: self.priors,
            times: self.times[range.clone()].to_vec(),
            cosensor: self.cosensor.restricted(range.clone()),
            density: self.density.restricted(range),
            storage: Mutex::new(JointStorage::default()),
        }
    }

    /// All the kept storage, to hand to another problem of the same knots.
    pub(crate) fn take_storage(&self) -> JointStorage {
        self.storage
            .lock()
            .map(|mut s| std::mem::take(&mut *s))
            .unwrap_or_default()
    }

    /// Keeps `storage` (from [`JointProblem::take_storage`]) for the next systems.
    pub(crate) fn keep_storage(&self, storage: JointStorage) {
        if let Ok(mut s) = self.storage.lock() {
            *s = storage;
        }
    }

    /// The kept system storage, if any.
    pub(crate) fn take_system(&self) -> Option<BlockTridiagonal> {
        self.storage.lock().ok().and_then(|mut s| s.system.take())
    }

    /// Keeps `sys` for the next update.
    pub(crate) fn keep_system(&self, sys: BlockTridiagonal) {
        if let Ok(mut s) = self.storage.lock() {
            s.system = Some(sys);
        }
    }

    /// The kept storage of `H_x theta` (empty when there is none).
    pub(super) fn take_cross(&self) -> Vec<CrossBlock> {
        self.storage
            .lock()
            .map(|mut s| std::mem::take(&mut s.cross))
            .unwrap_or_default()
    }

    /// The co-sensor and GP-prior terms (the trajectory fit's own problem).
    pub(super) fn trajectory_problem(&self) -> Problem<'_> {
        Problem {
            times: &self.times,
            cosensor: &*self.cosensor,
            density: &self.density,
        }
    }

    pub(super) fn view<'k>(&'k self, knots: &'k [Knot]) -> KnotView<'k> {
        KnotView {
            times: &self.times,
            knots,
        }
    }
}
