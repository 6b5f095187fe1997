//! Derivative checks shared by the adjoint crate's test files.
#![allow(dead_code)] // each test file uses a part

use adjoint::problem::Problem;

/// The adjoint gradient at `x` against central differences of the cost: per coordinate, the
/// best relative difference over the steps 1e-3, 1e-4, 1e-5 is below `tol`.
pub fn assert_gradient_is_the_fd_gradient(p: &mut Problem, x: &[f64], tol: f64) {
    let (ev, g, _) = p.gradient(x).unwrap();
    assert!(ev.cost > 0.0);
    for k in 0..x.len() {
        let mut best = f64::INFINITY;
        for eps in [1e-3, 1e-4, 1e-5] {
            let (mut xp, mut xm) = (x.to_vec(), x.to_vec());
            xp[k] += eps;
            xm[k] -= eps;
            let fd = (p.evaluate(&xp).unwrap().cost - p.evaluate(&xm).unwrap().cost) / (2.0 * eps);
            best = best.min((g[k] - fd).abs() / g[k].abs().max(fd.abs()));
        }
        assert!(best < tol, "{}: rel {best:.2e}", p.params.labels()[k]);
    }
}

/// The Gauss-Newton matrix at `x` against central differences (step `eps`) of the adjoint
/// gradient, each entry within 1e-5 of the larger of its two diagonal entries (at zero
/// residual the Gauss-Newton matrix is the Hessian).
pub fn assert_gauss_newton_is_the_fd_hessian(p: &mut Problem, x: &[f64], eps: f64) {
    let n = x.len();
    let h = p.gauss_newton_matrix(x).unwrap();
    for b in 0..n {
        let (mut xp, mut xm) = (x.to_vec(), x.to_vec());
        xp[b] += eps;
        xm[b] -= eps;
        let (gp, gm) = (p.gradient(&xp).unwrap().1, p.gradient(&xm).unwrap().1);
        for a in 0..n {
            let fd = (gp[a] - gm[a]) / (2.0 * eps);
            let scale = h[a * n + a].abs().max(h[b * n + b].abs());
            assert!(
                (h[a * n + b] - fd).abs() <= 1e-5 * scale,
                "H[{a}][{b}]: tangent {} vs fd {fd}",
                h[a * n + b]
            );
        }
    }
}
