//! Triangles of the deformed surface binned by their bounding boxes, for the two queries of
//! the surface cost: the closest triangle to a point and the first triangle a viewing ray
//! meets near a point.
//!
//! Both queries see only the triangles registered in the `5 x 5 x 5` bins around the point's
//! bin (bins of size `b >= reach / 2`, so the block covers the reach). A triangle is
//! registered in every bin its bounding box touches, so a triangle point `q` is found through
//! `q`'s own bin. That gives two exact shortcuts, which change no result:
//!
//! - closest point: the block is scanned in shells of growing Chebyshev radius `r`; after
//!   shell `r` every triangle point closer to `p` than `d_r`, the distance from `p` to the
//!   outside of the scanned `(2r+1)^3` cube, has been seen, so the scan stops once the best
//!   distance is below `d_r` (ties still go to the lower face index: every face at the best
//!   distance lies inside the cube);
//! - ray: the first hit inside the block is wanted (a hit farther out is farther than the reach
//!   from the point, which the cost rejects anyway); a hit point `X = o + t d` lies in a bin
//!   the ray crosses, so only the bins of the block whose box the ray crosses (`t > 0`, slab
//!   test) are searched, in the order the ray enters them; once a bin is entered after the
//!   best hit so far (`t_entry > t_best`, up to a rounding slack) no later bin can hold the
//!   first hit, whose own bin the ray enters before reaching it, and the search stops.

use gpumat::Vec3;
use std::collections::HashMap;

/// A best candidate: `(key, face, barycentric)`.
pub(super) type Best = Option<(f64, usize, [f64; 3])>;

/// Faces in uniform bins of their bounding boxes; see the module docs.
pub(super) struct FaceBins {
    bins: HashMap<[i64; 3], Vec<u32>>,
    size: f64,
}

/// Chebyshev radius of the searched block around a point's bin.
const RADIUS: i64 = 2;
/// Bins along one side of the block.
const SIDE: usize = (2 * RADIUS + 1) as usize;

impl FaceBins {
    /// Bins of `size` holding the faces of the deformed vertices `x` (a face whose box spans
    /// more than 8 bins, an exploded triangle, is left out).
    pub(super) fn new(faces: &[[u32; 3]], x: &[Vec3<f64>], size: f64) -> Self {
        let mut out = Self {
            bins: HashMap::new(),
            size,
        };
        for (fi, f) in faces.iter().enumerate() {
            let [a, b, c] = f.map(|v| x[v as usize].to_array());
            let lo = out.bin(std::array::from_fn(|d| a[d].min(b[d]).min(c[d])));
            let hi = out.bin(std::array::from_fn(|d| a[d].max(b[d]).max(c[d])));
            if (0..3).any(|d| hi[d] - lo[d] > 8) {
                continue;
            }
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    for xx in lo[0]..=hi[0] {
                        out.bins.entry([xx, y, z]).or_default().push(fi as u32);
                    }
                }
            }
        }
        out
    }

    /// The bin of point `p`.
    pub(super) fn bin(&self, p: [f64; 3]) -> [i64; 3] {
        p.map(|v| (v / self.size).floor() as i64)
    }

    /// The face with the smallest distance `key(face) = (|p - q|^2, barycentric)` among the
    /// faces in the block around `p` (shell by shell; module docs).
    pub(super) fn closest(&self, p: Vec3<f64>, mut key: impl FnMut(u32) -> (f64, [f64; 3])) -> Best {
        let pa = p.to_array();
        let c = self.bin(pa);
        let mut best: Best = None;
        for r in 0..=RADIUS {
            for off in shell(r) {
                self.visit(c, off, |fi| consider(&mut best, fi, Some(key(fi))));
            }
            // the distance from p to the outside of the scanned cube
            let inside = (0..3)
                .map(|a| {
                    let lo = (c[a] - r) as f64 * self.size;
                    let hi = (c[a] + r + 1) as f64 * self.size;
                    (pa[a] - lo).min(hi - pa[a])
                })
                .fold(f64::INFINITY, f64::min);
            if let Some((d2, _, _)) = best {
                if d2 < inside * inside {
                    break;
                }
            }
        }
        best
    }

    /// The face with the smallest ray parameter `key(face) = (t, barycentric)` (`None`: no
    /// hit) among the hits `o + t d`, `t > 0`, inside the block around `p` (found through the
    /// bins of the block that the ray crosses, in the order the ray enters them; the search
    /// stops at the first bin entered after the best hit so far, see [`Self::crossed`]).
    pub(super) fn first_hit(
        &self,
        p: Vec3<f64>,
        o: Vec3<f64>,
        d: Vec3<f64>,
        mut key: impl FnMut(u32) -> Option<(f64, [f64; 3])>,
    ) -> Best {
        let c = self.bin(p.to_array());
        let mut best: Best = None;
        // a hit at t lies in its own bin, which the ray enters (grown box) before t; rounding
        // of the entry parameter is far below this slack
        let slack = |t: f64| t + 1e-6 * self.size + 1e-9 * t.abs();
        let crossed = self.crossed(c, o, d);
        for &(t0, off) in &crossed.bins[..crossed.len] {
            if best.is_some_and(|(t, _, _)| t0 > slack(t)) {
                break;
            }
            self.visit(c, off, |fi| {
                let hit = key(fi).filter(|&(t, _)| {
                    let x = self.bin((o + d * t).to_array());
                    (0..3).all(|a| (x[a] - c[a]).abs() <= RADIUS)
                });
                consider(&mut best, fi, hit)
            });
        }
        best
    }

    /// The bins `c + off` of the block that the ray `o + t d`, `t > 0`, meets (their closed
    /// boxes grown by a rounding margin), as `(entry t, off)` in increasing entry.
    ///
    /// Per axis the ray's parameters at the 6 bin planes of the block (each moved out by the
    /// margin on either side of a bin) are computed once; a bin's interval is then the slab
    /// test's `max` of entries and `min` of exits.
    fn crossed(&self, c: [i64; 3], o: Vec3<f64>, d: Vec3<f64>) -> Crossed {
        let (o, d) = (o.to_array(), d.to_array());
        let margin = 1e-9 * self.size;
        // per axis and block index: the parameter interval inside the slab, or None (parallel
        // ray outside the slab); an axis the ray is parallel to gives (-inf, inf) inside
        let mut slabs = [[None; SIDE]; 3];
        for a in 0..3 {
            for (i, slot) in slabs[a].iter_mut().enumerate() {
                let b = c[a] - RADIUS + i as i64;
                let lo = b as f64 * self.size - margin;
                let hi = (b + 1) as f64 * self.size + margin;
                *slot = if d[a] == 0.0 {
                    (lo..=hi)
                        .contains(&o[a])
                        .then_some((f64::NEG_INFINITY, f64::INFINITY))
                } else {
                    let (ta, tb) = ((lo - o[a]) / d[a], (hi - o[a]) / d[a]);
                    Some((ta.min(tb), ta.max(tb)))
                };
            }
        }
        let mut out = Crossed {
            bins: [(0.0, [0; 3]); SIDE * SIDE * SIDE],
            len: 0,
        };
        for (z, sz) in slabs[2].iter().enumerate() {
            let Some((z0, z1)) = *sz else { continue };
            for (y, sy) in slabs[1].iter().enumerate() {
                let Some((y0, y1)) = *sy else { continue };
                for (x, sx) in slabs[0].iter().enumerate() {
                    let Some((x0, x1)) = *sx else { continue };
                    let t0 = x0.max(y0).max(z0).max(0.0);
                    let t1 = x1.min(y1).min(z1);
                    if t0 <= t1 {
                        out.bins[out.len] = (t0, [x as i64 - RADIUS, y as i64 - RADIUS, z as i64 - RADIUS]);
                        out.len += 1;
                    }
                }
            }
        }
        out.bins[..out.len].sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        out
    }

    /// Calls `f` for every face in bin `c + off`.
    fn visit(&self, c: [i64; 3], off: [i64; 3], mut f: impl FnMut(u32)) {
        if let Some(list) = self.bins.get(&[c[0] + off[0], c[1] + off[1], c[2] + off[2]]) {
            list.iter().for_each(|&fi| f(fi));
        }
    }
}

/// The bins of the block a ray crosses, with their entry parameters ([`FaceBins::crossed`]).
struct Crossed {
    bins: [(f64, [i64; 3]); SIDE * SIDE * SIDE],
    len: usize,
}

/// Keeps the smaller key, ties going to the lower face index.
fn consider(best: &mut Best, fi: u32, cand: Option<(f64, [f64; 3])>) {
    let Some((k, bary)) = cand else { return };
    let better = match *best {
        None => true,
        Some((bk, bf, _)) => k < bk || (k == bk && (fi as usize) < bf),
    };
    if better {
        *best = Some((k, fi as usize, bary));
    }
}

/// The bin offsets at Chebyshev distance exactly `r`.
fn shell(r: i64) -> impl Iterator<Item = [i64; 3]> {
    (-r..=r).flat_map(move |z| {
        (-r..=r).flat_map(move |y| {
            (-r..=r)
                .map(move |x| [x, y, z])
                .filter(move |o| o.iter().map(|v| v.abs()).max() == Some(r))
        })
    })
}

#[cfg(test)]
mod tests {
    use super::super::{closest_on_triangle, ray_triangle};
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn shells_tile_the_block_once() {
        let mut all: Vec<[i64; 3]> = (0..=RADIUS).flat_map(shell).collect();
        assert_eq!(all.len(), 125);
        all.sort();
        all.dedup();
        assert_eq!(all.len(), 125);
    }

    /// Every face registered in a bin of the block around `p`, each once.
    fn block_faces(bins: &FaceBins, p: Vec3<f64>) -> Vec<u32> {
        let c = bins.bin(p.to_array());
        let mut out: Vec<u32> = (0..=RADIUS)
            .flat_map(shell)
            .flat_map(|o| {
                let b = [c[0] + o[0], c[1] + o[1], c[2] + o[2]];
                bins.bins.get(&b).cloned().unwrap_or_default()
            })
            .collect();
        out.sort();
        out.dedup();
        out
    }

    fn smallest(cands: impl Iterator<Item = (u32, Option<(f64, [f64; 3])>)>) -> Best {
        let mut best = None;
        cands.for_each(|(fi, c)| consider(&mut best, fi, c));
        best
    }

    fn v(a: [f64; 3]) -> Vec3<f64> {
        Vec3::from_array(a)
    }

    fn soup() -> impl Strategy<Value = (Vec<Vec3<f64>>, Vec<[f64; 3]>)> {
        let corner = prop::array::uniform3(-1.0..1.0_f64);
        let edge = prop::array::uniform3(-0.3..0.3_f64);
        let tri = (corner, edge.clone(), edge);
        (
            prop::collection::vec(tri, 1..60).prop_map(|ts| {
                ts.into_iter()
                    .flat_map(|(a, e, f)| {
                        let a = v(a);
                        [a, a + v(e), a + v(f)]
                    })
                    .collect()
            }),
            prop::collection::vec(prop::array::uniform3(-1.2..1.2_f64), 1..20),
        )
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]

        /// The shell scan with its early stop returns what a scan of the whole block returns.
        #[test]
        fn closest_is_the_block_minimum((x, points) in soup(), size in 0.05..0.5_f64) {
            let faces: Vec<[u32; 3]> = (0..x.len() as u32 / 3).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
            let bins = FaceBins::new(&faces, &x, size);
            for p in points.into_iter().map(v) {
                let key = |fi: u32| {
                    let [a, b, c] = faces[fi as usize].map(|i| x[i as usize]);
                    let bary = closest_on_triangle(p, a, b, c);
                    let q = a * bary[0] + b * bary[1] + c * bary[2];
                    ((p - q).dot(p - q), bary)
                };
                let brute = smallest(block_faces(&bins, p).into_iter().map(|fi| (fi, Some(key(fi)))));
                prop_assert_eq!(bins.closest(p, key), brute);
            }
        }

        /// The ray search over the crossed bins finds the first hit inside the block that a scan
        /// of every face of the block finds.
        #[test]
        fn first_hit_is_the_first_hit_in_the_block(
            (x, points) in soup(),
            size in 0.05..0.5_f64,
            eye in prop::array::uniform3(-3.0..3.0_f64),
        ) {
            let faces: Vec<[u32; 3]> = (0..x.len() as u32 / 3).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
            let bins = FaceBins::new(&faces, &x, size);
            let eye = v(eye);
            for p in points.into_iter().map(v) {
                let s = (p - eye).norm();
                prop_assume!(s > 1e-6);
                let d = (p - eye) * (1.0 / s);
                let key = |fi: u32| {
                    let [a, b, c] = faces[fi as usize].map(|i| x[i as usize]);
                    ray_triangle(eye, d, a, b, c)
                };
                let c = bins.bin(p.to_array());
                let in_block = |t: f64| {
                    let b = bins.bin((eye + d * t).to_array());
                    (0..3).all(|a| (b[a] - c[a]).abs() <= RADIUS)
                };
                let brute = smallest(block_faces(&bins, p).into_iter().map(|fi| {
                    (fi, key(fi).filter(|&(t, _)| in_block(t)))
                }));
                prop_assert_eq!(bins.first_hit(p, eye, d, key), brute);
            }
        }
    }
}
