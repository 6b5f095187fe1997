//! A small z-buffered triangle rasterizer with per-vertex colours (Gouraud) and two-sided
//! Lambert shading from a headlight, for the diagnosis pictures; `cutfem::render` colours a
//! mesh uniformly or through viridis only. Vertices are placed with [`Camera::project`].

use cutfem::render::{cross, dot, normalize, sub, Camera, Image};
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

/// Area-weighted vertex normals (faces with bad indices skipped).
fn vertex_normals(mesh: &TriMesh) -> Vec<[f64; 3]> {
    let nv = mesh.vertices.len();
    let mut n = vec![[0.0; 3]; nv];
    for f in mesh.faces.iter().filter(|f| f.iter().all(|&v| (v as usize) < nv)) {
        let [a, b, c] = f.map(|v| mesh.vertices[v as usize]);
        let fnrm = cross(sub(b, a), sub(c, a));
        for &v in f {
            for d in 0..3 {
                n[v as usize][d] += fnrm[d];
            }
        }
    }
    n.into_iter().map(normalize).collect()
}

/// Renders `mesh` seen by `camera` into a `width` x `height` picture on white, each vertex in
/// its colour of `colors` (`[0, 1]` RGB; missing entries grey), interpolated
/// perspective-correctly, shaded by the interpolated normal.
pub fn shaded(mesh: &TriMesh, colors: &[[f64; 3]], camera: &Camera, width: usize, height: usize) -> View {
    let (w, h) = (width * SS, height * SS);
    let mut color = vec![[1.0; 3]; w * h];
    let mut depth = vec![f64::INFINITY; w * h];
    let light = camera.headlight();
    let normals = vertex_normals(mesh);
    let nv = mesh.vertices.len();
    let proj: Vec<Option<[f64; 3]>> = mesh.vertices.iter().map(|&p| camera.project(p, w, h)).collect();
    let grey = [0.6; 3];
    for f in mesh.faces.iter().filter(|f| f.iter().all(|&v| (v as usize) < nv)) {
        let [i0, i1, i2] = f.map(|v| v as usize);
        let (Some(p0), Some(p1), Some(p2)) = (proj[i0], proj[i1], proj[i2]) else {
            continue;
        };
        let area = (p1[0] - p0[0]) * (p2[1] - p0[1]) - (p2[0] - p0[0]) * (p1[1] - p0[1]);
        if area.abs() < 1e-12 {
            continue;
        }
        let cs = [i0, i1, i2].map(|i| *colors.get(i).unwrap_or(&grey));
        let ns = [i0, i1, i2].map(|i| normals[i]);
        let xmin = p0[0].min(p1[0]).min(p2[0]).floor().max(0.0) as usize;
        let ymin = p0[1].min(p1[1]).min(p2[1]).floor().max(0.0) as usize;
        let xmax = (p0[0].max(p1[0]).max(p2[0]).ceil().max(0.0) as usize).min(w);
        let ymax = (p0[1].max(p1[1]).max(p2[1]).ceil().max(0.0) as usize).min(h);
        let iz = [1.0 / p0[2], 1.0 / p1[2], 1.0 / p2[2]];
        for y in ymin..ymax {
            let py = y as f64 + 0.5;
            for x in xmin..xmax {
                let px = x as f64 + 0.5;
                let l1 = ((px - p0[0]) * (p2[1] - p0[1]) - (p2[0] - p0[0]) * (py - p0[1])) / area;
                let l2 = ((p1[0] - p0[0]) * (py - p0[1]) - (px - p0[0]) * (p1[1] - p0[1])) / area;
                let l0 = 1.0 - l1 - l2;
                if l0 < 0.0 || l1 < 0.0 || l2 < 0.0 {
                    continue;
                }
                let z = 1.0 / (l0 * iz[0] + l1 * iz[1] + l2 * iz[2]);
                let pix = x + w * y;
                if z >= depth[pix] {
                    continue;
                }
                depth[pix] = z;
                let wt = [l0 * iz[0] * z, l1 * iz[1] * z, l2 * iz[2] * z];
                let mix = |v: &[[f64; 3]; 3]| {
                    [0, 1, 2].map(|d| wt[0] * v[0][d] + wt[1] * v[1][d] + wt[2] * v[2][d])
                };
                let shade = AMBIENT + (1.0 - AMBIENT) * dot(normalize(mix(&ns)), light).abs();
                color[pix] = mix(&cs).map(|c| (c * shade).clamp(0.0, 1.0));
            }
        }
    }
    let mut img = Image::new(width, height, [255; 3]);
    let mut out_depth = vec![f64::INFINITY; width * height];
    for y in 0..height {
        for x in 0..width {
            let mut acc = [0.0; 3];
            for (sx, sy) in (0..SS).flat_map(|sy| (0..SS).map(move |sx| (sx, sy))) {
                let pix = (x * SS + sx) + w * (y * SS + sy);
                for d in 0..3 {
                    acc[d] += color[pix][d];
                }
                out_depth[x + width * y] = out_depth[x + width * y].min(depth[pix]);
            }
            let n = (SS * SS) as f64;
            img.set_pixel(x, y, acc.map(|a| (a / n * 255.0).round().clamp(0.0, 255.0) as u8));
        }
    }
    View {
        img,
        depth: out_depth,
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
