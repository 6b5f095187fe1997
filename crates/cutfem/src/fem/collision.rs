//! Soft ground contact (thesis sec. 2.8, Alg. 5.5).
//!
//! The ground is the half-space `{x : n . x >= height}` with signed distance
//! `d(x) = n . x - height`. Contact is tested where the body's surface crosses a grid edge:
//! for an edge between corners `a`, `b` with `phi_a < 0 <= phi_b` (or the reverse) the
//! crossing sits at `t = phi_a / (phi_a - phi_b)`, and its current position and velocity are
//! interpolated from the corners. A spring pushes it out along `n` with the softened force
//! `f = -k softmin_alpha(0, d) n`, `softmin_alpha(0, d) = -ln(1 + e^{-alpha d}) / alpha`
//! (eq. 2.8.3). The force is made semi-implicit by its first-order prediction
//! `f_next = f + dt df/dt`, `df/dt = -k (n . v) / (1 + e^{alpha d})` (eq. 2.8.2, 2.8.4), and the
//! Newmark-weighted `theta f_next + (1 - theta) f` (eq. 2.6.4) is spread to the two corners
//! with weights `1 - t` and `t`.
//!
//! Each grid edge is visited once (the thesis' per-cell loop visits an edge shared by several
//! active cells several times).
//!
//! Two time discretizations of the contact force ([`ContactScheme`]):
//! * `Thesis`: the prediction above, explicit in the unknown displacement. Stable only while
//!   `k * crossings * dt^2 / mass` stays below about 1.
//! * `Implicit` (default): the force is linearized about the current state,
//!   `f(u') ~ f(u) + J (u' - u)` with `J = -k softmin'(d) w w^T n n^T` (`w` the corner weights
//!   `1-t`, `t`), and its theta-weighted part `theta J u'` moves into the Newmark matrix:
//!   `A += theta dt K_c`, `b += dt (f(u) - theta J u)`, `K_c = -J` (positive semi-definite).
//!   Stable for stiff springs.

use super::grid::Grid;
use gpumat::{Matrix, Vec3};
use std::collections::BTreeSet;

/// How the contact force is discretized in time (see the module docs); `[ground].scheme` of a
/// scene, in lower case.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ContactScheme {
    /// linearized, implicit in the new displacement
    #[default]
    Implicit,
    /// the thesis' explicit prediction `f + theta dt df/dt`
    Thesis,
}

/// A ground plane with its spring constants.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ground {
    /// unit normal pointing out of the ground
    pub normal: Vec3<f64>,
    /// offset: the ground is `n . x >= height`
    pub height: f64,
    /// spring stiffness `k`
    pub stiffness: f64,
    /// softmin sharpness `alpha`
    pub softness: f64,
    /// time discretization of the contact force
    pub scheme: ContactScheme,
}

/// One surface crossing of a grid edge.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Crossing {
    /// first corner (dof)
    pub a: u32,
    /// second corner (dof)
    pub b: u32,
    /// position along the edge, `x = (1-t) x_a + t x_b`
    pub t: f64,
}

/// `softmin_alpha(0, d) = -ln(1 + e^{-alpha d}) / alpha`, evaluated stably.
pub fn softmin0(d: f64, alpha: f64) -> f64 {
    let z = -alpha * d;
    // ln(1 + e^z) without overflow (Maechler's log1pexp)
    let l = if z > 36.0 {
        z
    } else if z > -37.0 {
        z.exp().ln_1p()
    } else {
        z.exp()
    };
    -l / alpha
}

/// `d softmin_alpha(0, d) / dd = 1 / (1 + e^{alpha d})`.
pub fn softmin0_derivative(d: f64, alpha: f64) -> f64 {
    let z = alpha * d;
    if z > 700.0 {
        0.0
    } else {
        1.0 / (1.0 + z.exp())
    }
}

/// All surface crossings of grid edges between two active nodes, each edge once, in a fixed
/// order.
pub fn crossings(grid: &Grid) -> Vec<Crossing> {
    let mut seen = BTreeSet::new();
    let mut out = Vec::new();
    const EDGES: [(usize, usize); 12] = [
        (0, 1),
        (2, 3),
        (4, 5),
        (6, 7),
        (0, 2),
        (1, 3),
        (4, 6),
        (5, 7),
        (0, 4),
        (1, 5),
        (2, 6),
        (3, 7),
    ];
    for c in &grid.cells {
        for &(p, q) in &EDGES {
            let (fa, fb) = (c.phi[p], c.phi[q]);
            if (fa < 0.0) == (fb < 0.0) {
                continue;
            }
            let (a, b) = (c.dofs[p], c.dofs[q]);
            if !seen.insert((a.min(b), a.max(b))) {
                continue;
            }
            out.push(Crossing {
                a,
                b,
                t: fa / (fa - fb),
            });
        }
    }
    out
}

/// Adds the contact forces for displacement `u` and velocity `v` to `f`; returns the number
/// of crossings in contact (`d < 0`). With [`ContactScheme::Implicit`] the force added is
/// `f(u) - theta J u` and the stiffness `theta dt K_c` is returned in `stiffness` as
/// `(crossing, k softmin'(d))` terms (the caller adds them to the Newmark matrix).
pub fn add_ground_forces(
    grid: &Grid,
    crossings: &[Crossing],
    ground: &Ground,
    u: &Matrix<Vec3<f64>>,
    v: &Matrix<Vec3<f64>>,
    dt: f64,
    theta: f64,
    f: &mut Matrix<Vec3<f64>>,
    stiffness: &mut Vec<(Crossing, f64)>,
) -> usize {
    stiffness.clear();
    let (us, vs) = (u.as_slice(), v.as_slice());
    let n = ground.normal;
    let mut touching = 0;
    let fs = f.as_mut_slice();
    for c in crossings {
        let (a, b, t) = (c.a as usize, c.b as usize, c.t);
        let x = (grid.positions[a] + us[a]) * (1.0 - t) + (grid.positions[b] + us[b]) * t;
        let vel = vs[a] * (1.0 - t) + vs[b] * t;
        let d = n.dot(x) - ground.height;
        let ddt = n.dot(vel);
        let f_now = -ground.stiffness * softmin0(d, ground.softness);
        let slope = ground.stiffness * softmin0_derivative(d, ground.softness);
        if d < 0.0 {
            touching += 1;
        }
        let mag = match ground.scheme {
            ContactScheme::Thesis => {
                let f_next = f_now + dt * (-slope * ddt);
                theta * f_next + (1.0 - theta) * f_now
            }
            ContactScheme::Implicit => {
                // f(u) - theta J u with J u = -slope n (n . (w_a u_a + w_b u_b))
                if slope > 0.0 {
                    stiffness.push((*c, slope));
                }
                let un = n.dot(us[a] * (1.0 - t) + us[b] * t);
                f_now + theta * slope * un
            }
        };
        let fv = n * mag;
        fs[a] = fs[a] + fv * (1.0 - t);
        fs[b] = fs[b] + fv * t;
    }
    touching
}
