//! Where the model fails: the residuals of a fitted model per point, broken down per frame,
//! per camera and per region of the reference surface, their direction, and the noise floor
//! the data allow.
//!
//! * A point's residual vector is `p - q`, `q` the simulated surface point its residual
//!   measures to (the ray hit, or the closest point), and its **reference point** is `q` mapped
//!   back to the reference surface through the same face and barycentric coordinates.
//! * **Regions**: the reference surface vertices are clustered by k-means (farthest-point
//!   seeding from the lowest vertex, 20 Lloyd iterations: deterministic); a point belongs to
//!   the region of its reference point.
//! * **Direction**: the mean residual vector per frame, the share of the squared residual a
//!   uniform shift explains, and the principal direction `e_1` of `sum v v^T`. Mostly along
//!   gravity, mostly normal to a plane, growing or decaying in time: the clue to what is
//!   missing.
//! * **Noise floor** (model-free), per frame and camera. With the camera's intrinsics, each
//!   point's pixel `(i, j)` and distance `s` along its viewing ray are recovered; the second
//!   differences `s(i-1) - 2 s(i) + s(i+1)` (rows and columns) of a smooth surface vanish to
//!   second order in the pixel size, and of independent noise of deviation `sigma` have
//!   variance `6 sigma^2`, so `sigma = 1.4826 MAD / sqrt(6)` (the MAD ignores the few
//!   silhouettes and creases). The same holds in time, at a fixed pixel over three consecutive
//!   frames, where the surface moves little between frames. Surface shape (creases of the
//!   mesh, curvature at coarse pixels) and motion only add variance, so both are upper bounds
//!   of the noise and the smaller one is taken. Without intrinsics, a plane through the `k = 12` nearest
//!   neighbours of each point predicts it, along the ray when the eye is known, and
//!   `sigma = 1.4826 MAD / sqrt(1 + 1/k)`; surface curvature makes this one an upper bound.

use crate::cost_mesh::SurfaceCost;
use crate::observations::Observations;
use crate::observe::DepthCamera;
use crate::Error;
use cutfem::fem::collision::GroundPush;
use cutfem::fem::{Model, Simulation};
use gpumat::{Matrix, Vec3};
use std::collections::HashMap;

/// One observed point's residual at a fitted model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointResidual {
    /// frame
    pub frame: usize,
    /// camera, if known
    pub camera: Option<u32>,
    /// observed position
    pub position: [f64; 3],
    /// signed residual (outside every triangle: the cost's outside residual, `outside` set)
    pub residual: f64,
    /// `p - q` (zero when outside)
    pub vector: [f64; 3],
    /// the simulated point on the reference surface (the observed position when outside)
    pub reference: [f64; 3],
    /// far from every triangle
    pub outside: bool,
}

/// Runs `sim` with `model` for `steps` steps and returns every observed point's residual.
pub fn point_residuals(
    sim: &mut Simulation,
    model: Model,
    steps: usize,
    cost: &SurfaceCost,
    observations: &Observations,
) -> Result<Vec<PointResidual>, Error> {
    Ok(point_residuals_and_push(sim, model, steps, cost, observations)?.0)
}

/// [`point_residuals`], and the ground's push gathered at every frame (`GroundPush`: where the
/// contact law pushed the body, to tell a body held off the plane).
pub fn point_residuals_and_push(
    sim: &mut Simulation,
    model: Model,
    steps: usize,
    cost: &SurfaceCost,
    observations: &Observations,
) -> Result<(Vec<PointResidual>, GroundPush), Error> {
    sim.reset(model)?;
    let zero: Matrix<Vec3<f64>> = Matrix::zeros(sim.grid.dofs(), 1, 1);
    let reference = cost.vertices(&zero);
    let mut out = Vec::new();
    let mut push = GroundPush::default();
    for t in 0..=steps {
        if t > 0 {
            sim.step().map_err(|e| Error::step(format!("step {t}"), e))?;
        }
        sim.add_ground_push(&mut push);
        frame_residuals(&sim.u, t, cost, observations, &reference, &mut out);
    }
    Ok((out, push))
}

/// The residuals of frame `t`'s observed points at displacement `u` (appended to `out`);
/// `reference` is `cost.vertices` at zero displacement.
pub fn frame_residuals(
    u: &Matrix<Vec3<f64>>,
    t: usize,
    cost: &SurfaceCost,
    observations: &Observations,
    reference: &[Vec3<f64>],
    out: &mut Vec<PointResidual>,
) {
    let obs = observations.frame(t);
    if obs.is_empty() {
        return;
    }
    let faces = &cost.surface().mesh.faces;
    let x = cost.vertices(u);
    let hits = cost.locate(t, &x);
    for (p, hit) in obs.iter().zip(hits) {
        let r = match hit {
            Some(h) => {
                let f = faces[h.face];
                let at = |v: &[Vec3<f64>]| {
                    (v[f[0] as usize] * h.bary[0]
                        + v[f[1] as usize] * h.bary[1]
                        + v[f[2] as usize] * h.bary[2])
                        .to_array()
                };
                let q = at(&x);
                PointResidual {
                    frame: t,
                    camera: p.camera,
                    position: p.position,
                    residual: h.residual,
                    vector: [0, 1, 2].map(|d| p.position[d] - q[d]),
                    reference: at(reference),
                    outside: false,
                }
            }
            None => PointResidual {
                frame: t,
                camera: p.camera,
                position: p.position,
                residual: cost.outside_residual,
                vector: [0.0; 3],
                reference: p.position,
                outside: true,
            },
        };
        out.push(r);
    }
}

/// Root mean square of residuals.
pub fn rms<'a>(r: impl Iterator<Item = &'a PointResidual>) -> (f64, usize) {
    let (s, n) = r.fold((0.0, 0), |(s, n), p| (s + p.residual * p.residual, n + 1));
    (if n > 0 { (s / n as f64).sqrt() } else { 0.0 }, n)
}

/// A region of the reference surface and its residuals.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Region {
    /// index
    pub id: usize,
    /// center of its reference-surface vertices
    pub center: [f64; 3],
    /// observed points in it
    pub points: usize,
    /// rms residual
    pub rms: f64,
    /// mean signed residual (positive: observed outside the simulated surface)
    pub mean: f64,
    /// mean residual vector
    pub mean_vector: [f64; 3],
}

/// Deterministic k-means of `points` into at most `k` clusters: the centers.
pub fn kmeans(points: &[[f64; 3]], k: usize) -> Vec<[f64; 3]> {
    if points.is_empty() || k == 0 {
        return Vec::new();
    }
    let d2 = |a: &[f64; 3], b: &[f64; 3]| (0..3).map(|d| (a[d] - b[d]).powi(2)).sum::<f64>();
    // farthest-point seeding from the lowest point (smallest y, then x, z)
    let first = (0..points.len())
        .min_by(|&a, &b| {
            let (p, q) = (points[a], points[b]);
            p[1].total_cmp(&q[1])
                .then(p[0].total_cmp(&q[0]))
                .then(p[2].total_cmp(&q[2]))
        })
        .expect("non-empty");
    let mut centers = vec![points[first]];
    let mut near: Vec<f64> = points.iter().map(|p| d2(p, &points[first])).collect();
    while centers.len() < k {
        let (i, &d) = near
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1).then(b.0.cmp(&a.0)))
            .expect("non-empty");
        if d <= 0.0 {
            break;
        }
        centers.push(points[i]);
        for (n, p) in near.iter_mut().zip(points) {
            *n = n.min(d2(p, &points[i]));
        }
    }
    for _ in 0..20 {
        let mut sum = vec![[0.0; 3]; centers.len()];
        let mut count = vec![0usize; centers.len()];
        for p in points {
            let c = nearest(&centers, p);
            count[c] += 1;
            for d in 0..3 {
                sum[c][d] += p[d];
            }
        }
        for ((c, s), n) in centers.iter_mut().zip(&sum).zip(&count) {
            if *n > 0 {
                *c = s.map(|v| v / *n as f64);
            }
        }
    }
    centers
}

/// Index of the center nearest `p` (lowest index on ties).
pub fn nearest(centers: &[[f64; 3]], p: &[f64; 3]) -> usize {
    let d2 = |a: &[f64; 3]| (0..3).map(|d| (a[d] - p[d]).powi(2)).sum::<f64>();
    (0..centers.len())
        .min_by(|&a, &b| d2(&centers[a]).total_cmp(&d2(&centers[b])).then(a.cmp(&b)))
        .unwrap_or(0)
}

/// Residuals per region of the reference surface (`centers` from [`kmeans`] of its vertices).
pub fn regions(records: &[PointResidual], centers: &[[f64; 3]]) -> Vec<Region> {
    let mut acc = vec![(0usize, 0.0, 0.0, [0.0; 3]); centers.len()];
    for r in records.iter().filter(|r| !r.outside) {
        let a = &mut acc[nearest(centers, &r.reference)];
        a.0 += 1;
        a.1 += r.residual * r.residual;
        a.2 += r.residual;
        for d in 0..3 {
            a.3[d] += r.vector[d];
        }
    }
    centers
        .iter()
        .zip(acc)
        .enumerate()
        .map(|(id, (c, (n, s2, s, v)))| {
            let m = n.max(1) as f64;
            Region {
                id,
                center: *c,
                points: n,
                rms: (s2 / m).sqrt(),
                mean: s / m,
                mean_vector: v.map(|x| x / m),
            }
        })
        .collect()
}

/// The direction of the residuals.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Direction {
    /// per frame: `(frame, mean residual vector, rms)`
    pub per_frame: Vec<(usize, [f64; 3], f64)>,
    /// share of the squared residual vectors a per-frame uniform shift explains
    pub shift_share: f64,
    /// unit principal direction of `sum v v^T`
    pub principal: [f64; 3],
    /// share of `sum |v|^2` along the principal direction
    pub principal_share: f64,
    /// least-squares slope of the per-frame rms over the frame index, per frame
    pub rms_slope: f64,
}

/// The direction analysis of `records`.
pub fn direction(records: &[PointResidual]) -> Direction {
    let mut frames: Vec<usize> = records.iter().map(|r| r.frame).collect();
    frames.dedup();
    let mut per_frame = Vec::new();
    let (mut total, mut shift) = (0.0, 0.0);
    let mut m = [[0.0; 3]; 3];
    for &f in &frames {
        let rs: Vec<&PointResidual> = records.iter().filter(|r| r.frame == f && !r.outside).collect();
        let n = rs.len().max(1) as f64;
        let mut mean = [0.0; 3];
        for r in &rs {
            for d in 0..3 {
                mean[d] += r.vector[d] / n;
            }
            total += r.vector.iter().map(|v| v * v).sum::<f64>();
            for i in 0..3 {
                for j in 0..3 {
                    m[i][j] += r.vector[i] * r.vector[j];
                }
            }
        }
        shift += n * mean.iter().map(|v| v * v).sum::<f64>();
        let (rms, _) = rms(records.iter().filter(|r| r.frame == f));
        per_frame.push((f, mean, rms));
    }
    let (principal, lambda) = principal_direction(&m);
    let nf = per_frame.len() as f64;
    let rms_slope = if per_frame.len() > 1 {
        let mf = per_frame.iter().map(|p| p.0 as f64).sum::<f64>() / nf;
        let mr = per_frame.iter().map(|p| p.2).sum::<f64>() / nf;
        let sxy: f64 = per_frame.iter().map(|p| (p.0 as f64 - mf) * (p.2 - mr)).sum();
        let sxx: f64 = per_frame.iter().map(|p| (p.0 as f64 - mf).powi(2)).sum();
        if sxx > 0.0 {
            sxy / sxx
        } else {
            0.0
        }
    } else {
        0.0
    };
    Direction {
        per_frame,
        shift_share: if total > 0.0 { shift / total } else { 0.0 },
        principal,
        principal_share: if total > 0.0 { lambda / total } else { 0.0 },
        rms_slope,
    }
}

/// The dominant eigenvector and eigenvalue of a symmetric positive semi-definite 3x3 matrix
/// (power iteration from the largest diagonal axis).
fn principal_direction(m: &[[f64; 3]; 3]) -> ([f64; 3], f64) {
    let start = (0..3).max_by(|&a, &b| m[a][a].total_cmp(&m[b][b])).unwrap_or(0);
    let mut v = [0.0; 3];
    v[start] = 1.0;
    let mut lambda = 0.0;
    for _ in 0..200 {
        let w: [f64; 3] = std::array::from_fn(|i| (0..3).map(|j| m[i][j] * v[j]).sum());
        let n = w.iter().map(|x| x * x).sum::<f64>().sqrt();
        if n == 0.0 {
            return (v, 0.0);
        }
        lambda = n;
        v = w.map(|x| x / n);
    }
    // sign: largest component positive
    let k = (0..3)
        .max_by(|&a, &b| v[a].abs().total_cmp(&v[b].abs()))
        .unwrap_or(0);
    if v[k] < 0.0 {
        v = v.map(|x| -x);
    }
    (v, lambda)
}

/// Neighbours used by the noise-floor plane fits.
const NEIGHBOURS: usize = 12;

/// The model-free noise floor of `observations` (module docs): `cameras[c]` is camera `c`
/// when its intrinsics are known, else `eyes[c]` its eye when known; `spacing` sizes the
/// neighbour search of the plane fits. `None` when it cannot be estimated (fewer than 8 depth
/// differences and 8 local planes: one point per frame, all points at one place): "cannot
/// estimate" is never a number.
pub fn noise_floor(
    observations: &Observations,
    cameras: &[DepthCamera],
    eyes: &[[f64; 3]],
    spacing: f64,
) -> Option<f64> {
    let mut second = Vec::new();
    let mut temporal = Vec::new();
    let mut planar = Vec::new();
    // per camera: the ray distance per pixel of the previous two frames
    type PixelDepth = HashMap<(i64, i64), f64>;
    let mut history: HashMap<u32, (usize, PixelDepth, PixelDepth)> = HashMap::new();
    for (frame, pts) in observations.frames() {
        let mut groups: HashMap<Option<u32>, Vec<[f64; 3]>> = HashMap::new();
        for p in pts {
            groups.entry(p.camera).or_default().push(p.position);
        }
        let mut keys: Vec<_> = groups.keys().copied().collect();
        keys.sort();
        for key in keys {
            let group = &groups[&key];
            if let (Some(c), Some(cam)) = (key, key.and_then(|c| cameras.get(c as usize))) {
                let depth = pixel_depths(group, cam);
                second_differences(&depth, &mut second);
                let h = history
                    .entry(c)
                    .or_insert((usize::MAX, HashMap::new(), HashMap::new()));
                if frame == h.0.wrapping_add(1) {
                    let mut keys: Vec<_> = depth.keys().copied().collect();
                    keys.sort_unstable();
                    for k in keys {
                        if let (Some(a), Some(b)) = (h.1.get(&k), h.2.get(&k)) {
                            temporal.push(a - 2.0 * b + depth[&k]);
                        }
                    }
                    h.1 = std::mem::replace(&mut h.2, depth);
                } else {
                    h.1 = HashMap::new();
                    h.2 = depth;
                }
                h.0 = frame;
                continue;
            }
            let eye = key
                .and_then(|c| eyes.get(c as usize))
                .filter(|e| e.iter().all(|v| v.is_finite()));
            plane_distances(group, eye, spacing, &mut planar);
        }
    }
    // a deviation of exactly 0 comes from repeated points, not from a measurement: no estimate
    let robust_sigma = |mut d: Vec<f64>| {
        (d.len() >= 8)
            .then(|| 1.4826 * mad(&mut d))
            .filter(|s| *s > 0.0 && s.is_finite())
    };
    let (ns, np) = (second.len() as f64, planar.len() as f64);
    let a = match (robust_sigma(second), robust_sigma(temporal)) {
        (Some(x), Some(y)) => Some(x.min(y) / 6f64.sqrt()),
        (x, _) => x.map(|m| m / 6f64.sqrt()),
    };
    let b = robust_sigma(planar).map(|m| m / (1.0 + 1.0 / NEIGHBOURS as f64).sqrt());
    match (a, b) {
        (Some(a), Some(b)) => Some(((a * a * ns + b * b * np) / (ns + np)).sqrt()),
        (a, b) => a.or(b),
    }
}

/// The median absolute deviation from the median of `v` (non-empty; sorts `v`):
/// `1.4826 MAD` estimates a Gaussian's deviation, ignoring up to half the values.
pub(super) fn mad(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let med = v[v.len() / 2];
    let mut dev: Vec<f64> = v.iter().map(|x| (x - med).abs()).collect();
    dev.sort_by(f64::total_cmp);
    dev[dev.len() / 2]
}

/// The distance along the viewing ray per pixel of `cam` of the points it saw.
fn pixel_depths(pts: &[[f64; 3]], cam: &DepthCamera) -> HashMap<(i64, i64), f64> {
    let f = cam.frame();
    let mut depth = HashMap::new();
    for p in pts {
        if let Some([u, v, _]) = f.project(*p) {
            let s = (0..3)
                .map(|d| (p[d] - cam.camera.eye[d]).powi(2))
                .sum::<f64>()
                .sqrt();
            depth.insert((u.floor() as i64, v.floor() as i64), s);
        }
    }
    depth
}

/// Second differences of the ray distance over the pixel grid, along rows and columns.
fn second_differences(depth: &HashMap<(i64, i64), f64>, out: &mut Vec<f64>) {
    let mut keys: Vec<_> = depth.keys().copied().collect();
    keys.sort_unstable();
    for (i, j) in keys {
        let s = depth[&(i, j)];
        for (di, dj) in [(1, 0), (0, 1)] {
            if let (Some(a), Some(b)) = (depth.get(&(i - di, j - dj)), depth.get(&(i + di, j + dj))) {
                out.push(a - 2.0 * s + b);
            }
        }
    }
}

/// Signed distances of each point of `pts` to the plane of its nearest neighbours.
fn plane_distances(pts: &[[f64; 3]], eye: Option<&[f64; 3]>, spacing: f64, out: &mut Vec<f64>) {
    if pts.len() <= NEIGHBOURS {
        return;
    }
    let cell = spacing.max(1e-12);
    let key = |p: &[f64; 3]| p.map(|v| (v / cell).floor() as i64);
    let mut hash: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for (i, p) in pts.iter().enumerate() {
        hash.entry(key(p)).or_default().push(i);
    }
    let mut near: Vec<(f64, usize)> = Vec::new();
    for (i, p) in pts.iter().enumerate() {
        let c = key(p);
        near.clear();
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    if let Some(list) = hash.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) {
                        for &j in list {
                            if j != i {
                                let q = pts[j];
                                near.push(((0..3).map(|d| (q[d] - p[d]).powi(2)).sum(), j));
                            }
                        }
                    }
                }
            }
        }
        if near.len() < NEIGHBOURS {
            continue;
        }
        near.select_nth_unstable_by(NEIGHBOURS - 1, |a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let nb: Vec<[f64; 3]> = near[..NEIGHBOURS].iter().map(|&(_, j)| pts[j]).collect();
        let Some((c0, n)) = fit_plane(&nb) else { continue };
        let d = (0..3).map(|k| (p[k] - c0[k]) * n[k]).sum::<f64>();
        match eye {
            Some(e) => {
                let ray: [f64; 3] = [0, 1, 2].map(|k| p[k] - e[k]);
                let len = ray.iter().map(|v| v * v).sum::<f64>().sqrt();
                let cos = (0..3).map(|k| ray[k] * n[k]).sum::<f64>().abs() / len.max(1e-300);
                if cos > 0.3 {
                    out.push(d / cos);
                }
            }
            None => out.push(d),
        }
    }
}

/// Centroid and unit normal (smallest eigenvector of the covariance) of points.
fn fit_plane(p: &[[f64; 3]]) -> Option<([f64; 3], [f64; 3])> {
    let n = p.len() as f64;
    let c: [f64; 3] = std::array::from_fn(|d| p.iter().map(|q| q[d]).sum::<f64>() / n);
    let mut m = [[0.0; 3]; 3];
    for q in p {
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] += (q[i] - c[i]) * (q[j] - c[j]);
            }
        }
    }
    // smallest eigenvector = dominant eigenvector of (tr(M) I - M)
    let tr = m[0][0] + m[1][1] + m[2][2];
    if tr <= 0.0 {
        return None;
    }
    let s: [[f64; 3]; 3] =
        std::array::from_fn(|i| std::array::from_fn(|j| if i == j { tr - m[i][j] } else { -m[i][j] }));
    let (v, _) = principal_direction(&s);
    Some((c, v))
}

/// The reference surface mesh of `sim`'s body and the surface deformed by `model` at `frame`
/// (for pictures).
pub fn surfaces_at(
    sim: &mut Simulation,
    model: Model,
    frame: usize,
) -> Result<(cutfem::TriMesh, cutfem::TriMesh), Error> {
    let surface = sim.grid.surface()?;
    sim.reset(model)?;
    for t in 1..=frame {
        sim.step().map_err(|e| Error::step(format!("step {t}"), e))?;
    }
    let deformed = sim.grid.deformed(&surface, &sim.u);
    Ok((surface.mesh, deformed))
}
