//! Shaded pictures of meshes: vertices projected by the [`Camera`] (beyond the pictures' near
//! plane, 1e-3 of the eye-target distance), triangles drawn by the one z-buffer
//! ([`super::raster::rasterize`]), colours and normals interpolated with its
//! perspective-correct weights, two-sided Lambert shading from the camera's headlight plus
//! ambient light, an optional checkerboard ground (seen through each pixel's
//! [`ray`](super::CameraFrame::ray)), supersampling.

use super::raster::{rasterize, ScreenVertex};
use super::{cross, dot, normalize, sub, viridis, Camera, Coloring, Image, RenderItem, RenderOptions};
use crate::TriMesh;

/// Per-vertex colour source of a prepared mesh.
enum VertexColor<'a> {
    Uniform([f64; 3]),
    /// RGB in [0, 1] per vertex (missing entries grey)
    Rgb(&'a [[f64; 3]]),
    /// normalized scalar in [0, 1] or NaN
    Scalar(Vec<f64>),
}

/// Grey of vertices without a colour of their own.
const GREY: [f64; 3] = [0.6; 3];

impl VertexColor<'_> {
    fn new<'a>(coloring: &Coloring<'a>, nv: usize) -> VertexColor<'a> {
        match *coloring {
            Coloring::Uniform(c) => VertexColor::Uniform(c.map(|x| x as f64 / 255.0)),
            Coloring::PerVertex(c) => VertexColor::Rgb(c),
            Coloring::Scalar { values, range } => {
                let (lo, hi) = range.unwrap_or_else(|| {
                    values
                        .iter()
                        .filter(|v| v.is_finite())
                        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
                            (lo.min(v), hi.max(v))
                        })
                });
                let span = if hi > lo { hi - lo } else { 1.0 };
                let t = (0..nv).map(|v| match values.get(v) {
                    Some(&x) if x.is_finite() => ((x - lo) / span).clamp(0.0, 1.0),
                    _ => f64::NAN,
                });
                VertexColor::Scalar(t.collect())
            }
        }
    }

    /// The colour at weights `wt` of the corners `f`.
    fn at(&self, f: [usize; 3], wt: [f64; 3]) -> [f64; 3] {
        match self {
            VertexColor::Uniform(c) => *c,
            VertexColor::Rgb(c) => {
                let cs = f.map(|i| *c.get(i).unwrap_or(&GREY));
                [0, 1, 2].map(|d| wt[0] * cs[0][d] + wt[1] * cs[1][d] + wt[2] * cs[2][d])
            }
            VertexColor::Scalar(t) => {
                let tv = wt[0] * t[f[0]] + wt[1] * t[f[1]] + wt[2] * t[f[2]];
                viridis(tv).map(|c| c as f64 / 255.0)
            }
        }
    }
}

/// Area-weighted vertex normals (faces with out-of-range indices are left out).
pub fn vertex_normals(mesh: &TriMesh) -> Vec<[f64; 3]> {
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

/// Renders `items` into a `width` x `height` image seen by `camera`. Faces with out-of-range
/// vertex indices are skipped, colourings of the wrong length drawn grey, rather than
/// panicking.
pub fn render(
    items: &[RenderItem],
    camera: &Camera,
    width: usize,
    height: usize,
    options: &RenderOptions,
) -> Image {
    render_with_depth(items, camera, width, height, options).0
}

/// [`render`], also returning the depth seen through each output pixel (the nearest of its
/// supersamples; infinite where neither a mesh nor the ground is seen), row-major.
pub fn render_with_depth(
    items: &[RenderItem],
    camera: &Camera,
    width: usize,
    height: usize,
    options: &RenderOptions,
) -> (Image, Vec<f64>) {
    let s = options.supersample.clamp(1, 8);
    let (w, h) = (width * s, height * s);
    let fr = camera.frame(w, h);
    let near = camera.picture_near();
    let bg = options.background.map(|c| c as f64 / 255.0);
    let mut color = vec![bg; w * h];
    let mut depth = vec![f64::INFINITY; w * h];
    let light = camera.headlight();
    let ambient = options.ambient.clamp(0.0, 1.0);

    for item in items {
        let mesh = item.mesh;
        let nv = mesh.vertices.len();
        let vcolor = VertexColor::new(&item.coloring, nv);
        let normals = if options.smooth {
            vertex_normals(mesh)
        } else {
            Vec::new()
        };
        let proj: Vec<ScreenVertex> = mesh
            .vertices
            .iter()
            .map(|&p| fr.project_beyond(p, near).map(|q| ([q[0], q[1]], q[2])))
            .collect();
        let face_normal = |f: [usize; 3]| {
            let [a, b, c] = f.map(|i| mesh.vertices[i]);
            normalize(cross(sub(b, a), sub(c, a)))
        };
        rasterize(&proj, &mesh.faces, w, h, &mut depth, |fi, pix, wt| {
            let f = mesh.faces[fi].map(|v| v as usize);
            let n = if options.smooth {
                let ns = f.map(|i| normals[i]);
                normalize([0, 1, 2].map(|d| wt[0] * ns[0][d] + wt[1] * ns[1][d] + wt[2] * ns[2][d]))
            } else {
                face_normal(f)
            };
            let shade = ambient + (1.0 - ambient) * dot(n, light).abs();
            color[pix] = vcolor.at(f, wt).map(|c| (c * shade).clamp(0.0, 1.0));
        });
    }

    if let Some(g) = options.ground {
        let cell = if g.cell > 0.0 { g.cell } else { 1.0 };
        let extent = if g.extent > 0.0 { g.extent } else { f64::INFINITY };
        for y in 0..h {
            for x in 0..w {
                let dir = fr.ray(x as f64 + 0.5, y as f64 + 0.5);
                if dir[1].abs() < 1e-12 {
                    continue;
                }
                // dir has unit depth, so the ray parameter is the depth
                let t = (g.height - fr.eye[1]) / dir[1];
                let pix = x + w * y;
                if t <= near || t >= depth[pix] {
                    continue;
                }
                let q = [0, 1, 2].map(|d| fr.eye[d] + t * dir[d]);
                let checker = ((q[0] / cell).floor() + (q[2] / cell).floor()).rem_euclid(2.0) as usize;
                let c = g.colors[checker.min(1)].map(|c| c as f64 / 255.0);
                let r = ((q[0] - camera.target[0]).powi(2) + (q[2] - camera.target[2]).powi(2)).sqrt();
                let fade = (1.0 - (r / extent).powi(2)).clamp(0.0, 1.0);
                color[pix] = [0, 1, 2].map(|d| fade * c[d] + (1.0 - fade) * color[pix][d]);
                depth[pix] = t;
            }
        }
    }

    // downsample to the output size
    let mut img = Image::new(width, height, options.background);
    let mut out_depth = vec![f64::INFINITY; width * height];
    let norm = 1.0 / (s * s) as f64;
    for y in 0..height {
        for x in 0..width {
            let mut acc = [0.0; 3];
            for sy in 0..s {
                for sx in 0..s {
                    let pix = (x * s + sx) + w * (y * s + sy);
                    for d in 0..3 {
                        acc[d] += color[pix][d];
                    }
                    out_depth[x + width * y] = out_depth[x + width * y].min(depth[pix]);
                }
            }
            let c = acc.map(|a| (a * norm * 255.0).round().clamp(0.0, 255.0) as u8);
            img.set_pixel(x, y, c);
        }
    }
    (img, out_depth)
}
