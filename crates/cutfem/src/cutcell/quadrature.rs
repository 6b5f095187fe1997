//! Quadrature on the unit cube's pieces: the 14-point degree-5 tetrahedron rule and
//! Dunavant's degree-4 triangle rule (the integrals of the trilinear `N_i`, eq. 4.2.2-4.2.3,
//! and the monomial moments of [`super::CellIntegrals::moments`] up to degree 5), and the
//! 35-point Grundmann-Moeller rule of degree 7 for the one moment of degree 6,
//! `int x^2 y^2 z^2` (the consistent mass' `int N_i N_j`, [`crate::fem::assembly`]).
//!
//! Grundmann-Moeller (1978), on the simplex of dimension `n = 3` with `s = 3` (degree
//! `d = 2 s + 1 = 7`): `int_T f = 6 |T| sum_(i=0..s) w_i sum_(|beta| = s - i) f(x(lambda))`
//! with barycentric `lambda_j = (2 beta_j + 1) / (d + n - 2 i)` over the 4-tuples `beta` of
//! non-negative integers and `w_i = (-1)^i 2^(-2s) (d + n - 2i)^d / (i! (d + n - i)!)`. Its
//! weights are not all positive; it integrates a polynomial (here of degree 6) exactly.

use super::{basis, cross, dot, moment_index, sub, Accum, P3};
use std::sync::OnceLock;

/// The Grundmann-Moeller rule of degree 7 on a tetrahedron (module docs): (barycentric
/// coordinates, weight relative to `6 |T|`), 35 points.
fn gm7() -> &'static [([f64; 4], f64)] {
    static RULE: OnceLock<Vec<([f64; 4], f64)>> = OnceLock::new();
    RULE.get_or_init(|| {
        let (s, n) = (3usize, 3usize);
        let d = 2 * s + 1;
        let fact = |k: usize| (1..=k).map(|x| x as f64).product::<f64>();
        let mut out = Vec::new();
        for i in 0..=s {
            let den = (d + n - 2 * i) as f64;
            let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
            let w = sign * 0.5f64.powi(2 * s as i32) * den.powi(d as i32) / (fact(i) * fact(d + n - i));
            let m = s - i;
            for b0 in 0..=m {
                for b1 in 0..=m - b0 {
                    for b2 in 0..=m - b0 - b1 {
                        let beta = [b0, b1, b2, m - b0 - b1 - b2];
                        out.push((beta.map(|b| (2 * b + 1) as f64 / den), w));
                    }
                }
            }
        }
        out
    })
}

/// The degree-6 moment `int x^2 y^2 z^2` over the tetrahedron `v` of volume `vol`.
fn tet_moment_222(v: &[P3; 4], vol: f64) -> f64 {
    let mut s = 0.0;
    for (bary, w) in gm7() {
        let x: P3 = std::array::from_fn(|k| (0..4).map(|j| bary[j] * v[j][k]).sum());
        s += w * (x[0] * x[1] * x[2]).powi(2);
    }
    6.0 * vol * s
}

/// The positive 14-point degree-5 tetrahedron rule (Walkington 2000; Keast's rule 6): (barycentric
/// weight of the distinguished vertex, of the others, quadrature weight relative to the volume).
/// The first two classes run the distinguished vertex over all 4 corners; the third (two
/// barycentric weights `a`, two `1/2 - a`) over the 6 pairs ([`TET_PAIRS`]). Exact for the
/// trilinear `N_i` (degree 3) and for the moments of degree <= 5 (`tests/cutcell.rs`: `moments_are_exact_for_planar_cuts`).
pub(super) const TET_RULE: [(f64, f64, f64); 2] = [
    (
        0.721_794_249_067_326_4,
        0.092_735_250_310_891_2,
        0.073_493_043_116_361_9,
    ),
    (
        0.067_342_242_210_098_2,
        0.310_885_919_263_300_6,
        0.112_687_925_718_015_9,
    ),
];
/// The third class of [`TET_RULE`]: (the pair's barycentric weight, the others', weight).
const TET_RULE_PAIRS: (f64, f64, f64) = (
    0.454_496_295_874_350_4,
    0.045_503_704_125_649_6,
    0.042_546_020_777_081_5,
);
/// The 6 pairs of tetrahedron vertices.
const TET_PAIRS: [[usize; 2]; 6] = [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]];

/// Dunavant's degree-4 triangle rule: (weight of the distinguished vertex, of the other two,
/// quadrature weight relative to the area). The distinguished vertex runs over all 3.
pub(super) const TRI_RULE: [(f64, f64, f64); 2] = [
    (
        0.108_103_018_168_070_23,
        0.445_948_490_915_964_9,
        0.223_381_589_678_011_47,
    ),
    (
        0.816_847_572_980_458_5,
        0.091_576_213_509_770_74,
        0.109_951_743_655_321_87,
    ),
];

/// Adds the integrals of the `N_i` and the moments over the tetrahedron `v` to `acc`.
pub(super) fn add_tet(v: [P3; 4], acc: &mut Accum) {
    let vol = dot(sub(v[1], v[0]), cross(sub(v[2], v[0]), sub(v[3], v[0]))).abs() / 6.0;
    if vol == 0.0 {
        return;
    }
    let mut point = |bary: [f64; 4], w: f64| {
        let x: P3 = std::array::from_fn(|k| (0..4).map(|j| bary[j] * v[j][k]).sum());
        let n = basis(x);
        for i in 0..8 {
            acc.volume[i] += vol * w * n[i];
        }
        add_point_moments(x, vol * w, &mut acc.moments);
    };
    for &(a, b, w) in &TET_RULE {
        for d in 0..4 {
            point(std::array::from_fn(|j| if j == d { a } else { b }), w);
        }
    }
    let (a, b, w) = TET_RULE_PAIRS;
    for pair in &TET_PAIRS {
        point(std::array::from_fn(|j| if pair.contains(&j) { a } else { b }), w);
    }
    acc.moments[moment_index(2, 2, 2)] += tet_moment_222(&v, vol);
}

/// Adds `w x^a y^b z^c` to the moments of degree <= 5 (the degree-6 one has its own rule,
/// [`tet_moment_222`]).
fn add_point_moments(x: P3, w: f64, m: &mut [f64; 27]) {
    let p = x.map(|t| [1.0, t, t * t]);
    for c in 0..3 {
        for b in 0..3 {
            for a in 0..3 {
                if a + b + c < 6 {
                    m[moment_index(a, b, c)] += w * p[0][a] * p[1][b] * p[2][c];
                }
            }
        }
    }
}

/// Adds the moments of the box `[lo, lo + size]^3` in closed form.
pub(crate) fn add_box_moments(lo: P3, size: f64, m: &mut [f64; 27]) {
    // int_lo^{lo+size} t^a dt
    let one = |l: f64, a: i32| ((l + size).powi(a + 1) - l.powi(a + 1)) / (a + 1) as f64;
    let p: [[f64; 3]; 3] = std::array::from_fn(|k| std::array::from_fn(|a| one(lo[k], a as i32)));
    for c in 0..3 {
        for b in 0..3 {
            for a in 0..3 {
                m[moment_index(a, b, c)] += p[0][a] * p[1][b] * p[2][c];
            }
        }
    }
}
