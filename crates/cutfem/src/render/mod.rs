//! Pictures of triangle meshes: a small CPU rasterizer writing PNG files (the counterpart of
//! the thesis' OpenGL marching-cubes rendering, sec. 4.5.1).
//!
//! # What is implemented
//!
//! * [`Camera`]: a pinhole camera (eye, target, up, vertical field of view), with
//!   [`Camera::orbit`] and [`Camera::framing`] to place it around a body.
//! * [`render_mesh`] / [`render`]: z-buffered rasterization with perspective-correct
//!   interpolation, smooth (area-weighted vertex normals) or flat Lambert shading plus
//!   ambient light from a headlight just above and left of the eye, two-sided (back faces are
//!   lit like front faces), optional supersampling, an optional light checkerboard ground
//!   plane `y = height` ([`Ground`]) and per-mesh uniform colour or per-vertex scalar colouring
//!   through the [`viridis`] colour map ([`Coloring`]).
//! * [`Image`]: RGB images with PNG output (`png` crate), [`Image::tile`] for several frames
//!   side by side, and anti-aliased text in the embedded DejaVu Sans ([`font`],
//!   [`Image::draw_text`], [`Image::draw_text_up`], [`Image::label`]).
//!
//! Triangles with a vertex behind the camera's near plane are skipped (no clipping), so the
//! camera should look at the meshes from outside.

pub mod font;
mod image;
pub mod raster;
mod shade;

pub use font::{text_mask, TextMask, GLYPH_HEIGHT};
pub use image::{Image, BORDER_COLOR};
pub use shade::{render, render_with_depth, vertex_normals};

pub use crate::v3::{cross, dot, normalize, sub};
use crate::TriMesh;

/// Distance of the near plane from the eye, relative to the eye-target distance.
const NEAR: f64 = 1e-3;

/// A pinhole camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// position of the eye
    pub eye: [f64; 3],
    /// the point looked at (projected to the image centre)
    pub target: [f64; 3],
    /// the world direction that appears upward in the image (need not be orthogonal to the
    /// view direction, must not be parallel to it)
    pub up: [f64; 3],
    /// vertical field of view in degrees
    pub fov_y_degrees: f64,
}

/// The camera's orthonormal frame.
#[derive(Clone, Copy, Debug)]
struct Frame {
    eye: [f64; 3],
    right: [f64; 3],
    up: [f64; 3],
    forward: [f64; 3],
    /// focal length in pixels
    focal: f64,
    near: f64,
    cx: f64,
    cy: f64,
}

impl Camera {
    /// A camera with 40 degree vertical field of view at distance `radius` from `center`,
    /// looking at it, y up: `theta` is the azimuth in radians about +y (0 = on the +z side,
    /// pi/2 = on the +x side) and `phi` the elevation in radians above the xz-plane
    /// (|phi| < pi/2).
    pub fn orbit(center: [f64; 3], radius: f64, theta: f64, phi: f64) -> Self {
        let dir = [phi.cos() * theta.sin(), phi.sin(), phi.cos() * theta.cos()];
        Camera {
            eye: [0, 1, 2].map(|d| center[d] + radius * dir[d]),
            target: center,
            up: [0.0, 1.0, 0.0],
            fov_y_degrees: 40.0,
        }
    }

    /// An [`orbit`](Camera::orbit) camera around the box `[min, max]` at the distance where the
    /// box's bounding sphere just fits the vertical field of view (with a 5 % margin).
    pub fn framing(min: [f64; 3], max: [f64; 3], theta: f64, phi: f64) -> Self {
        let center = [0, 1, 2].map(|d| 0.5 * (min[d] + max[d]));
        let r = 0.5 * dot(sub(max, min), sub(max, min)).sqrt();
        let half = 20f64.to_radians();
        let dist = (1.05 * r / half.sin()).max(1e-9);
        Camera::orbit(center, dist, theta, phi)
    }

    /// The direction towards the headlight, just above and left of the eye (the light of
    /// every picture).
    pub fn headlight(&self) -> [f64; 3] {
        let fr = self.frame(1, 1);
        normalize([0, 1, 2].map(|d| -fr.forward[d] + 0.35 * fr.up[d] - 0.25 * fr.right[d]))
    }

    fn frame(&self, width: usize, height: usize) -> Frame {
        let view = sub(self.target, self.eye);
        let forward = normalize(view);
        let mut right = normalize(cross(forward, self.up));
        if dot(right, right) == 0.0 {
            // up parallel to the view direction: pick any perpendicular
            let alt = if forward[0].abs() < 0.9 {
                [1.0, 0.0, 0.0]
            } else {
                [0.0, 0.0, 1.0]
            };
            right = normalize(cross(forward, alt));
        }
        let up = cross(right, forward);
        let half = (0.5 * self.fov_y_degrees.clamp(1.0, 179.0)).to_radians();
        Frame {
            eye: self.eye,
            right,
            up,
            forward,
            focal: 0.5 * height as f64 / half.tan(),
            near: NEAR * dot(view, view).sqrt().max(1e-12),
            cx: 0.5 * width as f64,
            cy: 0.5 * height as f64,
        }
    }

    /// Projects world point `p` into a `width` x `height` image: `[x, y, depth]` with pixel
    /// coordinates (x to the right, y downward, pixel centres at half-integers) and the depth
    /// along the view direction; `None` when `p` is not in front of the near plane.
    pub fn project(&self, p: [f64; 3], width: usize, height: usize) -> Option<[f64; 3]> {
        self.frame(width, height).project(p)
    }
}

impl Frame {
    fn project(&self, p: [f64; 3]) -> Option<[f64; 3]> {
        let d = sub(p, self.eye);
        let z = dot(d, self.forward);
        if z <= self.near {
            return None;
        }
        let x = dot(d, self.right);
        let y = dot(d, self.up);
        Some([self.cx + self.focal * x / z, self.cy - self.focal * y / z, z])
    }

    /// The (unnormalized, unit depth) direction of the ray through pixel position `(px, py)`.
    fn ray(&self, px: f64, py: f64) -> [f64; 3] {
        let (x, y) = ((px - self.cx) / self.focal, (self.cy - py) / self.focal);
        [0, 1, 2].map(|d| self.forward[d] + x * self.right[d] + y * self.up[d])
    }
}

/// How a mesh is coloured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Coloring<'a> {
    /// one base colour for the whole mesh
    Uniform([u8; 3]),
    /// one RGB colour per vertex, components in `[0, 1]`, interpolated across the faces;
    /// vertices without an entry are grey
    PerVertex(&'a [[f64; 3]]),
    /// one scalar per vertex mapped through [`viridis`]; `range` is the `(low, high)` mapped to
    /// the ends of the map (values outside are clamped), by default the finite values'
    /// min and max. Non-finite values are drawn grey.
    Scalar {
        /// per-vertex values (`len` = vertex count)
        values: &'a [f64],
        /// the values mapped to 0 and 1
        range: Option<(f64, f64)>,
    },
}

/// One mesh to draw and how to colour it.
#[derive(Clone, Copy, Debug)]
pub struct RenderItem<'a> {
    /// the mesh
    pub mesh: &'a TriMesh,
    /// its colouring
    pub coloring: Coloring<'a>,
}

/// A checkerboard ground plane `y = height`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ground {
    /// height of the plane
    pub height: f64,
    /// edge length of a checker square (world units)
    pub cell: f64,
    /// horizontal distance from the camera target beyond which the plane fades into the
    /// background (world units)
    pub extent: f64,
    /// the two checker colours
    pub colors: [[u8; 3]; 2],
}

impl Default for Ground {
    fn default() -> Self {
        Ground {
            height: 0.0,
            cell: 0.5,
            extent: 5.0,
            colors: [[236, 236, 236], [206, 206, 206]],
        }
    }
}

/// Options of [`render`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderOptions {
    /// background colour
    pub background: [u8; 3],
    /// ambient light fraction in `[0, 1]`; the rest is Lambert from the headlight
    pub ambient: f64,
    /// interpolate vertex normals (true) or shade each triangle flat (false)
    pub smooth: bool,
    /// a ground plane, when wanted
    pub ground: Option<Ground>,
    /// supersampling factor per axis (1 = none; 2..4 smooth the edges)
    pub supersample: usize,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            background: [255, 255, 255],
            ambient: 0.25,
            smooth: true,
            ground: None,
            supersample: 1,
        }
    }
}

/// A viridis-like colour map: `t` in `[0, 1]` (clamped; NaN gives grey) from dark purple
/// through blue and green to yellow, piecewise linear through nine samples of matplotlib's
/// viridis.
pub fn viridis(t: f64) -> [u8; 3] {
    const MAP: [[f64; 3]; 9] = [
        [68.0, 1.0, 84.0],
        [71.0, 44.0, 122.0],
        [59.0, 81.0, 139.0],
        [44.0, 113.0, 142.0],
        [33.0, 144.0, 141.0],
        [39.0, 173.0, 129.0],
        [92.0, 200.0, 99.0],
        [170.0, 220.0, 50.0],
        [253.0, 231.0, 37.0],
    ];
    if t.is_nan() {
        return [128, 128, 128];
    }
    let s = t.clamp(0.0, 1.0) * 8.0;
    let i = (s.floor() as usize).min(7);
    let f = s - i as f64;
    [0, 1, 2].map(|d| (MAP[i][d] + f * (MAP[i + 1][d] - MAP[i][d])).round() as u8)
}

/// Renders `meshes`, each in one base colour, with the default [`RenderOptions`] (white
/// background, smooth shading, no ground, no supersampling).
pub fn render_mesh(meshes: &[(&TriMesh, [u8; 3])], camera: &Camera, width: usize, height: usize) -> Image {
    let items: Vec<RenderItem> = meshes
        .iter()
        .map(|&(mesh, c)| RenderItem {
            mesh,
            coloring: Coloring::Uniform(c),
        })
        .collect();
    render(&items, camera, width, height, &RenderOptions::default())
}

/// The axis-aligned bounding box `(min, max)` of all vertices of `meshes`; `None` when they
/// have no vertices.
pub fn bounds(meshes: &[&TriMesh]) -> Option<([f64; 3], [f64; 3])> {
    let mut it = meshes.iter().flat_map(|m| m.vertices.iter());
    let first = *it.next()?;
    Some(it.fold((first, first), |(lo, hi), p| {
        (
            [0, 1, 2].map(|d| lo[d].min(p[d])),
            [0, 1, 2].map(|d| hi[d].max(p[d])),
        )
    }))
}
