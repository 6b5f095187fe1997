//! Triangles of the deformed surface in a uniform grid of small cells, for the two queries of
//! the surface cost: the closest triangle to a point and the first triangle a viewing ray
//! meets near a point.
//!
//! A face is registered in every cell its bounding box (grown by a rounding margin) touches,
//! so a face point `q` is found through `q`'s own cell. The cells are about one triangle wide
//! (the mean largest side of the faces' boxes), so a cell holds a few faces; they are stored
//! densely (compressed rows) over the box of the faces. Faces with a non-finite vertex, or
//! whose box spans more than 8 *block bins* per axis (an exploded triangle), are left out.
//!
//! - closest point ([`FaceBins::closest`]): the cells around `p`'s cell are scanned in shells
//!   of growing Chebyshev radius `r`; after shell `r` every face point closer to `p` than
//!   `d_r`, the distance from `p` to the outside of the scanned `(2r+1)^3` cube, has been
//!   seen, so the scan stops once the best distance is below `d_r`, or once `d_r` exceeds
//!   the caller's limit (a farther face is of no use). The answer is the closest face of
//!   all, ties going to the lower face index, whenever that face lies within the limit.
//! - ray ([`FaceBins::first_hit`]): the first hit `X = o + t d`, `t > 0`, that lies in the
//!   block of `5 x 5 x 5` *block bins* (size `b >= reach / 2`, so the block covers the
//!   reach) around the point's block bin. A hit farther out is farther than the reach from
//!   the point, which the cost rejects anyway; the block keeps an occluder far from the point
//!   from hiding it. The cells the ray crosses inside the block's box are walked in the
//!   order the ray enters them (a 3D DDA); a hit point lies in (or within the margin of) the
//!   cell the walk is in at its `t`, so once a cell is entered after the best hit so far
//!   (`t_entry > t_best`, up to a rounding slack) no later cell can hold the first hit.
//!
//! Both answers equal a scan of every face (tests below), so the cell size changes speed,
//! never a result.

use gpumat::Vec3;
use std::cmp::Ordering;

/// A best candidate: `(key, face, barycentric)`.
pub(super) type Best = Option<(f64, usize, [f64; 3])>;

/// Faces in uniform cells of their bounding boxes; see the module docs.
pub(super) struct FaceBins {
    /// size of the block bins of the ray query
    size: f64,
    /// size of the search cells
    cell: f64,
    /// index of the first cell of the stored grid, and the grid's cells per axis
    lo: [i64; 3],
    dims: [i64; 3],
    /// the faces of stored cell `i` are `faces[start[i]..start[i + 1]]`, increasing
    start: Vec<u32>,
    faces: Vec<u32>,
}

/// Chebyshev radius of the ray query's block around a point's block bin.
const RADIUS: i64 = 2;

/// A face's box and the cells of it, before they are stored.
struct Boxed {
    face: u32,
    lo: [f64; 3],
    hi: [f64; 3],
}

impl FaceBins {
    /// Cells holding the faces of the deformed vertices `x`; `size` is the block bin of the ray
    /// query (module docs).
    pub(super) fn new(faces: &[[u32; 3]], x: &[Vec3<f64>], size: f64) -> Self {
        let boxed = boxed(faces, x, size);
        // cells about one face wide, but at most 64 per face on average
        let widest = |b: &Boxed| (0..3).map(|d| b.hi[d] - b.lo[d]).fold(0.0, f64::max);
        let mean = boxed.iter().map(widest).sum::<f64>() / boxed.len().max(1) as f64;
        let mut cell = if mean > 0.0 { mean.min(size) } else { size };
        let cap = (64 * boxed.len()).max(4096) as f64;
        loop {
            let out = Self::store(&boxed, size, cell, cap);
            match out {
                Some(bins) => return bins,
                None => cell *= 2.0,
            }
        }
    }

    /// The grid of cells of size `cell` over the boxes, or `None` when it would have more
    /// than `cap` cells.
    fn store(boxed: &[Boxed], size: f64, cell: f64, cap: f64) -> Option<Self> {
        let range = |b: &Boxed| -> ([i64; 3], [i64; 3]) {
            let scale = b.lo.iter().chain(&b.hi).fold(0.0_f64, |m, v| m.max(v.abs()));
            let margin = 1e-9 * cell + 1e-12 * scale;
            (
                b.lo.map(|v| ((v - margin) / cell).floor() as i64),
                b.hi.map(|v| ((v + margin) / cell).floor() as i64),
            )
        };
        let mut lo = [i64::MAX; 3];
        let mut hi = [i64::MIN; 3];
        for b in boxed {
            let (l, h) = range(b);
            for d in 0..3 {
                lo[d] = lo[d].min(l[d]);
                hi[d] = hi[d].max(h[d]);
            }
        }
        if boxed.is_empty() {
            (lo, hi) = ([0; 3], [-1; 3]);
        }
        // (in i128: faces far apart put the cell indices near the ends of i64)
        let span: [i128; 3] = std::array::from_fn(|d| (hi[d] as i128 - lo[d] as i128 + 1).max(0));
        if span.iter().map(|&n| n as f64).product::<f64>() > cap {
            return None;
        }
        let dims = span.map(|n| n as i64);
        let mut out = Self {
            size,
            cell,
            lo,
            dims,
            start: vec![0; (dims[0] * dims[1] * dims[2]) as usize + 1],
            faces: Vec::new(),
        };
        // count, then fill (compressed rows)
        for pass in 0..2 {
            let mut next = out.start.clone();
            for b in boxed {
                let (l, h) = range(b);
                for z in l[2]..=h[2] {
                    for y in l[1]..=h[1] {
                        for xx in l[0]..=h[0] {
                            let i = out.index([xx, y, z]).expect("inside the stored grid");
                            if pass == 0 {
                                out.start[i + 1] += 1;
                            } else {
                                out.faces[next[i] as usize] = b.face;
                                next[i] += 1;
                            }
                        }
                    }
                }
            }
            if pass == 0 {
                for i in 1..out.start.len() {
                    out.start[i] += out.start[i - 1];
                }
                out.faces = vec![0; *out.start.last().unwrap_or(&0) as usize];
            }
        }
        Some(out)
    }

    /// The stored index of cell `k`, `None` outside the stored grid.
    fn index(&self, k: [i64; 3]) -> Option<usize> {
        let r: [i64; 3] = std::array::from_fn(|d| k[d] - self.lo[d]);
        ((0..3).all(|d| (0..self.dims[d]).contains(&r[d])))
            .then(|| (r[0] + self.dims[0] * (r[1] + self.dims[1] * r[2])) as usize)
    }

    /// Calls `f` for every face of cell `k`.
    fn visit(&self, k: [i64; 3], mut f: impl FnMut(u32)) {
        if let Some(i) = self.index(k) {
            let (a, b) = (self.start[i] as usize, self.start[i + 1] as usize);
            self.faces[a..b].iter().for_each(|&fi| f(fi));
        }
    }

    /// The distance from `p` to the box of the stored cells (0 inside).
    fn box_distance(&self, p: [f64; 3]) -> f64 {
        (0..3)
            .map(|a| {
                let lo = self.lo[a] as f64 * self.cell;
                let hi = (self.lo[a] + self.dims[a]) as f64 * self.cell;
                (lo - p[a]).max(p[a] - hi).max(0.0)
            })
            .map(|d| d * d)
            .sum::<f64>()
            .sqrt()
    }

    /// The cell of point `p`.
    fn cell_of(&self, p: [f64; 3]) -> [i64; 3] {
        p.map(|v| (v / self.cell).floor() as i64)
    }

    /// The block bin of point `p`.
    fn block_of(&self, p: [f64; 3]) -> [i64; 3] {
        p.map(|v| (v / self.size).floor() as i64)
    }

    /// The face with the smallest distance `key(face) = (|p - q|^2, barycentric)`, searched
    /// shell by shell until no face within `limit` can be closer (module docs): the closest
    /// face of all when it lies within `limit`; otherwise some face, or none.
    pub(super) fn closest(
        &self,
        p: Vec3<f64>,
        limit: f64,
        mut key: impl FnMut(u32) -> (f64, [f64; 3]),
    ) -> Best {
        let pa = p.to_array();
        // no stored face lies within `limit` of a point farther than that from their box (this
        // also keeps the cell indices of absurdly far points out of the arithmetic below)
        if pa.iter().any(|v| !v.is_finite()) || self.faces.is_empty() || self.box_distance(pa) > limit {
            return None;
        }
        let c = self.cell_of(pa);
        let hi: [i64; 3] = std::array::from_fn(|d| self.lo[d] + self.dims[d] - 1);
        let mut best: Best = None;
        for r in 0.. {
            self.shell(c, r, |k| {
                self.visit(k, |fi| consider(&mut best, fi, Some(key(fi))))
            });
            // the distance from p to the outside of the scanned cube
            let inside = (0..3)
                .map(|a| {
                    let lo = (c[a] - r) as f64 * self.cell;
                    let hi = (c[a] + r + 1) as f64 * self.cell;
                    (pa[a] - lo).min(hi - pa[a])
                })
                .fold(f64::INFINITY, f64::min);
            let found = best.is_some_and(|(d2, _, _)| d2 < inside * inside);
            let all = (0..3).all(|a| c[a] - r <= self.lo[a] && c[a] + r >= hi[a]);
            if found || inside > limit || all {
                break;
            }
        }
        best
    }

    /// Calls `f` for the stored cells at Chebyshev distance exactly `r` from cell `c`.
    fn shell(&self, c: [i64; 3], r: i64, mut f: impl FnMut([i64; 3])) {
        let clip = |a: usize| {
            let lo = (c[a] - r).max(self.lo[a]);
            let hi = (c[a] + r).min(self.lo[a] + self.dims[a] - 1);
            lo..=hi
        };
        for z in clip(2) {
            for y in clip(1) {
                if (z - c[2]).abs() == r || (y - c[1]).abs() == r {
                    clip(0).for_each(|x| f([x, y, z]));
                } else {
                    // r > 0 here: the two end cells of the row
                    [c[0] - r, c[0] + r]
                        .into_iter()
                        .filter(|x| clip(0).contains(x))
                        .for_each(|x| f([x, y, z]));
                }
            }
        }
    }

    /// The face with the smallest ray parameter `key(face) = (t, barycentric)` (`None`: no
    /// hit) among the hits `o + t d`, `t > 0`, inside the block around `p`: the cells the ray
    /// crosses inside the block's box, walked in the order the ray enters them, until one is
    /// entered after the best hit so far (module docs).
    pub(super) fn first_hit(
        &self,
        p: Vec3<f64>,
        o: Vec3<f64>,
        d: Vec3<f64>,
        mut key: impl FnMut(u32) -> Option<(f64, [f64; 3])>,
    ) -> Best {
        let finite = |v: Vec3<f64>| v.to_array().iter().all(|x| x.is_finite());
        // a hit lies on a stored face, inside their box, and in the block, whose points lie
        // within 3 sqrt(3) < 6 block bins of p: none when p is farther than that from the box
        // (which also keeps absurdly far points out of the arithmetic below)
        let width = 6.0 * self.size;
        if self.faces.is_empty()
            || !(finite(p) && finite(o) && finite(d))
            || self.box_distance(p.to_array()) > width
        {
            return None;
        }
        let c = self.block_of(p.to_array());
        let (oa, da) = (o.to_array(), d.to_array());
        // the ray's parameters inside the block's box, grown by a rounding margin
        let margin = 1e-9 * self.size;
        let (mut t_in, mut t_out) = (0.0_f64, f64::INFINITY);
        for a in 0..3 {
            let lo = (c[a] - RADIUS) as f64 * self.size - margin;
            let hi = (c[a] + RADIUS + 1) as f64 * self.size + margin;
            if da[a] == 0.0 {
                if !(lo..=hi).contains(&oa[a]) {
                    return None;
                }
            } else {
                let (ta, tb) = ((lo - oa[a]) / da[a], (hi - oa[a]) / da[a]);
                t_in = t_in.max(ta.min(tb));
                t_out = t_out.min(ta.max(tb));
            }
        }
        // (no interval, or a NaN ray)
        if !matches!(t_in.partial_cmp(&t_out), Some(Ordering::Less | Ordering::Equal)) {
            return None;
        }
        // a hit at t lies in a cell the walk enters before t; rounding of the entry
        // parameter is far below this slack
        let slack = |t: f64| t + 1e-6 * self.cell + 1e-9 * t.abs();
        let step: [i64; 3] = std::array::from_fn(|a| match da[a] {
            v if v > 0.0 => 1,
            v if v < 0.0 => -1,
            _ => 0,
        });
        let hi: [i64; 3] = std::array::from_fn(|a| self.lo[a] + self.dims[a] - 1);
        let gone =
            |k: [i64; 3], a: usize| (k[a] > hi[a] && step[a] >= 0) || (k[a] < self.lo[a] && step[a] <= 0);
        let mut k = self.cell_of(std::array::from_fn(|a| oa[a] + t_in * da[a]));
        if (0..3).any(|a| gone(k, a)) {
            return None;
        }
        let mut best: Best = None;
        let mut t_entry = t_in;
        while t_entry <= t_out && !best.is_some_and(|(t, _, _)| t_entry > slack(t)) {
            self.visit(k, |fi| {
                let hit = key(fi).filter(|&(t, _)| {
                    let x = self.block_of((o + d * t).to_array());
                    (0..3).all(|a| (x[a] - c[a]).abs() <= RADIUS)
                });
                consider(&mut best, fi, hit)
            });
            // the next cell: across the nearest of the cell's exit planes
            let exit = (0..3)
                .filter(|&a| step[a] != 0)
                .map(|a| {
                    let plane = (k[a] + (step[a] > 0) as i64) as f64 * self.cell;
                    ((plane - oa[a]) / da[a], a)
                })
                .min_by(|x, y| x.0.total_cmp(&y.0));
            let Some((t_exit, a)) = exit else { break };
            t_entry = t_entry.max(t_exit);
            k[a] += step[a];
            if gone(k, a) {
                break;
            }
        }
        best
    }
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

/// The boxes of the faces that are stored: every vertex finite, at most 8 block bins of `size`
/// across on each axis.
fn boxed(faces: &[[u32; 3]], x: &[Vec3<f64>], size: f64) -> Vec<Boxed> {
    let block = |v: f64| (v / size).floor();
    faces
        .iter()
        .enumerate()
        .filter_map(|(fi, f)| {
            let [a, b, c] = f.map(|v| x[v as usize].to_array());
            let lo: [f64; 3] = std::array::from_fn(|d| a[d].min(b[d]).min(c[d]));
            let hi: [f64; 3] = std::array::from_fn(|d| a[d].max(b[d]).max(c[d]));
            let finite = [a, b, c].iter().flatten().all(|v| v.is_finite());
            (finite && (0..3).all(|d| block(hi[d]) - block(lo[d]) <= 8.0)).then_some(Boxed {
                face: fi as u32,
                lo,
                hi,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests;
