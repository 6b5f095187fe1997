//! The hexahedral grid element: basis gradients at the corners, the 3x3 stiffness blocks
//! `K_ij` (thesis eq. 4.4.5), the Nitsche blocks (4.4.15-4.4.17), the average deformation
//! gradient (4.4.8) and its polar decomposition (4.4.9).
//!
//! A cell is `[0,h]^3` with corners `c = 0..7` at `h (c&1, (c>>1)&1, (c>>2)&1)` (x fastest,
//! the thesis' `N1..N8`). The trilinear basis is `N_i(x) = prod_d (b_id x_d/h + (1-b_id)(1-x_d/h))`
//! with `b_id` bit `d` of `i`. Integrals over the inside part of a cell use the corner rule of
//! sec. 4.4.1.1: `int_{Omega_e} g dx ~ sum_c w_v(e,c) g(v_c)`, exact for `g` trilinear, with the
//! partial-volume weights `w_v(e,c) = int_{Omega_e} N_c` (eq. 4.2.2).
//!
//! The stiffness block between nodes `i` and `j` at a point with `a = grad N_i`, `b = grad N_j` is
//! `K_ij[p][q] = lambda a_p b_q + mu a_q b_p + mu (a . b) delta_pq` (eq. 4.4.5, the integrand of
//! `B^T C B` split into 3x3 blocks); it is linear in `(lambda, mu)`.

use gpumat::simd::Simd4;
use gpumat::{Mat3, Vec3};

mod blocks;
mod enhanced;

pub use blocks::{BlockCache, ElementBlocks};
pub use enhanced::{gram, mean_gradients, Element, ElementSet, Gram, FICTITIOUS_STIFFNESS, MONOMIALS};

/// `grad N_i` at corner `c` of a cell of size `h`.
pub fn basis_gradient(i: usize, c: usize, h: f64) -> Vec3<f64> {
    let mut g = [0.0; 3];
    for (d, gd) in g.iter_mut().enumerate() {
        let sign = if (i >> d) & 1 == 1 { 1.0 } else { -1.0 };
        // product of the other two factors at the corner: 1 if the bits agree, else 0
        let others = (0..3)
            .filter(|&e| e != d)
            .all(|e| ((i >> e) & 1) == ((c >> e) & 1));
        *gd = if others { sign / h } else { 0.0 };
    }
    Vec3::new(g[0], g[1], g[2])
}

/// The stiffness integrand block for gradients `a` (test node) and `b` (trial node).
#[inline]
pub fn stiffness_block(a: Vec3<f64>, b: Vec3<f64>, lambda: f64, mu: f64) -> Mat3<f64> {
    let a = a.to_array();
    let b = b.to_array();
    let ab = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    Mat3::from_rows(std::array::from_fn(|p| {
        std::array::from_fn(|q| lambda * a[p] * b[q] + mu * a[q] * b[p] + if p == q { mu * ab } else { 0.0 })
    }))
}

/// Per-corner stiffness tables for a cell size: `lam[c][i][j]` and `mu[c][i][j]` are the
/// `lambda`- and `mu`-parts of the integrand block `K_ij` at corner `c`, so that for volume
/// weights `w`, `K_ij = sum_c w[c] (lambda lam[c][i][j] + mu mu[c][i][j])`.
#[derive(Clone, Debug)]
pub struct StiffnessTables {
    /// cell size
    pub h: f64,
    /// the lambda part per corner and node pair
    pub lam: Box<[[[Mat3<f64>; 8]; 8]; 8]>,
    /// the mu part per corner and node pair
    pub mu: Box<[[[Mat3<f64>; 8]; 8]; 8]>,
    /// `grad N_i` at corner `c`: `grad[c][i]`
    pub grad: [[Vec3<f64>; 8]; 8],
}

impl StiffnessTables {
    /// The tables for cells of size `h`.
    pub fn new(h: f64) -> Self {
        let grad: [[Vec3<f64>; 8]; 8] =
            std::array::from_fn(|c| std::array::from_fn(|i| basis_gradient(i, c, h)));
        let mut lam = Box::new([[[Mat3::default(); 8]; 8]; 8]);
        let mut mu = Box::new([[[Mat3::default(); 8]; 8]; 8]);
        for c in 0..8 {
            for i in 0..8 {
                for j in 0..8 {
                    lam[c][i][j] = stiffness_block(grad[c][i], grad[c][j], 1.0, 0.0);
                    mu[c][i][j] = stiffness_block(grad[c][i], grad[c][j], 0.0, 1.0);
                }
            }
        }
        Self { h, lam, mu, grad }
    }

    /// The element block `K_ij = sum_c w[c] K_ij(v_c)` for volume weights `w`.
    #[inline]
    pub fn block(&self, w: &[f64; 8], i: usize, j: usize, lambda: f64, mu: f64) -> Mat3<f64> {
        let mut k = Mat3::default();
        for c in 0..8 {
            if w[c] != 0.0 {
                k = k + (self.lam[c][i][j] * (w[c] * lambda) + self.mu[c][i][j] * (w[c] * mu));
            }
        }
        k
    }
}

/// Corner positions of a cell relative to its first corner.
pub fn corner_offsets(h: f64) -> [Vec3<f64>; 8] {
    std::array::from_fn(|c| {
        Vec3::new(
            (c & 1) as f64 * h,
            ((c >> 1) & 1) as f64 * h,
            ((c >> 2) & 1) as f64 * h,
        )
    })
}

/// The sign patterns `s_i = (+-1, +-1, +-1)` of the corners: the gradient weights of eq. 4.4.8
/// ([`deformation_gradient`]).
pub const CORNER_SIGNS: [Vec3<f64>; 8] = {
    let mut s = [Vec3 {
        x: 0.0,
        y: 0.0,
        z: 0.0,
        w: 0.0,
    }; 8];
    let mut i = 0;
    while i < 8 {
        s[i] = Vec3 {
            x: if i & 1 == 1 { 1.0 } else { -1.0 },
            y: if i & 2 == 2 { 1.0 } else { -1.0 },
            z: if i & 4 == 4 { 1.0 } else { -1.0 },
            w: 0.0,
        };
        i += 1;
    }
    s
};

/// The average deformation gradient of a cell (eq. 4.4.8):
/// `F = I + 1/(4h) sum_i u_i (s_i)^T` with `s_i = (+-1, +-1, +-1)` the corner's sign pattern.
#[inline]
pub fn deformation_gradient(u: &[Vec3<f64>; 8], h: f64) -> Mat3<f64> {
    deformation_gradient_with(u, &CORNER_SIGNS, h)
}

/// The deformation gradient averaged with the weights `a`: `F = I + 1/(4h) sum_i u_i a_i^T`.
/// With `a = `[`CORNER_SIGNS`] it is the gradient at the cell's centre, the average over the
/// whole cell (eq. 4.4.8); [`ElementSet::gradient_weights`] gives the average over the cell's
/// inside part (`a_i = 4 mean grad_xi N_i` there), which the exactly integrated elements use.
#[inline]
pub fn deformation_gradient_with(u: &[Vec3<f64>; 8], a: &[Vec3<f64>; 8], h: f64) -> Mat3<f64> {
    let mut f = Mat3::identity();
    for (ui, ai) in u.iter().zip(a) {
        f = f + ui.outer(*ai) * (1.0 / (4.0 * h));
    }
    f
}

/// Iterations of the polar decomposition (eq. 4.4.9; Dick et al. report 5 are usually enough).
pub const POLAR_ITERATIONS: usize = 5;

/// The rotation of `F = R S` by `R <- (R + R^-T)/2` (eq. 4.4.9), `iterations` times. Returns
/// the identity when `det F` is tiny or not finite (collapsed cell), as the thesis does.
#[inline]
pub fn polar_rotation(f: Mat3<f64>, iterations: usize) -> Mat3<f64> {
    let det = f.determinant();
    if !det.is_finite() || det.abs() < 1e-6 {
        return Mat3::identity();
    }
    let mut r = f;
    for _ in 0..iterations {
        match r.inverse() {
            Some(inv) => r = (r + inv.transpose()) * 0.5,
            None => return Mat3::identity(),
        }
    }
    r
}

/// The rotations of four cells at once ([`polar_rotation`] of [`deformation_gradient_with`]
/// with the corner displacements `u[l]` and gradient weights `a[l]` of cell `l`), cell `l` in
/// lane `l` of every vector: per
/// lane the same operations in the same order as the scalar functions (and the same identity
/// fallbacks), so the values are bit-identical to them; four independent chains of divisions
/// run side by side.
#[inline(always)]
pub fn cell_rotations4<S: Simd4>(
    s: S,
    u: &[[Vec3<f64>; 8]; 4],
    a: &[[Vec3<f64>; 8]; 4],
    h: f64,
    iterations: usize,
) -> [Mat3<f64>; 4] {
    // (no closures or array maps: everything must inline into the caller's vector code)
    #[inline(always)]
    fn det<S: Simd4>(s: S, m: &[[S::V; 3]; 3]) -> S::V {
        let t0 = s.sub(s.mul(m[1][1], m[2][2]), s.mul(m[1][2], m[2][1]));
        let t1 = s.sub(s.mul(m[1][0], m[2][2]), s.mul(m[1][2], m[2][0]));
        let t2 = s.sub(s.mul(m[1][0], m[2][1]), s.mul(m[1][1], m[2][0]));
        s.add(s.sub(s.mul(m[0][0], t0), s.mul(m[0][1], t1)), s.mul(m[0][2], t2))
    }
    /// `(m[a][b] m[c][d] - m[e][f] m[g][h]) inv`
    #[inline(always)]
    fn cof<S: Simd4>(s: S, m: &[[S::V; 3]; 3], i: [usize; 8], inv: S::V) -> S::V {
        let x = s.mul(m[i[0]][i[1]], m[i[2]][i[3]]);
        let y = s.mul(m[i[4]][i[5]], m[i[6]][i[7]]);
        s.mul(s.sub(x, y), inv)
    }
    // F = I + sum_i (u_i a_i^T) / (4h)
    let k = s.splat(1.0 / (4.0 * h));
    let (one, zero) = (s.splat(1.0), s.splat(0.0));
    let mut f = [[one, zero, zero], [zero, one, zero], [zero, zero, one]];
    for i in 0..8 {
        let w = [0, 1, 2].map(|q| {
            let c = |l: usize| a[l][i].to_array()[q];
            s.set([c(0), c(1), c(2), c(3)])
        });
        for p in 0..3 {
            let c = |l: usize| u[l][i].to_array()[p];
            let up = s.set([c(0), c(1), c(2), c(3)]);
            for q in 0..3 {
                f[p][q] = s.add(f[p][q], s.mul(s.mul(up, w[q]), k));
            }
        }
    }
    let d = s.to_array(det(s, &f));
    let mut identity = [false; 4];
    for l in 0..4 {
        identity[l] = !d[l].is_finite() || d[l].abs() < 1e-6;
    }
    let mut r = f;
    for _ in 0..iterations {
        let dv = det(s, &r);
        let d = s.to_array(dv);
        for l in 0..4 {
            // `Mat3::inverse` is `None`: `polar_rotation` returns the identity
            identity[l] |= d[l] == 0.0 || !d[l].is_finite();
        }
        let inv = s.div(s.splat(1.0), dv);
        // the entries of `Mat3::inverse`
        let iv = [
            [
                cof(s, &r, [1, 1, 2, 2, 1, 2, 2, 1], inv),
                cof(s, &r, [0, 2, 2, 1, 0, 1, 2, 2], inv),
                cof(s, &r, [0, 1, 1, 2, 0, 2, 1, 1], inv),
            ],
            [
                cof(s, &r, [1, 2, 2, 0, 1, 0, 2, 2], inv),
                cof(s, &r, [0, 0, 2, 2, 0, 2, 2, 0], inv),
                cof(s, &r, [0, 2, 1, 0, 0, 0, 1, 2], inv),
            ],
            [
                cof(s, &r, [1, 0, 2, 1, 1, 1, 2, 0], inv),
                cof(s, &r, [0, 1, 2, 0, 0, 0, 2, 1], inv),
                cof(s, &r, [0, 0, 1, 1, 0, 1, 1, 0], inv),
            ],
        ];
        let half = s.splat(0.5);
        for i in 0..3 {
            for j in 0..3 {
                r[i][j] = s.mul(s.add(r[i][j], iv[j][i]), half);
            }
        }
    }
    let mut out = [Mat3::identity(); 4];
    let mut lanes = [[[0.0; 4]; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            lanes[i][j] = s.to_array(r[i][j]);
        }
    }
    for l in 0..4 {
        if !identity[l] {
            for i in 0..3 {
                for j in 0..3 {
                    out[l].m[i][j] = lanes[i][j][l];
                }
            }
        }
    }
    out
}

/// Lame coefficients `(lambda, mu)` of Young's modulus `e` and Poisson ratio `nu`.
pub fn lame(e: f64, nu: f64) -> (f64, f64) {
    let mu = e / (2.0 * (1.0 + nu));
    let lambda = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
    (lambda, mu)
}

/// `R B R^T` with plain loops (the operation order that [`rotate_add`] reproduces).
#[inline(always)]
pub fn rotate_block(r: &Mat3<f64>, b: &Mat3<f64>) -> Mat3<f64> {
    let (r, b) = (&r.m, &b.m);
    // t = B R^T
    let mut t = [[0.0f64; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            t[i][j] = b[i][0] * r[j][0] + b[i][1] * r[j][1] + b[i][2] * r[j][2];
        }
    }
    let mut o = [[0.0f64; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            o[i][j] = r[i][0] * t[0][j] + r[i][1] * t[1][j] + r[i][2] * t[2][j];
        }
    }
    Mat3 { m: o }
}

/// A block as three rows of four lanes (the fourth lane is padding), the layout of vector
/// registers.
pub type PaddedBlock = [[f64; 4]; 3];

/// `R^T` padded to four lanes per row: `rt[l][j] = R[j][l]`, `rt[l][3] = 0`.
#[inline]
pub fn padded_transpose(r: &Mat3<f64>) -> PaddedBlock {
    let m = &r.m;
    [
        [m[0][0], m[1][0], m[2][0], 0.0],
        [m[0][1], m[1][1], m[2][1], 0.0],
        [m[0][2], m[1][2], m[2][2], 0.0],
    ]
}

/// `acc += R B R^T (+ extra)` (the hot spot of the corotated assembly) with the vectors of
/// `s`: from the padded transposes `rt` of `R` and `bt` of `B` ([`padded_transpose`]), the
/// rows `t_k = sum_l b_kl rt_l` of `B R^T` (`b_kl = bt[l][k]`), then the rows
/// `o_i = sum_k r_ik t_k` of `R B R^T` (`r_ik = rt[k][i]`), then `acc_i += o_i + extra_i`
/// (lane 3 is padding). Lane by lane these are the operations of [`rotate_block`] in the same
/// order (no fused multiply-add), so the values are bit-identical to it on every backend.
#[inline(always)]
pub fn rotate_add<S: Simd4>(
    s: S,
    acc: &mut [S::V; 3],
    rt: &PaddedBlock,
    bt: &PaddedBlock,
    extra: Option<&Mat3<f64>>,
) {
    let x = [s.load(&rt[0]), s.load(&rt[1]), s.load(&rt[2])];
    let row = |k: usize| [bt[0][k], bt[1][k], bt[2][k]];
    let t = [comb(s, &row(0), &x), comb(s, &row(1), &x), comb(s, &row(2), &x)];
    for i in 0..3 {
        let mut o = comb(s, &[rt[0][i], rt[1][i], rt[2][i]], &t);
        if let Some(n) = extra {
            let n = &n.m[i];
            o = s.add(o, s.set([n[0], n[1], n[2], 0.0]));
        }
        acc[i] = s.add(acc[i], o);
    }
}

/// `a[0] v[0] + a[1] v[1] + a[2] v[2]`, lane-wise, left to right.
#[inline(always)]
pub(crate) fn comb<S: Simd4>(s: S, a: &[f64; 3], v: &[S::V; 3]) -> S::V {
    s.add(
        s.add(s.mul(s.splat(a[0]), v[0]), s.mul(s.splat(a[1]), v[1])),
        s.mul(s.splat(a[2]), v[2]),
    )
}

/// The first three lanes of `v`.
#[inline(always)]
pub fn lanes3<S: Simd4>(s: S, v: S::V) -> [f64; 3] {
    let a = s.to_array(v);
    [a[0], a[1], a[2]]
}

#[cfg(test)]
mod tests {
    use super::*;
    use gpumat::simd::Portable;

    /// Deterministic values in `[-1, 1)` with rounding in every product.
    fn values(seed: u64) -> impl FnMut() -> f64 {
        let mut s = seed;
        move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        }
    }

    fn mat(next: &mut impl FnMut() -> f64) -> Mat3<f64> {
        Mat3::from_rows(std::array::from_fn(|_| std::array::from_fn(|_| next())))
    }

    fn bits(m: &Mat3<f64>) -> [[u64; 3]; 3] {
        m.m.map(|r| r.map(f64::to_bits))
    }

    /// The vector kernels on every backend of this CPU give the bits of the textbook loops.
    fn check_kernels<S: Simd4>(s: S) {
        let mut next = values(7);
        for _ in 0..50 {
            let (r, b, n) = (mat(&mut next), mat(&mut next), mat(&mut next));
            let mut acc = [s.splat(0.0); 3];
            rotate_add(
                s,
                &mut acc,
                &padded_transpose(&r),
                &padded_transpose(&b),
                Some(&n),
            );
            let got = Mat3::from_rows(acc.map(|v| lanes3(s, v)));
            assert_eq!(bits(&got), bits(&(Mat3::default() + (rotate_block(&r, &b) + n))));
        }
        // four rotations at once, with a collapsed cell (identity) among them
        let mut u = [[Vec3::default(); 8]; 4];
        for (l, ul) in u.iter_mut().enumerate() {
            for c in ul.iter_mut() {
                *c = if l == 2 {
                    Vec3::splat(0.0)
                } else {
                    Vec3::new(next(), next(), next()) * 0.05
                };
            }
        }
        u[3] = [Vec3::new(-0.25, 0.0, 0.0); 8];
        for q in [1, 3, 5, 7] {
            u[3][q] = Vec3::new(-0.5, 0.0, 0.0); // flattened along x: det F = 0
        }
        // the centre weights, and in lane 1 the weights of a cut cell
        let mut a = [CORNER_SIGNS; 4];
        for w in a[1].iter_mut() {
            *w = *w * 0.7 + Vec3::new(next(), next(), next()) * 0.1;
        }
        let got = cell_rotations4(s, &u, &a, 0.25, POLAR_ITERATIONS);
        for l in 0..4 {
            let want = polar_rotation(deformation_gradient_with(&u[l], &a[l], 0.25), POLAR_ITERATIONS);
            assert_eq!(bits(&got[l]), bits(&want), "cell {l}");
            if l != 1 {
                let centre = polar_rotation(deformation_gradient(&u[l], 0.25), POLAR_ITERATIONS);
                assert_eq!(bits(&got[l]), bits(&centre), "cell {l}");
            }
        }
        assert_eq!(got[3], Mat3::identity());
    }

    #[test]
    fn vector_kernels_match_the_plain_loops_bitwise() {
        check_kernels(Portable);
        #[cfg(target_arch = "x86_64")]
        if let Some(s) = gpumat::simd::Avx2::detect() {
            check_kernels(s);
        }
    }
}
