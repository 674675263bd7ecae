//! Simulated DVL samples as the A50 reports them: json_v3.1 velocity reports with the beams
//! reported valid at a nominal distance (beam readings are not simulated).

use nalgebra::Matrix3;

use crate::io::dvl::a50::{A50Transducer, A50VelocityReport};
use crate::time::Epoch;
use crate::types::DvlSample;

/// The A50 report of one simulated sample. `prev_t` is the previous sample's time (for the
/// report's `time` field, the milliseconds since the last report; 100 ms for the first), and
/// `altitude` the distance every beam reports, m.
pub fn a50_report(
    s: &DvlSample,
    epoch: Epoch,
    prev_t: Option<f64>,
    altitude: f64,
) -> A50VelocityReport {
    let us = epoch.sec * 1_000_000 + (s.t * 1e6).round() as i64;
    let cov = s.cov.unwrap_or_else(Matrix3::zeros);
    let beam = |id: i64| A50Transducer {
        id,
        velocity: 0.0,
        distance: altitude,
        rssi: -40.0,
        nsd: -95.0,
        beam_valid: s.valid,
    };
    A50VelocityReport {
        time: prev_t.map(|p| (s.t - p) * 1e3).unwrap_or(100.0),
        vx: s.v.x,
        vy: s.v.y,
        vz: s.v.z,
        fom: cov.diagonal().max().max(0.0).sqrt(),
        covariance: [
            [cov[(0, 0)], cov[(0, 1)], cov[(0, 2)]],
            [cov[(1, 0)], cov[(1, 1)], cov[(1, 2)]],
            [cov[(2, 0)], cov[(2, 1)], cov[(2, 2)]],
        ],
        altitude,
        transducers: [beam(0), beam(1), beam(2), beam(3)],
        velocity_valid: s.valid,
        status: 0,
        format: "json_v3.1".into(),
        report_type: "velocity".into(),
        time_of_validity: us,
        // The report leaves the DVL a few tens of milliseconds after mid-ping.
        time_of_transmission: us + 40_000,
    }
}

/// The reports of a whole simulated log, in order, every beam at `altitude`.
pub fn a50_reports(samples: &[DvlSample], epoch: Epoch, altitude: f64) -> Vec<A50VelocityReport> {
    samples
        .iter()
        .enumerate()
        .map(|(i, s)| a50_report(s, epoch, i.checked_sub(1).map(|j| samples[j].t), altitude))
        .collect()
}
