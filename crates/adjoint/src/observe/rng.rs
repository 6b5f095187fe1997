//! A small self-contained deterministic random number generator.
//!
//! SplitMix64 (Steele, Lea and Flood 2014): the state advances by the odd constant
//! `0x9E3779B97F4A7C15` and each output is the state passed through a 64-bit finalizer
//! (two xor-shift-multiply rounds). Uniform numbers in `[0, 1)` take the top 53 bits;
//! standard normal numbers come from the Box-Muller transform
//! `z = sqrt(-2 ln u1) cos(2 pi u2)` with `u1` in `(0, 1]`.
//!
//! Written here (instead of taken from a crate) so that virtual observations are bit-for-bit
//! reproducible across crate versions, platforms and thread counts.

use std::f64::consts::TAU;

/// The SplitMix64 generator.
#[derive(Clone, Debug)]
pub struct SplitMix64 {
    state: u64,
}

/// The SplitMix64 output finalizer (a bijection of `u64`).
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

const GOLDEN: u64 = 0x9E37_79B9_7F4A_7C15;

impl SplitMix64 {
    /// A generator started from `seed`.
    pub fn new(seed: u64) -> Self {
        SplitMix64 { state: seed }
    }

    /// A generator for the sub-stream named by `tags` (e.g. `[purpose, frame, camera]`) of
    /// `seed`: different tag lists give unrelated streams, the same list the same stream.
    pub fn stream(seed: u64, tags: &[u64]) -> Self {
        let mut s = mix(seed ^ GOLDEN);
        for &t in tags {
            s = mix(s.wrapping_add(GOLDEN) ^ mix(t.wrapping_add(GOLDEN)));
        }
        SplitMix64::new(s)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(GOLDEN);
        mix(self.state)
    }

    /// Uniform in `[0, 1)` (53 random bits).
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Standard normal (Box-Muller, one value per two uniforms).
    pub fn gaussian(&mut self) -> f64 {
        let u1 = 1.0 - self.uniform(); // (0, 1]: ln is finite
        let u2 = self.uniform();
        (-2.0 * u1.ln()).sqrt() * (TAU * u2).cos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_values_of_splitmix64() {
        // the published SplitMix64 sequence for seed 1234567
        let mut r = SplitMix64::new(1234567);
        assert_eq!(r.next_u64(), 6457827717110365317);
        assert_eq!(r.next_u64(), 3203168211198807973);
    }

    #[test]
    fn uniform_and_gaussian_moments() {
        let mut r = SplitMix64::new(7);
        let n = 200_000;
        let (mut s, mut s2) = (0.0, 0.0);
        for _ in 0..n {
            let u = r.uniform();
            assert!((0.0..1.0).contains(&u));
            s += u;
        }
        assert!((s / n as f64 - 0.5).abs() < 0.005);
        s = 0.0;
        for _ in 0..n {
            let g = r.gaussian();
            s += g;
            s2 += g * g;
        }
        let mean = s / n as f64;
        let var = s2 / n as f64 - mean * mean;
        assert!(mean.abs() < 0.01, "mean {mean}");
        assert!((var - 1.0).abs() < 0.02, "variance {var}");
    }

    #[test]
    fn streams_differ_by_tags() {
        let a = SplitMix64::stream(0, &[1, 2]).next_u64();
        let b = SplitMix64::stream(0, &[2, 1]).next_u64();
        let c = SplitMix64::stream(1, &[1, 2]).next_u64();
        assert_ne!(a, b);
        assert_ne!(a, c);
        assert_eq!(a, SplitMix64::stream(0, &[1, 2]).next_u64());
    }
}
