//! A small deterministic random number generator: xoshiro256** seeded through splitmix64.
//!
//! Synthetic datasets must be reproducible from their seed for as long as the crate exists, so the
//! generator is defined here rather than taken from a crate whose streams may change between
//! versions. Normal variates use Marsaglia's polar method (only `ln` and `sqrt`).

use nalgebra::{Vector3, Vector6};

/// One step of splitmix64: advances `state` and returns the next output.
pub fn splitmix64(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// xoshiro256** generator.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Rng {
    s: [u64; 4],
}

impl Rng {
    /// Generator whose state is filled by four outputs of splitmix64 started at `seed`.
    pub fn new(seed: u64) -> Rng {
        let mut sm = seed;
        let s = [
            splitmix64(&mut sm),
            splitmix64(&mut sm),
            splitmix64(&mut sm),
            splitmix64(&mut sm),
        ];
        Rng { s }
    }

    /// An independent stream number `stream` of the seed `seed`: the same `(seed, stream)` always
    /// gives the same sequence, and different streams do not overlap in practice.
    pub fn stream(seed: u64, stream: u64) -> Rng {
        let mut sm = stream ^ 0xD1B5_4A32_D192_ED03;
        let mixed = seed ^ splitmix64(&mut sm);
        Rng::new(mixed)
    }

    /// Generator with an explicit state (must not be all zero; an all-zero state is replaced by
    /// the state of `Rng::new(0)`).
    pub fn from_state(s: [u64; 4]) -> Rng {
        if s == [0; 4] { Rng::new(0) } else { Rng { s } }
    }

    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        let s = &mut self.s;
        let result = s[1].wrapping_mul(5).rotate_left(7).wrapping_mul(9);
        let t = s[1] << 17;
        s[2] ^= s[0];
        s[3] ^= s[1];
        s[1] ^= s[2];
        s[0] ^= s[3];
        s[2] ^= t;
        s[3] = s[3].rotate_left(45);
        result
    }

    /// Uniform in [0, 1), with 53 random bits.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in [lo, hi).
    pub fn uniform_in(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }

    /// Standard normal variate (Marsaglia's polar method, one value per call).
    pub fn normal(&mut self) -> f64 {
        loop {
            let u = 2.0 * self.uniform() - 1.0;
            let v = 2.0 * self.uniform() - 1.0;
            let s = u * u + v * v;
            if s > 0.0 && s < 1.0 {
                return u * (-2.0 * s.ln() / s).sqrt();
            }
        }
    }

    /// Three independent standard normal variates.
    pub fn normal_vec3(&mut self) -> Vector3<f64> {
        let x = self.normal();
        let y = self.normal();
        let z = self.normal();
        Vector3::new(x, y, z)
    }

    /// Six independent standard normal variates.
    pub fn normal_vec6(&mut self) -> Vector6<f64> {
        let a = self.normal_vec3();
        let b = self.normal_vec3();
        Vector6::new(a.x, a.y, a.z, b.x, b.y, b.z)
    }
}
