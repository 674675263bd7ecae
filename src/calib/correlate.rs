//! Circular cross-correlations of real series by FFT, for the clock searches that score every
//! lag at once (the DVL's global alignment, the IMU's coarse offset).

use rustfft::FftPlanner;
use rustfft::num_complex::Complex;

/// Circular cross-correlations `c[k] = sum_j a[(j + k) mod m] b[j]` of several pairs, through
/// one forward transform per distinct series.
pub(crate) struct Correlator {
    m: usize,
    planner: FftPlanner<f64>,
}

impl Correlator {
    /// Correlations of length `m` (series are zero-padded to it).
    pub(crate) fn new(m: usize) -> Correlator {
        Correlator {
            m,
            planner: FftPlanner::new(),
        }
    }

    pub(crate) fn forward(&mut self, x: &[f64]) -> Vec<Complex<f64>> {
        let mut buf: Vec<Complex<f64>> = x.iter().map(|&v| Complex::new(v, 0.0)).collect();
        buf.resize(self.m, Complex::new(0.0, 0.0));
        self.planner.plan_fft_forward(self.m).process(&mut buf);
        buf
    }

    pub(crate) fn correlate(&mut self, fa: &[Complex<f64>], fb: &[Complex<f64>]) -> Vec<f64> {
        let mut buf: Vec<Complex<f64>> = fa.iter().zip(fb).map(|(a, b)| a * b.conj()).collect();
        self.planner.plan_fft_inverse(self.m).process(&mut buf);
        let scale = 1.0 / self.m as f64;
        buf.iter().map(|c| c.re * scale).collect()
    }
}
