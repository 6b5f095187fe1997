//! Where a surface vertex sits in the simulation grid, so that the surface moves with the
//! trilinear displacement field of the FEM (thesis sec. 4.5.1, generalised).
//!
//! The thesis extracts the surface on the simulation grid itself: every vertex lies on a grid
//! edge and moves by `(1 - t) u_a + t u_b`. That surface cuts every edge and corner of the
//! body by up to a cell (a box of side 0.5 at 20 cells per unit: rms 0.0099 between the
//! marching-cubes surface and the true box, as large as the measurement noise of the
//! independent reference cases). The surface can instead be extracted from the body's SDF
//! sampled `s` times finer ([`crate::fem::Grid::surface`], `[numerics] surface_subdivision`)
//! and each vertex `x` embedded in the simulation cell that holds it: with the cell's first
//! node `x_0`, cell size `h` and local coordinates `xi = (x - x_0) / h`, it moves by
//!
//! `u(x) = sum_q N_q(xi) u_q`, `N_q(xi) = prod_d (xi_d if bit d of q else 1 - xi_d)`,
//!
//! the FEM's own trilinear field (the interpolation of eq. 5.4.6, the shape functions `N_1..N_8` of
//! the hexahedron), so the
//! coarse extraction is the special case of a vertex on an edge (two non-zero weights).
//! A cell is chosen whose nodes with a non-zero weight all carry degrees of freedom; where the
//! fine surface pokes into a cell without any (a cap of the body through a face that no node
//! sees), the nearest such cell is used and its field extended linearly (weights outside
//! `[0, 1]`, at most one cell away).

use crate::SdfGrid;

/// Weights below this are dropped (a vertex on a cell face or edge).
const ZERO_WEIGHT: f64 = 1e-12;

/// The nodes and trilinear weights that move one surface vertex: `u = sum w_i u(n_i)` over the
/// first `len` entries.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Embedding {
    /// linear node indices of the simulation grid
    pub nodes: [usize; 8],
    /// weights (they sum to one)
    pub weights: [f64; 8],
    /// number of used entries
    pub len: u8,
}

impl Embedding {
    /// The two-node embedding of a point `(1 - t) x_a + t x_b` on a grid edge.
    pub fn on_edge(a: usize, b: usize, t: f64) -> Self {
        let mut e = Self {
            nodes: [0; 8],
            weights: [0.0; 8],
            len: 2,
        };
        e.nodes[..2].copy_from_slice(&[a, b]);
        e.weights[..2].copy_from_slice(&[1.0 - t, t]);
        e
    }

    /// The used `(node, weight)` pairs.
    pub fn terms(&self) -> impl Iterator<Item = (usize, f64)> + '_ {
        self.nodes[..self.len as usize]
            .iter()
            .copied()
            .zip(self.weights[..self.len as usize].iter().copied())
    }

    /// The interpolated value `sum w_i f(n_i)` of a nodal vector field, evaluated as
    /// `f(n_0) + sum_{i > 0} w_i (f(n_i) - f(n_0))` (the weights sum to one), so that a constant
    /// field is reproduced exactly.
    pub fn interpolate(&self, f: impl Fn(usize) -> [f64; 3]) -> [f64; 3] {
        let mut terms = self.terms();
        let Some((n0, _)) = terms.next() else {
            return [0.0; 3];
        };
        let f0 = f(n0);
        let mut s = f0;
        for (n, w) in terms {
            let v = f(n);
            for d in 0..3 {
                s[d] += w * (v[d] - f0[d]);
            }
        }
        s
    }
}

/// The trilinear embedding of point `x` in the grid `grid` (only its origin, spacing and
/// dimensions are used): a cell near `x` whose weighted nodes all satisfy `has_dof`, see the
/// module docs. `None` when no cell within one cell of `x` qualifies.
pub fn embed(grid: &SdfGrid, x: [f64; 3], has_dof: impl Fn(usize) -> bool) -> Option<Embedding> {
    let [nx, ny, _] = grid.dims;
    let h = grid.spacing;
    let s: [f64; 3] = std::array::from_fn(|d| (x[d] - grid.origin[d]) / h);
    let cells = grid.dims.map(|n| n as i64 - 1);
    let home: [i64; 3] = std::array::from_fn(|d| (s[d].floor() as i64).clamp(0, cells[d] - 1));
    let mut best: Option<(f64, Embedding)> = None;
    // the home cell and its 26 neighbours; the closest qualifying one wins (ties: first in order)
    for dz in -1..=1i64 {
        for dy in -1..=1i64 {
            for dx in -1..=1i64 {
                let c = [home[0] + dx, home[1] + dy, home[2] + dz];
                if (0..3).any(|d| c[d] < 0 || c[d] >= cells[d]) {
                    continue;
                }
                let xi: [f64; 3] = std::array::from_fn(|d| s[d] - c[d] as f64);
                // distance (in cells) from x to the cell's box
                let dist = xi.iter().map(|&v| (-v).max(v - 1.0).max(0.0)).fold(0.0, f64::max);
                if best.as_ref().is_some_and(|(b, _)| *b <= dist) {
                    continue;
                }
                let mut e = Embedding {
                    nodes: [0; 8],
                    weights: [0.0; 8],
                    len: 0,
                };
                let mut ok = true;
                for q in 0..8 {
                    let w: f64 = (0..3)
                        .map(|d| if q >> d & 1 == 1 { xi[d] } else { 1.0 - xi[d] })
                        .product();
                    if w.abs() <= ZERO_WEIGHT {
                        continue;
                    }
                    let [i, j, k] = [0, 1, 2].map(|d| (c[d] + (q >> d & 1) as i64) as usize);
                    let n = i + nx * (j + ny * k);
                    if !has_dof(n) {
                        ok = false;
                        break;
                    }
                    e.nodes[e.len as usize] = n;
                    e.weights[e.len as usize] = w;
                    e.len += 1;
                }
                if ok {
                    best = Some((dist, e));
                }
            }
        }
    }
    best.map(|(_, e)| e)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid() -> SdfGrid {
        SdfGrid::from_fn([-1.0, -2.0, 0.5], 0.25, [6, 5, 7], |_| 1.0)
    }

    #[test]
    fn weights_reproduce_the_point_and_any_linear_field() {
        let g = grid();
        let node_x = |n: usize| {
            let [nx, ny, _] = g.dims;
            let ijk = [n % nx, (n / nx) % ny, n / (nx * ny)];
            [0, 1, 2].map(|d| g.origin[d] + g.spacing * ijk[d] as f64)
        };
        let lin = |p: [f64; 3]| [1.0 + 2.0 * p[0] - p[2], p[1] * 3.0, 0.5 * p[0] + p[1] + p[2]];
        for x in [[-0.6, -1.3, 1.1], [-0.5, -1.5, 1.0], [0.1, -1.01, 1.49]] {
            let e = embed(&g, x, |_| true).unwrap();
            assert!((e.weights.iter().sum::<f64>() - 1.0).abs() < 1e-14);
            let y = e.interpolate(node_x);
            let v = e.interpolate(|n| lin(node_x(n)));
            for d in 0..3 {
                assert!((y[d] - x[d]).abs() < 1e-13, "{x:?} -> {y:?}");
                assert!((v[d] - lin(x)[d]).abs() < 1e-13);
            }
        }
        // a grid node: one weight
        assert_eq!(embed(&g, [-0.5, -1.5, 1.0], |_| true).unwrap().len, 1);
    }

    #[test]
    fn a_cell_without_degrees_of_freedom_is_replaced_by_a_neighbour() {
        let g = grid();
        let [nx, ny, _] = g.dims;
        // only nodes with i <= 2 carry dofs; x lies in a cell spanning i = 2..3
        let has = |n: usize| n % nx <= 2;
        let x = [-1.0 + 0.25 * 2.4, -1.6, 1.2];
        let e = embed(&g, x, has).unwrap();
        assert!(e.terms().all(|(n, _)| has(n)));
        // extended linearly from the cell i = 1..2: weights outside [0, 1], still exact for x
        assert!(e.weights[..e.len as usize].iter().any(|&w| w < 0.0));
        let node_x = |n: usize| {
            let ijk = [n % nx, (n / nx) % ny, n / (nx * ny)];
            [0, 1, 2].map(|d| g.origin[d] + g.spacing * ijk[d] as f64)
        };
        let y = e.interpolate(node_x);
        for d in 0..3 {
            assert!((y[d] - x[d]).abs() < 1e-13);
        }
        assert!(embed(&g, x, |_| false).is_none());
    }
}
