//! Pictures of triangle meshes: a small CPU rasterizer writing PNG files (the counterpart of
//! the thesis' OpenGL marching-cubes rendering, sec. 4.5.1).
//!
//! # What is implemented
//!
//! * [`Camera`]: the workspace's one pinhole camera (eye, target, up, vertical field of view
//!   in radians), with [`Camera::orbit`] and [`Camera::framing`] to place it around a body,
//!   and its [`CameraFrame`] for an image size (projection and unprojection, the maths in
//!   [`camera`]); the depth sensor of `adjoint::observe` is this camera plus an image size.
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

pub mod camera;
pub mod font;
mod image;
pub mod raster;
mod shade;

pub use camera::{Camera, CameraFrame, ORBIT_FOV_Y};
pub use font::{font_em_px, text_mask, TextMask, GLYPH_HEIGHT};
pub use image::{Image, BORDER_COLOR};
pub use shade::{render, render_with_depth, vertex_normals};

pub use crate::v3::{cross, dot, normalize, sub};
use crate::TriMesh;

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
