//! The held surface of the Dirichlet boxes (`[[dirichlet]]`): per cell, the Nitsche terms
//! (eq. 4.4.13-4.4.17) over the part of the body's surface inside a box, clipped exactly.
//!
//! For the test function `v = N_i e_p` and the trial function `u = N_j e_r`, the Nitsche form
//! `-int v . sigma(u) n - int sigma(v) n . u + eta int u . v` over the held surface `G` gives
//! the block
//!
//! `B_ij = -T(G_ij) - T(G_ji)^T + eta P_ij I`, with `P_ij = int N_i N_j`,
//! `G_ij = int N_i grad N_j (x) n` and `T(G)_pr = mu G_pr + lambda G_rp + delta_pr mu tr G`
//!
//! (`sigma(N_j e_r) n` has components `mu (d_p N_j n_r + delta_pr grad N_j . n) + lambda n_p
//! d_r N_j`). Two quadratures ([`NitscheQuadrature`], `[numerics] nitsche`):
//!
//! - `thesis` (eq. 4.4.15-4.4.17): nodal, `P_ij = delta_ij w_b(e, i)` and
//!   `G_ij = w_b(e, i) grad N_j(v_i) (x) n` with the nodal weights `w_b` of eq. 4.2.3 over the
//!   held part, the basis gradient at corner `i` and the cell's mean normal `n` (`grad N_j(v_i)`
//!   vanishes unless `i` and `j` are equal or share an edge);
//! - `consistent` (the default): the integrals over the surface quadrature points of the held part
//!   ([`crate::cutcell::refined_surface_in_box`]), each with its own normal. The nodal rule puts
//!   a weight proportional to the held area on corners a whole cell away from it, so a sliver
//!   of held surface (a strip of side face caught by a box a little wider than the face it
//!   holds) pins the cell's far corners; consistent quadrature weighs them by `N_i N_j`, which
//!   vanishes there (`docs/simulation.md`, "Nitsche").
//!
//! # The volumetric traction
//!
//! The part of `sigma(u) n` per unit of `lambda` is `div u n`: the block above carries it as
//! `lambda D_ij` with `D_ij = G_ij^T` (`[p][r] = int N_i n_p d_r N_j`, the pointwise
//! dilatation of the corner field). For the elements with incompatible modes that is not the
//! dilatation their energy sees: in bending the corner field has a dilatation `eps_xx` that
//! the bubbles cancel, so the energy holds no `lambda` term for it while the traction holds
//! `lambda eps_xx`. The form then needs a penalty growing like `lambda^2 / mu` to stay
//! coercive; with the scaled one (`~ lambda + 2 mu`) a held beam softened from `nu = 0.49` on
//! and turned indefinite near 0.497 (`tests/fem_nitsche.rs`). These elements therefore use the
//! cell's mean dilatation, `D_ij = b_i (x) gbar_j` with `b_i = int N_i n` over the held
//! surface and `gbar_j = (1/|Omega_e|) int_{Omega_e} grad N_j` (the B-bar reading of the
//! volumetric stress). Its energy bounds it whatever `lambda`: the bubbles are mean-free, so
//! the mean dilatation of the enhanced field is the corner field's, and
//! `int_{Omega_e} lambda (div u)^2 >= lambda |Omega_e| (mean div u)^2`. The consistency error
//! is `O(h)` (the mean against the surface value), the order of the element's stress. The
//! block stays linear in `(lambda, mu, eta)`, so the adjoint's Lame derivatives read it as
//! before.

use std::sync::Arc;

use gpumat::{Mat3, Vec3};

use crate::error::Error;
use crate::fem::element::{basis_gradient, gram, mean_gradients, Element};
use crate::fem::grid::Grid;
use crate::fem::model::{Model, NitscheQuadrature};

/// The part of a cell's surface held by the Dirichlet boxes and its Nitsche integrals.
#[derive(Clone, Debug, PartialEq)]
pub struct NitscheFace {
    /// `int N_i` over the held surface in the cell, world units (`w_b` of eq. 4.2.3 over the
    /// held part)
    pub boundary: [f64; 8],
    /// the area-weighted mean unit outward normal of the held surface
    pub normal: [f64; 3],
    /// `h |G_e| / |K_e|`: the held area over the cell's inside volume, relative to a full
    /// face of a full cell; the scaled penalty of the cell is multiplied by it
    /// ([`crate::fem::NitschePenalty`], module docs)
    pub penalty_factor: f64,
    /// the consistent integrals `P_ij` and `G_ij` (module docs)
    terms: Arc<NitscheTerms>,
}

#[derive(Debug, Default, PartialEq)]
struct NitscheTerms {
    /// `P_ij = int N_i N_j`
    mass: [[f64; 8]; 8],
    /// `G_ij = int N_i grad N_j (x) n`, row-major 3x3 (`[p][r] = int N_i d_p N_j n_r`)
    traction: [[Mat3<f64>; 8]; 8],
    /// `D_ij`, the part of the traction per unit of `lambda` (module docs, "The volumetric
    /// traction"): `G_ij^T` (`[p][r] = int N_i n_p d_r N_j`) for the plain trilinear
    /// elements, `b_i (x) gbar_j` with the cell's mean dilatation for the elements with
    /// incompatible modes
    volumetric: [[Mat3<f64>; 8]; 8],
    /// `b_i = int N_i n` over the held surface
    normal_weight: [Vec3<f64>; 8],
}

impl NitscheFace {
    /// The Nitsche block `B_ij` (module docs) for Lame constants `lambda, mu` and penalty `eta`.
    #[inline]
    pub fn block(&self, i: usize, j: usize, lambda: f64, mu: f64, eta: f64) -> Mat3<f64> {
        let t = &self.terms;
        let tr = |i: usize, j: usize| traction(&t.traction[i][j], &t.volumetric[i][j], lambda, mu);
        let k = tr(i, j) + tr(j, i).transpose();
        Mat3::from_scalar(eta * t.mass[i][j]) - k
    }
}

/// `T(G, D)_pr = mu G_pr + lambda D_pr + delta_pr mu tr G` (`D = G^T` for the pointwise
/// dilatation).
#[inline(always)]
fn traction(g: &Mat3<f64>, d: &Mat3<f64>, lambda: f64, mu: f64) -> Mat3<f64> {
    let tr = g.trace();
    *g * mu + *d * lambda + Mat3::from_scalar(mu * tr)
}

/// The thesis' nodal terms (module docs): `P_ij = delta_ij w_b(e, i)`, `G_ij = w_b(e, i)
/// grad N_j(v_i) (x) n`.
fn nodal_terms(f: &NitscheFace, h: f64, terms: &mut NitscheTerms) {
    let n = Vec3::from_array(f.normal);
    for i in 0..8 {
        for j in 0..8 {
            terms.mass[i][j] = if i == j { f.boundary[i] } else { 0.0 };
            terms.traction[i][j] = basis_gradient(j, i, h).outer(n) * f.boundary[i];
        }
        terms.normal_weight[i] = n * f.boundary[i];
    }
}

/// The volumetric traction `D_ij` (module docs): `G_ij^T`, or with the incompatible modes
/// `b_i (x) gbar_j` with the mean gradients of the cell's inside part.
fn volumetric_terms(c: &crate::fem::grid::Cell, h: f64, element: Element, terms: &mut NitscheTerms) {
    let mean = element
        .has_modes()
        .then(|| mean_gradients(&gram(&c.integrals, h, element), h));
    for i in 0..8 {
        for j in 0..8 {
            terms.volumetric[i][j] = match &mean {
                Some(g) => terms.normal_weight[i].outer(g[j]),
                None => terms.traction[i][j].transpose(),
            };
        }
    }
}

/// The trilinear basis values and world gradients at the unit-cube point `x` of a cell of
/// size `h`.
fn basis_at(x: [f64; 3], h: f64) -> ([f64; 8], [Vec3<f64>; 8]) {
    let w = x.map(|t| [1.0 - t, t]);
    let dw = [-1.0 / h, 1.0 / h];
    let n = std::array::from_fn(|i| w[0][i & 1] * w[1][(i >> 1) & 1] * w[2][(i >> 2) & 1]);
    let g = std::array::from_fn(|i| {
        let (a, b, c) = (i & 1, (i >> 1) & 1, (i >> 2) & 1);
        Vec3::new(
            dw[a] * w[1][b] * w[2][c],
            w[0][a] * dw[b] * w[2][c],
            w[0][a] * w[1][b] * dw[c],
        )
    });
    (n, g)
}

/// The held surface of every cell: the part of the body's surface inside a Dirichlet box
/// (`[[dirichlet]]`: the material inside the box is held), clipped to the box exactly
/// ([`crate::cutcell::refined_surface_in_box`]), so the held region does not depend on the
/// resolution. Overlapping boxes count their common surface once per box. Errors when a box
/// holds no part of the body's surface.
pub fn dirichlet_cells(grid: &Grid, model: &Model) -> Result<Vec<Option<NitscheFace>>, Error> {
    let h = grid.h();
    let mut sums: Vec<Option<(NitscheFace, NitscheTerms)>> = (0..grid.cells.len()).map(|_| None).collect();
    for (bi, bx) in model.dirichlet.iter().enumerate() {
        let mut any = false;
        for (e, c) in grid.cells.iter().enumerate() {
            if c.integrals.area <= 0.0 {
                continue;
            }
            let lo = grid.cell_origin(c).to_array();
            if (0..3).any(|d| lo[d] > bx.max[d] || lo[d] + h < bx.min[d]) {
                continue;
            }
            let (part, points) = crate::cutcell::refined_surface_in_box(&grid.sdf, c.coord, bx.min, bx.max);
            if part.area <= 0.0 {
                continue;
            }
            any = true;
            // the face's sums, its terms accumulated beside it and moved in at the end
            let f = sums[e].get_or_insert_with(|| {
                let face = NitscheFace {
                    boundary: [0.0; 8],
                    normal: [0.0; 3],
                    penalty_factor: 0.0,
                    terms: Arc::default(),
                };
                (face, NitscheTerms::default())
            });
            for i in 0..8 {
                f.0.boundary[i] += part.boundary[i];
            }
            for d in 0..3 {
                // area-weighted sum for now, normalized below
                f.0.normal[d] += part.area * part.normal[d];
            }
            let consistent = model.nitsche_quadrature == NitscheQuadrature::Consistent;
            for q in points.iter().filter(|_| consistent) {
                let (nv, g) = basis_at(q.x, h);
                let n = Vec3::from_array(q.normal);
                for i in 0..8 {
                    let wi = q.weight * nv[i];
                    f.1.normal_weight[i] = f.1.normal_weight[i] + n * wi;
                    for j in 0..8 {
                        f.1.mass[i][j] += wi * nv[j];
                        f.1.traction[i][j] = f.1.traction[i][j] + g[j].outer(n) * wi;
                    }
                }
            }
        }
        if !any {
            return Err(Error::Invalid(format!(
                "dirichlet[{bi}]: the box {:?}..{:?} holds no part of the body's surface (no material is held)",
                bx.min, bx.max
            )));
        }
    }
    Ok(sums
        .into_iter()
        .zip(&grid.cells)
        .map(|(s, c)| {
            // a cell with held surface but no material has nothing to hold (and no stiffness
            // to keep its consistency terms coercive)
            let volume: f64 = c.integrals.volume.iter().sum();
            s.filter(|_| volume > 0.0).map(|(mut f, mut terms)| {
                let area: f64 = f.boundary.iter().sum();
                f.penalty_factor = h * area / volume;
                let len = f.normal.iter().map(|x| x * x).sum::<f64>().sqrt();
                if len > 0.0 {
                    f.normal = f.normal.map(|x| x / len);
                }
                if model.nitsche_quadrature == NitscheQuadrature::Thesis {
                    nodal_terms(&f, h, &mut terms);
                }
                volumetric_terms(c, h, model.element, &mut terms);
                f.terms = Arc::new(terms);
                f
            })
        })
        .collect())
}
