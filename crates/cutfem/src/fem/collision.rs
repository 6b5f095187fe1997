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
//! Ground friction ([`add_friction_forces`]) adds a tangential traction against the sliding at
//! each crossing, proportional to its normal force.
//!
//! Each grid edge is visited once (the thesis' per-cell loop visits an edge shared by several
//! active cells several times).
//!
//! Two time discretizations of the contact force ([`ContactScheme`]):
//! * `Thesis`: the prediction above, explicit in the unknown displacement. Stable only while
//!   `k * crossings * dt^2 / mass` stays below about 1.
//! * `Implicit`: the force is linearized about the current state,
//!   `f(u') ~ f(u) + J (u' - u)` with `J = -k softmin'(d) w w^T n n^T` (`w` the corner weights
//!   `1-t`, `t`), and its theta-weighted part `theta J u'` moves into the Newmark matrix:
//!   `A += theta dt K_c`, `b += dt (f(u) - theta J u)`, `K_c = -J` (positive semi-definite).
//!   Stable for stiff springs.
//! * `Softmin`: the `Implicit` scheme's softmin law and linearization with each crossing's
//!   spring per unit area, `k a_c` (the area `a_c` below): `stiffness` is a pressure per unit
//!   penetration whatever the grid, as with `Penalty`, and the law still pushes before contact
//!   (`k ln 2 / alpha` per unit area at `d = 0`).
//! * `Penalty` (default, `[ground] scheme` absent): a penalty per unit area, iterated to convergence within the step, with the C2
//!   law [`penalty0`] in place of the softmin (no push before contact; `delta = 1 / alpha`). The spring of
//!   a crossing stands for the part of the body's (rest) surface around it: a surface with unit
//!   normal `m` crosses `|m|_1 / h^2` grid edges per unit area, so each crossing carries the
//!   area `a_c = h^2 / |m|_1` (`m` the gradient of the cell's trilinear SDF at the crossing)
//!   and its spring is `k a_c` with `k` the stiffness per unit area (pressure per unit
//!   penetration): the contact's stiffness no longer depends on the grid. The force is taken
//!   at the new state alone, `f(u')` (backward Euler; the weight `theta_c = 1` of
//!   [`Ground::contact_theta`] in place of eq. 2.6.4's `theta`: a spring that stiff has
//!   oscillations no frame rate resolves, and the trapezoidal rule would keep them ringing),
//!   and `u'` is found by Newton's method: each iteration linearizes `f` at the last iterate
//!   `u_l` (`A += dt K_c(u_l)`, `b += dt (f(u_l) + K_c(u_l) u_l)`)
//!   and solves again, until the linearization's error at the new iterate (its residual,
//!   [`penalty_residual`]) is at most [`PENALTY_TOLERANCE`]` h`. Its first iteration is
//!   linearized at `u` as the `Implicit` step is. A sharp law is then stable at any time
//!   step; the adjoint
//!   linearizes at the converged `u'` (implicit function theorem).

use super::grid::Grid;
use gpumat::{Matrix, Vec3};
use std::collections::BTreeSet;

/// A vector per degree of freedom (displacement, velocity).
type Field = Matrix<Vec3<f64>>;

/// How the contact force is discretized in time (see the module docs); `[ground].scheme` of a
/// scene, in lower case.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ContactScheme {
    /// linearized, implicit in the new displacement
    Implicit,
    /// the thesis' explicit prediction `f + theta dt df/dt`
    Thesis,
    /// a penalty per unit area, Newton-iterated within each step (the default)
    #[default]
    Penalty,
    /// the softmin law of `Implicit` with springs per unit area (`k a_c`, as `Penalty`'s)
    Softmin,
}

impl ContactScheme {
    /// Whether the law's stiffness is per unit area (each crossing's spring `k a_c`) rather
    /// than per crossing.
    pub fn per_area(self) -> bool {
        matches!(self, ContactScheme::Penalty | ContactScheme::Softmin)
    }
}

/// Newton iterations of the [`ContactScheme::Penalty`] step stop when no crossing's distance
/// to the ground moved by more than this many cell widths in the last iteration.
pub const PENALTY_TOLERANCE: f64 = 1e-10;

/// At most this many Newton iterations per step with [`ContactScheme::Penalty`].
pub const PENALTY_MAX_ITERATIONS: usize = 50;

/// A ground plane with its spring constants.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ground {
    /// unit normal pointing out of the ground
    pub normal: Vec3<f64>,
    /// offset: the ground is `n . x >= height`
    pub height: f64,
    /// spring stiffness `k`: per crossing, or per unit area with [`ContactScheme::Penalty`] and
    /// [`ContactScheme::Softmin`]
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
    /// the area of rest surface the crossing stands for, `h^2 / |m|_1` (module docs)
    pub area: f64,
}

impl Crossing {
    /// The nodal values `s` interpolated to the crossing, `(1 - t) s_a + t s_b`.
    pub fn lerp(&self, s: &[Vec3<f64>]) -> Vec3<f64> {
        s[self.a as usize] * (1.0 - self.t) + s[self.b as usize] * self.t
    }

    /// The crossing's position under the nodal displacements `u`.
    pub fn position(&self, grid: &Grid, u: &[Vec3<f64>]) -> Vec3<f64> {
        let (a, b, t) = (self.a as usize, self.b as usize, self.t);
        (grid.positions[a] + u[a]) * (1.0 - t) + (grid.positions[b] + u[b]) * t
    }
}

impl Ground {
    /// The signed distance of `x` from the plane, `n . x - height` (negative: inside).
    pub fn distance(&self, x: Vec3<f64>) -> f64 {
        self.normal.dot(x) - self.height
    }

    /// The signed distance of crossing `c` from the plane under the nodal displacements `u`.
    pub fn crossing_distance(&self, grid: &Grid, c: &Crossing, u: &[Vec3<f64>]) -> f64 {
        self.distance(c.position(grid, u))
    }

    /// Whether `stiffness` is per unit area (each crossing's spring `k a_c`) rather than per
    /// crossing.
    pub fn stiffness_per_area(&self) -> bool {
        self.scheme.per_area()
    }

    /// The spring constant of crossing `c`: `k`, or `k a_c` per unit area
    /// ([`ContactScheme::Penalty`], [`ContactScheme::Softmin`]).
    pub fn spring(&self, c: &Crossing) -> f64 {
        if self.stiffness_per_area() {
            self.stiffness * c.area
        } else {
            self.stiffness
        }
    }
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

/// The gradient (in cell-local coordinates, per unit of the local coordinate) of the trilinear
/// interpolant of the corner values `phi` at local point `p` in `[0, 1]^3`.
fn trilinear_gradient(phi: &[f64; 8], p: [f64; 3]) -> [f64; 3] {
    let mut g = [0.0; 3];
    for (c, &f) in phi.iter().enumerate() {
        let bit = |axis: usize| (c >> axis) & 1 == 1;
        let w = |axis: usize| if bit(axis) { p[axis] } else { 1.0 - p[axis] };
        let dw = |axis: usize| if bit(axis) { 1.0 } else { -1.0 };
        g[0] += f * dw(0) * w(1) * w(2);
        g[1] += f * w(0) * dw(1) * w(2);
        g[2] += f * w(0) * w(1) * dw(2);
    }
    g
}

/// The penalty scheme's law `P(d)` (negative in contact, like `softmin_alpha(0, d)`): with
/// the depth `x = -d` and `s = x / delta`, `delta = 1 / alpha`: zero for `x <= 0`,
/// `-delta (s^3 - s^4 / 2)` over the first `delta` of penetration, `-(x - delta / 2)` beyond.
/// Its slope is the smoothstep `3 s^2 - 2 s^3` (then 1): C2, no push before contact, the force
/// linear in the depth past `delta`.
pub fn penalty0(d: f64, alpha: f64) -> f64 {
    let (x, delta) = (-d, 1.0 / alpha);
    if x <= 0.0 {
        0.0
    } else if x < delta {
        let s = x / delta;
        -delta * s * s * s * (1.0 - 0.5 * s)
    } else {
        -(x - 0.5 * delta)
    }
}

/// `d P(d) / dd` of [`penalty0`]: 0, `3 s^2 - 2 s^3`, 1.
pub fn penalty0_derivative(d: f64, alpha: f64) -> f64 {
    let (x, delta) = (-d, 1.0 / alpha);
    if x <= 0.0 {
        0.0
    } else if x < delta {
        let s = x / delta;
        s * s * (3.0 - 2.0 * s)
    } else {
        1.0
    }
}

impl Ground {
    /// The weight of the new state's contact force in a step, `theta_c`: the penalty scheme
    /// takes the force at the new state alone (`1`, backward Euler: it damps the contact's
    /// unresolved oscillations), the others the Newmark `theta`.
    pub fn contact_theta(&self, theta: f64) -> f64 {
        match self.scheme {
            ContactScheme::Penalty => 1.0,
            ContactScheme::Implicit | ContactScheme::Softmin | ContactScheme::Thesis => theta,
        }
    }

    /// The contact law and its slope at distance `d`, `(S(d), S'(d))`: the softmin of the
    /// implicit and thesis schemes, [`penalty0`] of the penalty scheme; the force on a crossing
    /// is `-spring S(d) n`.
    pub fn law(&self, d: f64) -> (f64, f64) {
        match self.scheme {
            ContactScheme::Penalty => (penalty0(d, self.softness), penalty0_derivative(d, self.softness)),
            ContactScheme::Implicit | ContactScheme::Softmin | ContactScheme::Thesis => {
                (softmin0(d, self.softness), softmin0_derivative(d, self.softness))
            }
        }
    }
}

/// All surface crossings of grid edges between two active nodes, each edge once, in a fixed
/// order, with the area each stands for (module docs).
pub fn crossings(grid: &Grid) -> Vec<Crossing> {
    let h = grid.h();
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
            let t = fa / (fa - fb);
            // the crossing in cell-local coordinates and the SDF's normal there
            let corner = |q: usize| [q & 1, (q >> 1) & 1, (q >> 2) & 1].map(|x| x as f64);
            let (cp, cq) = (corner(p), corner(q));
            let at = std::array::from_fn(|i| cp[i] + t * (cq[i] - cp[i]));
            let m = trilinear_gradient(&c.phi, at);
            let (l1, l2) = (
                m.iter().map(|x| x.abs()).sum::<f64>(),
                m.iter().map(|x| x * x).sum::<f64>().sqrt(),
            );
            // |m|_1 / |m|_2 lies in [1, sqrt 3]; a vanishing gradient (never on a crossing of a
            // proper SDF) counts as an axis-aligned surface
            let ratio = if l2 > 0.0 { l1 / l2 } else { 1.0 };
            out.push(Crossing {
                a,
                b,
                t,
                area: h * h / ratio,
            });
        }
    }
    out
}

/// Adds the contact forces for displacement `u` and velocity `v` to `f`; returns the number
/// of crossings in contact (`d < 0`, at the linearization point). With [`ContactScheme::Implicit`] the force added is
/// `f(u) - theta J u` and the stiffness `theta dt K_c` is returned in `stiffness` as
/// `(crossing, k softmin'(d))` terms (the caller adds them to the Newmark matrix). With
/// [`ContactScheme::Penalty`] the force is linearized at `at` (the Newton iterate `u_l`; `u`
/// when `None`): `(1 - theta) f(u) + theta (f(u_l) - J(u_l) u_l)`, and the slopes are taken
/// at `u_l`.
pub fn add_ground_forces(
    grid: &Grid,
    crossings: &[Crossing],
    ground: &Ground,
    (u, v, at): (&Field, &Field, Option<&Field>),
    dt: f64,
    theta: f64,
    f: &mut Matrix<Vec3<f64>>,
    stiffness: &mut Vec<(Crossing, f64)>,
) -> usize {
    stiffness.clear();
    let (us, vs) = (u.as_slice(), v.as_slice());
    // the linearization point: the Newton iterate of the penalty scheme, else u
    let ls = match (ground.scheme, at) {
        (ContactScheme::Penalty, Some(m)) => m.as_slice(),
        _ => us,
    };
    let n = ground.normal;
    let mut touching = 0;
    let fs = f.as_mut_slice();
    for c in crossings {
        let (a, b, t) = (c.a as usize, c.b as usize, c.t);
        let vel = c.lerp(vs);
        let d = ground.crossing_distance(grid, c, us);
        // the linearization point (the penalty scheme's Newton iterate; else u itself)
        let ul = c.lerp(ls);
        let dl = if std::ptr::eq(ls, us) {
            d
        } else {
            ground.crossing_distance(grid, c, ls)
        };
        if dl < 0.0 {
            touching += 1;
        }
        let ddt = n.dot(vel);
        let k = ground.spring(c);
        let (s0, s1) = ground.law(d);
        let (f_now, slope) = (-k * s0, k * s1);
        let mag = match ground.scheme {
            ContactScheme::Thesis => {
                let f_next = f_now + dt * (-slope * ddt);
                theta * f_next + (1.0 - theta) * f_now
            }
            ContactScheme::Implicit | ContactScheme::Softmin => {
                // f(u) - theta J u with J u = -slope n (n . (w_a u_a + w_b u_b))
                if slope > 0.0 {
                    stiffness.push((*c, slope));
                }
                let un = n.dot(c.lerp(us));
                f_now + theta * slope * un
            }
            ContactScheme::Penalty => {
                let (sl, sl1) = ground.law(dl);
                let (f_l, slope_l) = (-k * sl, k * sl1);
                if slope_l > 0.0 {
                    stiffness.push((*c, slope_l));
                }
                let tc = ground.contact_theta(theta);
                (1.0 - tc) * f_now + tc * (f_l + slope_l * n.dot(ul))
            }
        };
        let fv = n * mag;
        fs[a] = fs[a] + fv * (1.0 - t);
        fs[b] = fs[b] + fv * t;
    }
    touching
}

/// Ground friction ([`crate::fem::Model::friction`], the `friction` effect): a tangential
/// traction against the sliding, proportional to the contact's normal force,
/// `f_c = -mu N_c P (u'_c - u_c) / dt` per crossing. `N_c = -spring S(d_c)` is the crossing's
/// normal force at the step's start (lagged: the law stays linear in `u'`), `P = I - n n^T` the
/// tangential projector and `(u'_c - u_c) / dt` the sliding velocity over the step (implicit in
/// `u'`, like the drag's). In the Newmark step (`b += dt f`) it adds `mu N_c w w^T (x) P` to
/// `A` (symmetric, positive semi-definite) and `mu N_c P u_c` to `b`, spread with the weights
/// `w = (1 - t, t)`. Adds `(mu N_c / dt) P u_c` spread to `f` and returns the `(crossing,
/// mu N_c)` terms of `A` in `terms` (crossings with a normal force only, in their fixed order).
pub fn add_friction_forces(
    grid: &Grid,
    crossings: &[Crossing],
    ground: &Ground,
    mu: f64,
    u: &Field,
    dt: f64,
    f: &mut Field,
    terms: &mut Vec<(Crossing, f64)>,
) {
    terms.clear();
    let us = u.as_slice();
    let n = ground.normal;
    let fs = f.as_mut_slice();
    for c in crossings {
        let (a, b, t) = (c.a as usize, c.b as usize, c.t);
        let uc = c.lerp(us);
        let d = ground.crossing_distance(grid, c, us);
        let normal_force = -ground.spring(c) * ground.law(d).0;
        if normal_force <= 0.0 {
            continue;
        }
        let coef = mu * normal_force;
        terms.push((*c, coef));
        // (mu N / dt) P u_c
        let fv = (uc - n * n.dot(uc)) * (coef / dt);
        fs[a] = fs[a] + fv * (1.0 - t);
        fs[b] = fs[b] + fv * t;
    }
}

/// How far the Newton iterate `x` of a [`ContactScheme::Penalty`] step is from solving the
/// step: the largest error of the contact law's linearization at `at` (the previous iterate)
/// over the crossings, `|P(d_x) - P(d_l) - P'(d_l) (d_x - d_l)|` (a distance; the force error
/// is the spring times it).
pub fn penalty_residual(
    grid: &Grid,
    crossings: &[Crossing],
    ground: &Ground,
    at: &Matrix<Vec3<f64>>,
    x: &Matrix<Vec3<f64>>,
) -> f64 {
    let (ls, xs) = (at.as_slice(), x.as_slice());
    let mut worst = 0.0f64;
    for c in crossings {
        let dist = |s: &[Vec3<f64>]| ground.crossing_distance(grid, c, s);
        let (dl, dx) = (dist(ls), dist(xs));
        let ((sl, sl1), (sx, _)) = (ground.law(dl), ground.law(dx));
        worst = worst.max((sx - sl - sl1 * (dx - dl)).abs());
    }
    worst
}

/// How the ground pushed over a run (sampled at chosen states, e.g. every frame): the sums over
/// states and crossings of the normal force `f_c = -spring S(d_c) > 0`, of its part on
/// crossings above the plane (`d_c > 0`: the softmin law's push before contact; the penalty
/// law has none) and of `f_c d_c`. Their ratio, the force-weighted distance of the push, is
/// about `-penetration` for a contact that acts on touching points and `+` the gap where the
/// softened law holds a body off the plane (a resting body sits where its bottom crossings'
/// `k ln(1 + e^(-alpha d)) / alpha` sum to its weight: centimetres for `alpha = 100`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GroundPush {
    /// sum of the normal forces
    pub force: f64,
    /// the part of `force` on crossings above the plane
    pub above: f64,
    /// sum of force times distance
    pub moment: f64,
    /// states added
    pub states: usize,
}

impl GroundPush {
    /// Adds the push of the state with displacement `u`.
    pub fn add_state(&mut self, grid: &Grid, crossings: &[Crossing], ground: &Ground, u: &Field) {
        let us = u.as_slice();
        for c in crossings {
            let d = ground.crossing_distance(grid, c, us);
            let f = -ground.spring(c) * ground.law(d).0;
            if f > 0.0 && f.is_finite() {
                self.force += f;
                self.moment += f * d;
                if d > 0.0 {
                    self.above += f;
                }
            }
        }
        self.states += 1;
    }

    /// The force-weighted mean distance of the push from the plane (`None`: no push).
    pub fn mean_distance(&self) -> Option<f64> {
        (self.force > 0.0).then(|| self.moment / self.force)
    }

    /// The share of the push on crossings above the plane (0 without push).
    pub fn share_above(&self) -> f64 {
        if self.force > 0.0 {
            self.above / self.force
        } else {
            0.0
        }
    }

    /// The ground holds the body off the plane: it carried at least a tenth of the weight
    /// `weight` (mass times gravity) on average over the states, and its push acted, weighted
    /// by force, more than a quarter of the cell size `h` above the plane.
    pub fn hovers(&self, weight: f64, h: f64) -> bool {
        self.states > 0
            && weight > 0.0
            && self.force >= 0.1 * weight * self.states as f64
            && self.mean_distance().is_some_and(|d| d > 0.25 * h)
    }
}
