//! Local adjoints: the derivatives of the per-cell and per-crossing stages of a step (thesis
//! sec. 5.5.4-5.5.5), each checked in isolation against central differences in
//! `tests/local.rs` (the thesis' randomized test, sec. 5.2.5).
//!
//! # Polar decomposition (eq. 4.4.9, adjoint 5.5.4)
//!
//! The forward iteration is `R_0 = F`, `R_{k+1} = (R_k + R_k^{-T}) / 2`. For `Y = X^{-T}`,
//! `dY = -X^{-T} dX^T X^{-T}`, so the adjoint of one iteration is
//! `X_bar = Y_bar / 2 - X^{-T} (Y_bar / 2)^T X^{-T}`, applied from the last iteration back to
//! `F`. When the forward returned the identity (collapsed cell) the adjoint is zero.
//!
//! # Elastic term of a cell
//!
//! With `lam_i` the adjoint of the Newmark solve at corner `i` (`A lam = g`), the cell's part of
//! the Lagrangian `lam^T (b - A u')` that depends on the rotation `R` and on `(lambda, mu)` is
//!
//! ```text
//! S(R) = sum_ij lam_i^T R K_ij R^T a_j  +  dt sum_ij lam_i^T R K_ij x_j,
//! a_j  = w_j - dt x_j,   w = (alpha_2 - (1-theta) dt) u - (alpha_2 + theta dt) u',
//! ```
//!
//! (the stiffness in `b` and `A`, eq. 2.6.2, and the corotation force 4.4.6 in `dt f`; `x_j`
//! the corner offsets). With `lt_i = R^T lam_i`, `b_j = R^T a_j + dt x_j`,
//! `y_i = sum_j K_ij b_j` and `z_j = sum_i K_ji lt_i`:
//!
//! ```text
//! dS/dR = sum_i lam_i y_i^T + sum_j a_j z_j^T,
//! ```
//!
//! and with the displacement gradients `G_l = sum_i lt_i grad N_i^T`, `G_b = sum_j b_j grad N_j^T`
//! (the bubbles of the incompatible modes included, at their condensed amplitudes):
//!
//! ```text
//! dS/dlambda = int tr G_l tr G_b,    dS/dmu = int (tr(G_l G_b) + G_l : G_b)
//! ```
//!
//! over the cell's inside part (eq. 5.5.5: the adjoints of the Lame parameters; for the thesis'
//! corner rule the integral is `sum_c w_v(c)` of the integrand at the corners), computed by
//! [`cutfem::fem::element::ElementSet::lame_derivatives`]. Without corotation `R = I` and the
//! same formulas hold (the corotation force vanishes).
//!
//! # Contact (Alg. 5.5)
//!
//! Per crossing with interpolated adjoint `Lambda = n . lam_c`, signed distance
//! `d = n . (X_c + u_c) - height` and `S(d) = softmin_alpha(0, d)`, the implicit scheme
//! contributes `L_c = dt Lambda (-k S(d) - theta k S'(d) n . (u'_c - u_c))`, the thesis'
//! explicit scheme `L_c = dt Lambda (-k S(d) - theta dt k S'(d) n . v_c)`, the penalty
//! scheme (Newton-iterated, `k` the crossing's spring `k a_c`, `d'` at the converged `u'`, `S`
//! its C2 law [`cutfem::fem::collision::penalty0`], `theta_c` its weight
//! [`cutfem::fem::collision::Ground::contact_theta`]) `L_c = -dt Lambda k ((1 - theta_c) S(d) +
//! theta_c S(d'))`: its `u'` derivative is the contact
//! part of the Jacobian `A` at `u'`, which the backward solve already holds.

use cutfem::fem::collision::{softmin0_derivative, ContactScheme, Ground};
use cutfem::fem::element::ElementSet;
use gpumat::{Mat3, Vec3};

/// Frobenius inner product `A : B`.
pub fn frobenius(a: &Mat3<f64>, b: &Mat3<f64>) -> f64 {
    (0..3)
        .map(|i| (0..3).map(|j| a.m[i][j] * b.m[i][j]).sum::<f64>())
        .sum()
}

/// The iterates `R_0 = F, ..., R_iterations` of the polar iteration, or `None` where the
/// forward ([`cutfem::fem::element::polar_rotation`]) returns the identity.
pub fn polar_iterates(f: Mat3<f64>, iterations: usize) -> Option<Vec<Mat3<f64>>> {
    let det = f.determinant();
    if !det.is_finite() || det.abs() < 1e-6 {
        return None;
    }
    let mut out = Vec::with_capacity(iterations + 1);
    let mut r = f;
    out.push(r);
    for _ in 0..iterations {
        let inv = r.inverse()?;
        r = (r + inv.transpose()) * 0.5;
        out.push(r);
    }
    Some(out)
}

/// The adjoint of the polar rotation: `F_bar` for the gradient `r_bar` of the final `R`.
pub fn polar_rotation_adjoint(f: Mat3<f64>, iterations: usize, r_bar: Mat3<f64>) -> Mat3<f64> {
    let Some(it) = polar_iterates(f, iterations) else {
        return Mat3::default();
    };
    let mut g = r_bar;
    for k in (0..iterations).rev() {
        let x_it = it[k].inverse().expect("forward inverted it").transpose();
        let y_bar = g * 0.5;
        g = y_bar - x_it * y_bar.transpose() * x_it;
    }
    g
}

/// The corner sign pattern `s_i` of eq. 4.4.8.
pub fn corner_signs(i: usize) -> Vec3<f64> {
    let s = |b: usize| if (i >> b) & 1 == 1 { 1.0 } else { -1.0 };
    Vec3::new(s(0), s(1), s(2))
}

/// The adjoint of the average deformation gradient `F = I + 1/(4h) sum_i u_i a_i^T` (eq.
/// 4.4.8 with the element's gradient weights `a`, `cutfem::fem::element::deformation_gradient_with`):
/// adds `F_bar a_i / (4h)` to `u_bar[i]`.
pub fn deformation_gradient_adjoint(
    f_bar: &Mat3<f64>,
    a: &[Vec3<f64>; 8],
    h: f64,
    u_bar: &mut [Vec3<f64>; 8],
) {
    for (ub, ai) in u_bar.iter_mut().zip(a) {
        *ub = *ub + *f_bar * *ai * (1.0 / (4.0 * h));
    }
}

/// The value of the cell's elastic term `S(R)` (module docs) for element blocks `k`.
pub fn cell_elastic_value(
    k: &[[Mat3<f64>; 8]; 8],
    r: &Mat3<f64>,
    lam: &[Vec3<f64>; 8],
    a: &[Vec3<f64>; 8],
    x: &[Vec3<f64>; 8],
    dt: f64,
) -> f64 {
    let rt = r.transpose();
    let mut s = 0.0;
    for i in 0..8 {
        let lt = rt * lam[i];
        for j in 0..8 {
            s += lt.dot(k[i][j] * (rt * a[j] + x[j] * dt));
        }
    }
    s
}

/// The derivatives of the cell's elastic term (module docs): `(dS/dR, dS/dlambda, dS/dmu)`
/// for the cell's element `set` (its blocks `set.k` at the current Lame parameters).
pub fn cell_elastic_adjoint(
    set: &ElementSet,
    r: &Mat3<f64>,
    lam: &[Vec3<f64>; 8],
    a: &[Vec3<f64>; 8],
    x: &[Vec3<f64>; 8],
    dt: f64,
) -> (Mat3<f64>, f64, f64) {
    let k = &set.k;
    let rt = r.transpose();
    let lt: [Vec3<f64>; 8] = std::array::from_fn(|i| rt * lam[i]);
    let b: [Vec3<f64>; 8] = std::array::from_fn(|j| rt * a[j] + x[j] * dt);
    let mut r_bar = Mat3::default();
    for i in 0..8 {
        let mut y = Vec3::default();
        let mut z = Vec3::default();
        for j in 0..8 {
            y = y + k[i][j] * b[j];
            // z_i = sum_j K_ji^T lt_j = sum_j K_ij lt_j (K_ji = K_ij^T)
            z = z + k[i][j] * lt[j];
        }
        r_bar = r_bar + lam[i].outer(y) + a[i].outer(z);
    }
    let (dl, dm) = set.lame_derivatives(&lt, &b);
    (r_bar, dl, dm)
}

/// Derivatives of one crossing's contact term `L_c` (module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ContactAdjoint {
    /// `dL_c/du_c` (to be spread to the corners with weights `1-t`, `t`)
    pub u: Vec3<f64>,
    /// `dL_c/du'_c`... not needed by the adjoint (u' is fixed), kept for checks
    pub u_next: Vec3<f64>,
    /// `dL_c/dv_c` (thesis scheme only)
    pub v: Vec3<f64>,
    /// `dL_c/dn` (the normal as a free vector)
    pub normal: Vec3<f64>,
    /// `dL_c/dheight`
    pub height: f64,
    /// `dL_c/dlam_c`
    pub lam: Vec3<f64>,
}

/// One crossing's ground-friction term (`cutfem::fem::collision::add_friction_forces`):
/// `L_f = mu N(d) lam_c . P (u_c - u'_c)` with `N(d) = -k S(d)` the normal force at the step's
/// start, `d = n . (x0 + u_c) - height`, `P = I - n n^T`.
pub fn friction_value(
    g: &Ground,
    mu: f64,
    x0: Vec3<f64>,
    u: Vec3<f64>,
    u_next: Vec3<f64>,
    lam: Vec3<f64>,
) -> f64 {
    let n = g.normal;
    let d = g.distance(x0 + u);
    let delta = u - u_next;
    mu * (-g.stiffness * g.law(d).0) * lam.dot(delta - n * n.dot(delta))
}

/// Derivatives of one crossing's friction term [`friction_value`] (the normal taken as a free
/// vector).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrictionAdjoint {
    /// `dL_f/du_c` (to be spread to the corners with weights `1-t`, `t`)
    pub u: Vec3<f64>,
    /// `dL_f/dn`
    pub normal: Vec3<f64>,
    /// `dL_f/dheight`
    pub height: f64,
    /// `dL_f/dmu`
    pub mu: f64,
}

/// The derivatives of [`friction_value`]: with `q = lam . P delta`, `delta = u_c - u'_c`,
/// `L_f = mu N(d) q`, `dq/du_c = P lam`, `dq/dn = -(n . delta) lam - (lam . n) delta`.
pub fn friction_adjoint(
    g: &Ground,
    mu: f64,
    x0: Vec3<f64>,
    u: Vec3<f64>,
    u_next: Vec3<f64>,
    lam: Vec3<f64>,
) -> FrictionAdjoint {
    let n = g.normal;
    let p = x0 + u;
    let d = g.distance(p);
    let (s, s1) = g.law(d);
    let (force, slope) = (-g.stiffness * s, -g.stiffness * s1);
    let delta = u - u_next;
    let q = lam.dot(delta - n * n.dot(delta));
    let dl_dd = mu * slope * q;
    let p_lam = lam - n * n.dot(lam);
    FrictionAdjoint {
        u: p_lam * (mu * force) + n * dl_dd,
        normal: p * dl_dd - (lam * n.dot(delta) + delta * lam.dot(n)) * (mu * force),
        height: -dl_dd,
        mu: force * q,
    }
}

/// `d^2 softmin_alpha(0, d) / dd^2 = -alpha S'(1 - S')`.
pub fn softmin0_second(d: f64, alpha: f64) -> f64 {
    let s1 = softmin0_derivative(d, alpha);
    -alpha * s1 * (1.0 - s1)
}

/// The value of one crossing's contact term `L_c` at reference point `x0` (interpolated
/// reference position), interpolated `u`, `u_next`, `v` and adjoint `lam`.
pub fn contact_value(
    g: &Ground,
    dt: f64,
    theta: f64,
    x0: Vec3<f64>,
    u: Vec3<f64>,
    u_next: Vec3<f64>,
    v: Vec3<f64>,
    lam: Vec3<f64>,
) -> f64 {
    let n = g.normal;
    let d = g.distance(x0 + u);
    let k = g.stiffness;
    let (s, s1) = g.law(d);
    let force = match g.scheme {
        ContactScheme::Implicit | ContactScheme::Softmin => -k * s - theta * k * s1 * n.dot(u_next - u),
        ContactScheme::Thesis => -k * s - theta * dt * k * s1 * n.dot(v),
        ContactScheme::Penalty => {
            let d1 = g.distance(x0 + u_next);
            let tc = g.contact_theta(theta);
            -k * ((1.0 - tc) * s + tc * g.law(d1).0)
        }
    };
    dt * n.dot(lam) * force
}

/// The derivatives of [`contact_value`] (the normal taken as a free vector).
pub fn contact_adjoint(
    g: &Ground,
    dt: f64,
    theta: f64,
    x0: Vec3<f64>,
    u: Vec3<f64>,
    u_next: Vec3<f64>,
    v: Vec3<f64>,
    lam: Vec3<f64>,
) -> ContactAdjoint {
    let n = g.normal;
    let p = x0 + u;
    let d = g.distance(p);
    let k = g.stiffness;
    let (s, s1) = g.law(d);
    let big_l = n.dot(lam);
    if g.scheme == ContactScheme::Penalty {
        // L = dt Lambda (-k) ((1 - theta_c) S(d) + theta_c S(d')), d' at the converged u'
        let p1 = x0 + u_next;
        let d1 = g.distance(p1);
        let (s_1, s1_1) = g.law(d1);
        let tc = g.contact_theta(theta);
        let inner = -k * ((1.0 - tc) * s + tc * s_1);
        let dl_dd = dt * big_l * (-k) * (1.0 - tc) * s1;
        let dl_dd1 = dt * big_l * (-k) * tc * s1_1;
        return ContactAdjoint {
            u: n * dl_dd,
            u_next: n * dl_dd1,
            v: Vec3::default(),
            normal: lam * (dt * inner) + p * dl_dd + p1 * dl_dd1,
            height: -dl_dd - dl_dd1,
            lam: n * (dt * inner),
        };
    }
    // L = dt Lambda (-k S(d) - c(d) q) with q the scheme's rate term
    let s2 = softmin0_second(d, g.softness);
    let (q_vec, coef) = match g.scheme {
        ContactScheme::Implicit | ContactScheme::Softmin | ContactScheme::Penalty => (u_next - u, theta * k),
        ContactScheme::Thesis => (v, theta * dt * k),
    };
    let q = n.dot(q_vec);
    let inner = -k * s - coef * s1 * q;
    let dl_dd = dt * big_l * (-k * s1 - coef * s2 * q);
    let dl_dq = -dt * big_l * coef * s1;
    let mut out = ContactAdjoint {
        lam: n * (dt * inner),
        height: -dl_dd,
        u: n * dl_dd,
        ..Default::default()
    };
    out.normal = lam * (dt * inner) + p * dl_dd + q_vec * dl_dq;
    match g.scheme {
        ContactScheme::Implicit | ContactScheme::Softmin | ContactScheme::Penalty => {
            out.u = out.u - n * dl_dq;
            out.u_next = n * dl_dq;
        }
        ContactScheme::Thesis => out.v = n * dl_dq,
    }
    out
}
