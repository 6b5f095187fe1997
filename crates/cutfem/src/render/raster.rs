//! The one triangle rasterizer: a z-buffer over projected triangles, used for the depth
//! images of virtual cameras (`adjoint::observe`) and for every picture ([`super::render`]).
//!
//! Each triangle's corners are projected to screen points `s_k = (u_k, v_k)` (pixels, `u` to
//! the right, `v` downward, pixel centres at half-integers) with depths `z_k` along the view
//! direction. A pixel centre `p` is covered when its three screen-space barycentric
//! coordinates `l_k(p) = E_k(p) / (E_0 + E_1 + E_2)` are all non-negative, where `E_k` is
//! the edge function of the edge opposite corner `k`. Under perspective projection the
//! *inverse* depth is affine in screen space, so the depth of the triangle's plane at `p` is
//!
//! `1 / z(p) = l_0 / z_0 + l_1 / z_1 + l_2 / z_2`
//!
//! and the perspective-correct interpolation weights of a vertex quantity are
//! `w_k = l_k z(p) / z_k` (they sum to one). The z-buffer keeps the smallest depth per pixel
//! (ties: the first triangle in order). Triangles are not culled by orientation.
//!
//! Watertight and deterministic: the edge function of a mesh edge is always evaluated from
//! its lower-numbered vertex to its higher-numbered one (negated as needed), so two
//! triangles sharing an edge see exactly opposite values and no pixel centre falls between
//! them. Corners that are not projected (behind the near plane) skip their triangle; faces
//! with out-of-range vertex indices are skipped.

/// A projected vertex: screen position and depth, `None` when it is not in front of the
/// camera's near plane.
pub type ScreenVertex = Option<([f64; 2], f64)>;

/// Edge function `(b - a) x (p - a)` (twice the signed area of `a, b, p`).
fn edge(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
}

/// Rasterizes `faces` (vertex indices into `screen`) into the `width` x `height` z-buffer
/// `depth` (row-major, initialised by the caller, usually to infinity). For each covered
/// pixel centre nearer than what `depth` holds, the depth is stored and `shade(face, pixel,
/// weights)` is called with the face's index, the pixel's index `x + width * y` and the
/// perspective-correct weights of the face's three corners.
pub fn rasterize(
    screen: &[ScreenVertex],
    faces: &[[u32; 3]],
    width: usize,
    height: usize,
    depth: &mut [f64],
    mut shade: impl FnMut(usize, usize, [f64; 3]),
) {
    assert_eq!(
        depth.len(),
        width * height,
        "rasterize: depth buffer of another size"
    );
    for (fi, face) in faces.iter().enumerate() {
        let corner = |k: usize| screen.get(face[k] as usize).copied().flatten();
        let (Some(c0), Some(c1), Some(c2)) = (corner(0), corner(1), corner(2)) else {
            continue; // a corner behind the near plane, or a bad index
        };
        let s = [c0.0, c1.0, c2.0];
        let inv_z = [1.0 / c0.1, 1.0 / c1.1, 1.0 / c2.1];
        // the edge opposite corner k runs from corner k+1 to k+2, evaluated from the lower id
        let edge_fn = |k: usize, p: [f64; 2]| {
            let (a, b) = ((k + 1) % 3, (k + 2) % 3);
            if face[a] < face[b] {
                edge(s[a], s[b], p)
            } else {
                -edge(s[b], s[a], p)
            }
        };
        let area = edge(s[0], s[1], s[2]);
        if area == 0.0 || !area.is_finite() {
            continue; // seen edge-on: covers no pixel centre
        }
        let sign = area.signum();
        // indices of the pixels whose centres k + 1/2 lie in the triangle's bounding box
        let range = |a: usize, n: usize| {
            let lo = s.iter().map(|p| p[a]).fold(f64::INFINITY, f64::min);
            let hi = s.iter().map(|p| p[a]).fold(f64::NEG_INFINITY, f64::max);
            let first = (lo - 0.5).ceil().max(0.0);
            let last = (hi - 0.5).floor().min(n as f64 - 1.0);
            (first <= last).then_some((first as usize, last as usize))
        };
        let (Some((i0, i1)), Some((j0, j1))) = (range(0, width), range(1, height)) else {
            continue;
        };
        for j in j0..=j1 {
            for i in i0..=i1 {
                let p = [i as f64 + 0.5, j as f64 + 0.5];
                let e = [0, 1, 2].map(|k| sign * edge_fn(k, p));
                if e.iter().any(|&x| x < 0.0) {
                    continue;
                }
                let total = e[0] + e[1] + e[2];
                if total <= 0.0 {
                    continue;
                }
                let iz = (e[0] * inv_z[0] + e[1] * inv_z[1] + e[2] * inv_z[2]) / total;
                let z = 1.0 / iz;
                let pix = j * width + i;
                if z < depth[pix] {
                    depth[pix] = z;
                    let weights = [0, 1, 2].map(|k| e[k] * inv_z[k] / total * z);
                    shade(fi, pix, weights);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two triangles sharing the diagonal of a square cover every pixel centre once; the
    /// nearer of two overlapping squares wins; weights sum to one and interpolate depth.
    #[test]
    fn shared_edges_are_watertight_and_the_nearest_face_wins() {
        let (w, h) = (16, 12);
        let sq = |z: f64| -> Vec<ScreenVertex> {
            [[1.3, 0.7], [14.9, 1.1], [15.2, 11.6], [0.4, 10.8]]
                .iter()
                .map(|&p| Some((p, z)))
                .collect()
        };
        let mut screen = sq(2.0);
        screen.extend(sq(1.0));
        let faces = [[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]];
        let mut depth = vec![f64::INFINITY; w * h];
        let mut hits = vec![0usize; w * h];
        rasterize(&screen, &faces[..2], w, h, &mut depth, |_, pix, wt| {
            hits[pix] += 1;
            assert!((wt.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        });
        assert!(hits.iter().all(|&n| n <= 1), "a pixel centre shaded twice");
        let covered = hits.iter().filter(|&&n| n == 1).count();
        // no gap: every pixel centre inside the square (by its own edges) is covered
        let corners = [[1.3, 0.7], [14.9, 1.1], [15.2, 11.6], [0.4, 10.8]];
        for pix in 0..w * h {
            let p = [(pix % w) as f64 + 0.5, (pix / w) as f64 + 0.5];
            let inside = (0..4).all(|k| edge(corners[k], corners[(k + 1) % 4], p) > 0.0);
            assert!(
                !inside || hits[pix] == 1,
                "pixel {pix} inside the square not covered"
            );
        }
        assert!(covered > 120, "{covered}");
        // the nearer square (depth 1) replaces every covered pixel, the farther never does
        let mut winner = vec![usize::MAX; w * h];
        rasterize(&screen, &faces[2..], w, h, &mut depth, |f, pix, _| {
            winner[pix] = f
        });
        let replaced = winner.iter().filter(|&&f| f != usize::MAX).count();
        assert_eq!(replaced, covered);
        rasterize(&screen, &faces[..2], w, h, &mut depth, |_, _, _| {
            panic!("farther face drawn")
        });
        // perspective: corners at depths 1 and 3 interpolate 1/z linearly
        let tri: Vec<ScreenVertex> = vec![
            Some(([0.0, 0.0], 1.0)),
            Some(([8.0, 0.0], 3.0)),
            Some(([0.0, 8.0], 1.0)),
        ];
        let mut d = vec![f64::INFINITY; 64];
        let mut seen = Vec::new();
        rasterize(&tri, &[[0, 1, 2]], 8, 8, &mut d, |_, pix, wt| {
            seen.push((pix, wt))
        });
        assert!(seen.len() > 20);
        for (pix, wt) in seen {
            let l1 = ((pix % 8) as f64 + 0.5) / 8.0;
            let z = 1.0 / ((1.0 - l1) / 1.0 + l1 / 3.0);
            assert!((d[pix] - z).abs() < 1e-12, "pixel {pix}");
            assert!((wt[1] - l1 * z / 3.0).abs() < 1e-12);
        }
        // a corner behind the camera or a bad index skips the face
        let mut d = vec![f64::INFINITY; 64];
        let bad: Vec<ScreenVertex> = vec![None, tri[1], tri[2]];
        rasterize(&bad, &[[0, 1, 2], [1, 2, 9]], 8, 8, &mut d, |_, _, _| {
            panic!("drawn")
        });
    }
}
