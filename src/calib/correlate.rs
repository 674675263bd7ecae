//! Circular cross-correlations of real series by FFT, for the clock searches that score every
//! lag at once (the DVL's global alignment, the IMU's coarse offset).
//!
//! Every series is real, so two of them share one complex transform: the spectrum of `x + i y`
//! splits into theirs by the conjugate symmetry of a real series' spectrum, and two real
//! correlations come back as the real and imaginary parts of one inverse transform. The pairs'
//! transforms run in parallel.

use std::sync::Arc;

use rayon::prelude::*;
use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};

/// A series' spectrum, of the correlator's length.
pub(crate) type Spectrum = Vec<Complex<f64>>;

/// Circular cross-correlations `c[k] = sum_j a[(j + k) mod m] b[j]` of several pairs, through
/// one forward transform per two distinct series. Rounding is relative to the larger of the two
/// sharing a transform (about `1e-15` of it), so series of like size are best given together.
pub(crate) struct Correlator {
    m: usize,
    forward: Arc<dyn Fft<f64>>,
    inverse: Arc<dyn Fft<f64>>,
}

impl Correlator {
    /// Correlations of length `m` (series are zero-padded to it).
    pub(crate) fn new(m: usize) -> Correlator {
        let mut planner = FftPlanner::new();
        Correlator {
            m,
            forward: planner.plan_fft_forward(m),
            inverse: planner.plan_fft_inverse(m),
        }
    }

    /// The spectra of `series`, in their order (each at most `m` long).
    pub(crate) fn forward(&self, series: &[&[f64]]) -> Vec<Spectrum> {
        let pairs: Vec<(Spectrum, Option<Spectrum>)> = series
            .par_chunks(2)
            .map(|p| {
                let (x, y) = (p[0], p.get(1).copied().unwrap_or(&[]));
                let mut z: Spectrum = (0..self.m)
                    .map(|j| Complex::new(at(x, j), at(y, j)))
                    .collect();
                self.forward.process(&mut z);
                if p.len() == 1 {
                    return (z, None);
                }
                // Z = X + iY with X, Y the spectra of real series: X[k] = (Z[k] + conj Z[-k]) / 2,
                // Y[k] = (Z[k] - conj Z[-k]) / 2i.
                let (xs, ys) = (0..self.m)
                    .map(|k| {
                        let (a, b) = (z[k], z[(self.m - k) % self.m].conj());
                        ((a + b) * 0.5, Complex::new(0.0, -0.5) * (a - b))
                    })
                    .unzip();
                (xs, Some(ys))
            })
            .collect();
        pairs
            .into_iter()
            .flat_map(|(x, y)| std::iter::once(x).chain(y))
            .collect()
    }

    /// The correlations of each pair `(a, b)` of spectra, in their order.
    pub(crate) fn correlate(&self, pairs: &[(&Spectrum, &Spectrum)]) -> Vec<Vec<f64>> {
        let scale = 1.0 / self.m as f64;
        let out: Vec<(Vec<f64>, Option<Vec<f64>>)> = pairs
            .par_chunks(2)
            .map(|p| {
                let spectrum = |(a, b): &(&Spectrum, &Spectrum)| -> Spectrum {
                    a.iter().zip(b.iter()).map(|(x, y)| x * y.conj()).collect()
                };
                let mut z = spectrum(&p[0]);
                // Both correlations are real: the second rides in the imaginary part.
                if let Some(q) = p.get(1) {
                    let i = Complex::new(0.0, 1.0);
                    for (z, w) in z.iter_mut().zip(spectrum(q)) {
                        *z += i * w;
                    }
                }
                self.inverse.process(&mut z);
                let re = z.iter().map(|c| c.re * scale).collect();
                let im = (p.len() == 2).then(|| z.iter().map(|c| c.im * scale).collect());
                (re, im)
            })
            .collect();
        out.into_iter()
            .flat_map(|(a, b)| std::iter::once(a).chain(b))
            .collect()
    }
}

/// `x[j]`, zero past its end.
fn at(x: &[f64], j: usize) -> f64 {
    x.get(j).copied().unwrap_or(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The correlations by their definition.
    fn direct(a: &[f64], b: &[f64], m: usize) -> Vec<f64> {
        (0..m)
            .map(|k| (0..m).map(|j| at(a, (j + k) % m) * at(b, j)).sum())
            .collect()
    }

    #[test]
    fn paired_transforms_give_each_pairs_correlation() {
        // Series of different lengths and scales, an odd number of them, and an odd number of
        // correlations; a length that is not a power of two.
        let m = 45;
        let s: Vec<Vec<f64>> = (0..5)
            .map(|i| {
                (0..30 + 3 * i)
                    .map(|j| ((j * (i + 2)) as f64 * 0.37).sin() * 10f64.powi(i - 2) + 0.1)
                    .collect()
            })
            .collect();
        let cor = Correlator::new(m);
        let refs: Vec<&[f64]> = s.iter().map(|v| v.as_slice()).collect();
        let f = cor.forward(&refs);
        assert_eq!(f.len(), 5);
        let pairs = [(0, 1), (2, 2), (4, 3), (1, 0), (3, 4)];
        let spectra: Vec<(&Spectrum, &Spectrum)> =
            pairs.iter().map(|(a, b)| (&f[*a], &f[*b])).collect();
        let got = cor.correlate(&spectra);
        assert_eq!(got.len(), pairs.len());
        // A pair's rounding is relative to the larger of the two sharing a transform: here
        // the largest correlation of all, about 3e4.
        let want: Vec<Vec<f64>> = pairs
            .iter()
            .map(|(a, b)| direct(&s[*a], &s[*b], m))
            .collect();
        let scale = want.iter().flatten().fold(0.0f64, |x, v| x.max(v.abs()));
        assert!(scale > 1e3);
        for (((a, b), c), w) in pairs.iter().zip(&got).zip(&want) {
            for (g, w) in c.iter().zip(w) {
                assert!((g - w).abs() <= 1e-14 * scale, "{a},{b}: {g} vs {w}");
            }
        }
    }
}
