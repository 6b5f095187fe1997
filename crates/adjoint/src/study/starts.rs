//! Multi-start: several fits of one problem from a spread of starting points, to see whether
//! the optimum is unique.
//!
//! The starts are the given one and `k - 1` points of a Latin hypercube in the plausible box of
//! the coordinates ([`crate::params::ParamSet::bounds`]): in every bounded coordinate the range
//! is cut into `k - 1` equal strata, each start takes one stratum (the strata permuted
//! independently per coordinate) and a uniform position inside it, from a seeded SplitMix64
//! stream, so the same seed gives the same starts on every machine. A coordinate unbounded on
//! either side (gravity, an initial velocity, a ground height) keeps its given value.
//!
//! Two optima disagree when some coordinate differs by more than [`DISAGREE_Z`] combined
//! standard errors, `|a_i - b_i| > z sqrt(se_a,i^2 + se_b,i^2)` (in the reported quantities):
//! then the optimum is not unique (or one fit stopped early), and the report says so.

use crate::observe::rng::SplitMix64;

/// Combined standard errors beyond which two optima disagree.
pub const DISAGREE_Z: f64 = 3.0;

/// `k` starting points: `x0` first, then `k - 1` Latin-hypercube points in `bounds` (module
/// docs), seeded by `seed`.
pub fn latin_hypercube(x0: &[f64], bounds: &[(f64, f64)], k: usize, seed: u64) -> Vec<Vec<f64>> {
    let m = k.saturating_sub(1);
    let mut out = vec![x0.to_vec()];
    if m == 0 {
        return out;
    }
    // per coordinate: a permutation of the strata (Fisher-Yates) and the offsets within them
    let mut columns: Vec<Vec<f64>> = Vec::with_capacity(x0.len());
    for (i, (&(lo, hi), &x)) in bounds.iter().zip(x0).enumerate() {
        if !(lo.is_finite() && hi.is_finite() && hi > lo) {
            columns.push(vec![x; m]);
            continue;
        }
        let mut rng = SplitMix64::stream(seed, &[0x5354_4152_5453, i as u64]);
        let mut perm: Vec<usize> = (0..m).collect();
        for j in (1..m).rev() {
            let r = (rng.next_u64() % (j as u64 + 1)) as usize;
            perm.swap(j, r);
        }
        columns.push(
            perm.iter()
                .map(|&s| lo + (hi - lo) * (s as f64 + rng.uniform()) / m as f64)
                .collect(),
        );
    }
    for j in 0..m {
        out.push(columns.iter().map(|c| c[j]).collect());
    }
    out
}

/// The largest `|a_i - b_i| / sqrt(se_a,i^2 + se_b,i^2)` over the coordinates of two optima
/// (their reported values and standard errors); infinite when values differ where both
/// standard errors are 0.
pub fn disagreement(a: &[f64], b: &[f64], se_a: &[f64], se_b: &[f64]) -> f64 {
    let mut worst: f64 = 0.0;
    for i in 0..a.len().min(b.len()) {
        let d = (a[i] - b[i]).abs();
        let s = (se_a.get(i).copied().unwrap_or(0.0).powi(2) + se_b.get(i).copied().unwrap_or(0.0).powi(2))
            .sqrt();
        let z = if d == 0.0 {
            0.0
        } else if s > 0.0 {
            d / s
        } else {
            f64::INFINITY
        };
        worst = worst.max(z);
    }
    worst
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn latin_hypercube_fills_each_stratum_once_and_keeps_unbounded_coordinates() {
        let x0 = [0.5, 3.0, -1.0];
        let bounds = [(0.0, 1.0), (f64::NEG_INFINITY, f64::INFINITY), (-2.0, 6.0)];
        let k = 9;
        let s = latin_hypercube(&x0, &bounds, k, 7);
        assert_eq!(s.len(), k);
        assert_eq!(s[0], x0);
        for (c, (lo, hi)) in [0, 2].iter().map(|&c| (c, bounds[c])) {
            let mut strata: Vec<usize> = s[1..]
                .iter()
                .map(|x| {
                    assert!(x[c] >= lo && x[c] < hi);
                    ((x[c] - lo) / (hi - lo) * (k - 1) as f64) as usize
                })
                .collect();
            strata.sort_unstable();
            assert_eq!(strata, (0..k - 1).collect::<Vec<_>>(), "coordinate {c}");
        }
        assert!(s.iter().all(|x| x[1] == 3.0));
        // seeded: the same seed the same starts, another seed others
        assert_eq!(latin_hypercube(&x0, &bounds, k, 7), s);
        assert_ne!(latin_hypercube(&x0, &bounds, k, 8), s);
        assert_eq!(latin_hypercube(&x0, &bounds, 1, 7), vec![x0.to_vec()]);
    }

    #[test]
    fn disagreement_counts_combined_standard_errors() {
        assert_eq!(
            disagreement(&[1.0, 2.0], &[1.0, 2.0], &[0.1, 0.1], &[0.1, 0.1]),
            0.0
        );
        let z = disagreement(&[1.0, 2.0], &[1.5, 2.0], &[0.3, 0.1], &[0.4, 0.1]);
        assert!((z - 1.0).abs() < 1e-12, "{z}");
        assert!(disagreement(&[1.0], &[2.0], &[0.0], &[0.0]).is_infinite());
    }
}
