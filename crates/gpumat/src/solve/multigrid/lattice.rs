//! Trilinear prolongations of a regular lattice (geometric coarsening).
//!
//! The coarse lattice keeps every second node in each axis: coarse node `(I, J, K)` sits at
//! fine node `(2I, 2J, 2K)`, so a lattice of `d` nodes along an axis has `d / 2 + 1` coarse
//! nodes there. Along one axis a fine node `i` takes weight 1 from coarse node `i / 2` when
//! `i` is even and 1/2 from each of `(i - 1) / 2` and `(i + 1) / 2` when odd; the 3D weights
//! are the products (1, 1/2, 1/4 or 1/8, from 1, 2, 4 or 8 coarse nodes): trilinear
//! interpolation, exact for fields linear in the coordinates (rigid motions included). Only
//! the active fine nodes are rows; the coarse unknowns are the coarse nodes with a nonzero
//! weight on some active fine node, numbered in increasing lattice order.

use super::MultigridParams;
use crate::sparse::SparseMatrix;

/// The prolongations `P_0, P_1, ...` of the lattice hierarchy: `P_l` maps the unknowns of
/// level `l + 1` to those of level `l`; level 0 has one unknown per entry of `nodes`, the
/// lattice index `i + dims[0] (j + dims[1] k)` of each (distinct, in any order). Coarsening
/// stops once a level has at most `params.max_coarse` unknowns, after
/// `params.max_levels - 1` prolongations, or when a level would keep more than 90% of the
/// unknowns of the one before.
///
/// ```
/// use gpumat::solve::{lattice_prolongations, MultigridParams};
/// // a line of 5 nodes: coarse nodes at 0, 2, 4
/// let p = lattice_prolongations([5, 1, 1], &[0, 1, 2, 3, 4], &MultigridParams { max_coarse: 3, ..Default::default() });
/// assert_eq!((p.len(), p[0].rows(), p[0].cols()), (1, 5, 3));
/// assert_eq!((p[0].get(1, 0, 0), p[0].get(1, 1, 0), p[0].get(2, 1, 0)), (0.5, 0.5, 1.0));
/// ```
#[track_caller]
pub fn lattice_prolongations(
    dims: [usize; 3],
    nodes: &[usize],
    params: &MultigridParams,
) -> Vec<SparseMatrix<f64>> {
    let total = dims[0] * dims[1] * dims[2];
    assert!(
        nodes.iter().all(|&n| n < total),
        "gpumat::lattice_prolongations: a node outside the {dims:?} lattice"
    );
    let mut out = Vec::new();
    let mut dims = dims;
    let mut nodes = nodes.to_vec();
    while nodes.len() > params.max_coarse && out.len() + 1 < params.max_levels.max(1) {
        let (p, cdims, cnodes) = coarsen(dims, &nodes);
        if cnodes.len() * 10 > nodes.len() * 9 {
            break;
        }
        out.push(p);
        dims = cdims;
        nodes = cnodes;
    }
    out
}

/// The coarse nodes and weights of fine index `i` along one axis.
fn axis_weights(i: usize) -> ([(usize, f64); 2], usize) {
    if i % 2 == 0 {
        ([(i / 2, 1.0), (0, 0.0)], 1)
    } else {
        ([(i / 2, 0.5), (i / 2 + 1, 0.5)], 2)
    }
}

/// One coarsening: the prolongation, the coarse lattice's dims and its active nodes.
fn coarsen(dims: [usize; 3], nodes: &[usize]) -> (SparseMatrix<f64>, [usize; 3], Vec<usize>) {
    let cdims = dims.map(|d| d / 2 + 1);
    let split = |n: usize| [n % dims[0], (n / dims[0]) % dims[1], n / (dims[0] * dims[1])];
    let cindex = |c: [usize; 3]| c[0] + cdims[0] * (c[1] + cdims[1] * c[2]);
    // every (fine row, coarse lattice node, weight)
    let mut entries = Vec::with_capacity(nodes.len() * 4);
    for (row, &n) in nodes.iter().enumerate() {
        let ijk = split(n);
        let [(wx, nx), (wy, ny), (wz, nz)] = ijk.map(axis_weights);
        for &(cz, fz) in &wz[..nz] {
            for &(cy, fy) in &wy[..ny] {
                for &(cx, fx) in &wx[..nx] {
                    entries.push((row, cindex([cx, cy, cz]), fx * fy * fz));
                }
            }
        }
    }
    let mut coarse_of = vec![u32::MAX; cdims[0] * cdims[1] * cdims[2]];
    for &(_, c, _) in &entries {
        coarse_of[c] = 0;
    }
    let mut cnodes = Vec::new();
    for (c, slot) in coarse_of.iter_mut().enumerate() {
        if *slot != u32::MAX {
            *slot = cnodes.len() as u32;
            cnodes.push(c);
        }
    }
    let trip: Vec<(usize, usize, f64)> = entries
        .into_iter()
        .map(|(r, c, w)| (r, coarse_of[c] as usize, w))
        .collect();
    (
        SparseMatrix::from_triplets(nodes.len(), cnodes.len(), &trip),
        cdims,
        cnodes,
    )
}
