//! The motion prior's jerk density along the recording.
//!
//! The white-noise-on-jerk prior has a power spectral density `Qc` (`[v; w]` order, one value
//! per component). A vehicle's motion is not equally smooth everywhere: it holds still, cruises
//! and turns in bursts. So the density may carry, for each interval between two knots, a factor
//! on its translational and one on its rotational part: the prior of interval `k` is then
//! `Q_k = Q(dt_k) (x) diag(base_v f_k,v, base_w f_k,w)`. Without factors the density is the
//! same everywhere.

use std::ops::Range;
use std::sync::Arc;

use nalgebra::Vector6;

/// `Qc` per interval between knots: a base value and optional factors per interval.
#[derive(Clone, Debug, PartialEq)]
pub struct JerkDensity {
    base: Vector6<f64>,
    /// Per interval `[translational, rotational]` factors on `base`; empty: 1 everywhere.
    factors: Arc<[[f64; 2]]>,
}

impl JerkDensity {
    /// The same density `qc` on every interval.
    pub fn constant(qc: Vector6<f64>) -> JerkDensity {
        JerkDensity {
            base: qc,
            factors: Arc::from(Vec::new()),
        }
    }

    /// The density `base` times `factors[k]` (translational, rotational) on interval `k`.
    pub fn varying(base: Vector6<f64>, factors: Vec<[f64; 2]>) -> JerkDensity {
        JerkDensity {
            base,
            factors: Arc::from(factors),
        }
    }

    /// The base density (the one of the whole recording when the density is constant).
    pub fn base(&self) -> Vector6<f64> {
        self.base
    }

    /// The per-interval factors (empty when the density is constant).
    pub fn factors(&self) -> &[[f64; 2]] {
        &self.factors
    }

    /// Whether the density is the same on every interval.
    pub fn is_constant(&self) -> bool {
        self.factors.is_empty()
    }

    /// The factors on interval `k` (1 beyond the ones given).
    pub fn factor(&self, k: usize) -> [f64; 2] {
        self.factors.get(k).copied().unwrap_or([1.0, 1.0])
    }

    /// `Qc` on interval `k`.
    pub fn qc(&self, k: usize) -> Vector6<f64> {
        let [ft, fr] = self.factor(k);
        Vector6::from_fn(|i, _| self.base[i] * if i < 3 { ft } else { fr })
    }

    /// `Qc^-1` on interval `k`.
    pub fn qc_inv(&self, k: usize) -> Vector6<f64> {
        self.qc(k).map(|q| 1.0 / q)
    }

    /// The density with its base multiplied by `factor` (the per-interval factors kept).
    pub fn scaled(&self, factor: f64) -> JerkDensity {
        JerkDensity {
            base: self.base * factor,
            factors: self.factors.clone(),
        }
    }

    /// The density of the knots `knots` alone (their intervals' factors).
    pub fn restricted(&self, knots: Range<usize>) -> JerkDensity {
        if self.factors.is_empty() {
            return self.clone();
        }
        let end = knots.end.saturating_sub(1).min(self.factors.len());
        let start = knots.start.min(end);
        JerkDensity {
            base: self.base,
            factors: Arc::from(self.factors[start..end].to_vec()),
        }
    }

    /// `sum_k log det Q_k` less the same sum at the base density over `intervals` intervals:
    /// each factor scales nine of the interval's eighteen dimensions (three components times
    /// pose, twist and rate).
    pub fn log_det_relative(&self, intervals: usize) -> f64 {
        (0..intervals)
            .map(|k| {
                let [ft, fr] = self.factor(k);
                9.0 * (ft.ln() + fr.ln())
            })
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn factors_scale_their_part_and_restrict_by_knots() {
        let base = Vector6::new(1.0, 2.0, 3.0, 4.0, 5.0, 6.0);
        let d = JerkDensity::varying(base, vec![[2.0, 1.0], [1.0, 10.0], [3.0, 3.0]]);
        assert_eq!(d.qc(0), Vector6::new(2.0, 4.0, 6.0, 4.0, 5.0, 6.0));
        assert_eq!(d.qc(1), Vector6::new(1.0, 2.0, 3.0, 40.0, 50.0, 60.0));
        assert_eq!(d.qc(7), base);
        assert!((d.qc_inv(2)[3] - 1.0 / 12.0).abs() < 1e-15);
        // Knots 1..4 hold intervals 1 and 2.
        let r = d.restricted(1..4);
        assert_eq!(r.factors(), &[[1.0, 10.0], [3.0, 3.0]]);
        assert_eq!(d.scaled(2.0).qc(1)[0], 2.0);
        let expect = 9.0 * (2f64.ln() + 10f64.ln() + 2.0 * 3f64.ln());
        assert!((d.log_det_relative(3) - expect).abs() < 1e-12);
        assert!(JerkDensity::constant(base).is_constant());
        assert_eq!(JerkDensity::constant(base).log_det_relative(5), 0.0);
    }
}
