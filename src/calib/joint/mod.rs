//! The joint problem over trajectory and calibration: the problem itself ([`problem`]: the
//! co-sensor's factors, the DVL observations, the priors and the storage its systems reuse), the
//! DVL factors and the assembly of the joint normal equations ([`factors`]), the calibration's
//! marginal covariance from them ([`covariance`]), and the steps taken on the problem
//! ([`steps`]: the state update with the calibration fixed, the joint Gauss-Newton step, the
//! joint cost and the evidence of a jerk density), the clock drift as a ninth parameter
//! ([`drift`]), and each sensor's redundancy in it
//! ([`redundancy`], for the estimate of its noise).

pub(crate) mod covariance;
pub(crate) mod drift;
pub(crate) mod factors;
pub(crate) mod problem;
pub(crate) mod redundancy;
pub(crate) mod steps;
