//! The depth rasterizer: a CPU z-buffer of a triangle mesh seen by a [`DepthCamera`].
//!
//! The vertices are projected by the camera ([`cutfem::render::camera`]) and the triangles
//! drawn by `cutfem::render::raster::rasterize`, the one z-buffer of the workspace (its
//! module documents the perspective-correct depth `1 / z = sum_k l_k / z_k`, the
//! watertight edge functions and the tie rule). Triangles with a corner at or behind the
//! near plane (`z <= 1e-6 |target - eye|`) are skipped rather than clipped: the body must lie
//! in front of the camera.

use super::camera::DepthCamera;
use cutfem::render::raster::{rasterize, ScreenVertex};
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

/// Renders the depth image of `mesh` seen by `camera`.
pub fn render_depth(mesh: &TriMesh, camera: &DepthCamera) -> DepthImage {
    let (w, h) = (camera.width, camera.height);
    let mut depth = vec![f64::INFINITY; w * h];
    let frame = camera.frame();
    let near = NEAR * camera.camera.distance().max(1e-300);
    // project every vertex once
    let screen: Vec<ScreenVertex> = mesh
        .vertices
        .iter()
        .map(|&p| frame.project_beyond(p, near).map(|q| ([q[0], q[1]], q[2])))
        .collect();
    rasterize(&screen, &mesh.faces, w, h, &mut depth, |_, _, _| {});
    DepthImage {
        width: w,
        height: h,
        depth,
    }
}
