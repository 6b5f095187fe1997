//! The depth rasterizer: a CPU z-buffer of a triangle mesh seen by a [`Camera`].
//!
//! Each triangle's corners are projected (see [`camera`](super::camera)) to screen points
//! `s_k = (u_k, v_k)` with depths `z_k`. A pixel centre `p` is covered when its three
//! screen-space barycentric coordinates `l_k(p) = E_k(p) / (E_0 + E_1 + E_2)` are all
//! non-negative, where `E_k` is the edge function of the edge opposite corner `k`. Under
//! perspective projection the *inverse* depth is affine in screen space, so the
//! perspective-correct depth of the triangle's plane at `p` is
//!
//! `1 / z(p) = l_0 / z_0 + l_1 / z_1 + l_2 / z_2`
//!
//! and the point unprojected from `(p, z(p))` lies exactly on the triangle. The z-buffer
//! keeps the smallest depth per pixel (ties: the first triangle in mesh order), so only the
//! parts of the surface facing the camera are seen. Triangles are not culled by
//! orientation (the mesh's winding does not matter).
//!
//! Determinism and watertightness: the edge function of a mesh edge is always evaluated
//! from its lower-numbered vertex to its higher-numbered one (negated as needed), so two
//! triangles sharing an edge see exactly opposite values and no pixel centre falls between
//! them. Triangles with a corner at or behind the near plane (`z <= 1e-6 |target - eye|`)
//! are skipped rather than clipped: the body must lie in front of the camera.

use super::camera::Camera;
use cutfem::TriMesh;

/// Relative near-plane distance (times the eye-target distance).
const NEAR: f64 = 1e-6;

/// A depth image: `depth[j * width + i]` is the depth (along the viewing axis) seen through
/// pixel `(i, j)` (row `j = 0` at the top), `f64::INFINITY` where no surface is seen.
#[derive(Clone, Debug, PartialEq)]
pub struct DepthImage {
    /// width in pixels
    pub width: usize,
    /// height in pixels
    pub height: usize,
    /// row-major depths
    pub depth: Vec<f64>,
}

impl DepthImage {
    /// Number of pixels that see the surface.
    pub fn hits(&self) -> usize {
        self.depth.iter().filter(|d| d.is_finite()).count()
    }
}

/// Edge function `(b - a) x (p - a)` (twice the signed area of `a, b, p`).
fn edge(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
}

/// Renders the depth image of `mesh` seen by `camera`.
pub fn render_depth(mesh: &TriMesh, camera: &Camera) -> DepthImage {
    let (w, h) = (camera.width, camera.height);
    let mut depth = vec![f64::INFINITY; w * h];
    let frame = camera.frame();
    let near = NEAR * {
        let d: [f64; 3] = std::array::from_fn(|a| camera.target[a] - camera.eye[a]);
        (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt().max(1e-300)
    };
    // project every vertex once
    let screen: Vec<Option<([f64; 2], f64)>> = mesh
        .vertices
        .iter()
        .map(|&p| {
            let [x, y, z] = frame.to_view(p);
            (z > near).then(|| {
                (
                    [frame.cx + frame.focal * x / z, frame.cy - frame.focal * y / z],
                    z,
                )
            })
        })
        .collect();
    for face in &mesh.faces {
        let [Some(c0), Some(c1), Some(c2)] = face.map(|v| screen[v as usize]) else {
            continue; // a corner behind the near plane
        };
        let s = [c0.0, c1.0, c2.0];
        let inv_z = [1.0 / c0.1, 1.0 / c1.1, 1.0 / c2.1];
        // edge opposite corner k runs from corner k+1 to k+2, evaluated from the lower vertex id
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
        let (Some((i0, i1)), Some((j0, j1))) = (range(0, w), range(1, h)) else {
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
                let cell = &mut depth[j * w + i];
                if z < *cell {
                    *cell = z;
                }
            }
        }
    }
    DepthImage {
        width: w,
        height: h,
        depth,
    }
}
