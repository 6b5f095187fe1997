//! Exact point-to-triangle distance and a bounding volume hierarchy for nearest-triangle queries.
//!
//! # Closest point on a triangle (Ericson, *Real-Time Collision Detection*, 5.1.5)
//!
//! For `p` and triangle `(a, b, c)` with `ab = b - a`, `ac = c - a`, the closest point is found
//! by testing the Voronoi regions of the vertices, then of the edges, then the face, using only
//! dot products:
//!
//! * vertex `a` if `ab.ap <= 0` and `ac.ap <= 0` (likewise for `b` and `c`);
//! * edge `ab` if `vc = d1 d4 - d3 d2 <= 0`, `d1 >= 0`, `d3 <= 0`, giving `a + ab d1 / (d1 - d3)`
//!   (with `d1 = ab.ap`, `d2 = ac.ap`, `d3 = ab.bp`, `d4 = ac.bp`; likewise for `ac`, `bc`);
//! * otherwise the face point with barycentrics `(va, vb, vc) / (va + vb + vc)`.
//!
//! Degenerate (zero-area) triangles fall back to the closest of their three edges.
//!
//! # BVH
//!
//! Triangles are sorted into a binary tree of axis-aligned boxes (median split of centroids on
//! the longest axis, leaves of at most [`LEAF_SIZE`] triangles). A query keeps the best squared
//! distance found so far, visits the nearer child first and skips boxes farther than it, so it
//! returns the exact minimum over all triangles.

/// Maximum number of triangles in a BVH leaf.
pub const LEAF_SIZE: usize = 4;

pub(crate) use crate::v3::{add, cross, dot, norm, scale, sub, V3};

/// Closest point to `p` on the segment `[a, b]`.
pub fn closest_point_on_segment(p: V3, a: V3, b: V3) -> V3 {
    let ab = sub(b, a);
    let len2 = dot(ab, ab);
    if len2 <= 0.0 {
        return a;
    }
    let t = (dot(sub(p, a), ab) / len2).clamp(0.0, 1.0);
    add(a, scale(ab, t))
}

/// Closest point to `p` on the (filled) triangle `(a, b, c)`, by Ericson's Voronoi-region
/// method (see the module docs). Exact up to round-off; degenerate triangles are handled.
pub fn closest_point_on_triangle(p: V3, a: V3, b: V3, c: V3) -> V3 {
    let ab = sub(b, a);
    let ac = sub(c, a);
    let ap = sub(p, a);
    let d1 = dot(ab, ap);
    let d2 = dot(ac, ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = sub(p, b);
    let d3 = dot(ab, bp);
    let d4 = dot(ac, bp);
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return add(a, scale(ab, v));
    }
    let cp = sub(p, c);
    let d5 = dot(ab, cp);
    let d6 = dot(ac, cp);
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return add(a, scale(ac, w));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return add(b, scale(sub(c, b), w));
    }
    let sum = va + vb + vc;
    if !(sum.is_finite() && sum > 0.0) {
        // degenerate triangle: the closest of the three edges
        let cands = [
            closest_point_on_segment(p, a, b),
            closest_point_on_segment(p, b, c),
            closest_point_on_segment(p, c, a),
        ];
        let d = |q: V3| dot(sub(p, q), sub(p, q));
        return cands
            .into_iter()
            .fold(cands[0], |best, q| if d(q) < d(best) { q } else { best });
    }
    let denom = 1.0 / sum;
    let v = vb * denom;
    let w = vc * denom;
    add(a, add(scale(ab, v), scale(ac, w)))
}

/// Squared distance from `p` to triangle `t`.
#[inline]
pub(crate) fn triangle_distance2(p: V3, t: &[V3; 3]) -> f64 {
    let q = closest_point_on_triangle(p, t[0], t[1], t[2]);
    let d = sub(p, q);
    dot(d, d)
}

/// One BVH node: a box and either a range of triangles (leaf, `count > 0`) or two children at
/// `first` and `first + 1` (`count == 0`).
#[derive(Clone, Debug)]
pub(crate) struct Node {
    pub lo: V3,
    pub hi: V3,
    pub first: u32,
    pub count: u32,
}

/// A bounding volume hierarchy over a triangle soup (triangles stored in tree order).
#[derive(Clone, Debug)]
pub(crate) struct Bvh {
    pub nodes: Vec<Node>,
    pub tris: Vec<[V3; 3]>,
}

fn tri_box(t: &[V3; 3]) -> (V3, V3) {
    let mut lo = t[0];
    let mut hi = t[0];
    for v in &t[1..] {
        for a in 0..3 {
            lo[a] = lo[a].min(v[a]);
            hi[a] = hi[a].max(v[a]);
        }
    }
    (lo, hi)
}

/// Squared distance from `p` to the box `[lo, hi]` (0 inside).
#[inline]
pub(crate) fn box_distance2(p: V3, lo: V3, hi: V3) -> f64 {
    let mut d2 = 0.0;
    for a in 0..3 {
        let d = (lo[a] - p[a]).max(p[a] - hi[a]).max(0.0);
        d2 += d * d;
    }
    d2
}

impl Bvh {
    /// Builds the tree over `tris` (non-empty).
    pub fn new(tris: Vec<[V3; 3]>) -> Bvh {
        let centroids: Vec<V3> = tris
            .iter()
            .map(|t| scale(add(add(t[0], t[1]), t[2]), 1.0 / 3.0))
            .collect();
        let mut order: Vec<u32> = (0..tris.len() as u32).collect();
        let mut nodes = vec![Node {
            lo: [0.0; 3],
            hi: [0.0; 3],
            first: 0,
            count: 0,
        }];
        // explicit stack of (node, start, end)
        let mut stack = vec![(0usize, 0usize, tris.len())];
        while let Some((n, start, end)) = stack.pop() {
            let (mut lo, mut hi) = tri_box(&tris[order[start] as usize]);
            let (mut clo, mut chi) = (centroids[order[start] as usize], centroids[order[start] as usize]);
            for &t in &order[start..end] {
                let (l, h) = tri_box(&tris[t as usize]);
                let c = centroids[t as usize];
                for a in 0..3 {
                    lo[a] = lo[a].min(l[a]);
                    hi[a] = hi[a].max(h[a]);
                    clo[a] = clo[a].min(c[a]);
                    chi[a] = chi[a].max(c[a]);
                }
            }
            nodes[n].lo = lo;
            nodes[n].hi = hi;
            let ext = sub(chi, clo);
            let axis = if ext[0] >= ext[1] && ext[0] >= ext[2] {
                0
            } else if ext[1] >= ext[2] {
                1
            } else {
                2
            };
            if end - start <= LEAF_SIZE || ext[axis] <= 0.0 {
                nodes[n].first = start as u32;
                nodes[n].count = (end - start) as u32;
                continue;
            }
            let mid = start + (end - start) / 2;
            order[start..end].select_nth_unstable_by(mid - start, |&x, &y| {
                centroids[x as usize][axis].total_cmp(&centroids[y as usize][axis])
            });
            let child = nodes.len();
            nodes[n].first = child as u32;
            nodes[n].count = 0;
            let empty = Node {
                lo: [0.0; 3],
                hi: [0.0; 3],
                first: 0,
                count: 0,
            };
            nodes.push(empty.clone());
            nodes.push(empty);
            stack.push((child, start, mid));
            stack.push((child + 1, mid, end));
        }
        let tris = order.iter().map(|&t| tris[t as usize]).collect();
        Bvh { nodes, tris }
    }

    /// Smallest squared distance from `p` to a triangle if it is below `bound2`, else `None`.
    pub fn nearest2(&self, p: V3, bound2: f64) -> Option<f64> {
        let mut best = bound2;
        let mut found = false;
        let mut stack: Vec<(u32, f64)> = Vec::with_capacity(64);
        stack.push((0, box_distance2(p, self.nodes[0].lo, self.nodes[0].hi)));
        while let Some((n, d2)) = stack.pop() {
            if d2 >= best {
                continue;
            }
            let node = &self.nodes[n as usize];
            if node.count > 0 {
                let s = node.first as usize;
                for t in &self.tris[s..s + node.count as usize] {
                    let d = triangle_distance2(p, t);
                    if d < best {
                        best = d;
                        found = true;
                    }
                }
            } else {
                let (l, r) = (node.first, node.first + 1);
                let dl = box_distance2(p, self.nodes[l as usize].lo, self.nodes[l as usize].hi);
                let dr = box_distance2(p, self.nodes[r as usize].lo, self.nodes[r as usize].hi);
                // push the farther child first so that the nearer one is visited first
                if dl < dr {
                    stack.push((r, dr));
                    stack.push((l, dl));
                } else {
                    stack.push((l, dl));
                    stack.push((r, dr));
                }
            }
        }
        found.then_some(best)
    }
}
