//! First-order statistics of a fit: the covariance and standard errors of the fitted
//! parameters from the Gauss-Newton matrix at the result.
//!
//! # The weighted least-squares model
//!
//! The fit minimises `J(x) = 1/2 sum_i w_i r_i(x)^2` over the residuals `r_i` of the observed
//! points (distances to the simulated surface) with the weights `w_i` of the CSV. The weights
//! are *relative precisions* (analytic weights): point `i` has variance `sigma^2 / w_i` with one
//! unknown `sigma^2` for the whole set. With the sensitivities `A = dr/dx` (`n_pts x p`, from
//! the tangent-linear pass) and `W = diag(w_i)` (times the loss' IRLS weight `rho'(r)/r`, 1 for
//! squares), the first-order covariance of the estimate is
//!
//! `Cov(x) = s^2 H^{-1}`, `H = A^T W A`, `s^2 = r^T W r / (n - p)`,
//!
//! where the sum `r^T W r` and the count `n` run over the *same* points as `H`: those within
//! reach of the surface (a point beyond it carries a constant cost and no sensitivity) with a
//! positive weight (a point of weight 0 is not observed). `p` is the number of fitted
//! coordinates. Standard errors of the reported quantities are `scale_k sqrt(Cov_kk)` with
//! `scale_k = d quantity_k / d x_k` ([`crate::params::Layout::x_scales`]).
//!
//! # What the weights mean (and what they cannot mean at the same time)
//!
//! * **Scale invariance (exact).** Multiplying every weight by `c > 0` multiplies `H` by `c`
//!   and `r^T W r` by `c` while `n` stays: `Cov` is unchanged, and so is the estimate (the
//!   minimiser of `c J` is that of `J`). Only the ratios of the weights matter.
//! * **A weight of 4 is four observations (of the information; of the degrees of freedom only
//!   approximately).** Point `i` with weight 4 contributes `4 a_i a_i^T` to `H`, `4 r_i^2` to
//!   `r^T W r` and `4 rho(r_i)` to the cost: exactly what four rows of weight 1 at the same
//!   place contribute. So the cost, its gradient, `H`, the estimate and `r^T W r` of a file
//!   with weight 4 on `k` points are those of the file with these rows written four times.
//!   The degrees of freedom differ: `n - p` against `n + 3k - p`, so
//!   `SE_weighted / SE_duplicated = sqrt((n + 3k - p) / (n - p))`, which tends to 1 as the
//!   share of repeated points falls. Both properties cannot hold exactly: with every weight 4,
//!   scale invariance says "the same as every weight 1" (`n` points), duplication says `4n`.
//!   Scale invariance is kept exactly because a weight read from a file is a relative
//!   precision: a weight-4 point is worth the *mean* of four observations, whose variance is
//!   `sigma^2 / 4`, and its residual carries one degree of freedom (the scatter of four real
//!   observations about their mean is not in the file; duplicated identical rows claim it
//!   without having it, which is why they give the smaller standard error). This is the
//!   convention of weighted least squares in R's `lm(weights = )` and of SciPy's
//!   `curve_fit(sigma = , absolute_sigma = False)`.
//!
//! `crates/adjoint/tests/statistics.rs` checks both statements (scaling by 100: standard errors
//! equal to 1e-9; weight 4 against duplicated rows: cost, gradient, `H` and `r^T W r` equal,
//! standard errors in the ratio above).

use crate::problem::{Evaluation, Problem};
use crate::Error;
pub use gpumat::solve::invert_small;

/// First-order uncertainty of a fit (module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct Uncertainty {
    /// component labels ([`crate::params::ParamSet::labels`])
    pub labels: Vec<String>,
    /// standard errors of the reported quantities, per label
    pub std_errors: Vec<f64>,
    /// covariance of `x` (`n x n`, row-major)
    pub cov_x: Vec<f64>,
    /// `d quantity / d x_k` ([`crate::params::Layout::x_scales`])
    pub scales: Vec<f64>,
    /// the residual variance `s^2 = r^T W r / (n - p)`
    pub residual_variance: f64,
    /// `n`: the points within reach with a positive weight
    pub points: usize,
}

/// First-order standard errors of the fitted quantities at `x` (module docs): the covariance
/// `s^2 H^{-1}` with the Gauss-Newton matrix `H = A^T W A` of the tangent-linear pass and the
/// residual variance `s^2 = r^T W r / (n - p)` over the same points and weights as `H`, mapped
/// to the reported quantities by [`crate::params::Layout::x_scales`]. `None` when `H` is
/// singular (a parameter the data do not determine) or there are no more points than
/// parameters. `ev` is the evaluation at `x`; its Gauss-Newton matrix serves when it has one
/// ([`Evaluation::gauss_newton`]).
pub fn uncertainty(problem: &mut Problem, x: &[f64], ev: &Evaluation) -> Result<Option<Uncertainty>, Error> {
    let p = x.len();
    let n: usize = ev.frames.iter().map(|f| f.informative).sum();
    if n <= p {
        return Ok(None);
    }
    let rwr: f64 = ev.frames.iter().map(|f| f.weighted_squared).sum();
    // the evaluation's own matrix when it made one (the same bits as a new pass at `x`)
    let h = match &ev.gauss_newton {
        Some(h) if h.len() == p * p => h.clone(),
        _ => problem.gauss_newton_matrix(x)?,
    };
    let model = problem.model_at(x);
    let scales = problem.params.x_scales(&model);
    Ok(uncertainty_of(&h, rwr, n, scales, problem.params.labels()))
}

/// Why [`uncertainty`] gave none for `p` coordinates over `n` informative points: the words a
/// report puts beside `standard_errors: null`.
pub fn no_uncertainty_reason(n: usize, p: usize) -> String {
    if n <= p {
        format!("{n} informative points for {p} coordinates: no residual variance to estimate")
    } else {
        "the Gauss-Newton matrix is singular at the fit: a parameter the data do not determine".into()
    }
}

/// The covariance `s^2 H^{-1}` and standard errors (module docs) from the Gauss-Newton matrix
/// `h` (`p x p`, row-major), `r^T W r` and the count `n` over the same points, the coordinates'
/// scales and labels: the arithmetic of [`uncertainty`], shared with the joint fits of a study
/// ([`crate::study`]). `None` when `n <= p` or `h` is singular ([`no_uncertainty_reason`] says
/// which); a standard error whose variance comes out negative is NaN.
pub fn uncertainty_of(
    h: &[f64],
    rwr: f64,
    n: usize,
    scales: Vec<f64>,
    labels: Vec<String>,
) -> Option<Uncertainty> {
    let p = scales.len();
    if n <= p || h.len() != p * p {
        return None;
    }
    let s2 = rwr / (n - p) as f64;
    let inv = invert_small(h, p)?;
    let cov_x: Vec<f64> = inv.iter().map(|v| v * s2).collect();
    // a negative variance is a matrix too ill-conditioned to invert in double precision: that
    // standard error cannot be computed (NaN, `null` in reports), it is not 0
    let std_errors = (0..p)
        .map(|k| {
            let v = cov_x[k * p + k];
            if v >= 0.0 {
                scales[k] * v.sqrt()
            } else {
                f64::NAN
            }
        })
        .collect();
    Some(Uncertainty {
        labels,
        std_errors,
        cov_x,
        scales,
        residual_variance: s2,
        points: n,
    })
}

impl Uncertainty {
    /// The correlation of coordinates `i` and `j`: `Cov_ij / sqrt(Cov_ii Cov_jj)` of the
    /// reported quantities (the sign follows the scales'); NaN when a variance is 0.
    pub fn correlation(&self, i: usize, j: usize) -> f64 {
        let p = self.scales.len();
        let c = |a: usize, b: usize| self.scales[a] * self.scales[b] * self.cov_x[a * p + b];
        c(i, j) / (c(i, i) * c(j, j)).sqrt()
    }
}
