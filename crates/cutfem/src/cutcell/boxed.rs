//! Surface integrals restricted to an axis-aligned box: the part of a cell's surface that a
//! Dirichlet box holds ([`crate::fem::sim::dirichlet_cells`]). The surface triangles of the cell
//! integration are clipped against the box's six planes (Sutherland-Hodgman; a triangle
//! clipped by a convex box is a convex polygon, integrated as a fan of triangles with the same
//! degree-4 rule), so the weights `w_b` and the mean normal are those of exactly the surface
//! inside the box, whatever the resolution.

use super::refine::{refined_in, subdivisions};
use super::{CellIntegrals, SurfacePoint, P3};
use crate::SdfGrid;

/// The box is widened by this many cells on every side before clipping, so that a face of the
/// body lying on a plane of the box (a clamp box ending at the body's end face) is held whichever
/// way the rounding of its computed position falls.
const BOUNDARY_TOL: f64 = 1e-9;

/// At most 3 + 6 vertices after clipping a triangle by six planes.
const MAX_POLY: usize = 9;

/// Calls `f` with the triangles of the part of `v` inside the box `b` (`b[0]` lower, `b[1]`
/// upper corner).
pub(super) fn clip_triangle(v: [P3; 3], b: &[P3; 2], mut f: impl FnMut([P3; 3])) {
    let mut poly = [[0.0; 3]; MAX_POLY];
    poly[..3].copy_from_slice(&v);
    let mut n = 3;
    for axis in 0..3 {
        for (side, bound) in [(1.0, b[0][axis]), (-1.0, b[1][axis])] {
            // keep side * (x[axis] - bound) >= 0
            let d = |p: &P3| side * (p[axis] - bound);
            let mut out = [[0.0; 3]; MAX_POLY];
            let mut m = 0;
            for k in 0..n {
                let (p, q) = (poly[k], poly[(k + 1) % n]);
                let (dp, dq) = (d(&p), d(&q));
                if dp >= 0.0 && m < MAX_POLY {
                    out[m] = p;
                    m += 1;
                }
                if (dp >= 0.0) != (dq >= 0.0) && m < MAX_POLY {
                    let t = dp / (dp - dq);
                    out[m] = std::array::from_fn(|c| p[c] + t * (q[c] - p[c]));
                    m += 1;
                }
            }
            poly = out;
            n = m;
            if n < 3 {
                return;
            }
        }
    }
    for k in 1..n - 1 {
        f([poly[0], poly[k], poly[k + 1]]);
    }
}

/// The surface weights `w_b`, area and mean normal of cell `cell` of `sdf` over the part of
/// its surface inside the world box `[lo, hi]` (the refined integration of
/// [`super::refined_cell_integrals`]; the volume fields are those of the whole cell), and the
/// quadrature points of that part of the surface (the degree-4 rule on each clipped triangle;
/// positions on the cell's unit cube, world weights): the Nitsche terms of the held surface
/// ([`crate::fem::NitscheFace`]). The box's boundary counts as inside ([`BOUNDARY_TOL`]).
pub fn refined_surface_in_box(
    sdf: &SdfGrid,
    cell: [usize; 3],
    lo: [f64; 3],
    hi: [f64; 3],
) -> (CellIntegrals, Vec<SurfacePoint>) {
    let h = sdf.spacing;
    let unit = |p: [f64; 3], out: f64| -> P3 {
        std::array::from_fn(|d| (p[d] - sdf.origin[d]) / h - cell[d] as f64 + out * BOUNDARY_TOL)
    };
    refined_in(
        sdf,
        cell,
        subdivisions(sdf),
        Some([unit(lo, -1.0), unit(hi, 1.0)]),
        true,
    )
}
