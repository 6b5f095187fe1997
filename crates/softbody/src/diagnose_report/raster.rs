//! Shaded views with per-vertex colours for the diagnosis pictures (drawn by
//! `cutfem::render`, the one rasterizer), and what is drawn over them: which points are
//! visible, discs.

use cutfem::render::{render_with_depth, Camera, Coloring, Image, RenderItem, RenderOptions};
use cutfem::TriMesh;

/// Supersampling factor per axis.
const SS: usize = 2;
/// Ambient share of the shading (high, so that the colour map stays readable).
const AMBIENT: f64 = 0.45;

/// A rendered view: the picture, its depth per pixel (infinite on the background) and the
/// camera, so that points can be drawn over it where they are visible.
pub struct View {
    /// the picture
    pub img: Image,
    depth: Vec<f64>,
    camera: Camera,
}

/// Renders `mesh` seen by `camera` into a `width` x `height` picture on white, each vertex in
/// its colour of `colors` (`[0, 1]` RGB; missing entries grey), interpolated
/// perspective-correctly, shaded by the interpolated normal.
pub fn shaded(mesh: &TriMesh, colors: &[[f64; 3]], camera: &Camera, width: usize, height: usize) -> View {
    let item = RenderItem {
        mesh,
        coloring: Coloring::PerVertex(colors),
    };
    let options = RenderOptions {
        background: [255; 3],
        ambient: AMBIENT,
        smooth: true,
        ground: None,
        supersample: SS,
    };
    let (img, depth) = render_with_depth(&[item], camera, width, height, &options);
    View {
        img,
        depth,
        camera: *camera,
    }
}

impl View {
    /// The pixel position and depth of `p` when it is in front of the near plane, inside the
    /// picture and not hidden: no surface lies more than `tolerance` (world units) in front of it.
    pub fn visible(&self, p: [f64; 3], tolerance: f64) -> Option<(f64, f64, f64)> {
        let (w, h) = (self.img.width, self.img.height);
        let q = self.camera.project(p, w, h)?;
        if !(q[0] >= 0.0 && q[1] >= 0.0 && q[0] < w as f64 && q[1] < h as f64) {
            return None;
        }
        let (x, y) = (q[0] as usize, q[1] as usize);
        (q[2] <= self.depth[x + w * y] + tolerance).then_some((q[0], q[1], q[2]))
    }

    /// A filled disc of radius `r` pixels centred at `(cx, cy)`, edge pixels blended by
    /// coverage.
    pub fn disc(&mut self, (cx, cy): (f64, f64), r: f64, color: [u8; 3]) {
        let (x0, x1) = (
            (cx - r - 1.0).floor().max(0.0) as usize,
            (cx + r + 1.0).ceil().max(0.0) as usize,
        );
        let (y0, y1) = (
            (cy - r - 1.0).floor().max(0.0) as usize,
            (cy + r + 1.0).ceil().max(0.0) as usize,
        );
        for y in y0..y1.min(self.img.height) {
            for x in x0..x1.min(self.img.width) {
                let d = (x as f64 + 0.5 - cx).hypot(y as f64 + 0.5 - cy);
                let a = (r + 0.5 - d).clamp(0.0, 1.0);
                if a > 0.0 {
                    let old = self.img.pixel(x, y);
                    let c =
                        [0, 1, 2].map(|k| (a * color[k] as f64 + (1.0 - a) * old[k] as f64).round() as u8);
                    self.img.set_pixel(x, y, c);
                }
            }
        }
    }
}
