//! Generalized winding numbers (Jacobson, Kavan and Sorkine-Hornung 2013), evaluated
//! hierarchically (after Barill et al. 2018, "Fast winding numbers for soups and clouds").
//!
//! # Definition
//!
//! `w(q) = (1 / 4 pi) sum_t Omega_t(q)`, where `Omega_t(q)` is the signed solid angle that
//! triangle `t = (a, b, c)` subtends at `q`. With `a, b, c` taken relative to `q`
//! (Van Oosterom and Strackee 1983):
//!
//! `tan(Omega / 2) = a.(b x c) / (|a||b||c| + (a.b)|c| + (b.c)|a| + (c.a)|b|)`,
//!
//! evaluated with `atan2` so that `Omega` lies in `(-2 pi, 2 pi)`. For a closed, outward
//! (counter-clockwise) oriented surface `w` is 1 inside and 0 outside; for a surface with holes
//! it varies smoothly across the holes, so thresholding at `1/2` closes them plausibly.
//!
//! # Hierarchical evaluation
//!
//! Each BVH node stores its area-weighted centroid `c`, its area vector `N = sum_t A_t n_t`
//! (`A_t n_t = (b - a) x (c - a) / 2`) and a radius `r` bounding the distance from `c` to its
//! triangles. When `|q - c| > beta r` the node's triangles are replaced by their first-order
//! (dipole) far field `Omega ~ N.(c - q) / |c - q|^3`; otherwise its children (or, at a leaf,
//! its triangles exactly) are visited. The far-field error of a node is `O((r / |q - c|)^2)`
//! relative to its contribution; with [`BETA`] `= 2.5` the total error is far below the `1/2`
//! threshold except within a fraction of a cell of the surface, where the distance is ~0 and
//! the sign does not matter (measured in the tests against the exact sum).

use super::distance::{add, cross, dot, norm, scale, sub, Bvh, V3};
use std::f64::consts::PI;

/// Opening criterion: a node is approximated when the query is farther than `BETA` times its
/// radius from its centroid.
pub const BETA: f64 = 2.5;

/// Signed solid angle subtended at `q` by triangle `(a, b, c)` (positive when `q` sees the
/// triangle's counter-clockwise side from behind, i.e. `q` is on the side opposite its normal),
/// in `(-2 pi, 2 pi)`.
pub fn solid_angle(q: V3, a: V3, b: V3, c: V3) -> f64 {
    let (a, b, c) = (sub(a, q), sub(b, q), sub(c, q));
    let (la, lb, lc) = (norm(a), norm(b), norm(c));
    let num = dot(a, cross(b, c));
    let den = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb;
    2.0 * num.atan2(den)
}

/// Far-field data of one BVH node.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Dipole {
    centroid: V3,
    area_vector: V3,
    radius: f64,
}

/// Per-node dipoles of a [`Bvh`], for the hierarchical winding number.
#[derive(Clone, Debug)]
pub(crate) struct WindingTree {
    dipoles: Vec<Dipole>,
}

impl WindingTree {
    /// Computes each node's dipole bottom-up (children always follow their parent in
    /// `bvh.nodes`, so a reverse sweep sees children first).
    pub fn new(bvh: &Bvh) -> WindingTree {
        let zero = Dipole {
            centroid: [0.0; 3],
            area_vector: [0.0; 3],
            radius: 0.0,
        };
        let mut dipoles = vec![zero; bvh.nodes.len()];
        // area-weighted centroid sums (before division) and total areas
        let mut moment = vec![[0.0; 3]; bvh.nodes.len()];
        let mut area = vec![0.0; bvh.nodes.len()];
        for n in (0..bvh.nodes.len()).rev() {
            let node = &bvh.nodes[n];
            let (mut m, mut a, mut nv) = ([0.0; 3], 0.0, [0.0; 3]);
            if node.count > 0 {
                let s = node.first as usize;
                for t in &bvh.tris[s..s + node.count as usize] {
                    let an = scale(cross(sub(t[1], t[0]), sub(t[2], t[0])), 0.5);
                    let ta = norm(an);
                    let c = scale(add(add(t[0], t[1]), t[2]), 1.0 / 3.0);
                    m = add(m, scale(c, ta));
                    a += ta;
                    nv = add(nv, an);
                }
            } else {
                for ch in [node.first as usize, node.first as usize + 1] {
                    m = add(m, moment[ch]);
                    a += area[ch];
                    nv = add(nv, dipoles[ch].area_vector);
                }
            }
            moment[n] = m;
            area[n] = a;
            let centroid = if a > 0.0 {
                scale(m, 1.0 / a)
            } else {
                scale(add(node.lo, node.hi), 0.5)
            };
            // farthest box corner bounds the distance to every triangle point
            let mut r2 = 0.0;
            for a in 0..3 {
                let d = (centroid[a] - node.lo[a])
                    .abs()
                    .max((node.hi[a] - centroid[a]).abs());
                r2 += d * d;
            }
            dipoles[n] = Dipole {
                centroid,
                area_vector: nv,
                radius: r2.sqrt(),
            };
        }
        WindingTree { dipoles }
    }

    /// Hierarchical generalized winding number at `q`.
    pub fn winding_number(&self, bvh: &Bvh, q: V3) -> f64 {
        let mut sum = 0.0;
        let mut stack: Vec<u32> = Vec::with_capacity(64);
        stack.push(0);
        while let Some(n) = stack.pop() {
            let d = &self.dipoles[n as usize];
            let r = sub(d.centroid, q);
            let dist2 = dot(r, r);
            if dist2 > (BETA * d.radius).powi(2) {
                sum += dot(d.area_vector, r) / (dist2 * dist2.sqrt());
                continue;
            }
            let node = &bvh.nodes[n as usize];
            if node.count > 0 {
                let s = node.first as usize;
                for t in &bvh.tris[s..s + node.count as usize] {
                    sum += solid_angle(q, t[0], t[1], t[2]);
                }
            } else {
                stack.push(node.first);
                stack.push(node.first + 1);
            }
        }
        sum / (4.0 * PI)
    }
}

/// Exact generalized winding number at `q`: the plain sum over all triangles of `tris`.
pub(crate) fn winding_number_exact(tris: &[[V3; 3]], q: V3) -> f64 {
    tris.iter().map(|t| solid_angle(q, t[0], t[1], t[2])).sum::<f64>() / (4.0 * PI)
}
