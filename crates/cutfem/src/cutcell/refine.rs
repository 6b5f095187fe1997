//! Higher-order cut-cell integrals on a grid: a tricubic interpolant of the SDF from the
//! 4x4x4 node stencil, sampled on `s^3` sub-cells, each integrated exactly (see the module docs
//! of [`crate::cutcell`], "Refinement").

use super::{
    add_box_moments, cell_corner_values, cell_integrals_into, snap, snap_value, Accum, CellIntegrals,
    SurfacePoint, P3,
};
use super::{clip_tet, KUHN_TETS};
use crate::SdfGrid;

/// Sub-cells per axis used by [`refined_cell_integrals`] (and so by
/// [`super::grid_integrals`] and the FEM grid).
pub const SUBDIVISIONS: usize = 3;

/// Sub-cells per axis where the grid keeps its exact distance ([`SdfGrid::exact`]): the
/// sub-cells' linear interpolation is then the only error, and it cuts the body's edges by a
/// chamfer of up to half a sub-cell (a twisting bar's fitted nu moved by +0.029 with 3, +0.005
/// with 6: `docs/simulation.md`, "Element").
pub const EXACT_SUBDIVISIONS: usize = 6;

/// The largest `s` [`refined_cell_integrals_with`] accepts.
pub const MAX_SUBDIVISIONS: usize = 6;

/// The sub-cells per axis of the refined integration of `sdf`: [`EXACT_SUBDIVISIONS`] where it
/// keeps its exact distance, else [`SUBDIVISIONS`].
pub fn subdivisions(sdf: &SdfGrid) -> usize {
    if sdf.exact.is_some() {
        EXACT_SUBDIVISIONS
    } else {
        SUBDIVISIONS
    }
}

/// A cell is refined only if neighbouring stencil values differ by at most this many cell
/// sizes (a true SDF: at most 1); otherwise (far-field sentinels, non-finite values, wildly
/// scaled fields) the tricubic interpolant would ring and the linear method is used.
pub const LIPSCHITZ_MAX: f64 = 4.0;

/// Node values `i - 1 ..= i + 2` (x), `j - 1 ..= j + 2` (y), `k - 1 ..= k + 2` (z) around cell
/// `(i, j, k)`, indexed `[z][y][x]`.
type Stencil = [[[f64; 4]; 4]; 4];

const N1: usize = MAX_SUBDIVISIONS + 1;

/// The Catmull-Rom weights of the nodes `-1, 0, 1, 2` at `t` in `[0, 1]`: exactly `(0, 1, 0, 0)`
/// at `t = 0` and `(0, 0, 1, 0)` at `t = 1`; they sum to 1 and reproduce linear (and quadratic)
/// functions.
fn catmull_rom(t: f64) -> [f64; 4] {
    let (t2, t3) = (t * t, t * t * t);
    [
        (-t3 + 2.0 * t2 - t) / 2.0,
        (3.0 * t3 - 5.0 * t2 + 2.0) / 2.0,
        (-3.0 * t3 + 4.0 * t2 + t) / 2.0,
        (t3 - t2) / 2.0,
    ]
}

/// The raw stencil of a cell; nodes outside the grid are extrapolated linearly from the two
/// nearest nodes on their line, first along x, then y, then z (so a value on a cell face depends
/// only on node values in the face's plane, as it must for watertightness).
fn stencil(sdf: &SdfGrid, cell: [usize; 3]) -> Stencil {
    let [nx, ny, nz] = sdf.dims;
    let n = [nx, ny, nz];
    // real[a][o]: whether offset o (node cell[a] + o - 1) is inside the grid
    let real: [[bool; 4]; 3] =
        std::array::from_fn(|a| std::array::from_fn(|o| (1..n[a] + 1).contains(&(cell[a] + o))));
    let mut f: Stencil = [[[0.0; 4]; 4]; 4];
    for c in 0..4 {
        for b in 0..4 {
            for a in 0..4 {
                if real[0][a] && real[1][b] && real[2][c] {
                    let (i, j, k) = (cell[0] + a - 1, cell[1] + b - 1, cell[2] + c - 1);
                    f[c][b][a] = sdf.values[i + nx * (j + ny * k)];
                }
            }
        }
    }
    // Extrapolate the missing ends of one line of 4.
    fn extend(real: &[bool; 4], line: &mut [f64; 4]) {
        if !real[0] {
            line[0] = 2.0 * line[1] - line[2];
        }
        if !real[3] {
            line[3] = 2.0 * line[2] - line[1];
        }
    }
    // x: rows with real y and z
    for c in (0..4).filter(|&c| real[2][c]) {
        for b in (0..4).filter(|&b| real[1][b]) {
            extend(&real[0], &mut f[c][b]);
        }
    }
    // y: all x, real z
    for c in (0..4).filter(|&c| real[2][c]) {
        for a in 0..4 {
            let mut line = [f[c][0][a], f[c][1][a], f[c][2][a], f[c][3][a]];
            extend(&real[1], &mut line);
            for b in 0..4 {
                f[c][b][a] = line[b];
            }
        }
    }
    // z: everything
    for b in 0..4 {
        for a in 0..4 {
            let mut line = [f[0][b][a], f[1][b][a], f[2][b][a], f[3][b][a]];
            extend(&real[2], &mut line);
            for c in 0..4 {
                f[c][b][a] = line[c];
            }
        }
    }
    f
}

/// Whether the stencil is an affine function to rounding (then the linear method is exact).
fn is_affine(f: &Stencil, h: f64) -> bool {
    let o = f[1][1][1];
    let g = [f[1][1][2] - o, f[1][2][1] - o, f[2][1][1] - o];
    let max_abs = f.iter().flatten().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    let tol = 1e-12 * h + 1e-13 * max_abs;
    (0..64).all(|n| {
        let (a, b, c) = (n & 3, (n >> 2) & 3, n >> 4);
        let lin = o + (a as f64 - 1.0) * g[0] + (b as f64 - 1.0) * g[1] + (c as f64 - 1.0) * g[2];
        (f[c][b][a] - lin).abs() <= tol
    })
}

/// Whether neighbouring stencil values differ by at most `LIPSCHITZ_MAX * h` (false for
/// non-finite values).
fn is_tame(f: &Stencil, h: f64) -> bool {
    let lim = LIPSCHITZ_MAX * h;
    let ok = |u: f64, v: f64| (u - v).abs() <= lim;
    (0..4).all(|c| {
        (0..4).all(|b| {
            (0..3).all(|a| {
                ok(f[c][b][a + 1], f[c][b][a])
                    && ok(f[c][a + 1][b], f[c][a][b])
                    && ok(f[a + 1][c][b], f[a][c][b])
            })
        })
    })
}

/// The sub-node values of a refined cell: `[z][y][x]`, indices `0..=s`.
type SubValues = [[[f64; N1]; N1]; N1];

/// The integrals of cell `cell` of `sdf` with the refined method and [`subdivisions`]
/// sub-cells per axis (see the module docs of [`crate::cutcell`], "Refinement"): all-zero for
/// an inactive cell, [`CellIntegrals::full`] for a cell whose corners are all inside, and
/// exactly [`cell_integrals`] of the corner values where the cell is not refined (a stencil that
/// is affine to rounding, or one that fails the [`LIPSCHITZ_MAX`] test).
///
/// # Panics
/// If the cell is outside the grid or the spacing is not positive and finite.
pub fn refined_cell_integrals(sdf: &SdfGrid, cell: [usize; 3]) -> CellIntegrals {
    refined_cell_integrals_with(sdf, cell, subdivisions(sdf))
}

/// [`refined_cell_integrals`] with `s` sub-cells per axis (`1..=MAX_SUBDIVISIONS`; `s = 1` is
/// [`cell_integrals`] of the corner values).
///
/// # Panics
/// If `s` is out of range, the cell is outside the grid or the spacing is not positive and
/// finite.
pub fn refined_cell_integrals_with(sdf: &SdfGrid, cell: [usize; 3], s: usize) -> CellIntegrals {
    refined_in(sdf, cell, s, None, false).0
}

/// [`refined_cell_integrals_with`] with the surface integrals restricted to the box `clip`
/// (unit-cube coordinates of the cell) when set, and the surface quadrature points (world
/// weights) when `points`.
pub(super) fn refined_in(
    sdf: &SdfGrid,
    cell: [usize; 3],
    s: usize,
    clip: Option<[P3; 2]>,
    points: bool,
) -> (CellIntegrals, Vec<SurfacePoint>) {
    let h = sdf.spacing;
    let phi = cell_corner_values(sdf, cell);
    let fresh = || Accum {
        clip,
        points: points.then(Vec::new),
        ..Default::default()
    };
    let Some(v) = sub_values(sdf, cell, s) else {
        return cell_integrals_into(&phi, h, fresh());
    };
    let mut acc = fresh();
    let size = 1.0 / s as f64;
    let at = |i: usize| i as f64 / s as f64;
    for iz in 0..s {
        for iy in 0..s {
            for ix in 0..s {
                let q: [f64; 8] =
                    std::array::from_fn(|c| v[iz + ((c >> 2) & 1)][iy + ((c >> 1) & 1)][ix + (c & 1)]);
                let inside = q.iter().filter(|&&x| x < 0.0).count();
                if inside == 0 {
                    continue;
                }
                if inside == 8 {
                    add_box([at(ix), at(iy), at(iz)], size, &mut acc);
                    continue;
                }
                let pos: [P3; 8] = std::array::from_fn(|c| {
                    [at(ix + (c & 1)), at(iy + ((c >> 1) & 1)), at(iz + ((c >> 2) & 1))]
                });
                for tet in &KUHN_TETS {
                    clip_tet(tet, &q, &pos, &mut acc);
                }
            }
        }
    }
    // A refined cut cell keeps an inside corner, so its volume is positive; guard anyway.
    if acc.volume.iter().sum::<f64>() <= 0.0 {
        return cell_integrals_into(&phi, h, fresh());
    }
    (acc.finish(h), acc.take_points(h))
}

/// The values of the refined SDF at the `(s + 1)^3` sub-nodes of cell `cell` (sub-node
/// `(mx, my, mz)` at `h * (cell + (mx, my, mz) / s)`, index `mx + (s + 1) * (my + (s + 1) * mz)`)
/// as used by [`refined_cell_integrals_with`]: interpolated, limited and snapped (to
/// `SNAP_REL * h / s`). `None` where the cell is not refined: inactive, all corners inside,
/// `s = 1`, an affine stencil, or a stencil failing the [`LIPSCHITZ_MAX`] test. Values on a
/// face shared by two refined cells are bitwise identical from both sides.
///
/// # Panics
/// If `s` is out of range, the cell is outside the grid or the spacing is not positive and
/// finite.
pub fn refined_sub_values(sdf: &SdfGrid, cell: [usize; 3], s: usize) -> Option<Vec<f64>> {
    let v = sub_values(sdf, cell, s)?;
    let mut out = Vec::with_capacity((s + 1).pow(3));
    for plane in &v[..=s] {
        for row in &plane[..=s] {
            out.extend_from_slice(&row[..=s]);
        }
    }
    Some(out)
}

/// [`refined_sub_values`] as an array (see there).
fn sub_values(sdf: &SdfGrid, cell: [usize; 3], s: usize) -> Option<SubValues> {
    assert!(
        (1..=MAX_SUBDIVISIONS).contains(&s),
        "subdivisions {s} not in 1..={MAX_SUBDIVISIONS}"
    );
    let h = sdf.spacing;
    assert!(
        h > 0.0 && h.is_finite(),
        "cell size h must be positive and finite, got {h}"
    );
    let p = snap(&cell_corner_values(sdf, cell), h);
    let n_in = p.iter().filter(|&&v| v < 0.0).count();
    if n_in == 0 || n_in == 8 || s == 1 {
        return None;
    }
    let raw = stencil(sdf, cell);
    if is_affine(&raw, h) || !is_tame(&raw, h) {
        return None;
    }
    let f = raw.map(|plane| plane.map(|row| row.map(|v| snap_value(v, h))));
    // 1D weights at the sub-node positions m / s
    let mut w = [[0.0; 4]; N1];
    for (m, wm) in w.iter_mut().enumerate().take(s + 1) {
        *wm = catmull_rom(m as f64 / s as f64);
    }
    // Contract x, then y, then z: a fixed order, the same for every cell, and the weights at
    // the cell's faces are exactly 0 and 1, so values on a shared face are bitwise identical
    // from both sides.
    let mut gx = [[[0.0; N1]; 4]; 4];
    for c in 0..4 {
        for b in 0..4 {
            for m in 0..=s {
                gx[c][b][m] = (0..4).fold(0.0, |acc, a| acc + w[m][a] * f[c][b][a]);
            }
        }
    }
    let mut gy = [[[0.0; N1]; N1]; 4];
    for c in 0..4 {
        for my in 0..=s {
            for mx in 0..=s {
                gy[c][my][mx] = (0..4).fold(0.0, |acc, b| acc + w[my][b] * gx[c][b][mx]);
            }
        }
    }
    let mut v: SubValues = [[[0.0; N1]; N1]; N1];
    let hs = h / s as f64;
    // The sub-node's world position from its integer index on the sub-lattice, so that a
    // sub-node on a shared face has bitwise the same position from both cells.
    let at = |a: usize, m: usize| sdf.origin[a] + h * ((cell[a] * s + m) as f64 / s as f64);
    for mz in 0..=s {
        for my in 0..=s {
            for mx in 0..=s {
                let val = match &sdf.exact {
                    Some(e) => e.at([at(0, mx), at(1, my), at(2, mz)]),
                    None => (0..4).fold(0.0, |acc, c| acc + w[mz][c] * gy[c][my][mx]),
                };
                // Limiter: clamp to the range of the corner values of the smallest parent
                // feature (corner, edge, face or the cell) holding the sub-node.
                let m = [mx, my, mz];
                let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
                for (corner, &pc) in p.iter().enumerate() {
                    let on = (0..3).all(|a| {
                        let bit = (corner >> a) & 1;
                        (m[a] != 0 || bit == 0) && (m[a] != s || bit == 1)
                    });
                    if on {
                        lo = lo.min(pc);
                        hi = hi.max(pc);
                    }
                }
                v[mz][my][mx] = snap_value(val.clamp(lo, hi), hs);
            }
        }
    }
    Some(v)
}

/// Adds the integrals of the unit-cube basis functions over the box `[lo, lo + size]^3`
/// (exact: each factor is linear, so its midpoint value times the length).
fn add_box(lo: P3, size: f64, acc: &mut Accum) {
    let mid = lo.map(|l| l + 0.5 * size);
    let vol = size * size * size;
    for i in 0..8 {
        let mut prod = vol;
        for a in 0..3 {
            prod *= if (i >> a) & 1 == 1 { mid[a] } else { 1.0 - mid[a] };
        }
        acc.volume[i] += prod;
    }
    add_box_moments(lo, size, &mut acc.moments);
}
