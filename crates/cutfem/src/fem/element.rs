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

use gpumat::{Mat3, Vec3};

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

    /// The Nitsche consistency block `KD_{j,c}` (eq. 4.4.15): the traction `sigma(N_j e_r) n`
    /// at corner `c`, `KD[p][r] = mu (B.n) delta_pr + mu B_p n_r + lambda n_p B_r` with
    /// `B = grad N_j(v_c)`. (The thesis' printed entry (3,2) reads `B1 lambda n3`; the
    /// derivation gives `B2 lambda n3`, used here.)
    #[inline]
    pub fn traction_block(&self, j: usize, c: usize, n: Vec3<f64>, lambda: f64, mu: f64) -> Mat3<f64> {
        let b = self.grad[c][j].to_array();
        let n = n.to_array();
        let bn = b[0] * n[0] + b[1] * n[1] + b[2] * n[2];
        Mat3::from_rows(std::array::from_fn(|p| {
            std::array::from_fn(|r| {
                mu * b[p] * n[r] + lambda * n[p] * b[r] + if p == r { mu * bn } else { 0.0 }
            })
        }))
    }

    /// The Nitsche terms of block `(i, j)` for boundary weights `wb`, outward normal `n` and
    /// penalty `eta` (eq. 4.4.16, 4.4.17, with the penalty entering with a positive sign so the
    /// form stays coercive): `- wb_i KD_{j,i} - wb_j KD_{i,j}^T + delta_ij eta wb_i I`.
    #[inline]
    pub fn nitsche_block(
        &self,
        wb: &[f64; 8],
        n: Vec3<f64>,
        i: usize,
        j: usize,
        lambda: f64,
        mu: f64,
        eta: f64,
    ) -> Mat3<f64> {
        let mut k = Mat3::default();
        if wb[i] != 0.0 {
            k = k - self.traction_block(j, i, n, lambda, mu) * wb[i];
        }
        if wb[j] != 0.0 {
            k = k - self.traction_block(i, j, n, lambda, mu).transpose() * wb[j];
        }
        if i == j {
            k = k + Mat3::from_scalar(eta * wb[i]);
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

/// The average deformation gradient of a cell (eq. 4.4.8):
/// `F = I + 1/(4h) sum_i u_i (s_i)^T` with `s_i = (+-1, +-1, +-1)` the corner's sign pattern.
pub fn deformation_gradient(u: &[Vec3<f64>; 8], h: f64) -> Mat3<f64> {
    let mut f = Mat3::identity();
    for (i, ui) in u.iter().enumerate() {
        let s = Vec3::new(
            if i & 1 == 1 { 1.0 } else { -1.0 },
            if i & 2 == 2 { 1.0 } else { -1.0 },
            if i & 4 == 4 { 1.0 } else { -1.0 },
        );
        f = f + ui.outer(s) * (1.0 / (4.0 * h));
    }
    f
}

/// Iterations of the polar decomposition (eq. 4.4.9; Dick et al. report 5 are usually enough).
pub const POLAR_ITERATIONS: usize = 5;

/// The rotation of `F = R S` by `R <- (R + R^-T)/2` (eq. 4.4.9), `iterations` times. Returns
/// the identity when `det F` is tiny or not finite (collapsed cell), as the thesis does.
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

/// Lame coefficients `(lambda, mu)` of Young's modulus `e` and Poisson ratio `nu`.
pub fn lame(e: f64, nu: f64) -> (f64, f64) {
    let mu = e / (2.0 * (1.0 + nu));
    let lambda = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
    (lambda, mu)
}
