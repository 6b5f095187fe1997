//! Partial integrals of the trilinear basis functions over the cut part of a grid cell
//! (thesis sec. 2.5.2.3 and 4.2, eq. (4.2.2) and (4.2.3), appendix C).
//!
//! # Definitions
//!
//! A cell is the cube `[0, h]^3`. Its corners are numbered `i = 0..8` with corner `i` at
//! `h * (i & 1, (i >> 1) & 1, (i >> 2) & 1)` (x fastest; corner `i` is the thesis' node `i + 1`).
//! The trilinear basis function of corner `i` is
//!
//! ```text
//! N_i(x) = prod over axes a of ( x_a / h  if bit a of i is set,  else 1 - x_a / h ),
//! ```
//!
//! so that `sum_i N_i = 1` and `sum_i N_i(x) v_i = x` (v_i the corner positions).
//! With `phi[i]` the SDF at the corners (negative inside), `Omega_e` is the inside part of the
//! cell and `Gamma_e` the part of the zero level set inside it (the object's surface, *not* the
//! cell faces). The thesis' weights are
//!
//! ```text
//! w_v(e, i) = integral over Omega_e of N_i dx   (eq. 4.2.2)   -> CellIntegrals::volume[i]
//! w_b(e, i) = integral over Gamma_e of N_i ds   (eq. 4.2.3)   -> CellIntegrals::boundary[i]
//! ```
//!
//! so that `int_{Omega_e} f dx = sum_i f(v_i) w_v(e, i)` for any trilinearly interpolated `f`,
//! and likewise on `Gamma_e`.
//!
//! # Method: Kuhn tetrahedra and exact quadrature
//!
//! The thesis (appendix C) evaluates `w_v` with case-by-case analytic integrals over a
//! piecewise planar approximation of the surface (with a sampling fallback for rare cases) and
//! `w_b` over marching-cubes triangles. Here instead the cell is split into the 6 Kuhn
//! (Freudenthal) tetrahedra around the main diagonal 0–7: for every ordering `(a, b, c)` of the
//! axes, the tetrahedron `0, e_a, e_a + e_b, 7`. On each face of the cube the split uses the
//! diagonal from the face's lowest to its highest corner, so neighbouring cells' splits match
//! and the reconstructed surface is watertight across cells. In each tetrahedron the SDF is
//! replaced by the linear interpolant of its 4 corner values; the inside part is clipped by the
//! resulting plane (a tetrahedron or a triangular prism, split into at most 3 tetrahedra) and the
//! surface piece is a triangle or a planar quadrilateral (2 triangles).
//!
//! Each `N_i` is a polynomial of total degree 3, integrated *exactly* on every piece:
//!
//! * tetrahedra: the positive degree-3 rule with 4 points at barycentric `(5/8, 1/8, 1/8, 1/8)`
//!   (weight `4/25` each) and the 4 face centroids `(1/3, 1/3, 1/3, 0)` (weight `9/100` each),
//!   derived from the symmetric moment equations;
//! * triangles: the positive 6-point degree-4 rule of Dunavant (1985).
//!
//! The result is therefore exact (to rounding) whenever the zero level set is planar inside the
//! cell, i.e. whenever the corner values come from an affine function (the trilinear and
//! the piecewise linear interpolants then agree). The integration domain is the zero set of the
//! piecewise linear (not the trilinear) interpolant of the corner values; the two differ by
//! `O(h^2)`, the order of the error of interpolating the SDF linearly at all (the thesis'
//! piecewise planar integrals likewise approximate the trilinear surface, appendix C). For
//! curved surfaces this is a second-order approximation, and a biased one: the linear
//! interpolant of a convex SDF lies above it, so the surface lies inside the true one and the
//! volume is too low (sphere r = 0.5 at 10 cells per unit: -2.0 %, torus R = 0.5, r = 0.2:
//! -4.2 %). Hence the refinement below, used by [`grid_integrals`] and the FEM grid.
//!
//! # Refinement: the SDF from the neighbouring nodes
//!
//! [`cell_integrals`] sees only the 8 corner values. [`refined_cell_integrals`] (a grid-level
//! function, the same weights `w_v`, `w_b` of eq. (4.2.2), (4.2.3) for the cell's own `N_i`)
//! also reads the neighbours: for a cut cell `(i, j, k)` (some but not all corners inside)
//!
//! 1. *stencil*: the 4x4x4 node values `i - 1 ..= i + 2` (and likewise in y, z); nodes beyond the
//!    grid border are extrapolated linearly from the two nearest nodes on their grid line
//!    (along x, then y, then z);
//! 2. *interpolant*: the tensor-product Catmull-Rom spline of the stencil (tricubic, `C^1`
//!    across cells, error `O(h^3)`, exact for affine functions and per axis for quadratics),
//!    evaluated at the `(s + 1)^3` sub-nodes `h (m_x, m_y, m_z) / s`, `s` = [`SUBDIVISIONS`] = 3;
//!    where the grid keeps the exact distance it was sampled from ([`crate::SdfGrid::exact`]:
//!    analytic shapes), the sub-nodes take its values instead, on a finer sub-grid
//!    ([`EXACT_SUBDIVISIONS`] = 6), so that edges and corners stay sharp to a sub-cell (the spline rounds a box's edge over about a cell; a clamp box that
//!    ends at the box's end face then holds only 56-84% of that face at 20 cells per unit, all
//!    of it but a sub-cell rim with the exact values: `docs/simulation.md`, "Element");
//! 3. *limiter*: each sub-node value is clamped to the range of the snapped corner values of
//!    the smallest part of the cell holding it (a corner keeps its value; a sub-node on an edge
//!    stays between the edge's 2 corner values, on a face within its 4, inside within all 8),
//!    so the cubic cannot ring at kinks of the SDF (on a box whose faces lie on grid nodes,
//!    ringing at the edges would lose about a third of the box's area at 20 cells per unit);
//! 4. *sub-cells*: the sub-node values are snapped with `SNAP_REL * h / s` and each of the
//!    `s^3` sub-cells is clipped and integrated exactly as above (6 Kuhn tetrahedra, linear
//!    interpolant of the sub-cell's corner values, the degree-3 and degree-4 rules), but for the
//!    *parent* cell's basis functions `N_i` at the mapped quadrature points: `N_i` is a
//!    polynomial of degree 3 on every piece, so the rules stay exact. Sub-cells entirely inside
//!    add `int N_i` over the sub-cube in closed form. The normal is the area-weighted mean of
//!    the sub-cells' surface normals.
//!
//! Properties:
//!
//! * *exact for planes*: a cell whose raw stencil is affine to rounding (`1e-12 h + 1e-13
//!   max |phi|`) returns exactly [`cell_integrals`] of its corners (the refinement would agree
//!   to rounding: Catmull-Rom reproduces affine functions and the limiter is then inactive);
//! * *watertight*: on a cell face the weights across the face are exactly `0` and `1`, so the
//!   interpolant there is a bicubic of the 4x4 node values in the face's plane (the
//!   extrapolated ones included, computed from nodes in that plane), contracted in the same
//!   order from both sides, and the limiter uses the face's corners: the sub-node values on a
//!   shared face are bitwise identical from both cells, the sub-cells' Kuhn splits match, and
//!   the refined surface is closed across refined cells. By the limiter, a face whose 4 corners
//!   are all inside (all outside) stays entirely inside (outside), so the refined surface never
//!   enters a face shared with a full or an inactive cell. Next to a cut cell that is not refined it
//!   meets the linear surface within the affine tolerance (affine stencils); a cell whose
//!   stencil fails the Lipschitz test below keeps the linear surface;
//! * *the same active cells*: activity is still decided by the corner signs ([`cell_active`],
//!   [`node_inside`]); cells with all corners inside stay full and cells with none inside stay
//!   empty, so a cap of the body poking into a cell between its corners is missed as before.
//!   The sub-node values at the corners are the snapped corner values, so a cut cell keeps a
//!   positive inside volume (a degenerate result would fall back to the linear one);
//! * *robust*: a cell is refined only if neighbouring stencil values differ by at most
//!   `LIPSCHITZ_MAX * h` ([`LIPSCHITZ_MAX`] = 4; a true SDF: `<= h`), so far-field sentinels, NaN or
//!   infinite values make the cell fall back to [`cell_integrals`] of its corners;
//! * *accuracy*: still second order (the surface is linear on the sub-cells), with about
//!   `1 / s^2` of the error: at 10 cells per unit -0.23 % (sphere) and -0.41 % (torus) volume,
//!   -0.12 % and -0.08 % area; the cell normals of the sphere deviate from the radial direction
//!   by at most 1.2° at 20 cells per unit (linear: 3.7°). See `docs/cutcell-convergence.md`;
//! * *cost*: about `s^3` sub-cell clips per cut cell; [`grid_integrals`] of the sphere at 40
//!   cells per unit (74 088 cells, 7 552 cut) takes about 35-55 ms instead of 7-9 ms on 2 cores;
//! * *deterministic*: each cell is computed on its own in a fixed order.
//!
//! This refinement goes beyond the thesis, whose weights (sec. 4.2, appendix C) integrate
//! over the piecewise planar surface of the corner values only.
//!
//! # Snapping and the tie rule
//!
//! Corner values with `|phi| < SNAP_REL * h` (`1e-5 h`) are snapped to exactly `0` before
//! anything else, so that the surface never passes within `1e-5 h` of a corner without passing
//! through it; this avoids ill-conditioned sliver pieces and nearly empty cells. A corner value
//! of `0` then counts as **outside** (as if it were `+0`, infinitesimally positive):
//!
//! * a corner is *inside* iff its snapped value is `< 0` ([`node_inside`]); a cell is *active*
//!   iff one of its corners is inside ([`cell_active`]); a cell whose snapped corner values are
//!   all `>= 0` has all-zero integrals;
//! * a surface lying exactly on grid nodes is counted once, by the cells on its inside: e.g.
//!   for `phi = z - k h` the face `z = k h` belongs to the cell below (whose corners are `< 0`
//!   and `0`), not to the cell above (corners `0` and `> 0`, hence inactive). A zero-thickness
//!   sheet of zeros with inside values on *both* sides (impossible for a true SDF) would be
//!   counted twice.
//!
//! NaN corner values count as outside, as `+inf`; infinities are clamped to `±f64::MAX / 4`
//! (so a `+inf` or NaN corner makes the interpolant positive almost everywhere in the
//! tetrahedra touching it; every Kuhn tetrahedron touches corners 0 and 7).

mod boxed;
mod quadrature;
mod refine;

pub use boxed::refined_surface_in_box;
pub(crate) use quadrature::add_box_moments;
use quadrature::{add_tet, TRI_RULE};

pub use refine::{
    refined_cell_integrals, refined_cell_integrals_with, refined_sub_values, subdivisions,
    EXACT_SUBDIVISIONS, LIPSCHITZ_MAX, MAX_SUBDIVISIONS, SUBDIVISIONS,
};

use crate::v3::{cross, dot, norm, sub};
use crate::SdfGrid;
use rayon::prelude::*;

/// Snapping tolerance relative to the cell size: corner values with `|phi| < SNAP_REL * h`
/// are replaced by `0` (which counts as outside).
pub const SNAP_REL: f64 = 1e-5;

/// The 6 Kuhn tetrahedra of a cell (corner indices): for each ordering `(a, b, c)` of the axes,
/// the path `0 -> e_a -> e_a + e_b -> 7` along cube edges.
pub const KUHN_TETS: [[usize; 4]; 6] = [
    [0, 1, 3, 7],
    [0, 1, 5, 7],
    [0, 2, 3, 7],
    [0, 2, 6, 7],
    [0, 4, 5, 7],
    [0, 4, 6, 7],
];

/// Magnitude to which infinite (and NaN, as `+`) corner values are clamped.
const BIG: f64 = f64::MAX / 4.0;

/// The integrals of one cell (thesis sec. 4.2 and 4.3.2).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CellIntegrals {
    /// `w_v(e, i)`: integral of `N_i` over the inside part of the cell (eq. 4.2.2), world units
    /// (`h^3`); the sum over `i` is the inside volume.
    pub volume: [f64; 8],
    /// `w_b(e, i)`: integral of `N_i` over the surface (zero level set) inside the cell
    /// (eq. 4.2.3), world units (`h^2`); the sum over `i` is the surface area in the cell.
    pub boundary: [f64; 8],
    /// Area-weighted average of the unit outward surface normal (direction of increasing
    /// `phi`), normalised to unit length; `[0, 0, 0]` if the cell holds no surface.
    pub normal: [f64; 3],
    /// Inside volume divided by `h^3`, in `[0, 1]`.
    pub volume_fraction: f64,
    /// Surface area in the cell (sum of `boundary`), world units.
    pub area: f64,
    /// The moments of the inside part on the unit cube, `int xi^a eta^b zeta^c` over the
    /// inside part mapped to `[0, 1]^3` (dimensionless; world moments scale with `h^3`), at
    /// index [`moment_index`]`(a, b, c)` for `a, b, c` in `0..=2`, all exact to rounding (like
    /// `volume`): degree <= 5 by the degree-5 rule, the degree-6 `(2, 2, 2)` (read only by the
    /// consistent mass, `int N_i N_j`) by a degree-7 rule ([`quadrature`]).
    pub moments: [f64; 27],
}

/// The index of the moment `xi^a eta^b zeta^c` in [`CellIntegrals::moments`].
pub const fn moment_index(a: usize, b: usize, c: usize) -> usize {
    a + 3 * b + 9 * c
}

impl CellIntegrals {
    /// The integrals of a cell entirely inside: `volume[i] = h^3 / 8`, no surface.
    pub fn full(h: f64) -> Self {
        let mut moments = [0.0; 27];
        add_box_moments([0.0; 3], 1.0, &mut moments);
        CellIntegrals {
            volume: [h * h * h / 8.0; 8],
            volume_fraction: 1.0,
            moments,
            ..Default::default()
        }
    }

    /// The inside volume (sum of `volume`), world units.
    pub fn inside_volume(&self) -> f64 {
        self.volume.iter().sum()
    }
}

/// A corner value after snapping (see the module docs): `0` if `|phi| < SNAP_REL * h`,
/// `f64::MAX / 4` for NaN, clamped to `±f64::MAX / 4` (infinities), otherwise `phi`.
pub fn snap_value(phi: f64, h: f64) -> f64 {
    if phi.is_nan() {
        BIG
    } else if phi.abs() < SNAP_REL * h {
        0.0
    } else {
        phi.clamp(-BIG, BIG)
    }
}

/// Snaps the 8 corner values of a cell (see [`snap_value`]).
pub fn snap(phi: &[f64; 8], h: f64) -> [f64; 8] {
    phi.map(|p| snap_value(p, h))
}

/// Whether a node with SDF value `phi` is inside under the snapping and tie rule
/// (`snap_value(phi, h) < 0`, i.e. `phi <= -SNAP_REL * h`). Use this for active nodes so that
/// they agree with the cells' integrals.
pub fn node_inside(phi: f64, h: f64) -> bool {
    snap_value(phi, h) < 0.0
}

/// Whether a cell with corner values `phi` is active (at least one corner [`node_inside`]).
/// Inactive cells have all-zero integrals.
pub fn cell_active(phi: &[f64; 8], h: f64) -> bool {
    phi.iter().any(|&p| node_inside(p, h))
}

/// The integrals `w_v`, `w_b` (eq. 4.2.2, 4.2.3) and the mean surface normal of the cell
/// `[0, h]^3` with corner SDF values `phi` (corner `i` at `h * (i & 1, (i >> 1) & 1, i >> 2)`,
/// negative inside). See the module docs for the method, the snapping and the tie rule. This
/// is the linear method (exact for planar interfaces); on a grid, [`refined_cell_integrals`]
/// also uses the neighbouring nodes and is about `s^2 = 9` times more accurate on curved ones.
///
/// # Panics
/// If `h` is not positive and finite.
pub fn cell_integrals(phi: &[f64; 8], h: f64) -> CellIntegrals {
    cell_integrals_in(phi, h, None)
}

/// [`cell_integrals`] with the surface integrals restricted to the box `clip` (unit-cube
/// coordinates) when set.
fn cell_integrals_in(phi: &[f64; 8], h: f64, clip: Option<[P3; 2]>) -> CellIntegrals {
    cell_integrals_into(
        phi,
        h,
        Accum {
            clip,
            ..Default::default()
        },
    )
    .0
}

/// [`cell_integrals_in`] accumulating into `acc` (its clip box and point recording), with the
/// recorded surface points scaled to world area.
fn cell_integrals_into(phi: &[f64; 8], h: f64, mut acc: Accum) -> (CellIntegrals, Vec<SurfacePoint>) {
    assert!(
        h > 0.0 && h.is_finite(),
        "cell size h must be positive and finite, got {h}"
    );
    let p = snap(phi, h);
    let n_in = p.iter().filter(|&&v| v < 0.0).count();
    if n_in == 0 {
        return (CellIntegrals::default(), Vec::new());
    }
    if n_in == 8 {
        return (CellIntegrals::full(h), Vec::new());
    }
    // Integrate on the unit cube, then scale.
    let pos = std::array::from_fn(corner);
    for tet in &KUHN_TETS {
        clip_tet(tet, &p, &pos, &mut acc);
    }
    (acc.finish(h), acc.take_points(h))
}

/// Number of cells along x, y, z of a grid (`dims - 1`, or 0).
pub fn cell_dims(sdf: &SdfGrid) -> [usize; 3] {
    sdf.dims.map(|n| n.saturating_sub(1))
}

/// The 8 corner SDF values of cell `(i, j, k)` (the cell between nodes `(i, j, k)` and
/// `(i + 1, j + 1, k + 1)`), in the corner order of [`cell_integrals`].
///
/// # Panics
/// If the cell is outside the grid.
pub fn cell_corner_values(sdf: &SdfGrid, cell: [usize; 3]) -> [f64; 8] {
    let [nx, ny, _] = sdf.dims;
    let [i, j, k] = cell;
    std::array::from_fn(|c| {
        let (di, dj, dk) = (c & 1, (c >> 1) & 1, (c >> 2) & 1);
        sdf.values[(i + di) + nx * ((j + dj) + ny * (k + dk))]
    })
}

/// The integrals of every cell of the grid with the refined method
/// ([`refined_cell_integrals`]), computed in parallel: entry
/// `i + (nx - 1) * (j + (ny - 1) * k)` holds `Some` integrals for an active cell
/// ([`cell_active`]: a corner value `<= -SNAP_REL * h`) and `None` otherwise.
///
/// # Panics
/// If `sdf.values.len()` is not the product of `sdf.dims`, or the spacing is not positive.
pub fn grid_integrals(sdf: &SdfGrid) -> Vec<Option<CellIntegrals>> {
    let n_nodes: usize = sdf.dims.iter().product();
    assert_eq!(
        sdf.values.len(),
        n_nodes,
        "SdfGrid: values has {} entries but dims {:?} need {n_nodes}",
        sdf.values.len(),
        sdf.dims
    );
    let h = sdf.spacing;
    let [cx, cy, cz] = cell_dims(sdf);
    (0..cx * cy * cz)
        .into_par_iter()
        .map(|c| {
            let cell = [c % cx, (c / cx) % cy, c / (cx * cy)];
            let phi = cell_corner_values(sdf, cell);
            cell_active(&phi, h).then(|| refined_cell_integrals(sdf, cell))
        })
        .collect()
}

/// Total inside volume of the cells returned by [`grid_integrals`].
pub fn total_volume(cells: &[Option<CellIntegrals>]) -> f64 {
    cells.iter().flatten().map(CellIntegrals::inside_volume).sum()
}

/// Total surface area of the cells returned by [`grid_integrals`].
pub fn total_area(cells: &[Option<CellIntegrals>]) -> f64 {
    cells.iter().flatten().map(|c| c.area).sum()
}

// ---------------------------------------------------------------------------------------------
// Clipping and quadrature on the unit cube.

pub(crate) type P3 = [f64; 3];

/// A quadrature point of a cell's surface ([`refined_surface_in_box`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    /// position on the unit cube of the cell
    pub x: [f64; 3],
    /// quadrature weight, world area
    pub weight: f64,
    /// unit outward normal (direction of increasing phi) of the surface triangle
    pub normal: [f64; 3],
}

/// Running sums on the unit cube.
#[derive(Default)]
struct Accum {
    volume: [f64; 8],
    boundary: [f64; 8],
    normal: P3,
    moments: [f64; 27],
    /// when set, surface integrals only over the part inside this box (unit-cube
    /// coordinates; [`boxed`])
    clip: Option<[P3; 2]>,
    /// when set, every surface quadrature point is recorded (weights on the unit cube)
    points: Option<Vec<SurfacePoint>>,
}

impl Accum {
    /// The recorded surface points with their weights scaled to a cell of size `h`.
    fn take_points(&mut self, h: f64) -> Vec<SurfacePoint> {
        let mut p = self.points.take().unwrap_or_default();
        for q in &mut p {
            q.weight *= h * h;
        }
        p
    }

    /// Scales the unit-cube sums to a cell of size `h` and normalises the normal.
    fn finish(&self, h: f64) -> CellIntegrals {
        let h2 = h * h;
        let h3 = h2 * h;
        let volume = self.volume.map(|v| v * h3);
        let boundary = self.boundary.map(|b| b * h2);
        let len = norm(self.normal);
        let normal = if len > 0.0 {
            self.normal.map(|c| c / len)
        } else {
            [0.0; 3]
        };
        let volume_fraction = self.volume.iter().sum::<f64>().clamp(0.0, 1.0);
        let area = boundary.iter().sum();
        CellIntegrals {
            volume,
            boundary,
            normal,
            volume_fraction,
            area,
            moments: self.moments,
        }
    }
}

/// Corner `c` of the unit cube.
fn corner(c: usize) -> P3 {
    [(c & 1) as f64, ((c >> 1) & 1) as f64, ((c >> 2) & 1) as f64]
}

/// The 8 trilinear basis functions at a point of the unit cube.
fn basis(x: P3) -> [f64; 8] {
    let w = x.map(|t| [1.0 - t, t]);
    std::array::from_fn(|i| w[0][i & 1] * w[1][(i >> 1) & 1] * w[2][(i >> 2) & 1])
}

/// Adds the integrals of the `N_i` over the triangle `v` (its part inside `acc.clip`) to
/// `acc.boundary`, and its area-weighted unit normal `dir` (the direction of increasing phi) to
/// `acc.normal`.
fn add_tri(v: [P3; 3], dir: P3, acc: &mut Accum) {
    if let Some(b) = acc.clip {
        boxed::clip_triangle(v, &b, |t| add_tri_whole(t, dir, acc));
    } else {
        add_tri_whole(v, dir, acc);
    }
}

/// [`add_tri`] of the whole triangle.
fn add_tri_whole(v: [P3; 3], dir: P3, acc: &mut Accum) {
    let area = norm(cross(sub(v[1], v[0]), sub(v[2], v[0]))) / 2.0;
    if area == 0.0 {
        return;
    }
    for &(a, b, w) in &TRI_RULE {
        for d in 0..3 {
            let x: P3 = std::array::from_fn(|k| (0..3).map(|j| if j == d { a } else { b } * v[j][k]).sum());
            let n = basis(x);
            for i in 0..8 {
                acc.boundary[i] += area * w * n[i];
            }
            if let Some(p) = &mut acc.points {
                p.push(SurfacePoint {
                    x,
                    weight: area * w,
                    normal: dir,
                });
            }
        }
    }
    for k in 0..3 {
        acc.normal[k] += area * dir[k];
    }
}

/// Adds the convex triangular prism with end triangles `a` and `b` (lateral edges
/// `a[j] - b[j]`) as 3 tetrahedra, with the diagonals `a0-b1`, `a1-b2`, `a0-b2`.
fn add_prism(a: [P3; 3], b: [P3; 3], acc: &mut Accum) {
    add_tet([a[0], a[1], a[2], b[2]], acc);
    add_tet([a[0], a[1], b[1], b[2]], acc);
    add_tet([a[0], b[0], b[1], b[2]], acc);
}

/// Clips the Kuhn tetrahedron `tet` (corner indices, a path along cube edges) of the cube with
/// corner positions `pos` (an axis-aligned cube in the unit cube of the cell, corner `c` at
/// `pos[c]`; the basis functions are those of the unit cube) at the zero level of the linear
/// interpolant of the snapped values `p` and accumulates its pieces.
fn clip_tet(tet: &[usize; 4], p: &[f64; 8], pos: &[P3; 8], acc: &mut Accum) {
    let v = tet.map(|c| pos[c]);
    let f = tet.map(|c| p[c]);
    let (mut ins, mut outs) = ([0usize; 4], [0usize; 4]);
    let (mut ni, mut no) = (0, 0);
    for j in 0..4 {
        if f[j] < 0.0 {
            ins[ni] = j;
            ni += 1;
        } else {
            outs[no] = j;
            no += 1;
        }
    }
    if ni == 0 {
        return;
    }
    if ni == 4 {
        add_tet(v, acc);
        return;
    }
    // Gradient of the linear interpolant: the path steps along one axis at a time.
    let mut grad = [0.0; 3];
    for s in 0..3 {
        let axis = (tet[s] ^ tet[s + 1]).trailing_zeros() as usize;
        grad[axis] = f[s + 1] - f[s];
    }
    let g = norm(grad);
    let dir = if g > 0.0 { grad.map(|c| c / g) } else { [0.0; 3] };
    // Zero crossing on the edge from inside vertex `a` to outside vertex `b` (t in (0, 1]).
    let x = |a: usize, b: usize| -> P3 {
        let t = f[a] / (f[a] - f[b]);
        std::array::from_fn(|k| v[a][k] + t * (v[b][k] - v[a][k]))
    };
    match ni {
        1 => {
            let a = ins[0];
            let [b, c, d] = [outs[0], outs[1], outs[2]];
            let (xb, xc, xd) = (x(a, b), x(a, c), x(a, d));
            add_tet([v[a], xb, xc, xd], acc);
            add_tri([xb, xc, xd], dir, acc);
        }
        2 => {
            let [a, b] = [ins[0], ins[1]];
            let [c, d] = [outs[0], outs[1]];
            let (xac, xad, xbc, xbd) = (x(a, c), x(a, d), x(b, c), x(b, d));
            add_prism([v[a], xac, xad], [v[b], xbc, xbd], acc);
            // The quadrilateral xac, xad, xbd, xbc (cyclic order along the tet's faces).
            add_tri([xac, xad, xbd], dir, acc);
            add_tri([xac, xbd, xbc], dir, acc);
        }
        _ => {
            let [a, b, c] = [ins[0], ins[1], ins[2]];
            let d = outs[0];
            let (xa, xb, xc) = (x(a, d), x(b, d), x(c, d));
            add_prism([v[a], v[b], v[c]], [xa, xb, xc], acc);
            add_tri([xa, xb, xc], dir, acc);
        }
    }
}
