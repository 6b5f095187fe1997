//! The noise floor from the residuals at a fit: a local-linear, leave-one-out estimate (the
//! difference-based estimators of nonparametric regression, Rice 1984 / Hall et al. 1990, on a
//! surface), for observations without camera intrinsics.
//!
//! At a fit, a point's residual is `r_i = e(q_i) + n_i`: the model's misfit `e`, smooth over the
//! surface (a missing effect, the discretisation), plus the measurement noise `n_i`, independent
//! with deviation `sigma`; `q_i` is the point's simulated surface point (`p - (p - q)`: the
//! observed positions are displaced by their own residuals, and neighbours among them would
//! prefer pairs of alike residuals). For each point, the linear function `a + g . (q - q_i)`
//! fitted by least squares to the residuals of its `K` nearest neighbours in the same frame (and
//! camera) predicts `r_i` without using it: `d_i = r_i - a_i` has variance
//! `sigma^2 (1 + c_i)`, `c_i` the intercept's variance factor `[(X^T X)^-1]_00`, and the misfit
//! cancels to second order in the neighbourhood's size (its gradient is fitted). So
//!
//! `sigma = 1.4826 MAD(d_i / sqrt(1 + c_i))`
//!
//! (the MAD ignores the neighbourhoods across a crease or a jump of the misfit, e.g. where a
//! displacement seen along the normal changes face at the body's edges). The model-free estimates of
//! [`super::residuals::noise_floor`] without intrinsics fit planes through the observed
//! points, which on sparse points straddle the body's edges and curvature: about twice the
//! true noise on 300 points per frame of a thin bar, four times on 100 (the tests).
//!
//! Standard error: the MAD's asymptotic variance for Gaussian data is `1.36 sigma^2 / n`;
//! neighbouring estimates share points, so `n` counts a third of the points.

use super::residuals::{mad, noise_floor, PointResidual};
use crate::observations::Observations;
use crate::observe::DepthCamera;
use std::collections::{BTreeMap, HashMap};

/// A noise floor with its uncertainty.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FloorEstimate {
    /// the noise's deviation
    pub sigma: f64,
    /// the estimate's standard error
    pub std_error: f64,
    /// the points whose leave-one-out prediction it rests on
    pub points: usize,
}

/// The noise floor a report states, with how it was estimated and its standard error: the
/// smaller of two upper bounds when the cameras' intrinsics are known, the depth images'
/// ([`noise_floor`]: shape, creases and motion add variance) and the residuals' at the fit
/// ([`residual_floor`]: the model's misfit where it is not smooth on the scale of a point's
/// neighbours adds variance); without intrinsics the residuals', else (too few residuals) plane
/// fits through the observed points ([`noise_floor`] without intrinsics; `spacing` sizes its
/// search). Measured on the independent bar seen by a 40 x 30 depth camera at sigma 0.0025
/// (tests/reference_values/independent/hidden, a model error as large as the noise): depth images
/// 1.24 sigma, residuals 1.18 sigma; at sigma 0.01 to 0.04 both within 5%.
///
/// When neither can be estimated (one point per frame, every point at one place) the floor is
/// `None` and the method says why ([`NO_FLOOR`]): "cannot estimate" is never a number.
pub fn stated_floor(
    observations: &Observations,
    cameras: &[DepthCamera],
    eyes: &[[f64; 3]],
    spacing: f64,
    records: &[PointResidual],
) -> (Option<f64>, &'static str, Option<f64>) {
    let residual = residual_floor(records);
    let model_free = || noise_floor(observations, cameras, eyes, spacing);
    match (residual, cameras.is_empty()) {
        (Some(f), true) => (Some(f.sigma), "residuals", Some(f.std_error)),
        (None, true) => match model_free() {
            Some(p) => (Some(p), "plane fits", None),
            None => (None, NO_FLOOR, None),
        },
        (r, false) => match (r, model_free()) {
            (Some(f), Some(d)) if f.sigma < d => (Some(f.sigma), "residuals", Some(f.std_error)),
            (_, Some(d)) => (Some(d), "depth images", None),
            (Some(f), None) => (Some(f.sigma), "residuals", Some(f.std_error)),
            (None, None) => (None, NO_FLOOR, None),
        },
    }
}

/// The method of a floor that cannot be estimated: why.
pub const NO_FLOOR: &str = "cannot be estimated: fewer than 16 points with neighbours in their frame and camera, and too few for local planes or depth differences";

/// [`stated_floor`] for the model `model` of `problem` (a fit's result): the residuals come from
/// one forward run of `problem`'s simulation, measured as the diagnosis measures them (the
/// distance to the simulated surface, along the viewing rays when `eyes` are known).
pub fn floor_at(
    problem: &mut crate::problem::Problem,
    model: &cutfem::fem::Model,
    observations: &Observations,
    cameras: &[DepthCamera],
    eyes: &[[f64; 3]],
    robust: crate::cost::Robust,
) -> Result<(Option<f64>, &'static str, Option<f64>), crate::Error> {
    let grid = &problem.sim.grid;
    let spacing = 2.0 * grid.h();
    let frames = crate::fit::observed_frames(observations, eyes);
    let cost =
        crate::cost_mesh::SurfaceCost::new(grid, frames, robust)?.with_reach(super::Setup::reach(grid));
    let records = super::residuals::point_residuals(
        &mut problem.sim,
        model.clone(),
        problem.steps,
        &cost,
        observations,
    )?;
    Ok(stated_floor(observations, cameras, eyes, spacing, &records))
}

/// The noise floor of `records` (module docs): `None` with fewer than 16 points whose
/// neighbourhood (in the same frame and camera) gives a prediction, or when the predictions
/// are exact (repeated points: a deviation of 0 is not a measurement).
pub fn residual_floor(records: &[PointResidual]) -> Option<FloorEstimate> {
    let mut groups: BTreeMap<(usize, Option<u32>), Vec<usize>> = BTreeMap::new();
    for (i, r) in records.iter().enumerate() {
        if !r.outside && r.residual.is_finite() {
            groups.entry((r.frame, r.camera)).or_default().push(i);
        }
    }
    let mut z = Vec::new();
    for members in groups.values() {
        let on_surface = |r: &PointResidual| [0, 1, 2].map(|d| r.position[d] - r.vector[d]);
        let pts: Vec<[f64; 3]> = members.iter().map(|&i| on_surface(&records[i])).collect();
        let res: Vec<f64> = members.iter().map(|&i| records[i].residual).collect();
        for (i, near) in nearest(&pts, NEIGHBOURS).iter().enumerate() {
            if let Some(v) = loo_linear(&pts, &res, i, near) {
                z.push(v);
            }
        }
    }
    if z.len() < 16 {
        return None;
    }
    let n = z.len();
    let sigma = 1.4826 * mad(&mut z);
    // exactly 0 (or not a number): the points repeat one another, nothing was measured
    if !(sigma > 0.0 && sigma.is_finite()) {
        return None;
    }
    Some(FloorEstimate {
        sigma,
        std_error: sigma * (1.36 * 3.0 / n as f64).sqrt(),
        points: n,
    })
}

/// Neighbours of each local fit.
const NEIGHBOURS: usize = 5;

/// `(r_i - a_i) / sqrt(1 + c_i)` for point `i` and its neighbours `near` (module docs): the
/// least-squares fit `a + g . (q - q_i)` in the neighbours' principal plane (two slopes: the
/// points lie on a surface), `None` when that fit is singular.
fn loo_linear(pts: &[[f64; 3]], res: &[f64], i: usize, near: &[usize]) -> Option<f64> {
    let d: Vec<[f64; 3]> = near
        .iter()
        .map(|&j| [0, 1, 2].map(|k| pts[j][k] - pts[i][k]))
        .collect();
    let [t1, t2] = tangents(&d)?;
    let dot = |a: &[f64; 3], b: &[f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let mut ata = [0.0; 9];
    let mut atb = [0.0; 3];
    for (dj, &j) in d.iter().zip(near) {
        let row = [1.0, dot(dj, &t1), dot(dj, &t2)];
        for a in 0..3 {
            atb[a] += row[a] * res[j];
            for b in 0..3 {
                ata[3 * a + b] += row[a] * row[b];
            }
        }
    }
    let inv = gpumat::solve::invert_small(&ata, 3)?;
    let a0: f64 = (0..3).map(|k| inv[k] * atb[k]).sum();
    let c = inv[0];
    (c.is_finite() && c >= 0.0).then(|| (res[i] - a0) / (1.0 + c).sqrt())
}

/// Two orthonormal directions spanning the offsets `d` best (the two largest principal axes of
/// `sum d d^T`), `None` when they span less than a plane.
fn tangents(d: &[[f64; 3]]) -> Option<[[f64; 3]; 2]> {
    let mut m = [[0.0f64; 3]; 3];
    for v in d {
        for a in 0..3 {
            for b in 0..3 {
                m[a][b] += v[a] * v[b];
            }
        }
    }
    let (vals, v) = cutfem::v3::sym_eigen(m);
    let vecs = [0, 1, 2].map(|k| [v[0][k], v[1][k], v[2][k]]);
    let mut order = [0, 1, 2];
    order.sort_by(|&a, &b| vals[b].total_cmp(&vals[a]));
    let scale = vals[order[0]];
    if scale.is_nan() || scale <= 0.0 || vals[order[1]] < 1e-6 * scale {
        return None;
    }
    Some([vecs[order[0]], vecs[order[1]]])
}

/// The `k` nearest other points of each point (by distance, then index), from a hash grid
/// whose cells hold a few dozen points; a point with fewer than `k` others within one cell's
/// distance gets an empty list.
fn nearest(pts: &[[f64; 3]], k: usize) -> Vec<Vec<usize>> {
    let n = pts.len();
    if n <= k {
        return vec![Vec::new(); n];
    }
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in pts {
        for d in 0..3 {
            lo[d] = lo[d].min(p[d]);
            hi[d] = hi[d].max(p[d]);
        }
    }
    let extent = (0..3).map(|d| hi[d] - lo[d]).fold(0.0, f64::max);
    // points on a surface: about sqrt(area / n) apart; a cell's width holds ~sqrt(k) of them
    let cell = (extent * (2.0 * k as f64 / n as f64).sqrt()).max(1e-12);
    let key = |p: &[f64; 3]| [0, 1, 2].map(|d| ((p[d] - lo[d]) / cell).floor() as i64);
    let mut grid: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for (i, p) in pts.iter().enumerate() {
        grid.entry(key(p)).or_default().push(i);
    }
    let mut cand: Vec<(f64, usize)> = Vec::new();
    pts.iter()
        .enumerate()
        .map(|(i, p)| {
            let c = key(p);
            cand.clear();
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        if let Some(list) = grid.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) {
                            for &j in list.iter().filter(|&&j| j != i) {
                                let d2: f64 = (0..3).map(|d| (pts[j][d] - p[d]).powi(2)).sum();
                                cand.push((d2, j));
                            }
                        }
                    }
                }
            }
            if cand.len() < k {
                return Vec::new();
            }
            cand.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            // exact when the k-th lies within one cell (every point outside the 27 is farther)
            if cand[k - 1].0.sqrt() > cell {
                return Vec::new();
            }
            cand[..k].iter().map(|c| c.1).collect()
        })
        .collect()
}
