//! Dual contouring: a surface that keeps the body's sharp edges and corners.
//!
//! Marching cubes ([`super::extract_surface`]) puts every vertex on a grid edge, so a box's
//! edge or corner that runs through a cell is cut off by a bevel up to a cell wide. A
//! Poisson bulge that pushes the bevelled faces outward then mimics the missing volume: on the
//! independent block case this biased a fitted Poisson ratio by +0.15 (`docs/simulation.md`,
//! "The observed surface"). Dual contouring (Ju, Losasso, Schaefer, Warren 2002) instead
//! places one vertex *inside* every cut cell, at the point that best fits the tangent planes
//! of the surface at the cell's edge crossings (the quadratic error function, QEF):
//!
//! `x* = argmin_x sum_i (n_i . (x - p_i))^2`,
//!
//! where `p_i` is the crossing on cut edge `i` (linear interpolation of `phi`, as in marching
//! cubes) and `n_i` the unit gradient of the cell's trilinear interpolant of `phi` there. With
//! `A = sum n_i n_i^T`, `b = sum n_i (n_i . p_i)` and the mass point `c = mean p_i`, the
//! minimiser nearest `c` is `x* = c + A^+ (b - A c)`, where the pseudo-inverse `A^+` drops the
//! eigen-directions with eigenvalue below `TRUNCATE * lambda_max`: on a flat face only the
//! normal direction is fitted (the vertex slides to the mass point along the face), on an
//! edge two directions (the vertex lands on the edge), at a corner all three. The vertex is
//! clamped to its cell.
//!
//! Every grid edge whose ends have opposite signs (inside `phi < 0`, as everywhere) is shared
//! by four cells; their four vertices form a quad, split along its shorter diagonal into two
//! triangles, counter-clockwise seen from outside (normals toward increasing `phi`). Edges on
//! the outermost grid layer (fewer than four cells) add no quad: the surface is open there, as
//! with marching cubes. The mesh is watertight; unlike our marching cubes it is not
//! guaranteed to be edge-manifold (a cell face with four cut edges gives one mesh edge four
//! triangles), which the surface cost and the renderer accept.
//!
//! The vertices are not on grid edges: [`Surface::vertex_edges`] is empty, and
//! [`Surface::embedded_in`] gives each vertex the trilinear field of its simulation cell.

use super::{contourable, Surface};
use crate::sdf::trilinear_gradient;
use crate::v3::sym_eigen;
use crate::v3::{dot, sub};
use crate::SdfGrid;
use std::collections::HashMap;

/// Eigenvalues of the QEF matrix below this fraction of the largest are dropped.
const TRUNCATE: f64 = 0.1;

/// The QEF vertex of one cell from its crossings `(p_i, n_i)` (module docs), clamped to the
/// box `[lo, lo + h]^3`.
pub(crate) fn qef_vertex(crossings: &[([f64; 3], [f64; 3])], lo: [f64; 3], h: f64) -> [f64; 3] {
    let m = crossings.len().max(1) as f64;
    let mut c = [0.0; 3];
    for (p, _) in crossings {
        for d in 0..3 {
            c[d] += p[d] / m;
        }
    }
    let mut a = [[0.0; 3]; 3];
    // r = sum n (n . (p - c)) = b - A c
    let mut r = [0.0; 3];
    for (p, n) in crossings {
        let off: f64 = (0..3).map(|d| n[d] * (p[d] - c[d])).sum();
        for i in 0..3 {
            r[i] += n[i] * off;
            for j in 0..3 {
                a[i][j] += n[i] * n[j];
            }
        }
    }
    let (lambda, v) = sym_eigen(a);
    let top = lambda.iter().fold(0.0f64, |m, &l| m.max(l.abs()));
    let mut x = c;
    for k in 0..3 {
        if top == 0.0 || lambda[k] < TRUNCATE * top {
            continue;
        }
        let coef: f64 = (0..3).map(|d| v[d][k] * r[d]).sum::<f64>() / lambda[k];
        for d in 0..3 {
            x[d] += coef * v[d][k];
        }
    }
    std::array::from_fn(|d| x[d].clamp(lo[d], lo[d] + h))
}

/// The zero level set of `sdf` by dual contouring (module docs), counter-clockwise seen from
/// outside. Vertices carry no grid edge ([`Surface::vertex_edges`] is empty); each is embedded
/// in its own cell of `sdf`'s grid ([`Surface::vertex_nodes`]; re-embed with
/// [`Surface::embedded_in`] for a simulation grid whose empty nodes must not move it).
/// Returns an empty surface when the grid has fewer than two nodes along some axis.
pub fn dual_contour(sdf: &SdfGrid) -> Surface {
    let mut surface = Surface::default();
    if !contourable(sdf) {
        return surface;
    }
    let [nx, ny, nz] = sdf.dims;
    let h = sdf.spacing;
    let o = sdf.origin;
    let node = |i: usize, j: usize, k: usize| i + nx * (j + ny * k);
    let inside = |v: f64| v < 0.0;
    // cell (first node's linear index) -> vertex id
    let mut cell_vertex: HashMap<usize, u32> = HashMap::new();
    let mut crossings: Vec<([f64; 3], [f64; 3])> = Vec::with_capacity(12);
    for k in 0..nz - 1 {
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let corner_ijk = |c: usize| [i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1)];
                let f: [f64; 8] = std::array::from_fn(|c| {
                    let [a, b, d] = corner_ijk(c);
                    sdf.values[node(a, b, d)]
                });
                let n_in = f.iter().filter(|&&v| inside(v)).count();
                if n_in == 0 || n_in == 8 {
                    continue;
                }
                let lo = [0, 1, 2].map(|d| o[d] + h * [i, j, k][d] as f64);
                crossings.clear();
                for c in 0..8 {
                    for axis in 0..3 {
                        if c >> axis & 1 == 1 {
                            continue;
                        }
                        let e = c | 1 << axis;
                        if inside(f[c]) == inside(f[e]) {
                            continue;
                        }
                        let t = f[c] / (f[c] - f[e]);
                        let t = if t.is_finite() { t.clamp(0.0, 1.0) } else { 0.5 };
                        // unit-cube coordinates of the crossing
                        let xi: [f64; 3] =
                            std::array::from_fn(|d| if d == axis { t } else { (c >> d & 1) as f64 });
                        let g = flattest_gradient(sdf, [i, j, k], c, axis, t);
                        let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
                        let n = if len > 0.0 { g.map(|x| x / len) } else { [0.0; 3] };
                        let p = std::array::from_fn(|d| lo[d] + h * xi[d]);
                        crossings.push((p, n));
                    }
                }
                let x = qef_vertex(&crossings, lo, h);
                cell_vertex.insert(node(i, j, k), surface.mesh.vertices.len() as u32);
                surface.mesh.vertices.push(x);
                // inside its cell, so inside the grid
                let own = super::embed(sdf, x, |_| true).expect("a vertex lies in its cell");
                surface.vertex_nodes.push(own);
            }
        }
    }
    // one quad per cut grid edge with four cells around it
    let dims = [nx, ny, nz];
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let a = [i, j, k];
                for axis in 0..3 {
                    if a[axis] + 1 >= dims[axis] {
                        continue;
                    }
                    let (u, w) = ((axis + 1) % 3, (axis + 2) % 3);
                    if a[u] == 0 || a[w] == 0 || a[u] + 1 >= dims[u] || a[w] + 1 >= dims[w] {
                        continue;
                    }
                    let mut b = a;
                    b[axis] += 1;
                    let (fa, fb) = (
                        sdf.values[node(a[0], a[1], a[2])],
                        sdf.values[node(b[0], b[1], b[2])],
                    );
                    if inside(fa) == inside(fb) {
                        continue;
                    }
                    // the cells around the edge, counter-clockwise seen from +axis (u x w = axis)
                    let quad: [u32; 4] = [(1, 1), (0, 1), (0, 0), (1, 0)].map(|(du, dw)| {
                        let mut c = a;
                        c[u] -= du;
                        c[w] -= dw;
                        cell_vertex[&node(c[0], c[1], c[2])]
                    });
                    // outward = toward increasing phi: +axis when the edge's first node is inside
                    let quad = if inside(fa) {
                        quad
                    } else {
                        [quad[3], quad[2], quad[1], quad[0]]
                    };
                    push_quad(&surface.mesh.vertices, quad, &mut surface.mesh.faces);
                }
            }
        }
    }
    surface
}

/// The corner values of cell `c` (first node), `None` when it is not a cell of the grid.
fn cell_values(sdf: &SdfGrid, c: [i64; 3]) -> Option<[f64; 8]> {
    let inside = (0..3).all(|d| c[d] >= 0 && c[d] + 1 < sdf.dims[d] as i64);
    inside.then(|| sdf.corners(c.map(|x| x as usize)))
}

/// How far the trilinear interpolant of corner values `f` is from a linear function: the sum
/// of the magnitudes of its bilinear and trilinear coefficients.
fn nonlinearity(f: &[f64; 8]) -> f64 {
    let cxy = f[0] - f[1] - f[2] + f[3];
    let cxz = f[0] - f[1] - f[4] + f[5];
    let cyz = f[0] - f[2] - f[4] + f[6];
    let cxyz = -f[0] + f[1] + f[2] + f[4] - f[3] - f[5] - f[6] + f[7];
    cxy.abs() + cxz.abs() + cyz.abs() + cxyz.abs()
}

/// The surface normal (unnormalised) at the crossing at fraction `t` along the grid edge from
/// corner `corner` of cell `cell` along `axis`: the gradient of the trilinear interpolant of
/// the flattest of the (up to four) cells around that edge. Near a sharp edge or corner the
/// sampled distance field bends inside the cells that hold the feature, and their gradient
/// blends the faces' normals; a neighbour on the face's side is linear and gives the face's
/// normal exactly. On a smooth surface all four are nearly linear and nearly agree.
fn flattest_gradient(sdf: &SdfGrid, cell: [usize; 3], corner: usize, axis: usize, t: f64) -> [f64; 3] {
    let a: [i64; 3] = std::array::from_fn(|d| (cell[d] + (corner >> d & 1)) as i64);
    let (u, w) = ((axis + 1) % 3, (axis + 2) % 3);
    let mut best: Option<(f64, [f64; 3])> = None;
    for (du, dw) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
        let mut c = a;
        c[u] -= du;
        c[w] -= dw;
        let Some(f) = cell_values(sdf, c) else { continue };
        let xi: [f64; 3] = std::array::from_fn(|d| if d == axis { t } else { (a[d] - c[d]) as f64 });
        let bend = nonlinearity(&f);
        if best.as_ref().map_or(true, |(b, _)| bend < *b) {
            best = Some((bend, trilinear_gradient(&f, xi)));
        }
    }
    best.map_or([0.0; 3], |(_, g)| g)
}

/// Splits the quad `q` (counter-clockwise) along its shorter diagonal.
fn push_quad(x: &[[f64; 3]], q: [u32; 4], faces: &mut Vec<[u32; 3]>) {
    let d2 = |a: u32, b: u32| {
        let e = sub(x[a as usize], x[b as usize]);
        dot(e, e)
    };
    if d2(q[0], q[2]) <= d2(q[1], q[3]) {
        faces.push([q[0], q[1], q[2]]);
        faces.push([q[0], q[2], q[3]]);
    } else {
        faces.push([q[0], q[1], q[3]]);
        faces.push([q[1], q[2], q[3]]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_qef_finds_a_corner_an_edge_and_a_face() {
        let lo = [0.0; 3];
        // the corner (0.3, 0.4, 0.6) of three axis planes, seen through crossings on each
        let corner = [0.3, 0.4, 0.6];
        let mut cr = Vec::new();
        for d in 0..3 {
            let mut n = [0.0; 3];
            n[d] = 1.0;
            for s in [0.1, 0.9] {
                let mut p = [s, 1.0 - s, 0.5];
                p[d] = corner[d];
                cr.push((p, n));
            }
        }
        let x = qef_vertex(&cr, lo, 1.0);
        for d in 0..3 {
            assert!((x[d] - corner[d]).abs() < 1e-12, "{x:?}");
        }
        // an edge: only the x and y planes; z stays at the mass point
        let x = qef_vertex(&cr[..4], lo, 1.0);
        let cz = cr[..4].iter().map(|(p, _)| p[2]).sum::<f64>() / 4.0;
        assert!((x[0] - 0.3).abs() < 1e-12 && (x[1] - 0.4).abs() < 1e-12 && (x[2] - cz).abs() < 1e-12);
        // a tilted plane: the vertex lies on it
        let n = [0.6, 0.0, 0.8];
        let cr: Vec<_> = [[0.5, 0.1, 0.2], [0.1, 0.7, 0.5], [0.9, 0.9, -0.1]]
            .map(|p| (p, n))
            .to_vec();
        let x = qef_vertex(&cr, [-1.0; 3], 3.0);
        let off = |p: [f64; 3]| n[0] * p[0] + n[2] * p[2];
        assert!((off(x) - off(cr[0].0)).abs() < 1e-12);
    }

    #[test]
    fn a_standalone_surface_moves_with_a_linear_field_exactly() {
        let sdf = SdfGrid::from_fn([-0.5, -0.5, -0.5], 0.1, [11, 11, 11], |p| {
            (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 0.31
        });
        let s = dual_contour(&sdf);
        assert!(!s.mesh.faces.is_empty());
        assert_eq!(s.vertex_nodes.len(), s.mesh.vertices.len());
        let node = |n: usize| {
            let [nx, ny, _] = sdf.dims;
            let ijk = [n % nx, (n / nx) % ny, n / (nx * ny)];
            [0, 1, 2].map(|d| sdf.origin[d] + sdf.spacing * ijk[d] as f64)
        };
        let lin = |x: [f64; 3]| [0.2 * x[1] + 0.01, -0.1 * x[0], 0.3 * x[2]];
        let moved = s.deformed(|n| lin(node(n)));
        for (p, x) in moved.vertices.iter().zip(&s.mesh.vertices) {
            for d in 0..3 {
                assert!((p[d] - x[d] - lin(*x)[d]).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn jacobi_diagonalises_a_symmetric_matrix() {
        let a = [[4.0, 1.0, -2.0], [1.0, 2.0, 0.5], [-2.0, 0.5, 3.0]];
        let (l, v) = sym_eigen(a);
        for k in 0..3 {
            for i in 0..3 {
                let av: f64 = (0..3).map(|j| a[i][j] * v[j][k]).sum();
                assert!((av - l[k] * v[i][k]).abs() < 1e-12);
            }
        }
    }
}
