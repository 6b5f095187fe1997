//! Signed distance fields sampled on a regular grid.
//!
//! # Grid convention
//!
//! Node `(i, j, k)` sits at `origin + h (i, j, k)` with `h = spacing`; values are stored x
//! fastest (flat index `i + nx (j + ny k)`), in world units, negative inside. A node is
//! *inside* when its value is `< 0` (a zero value counts as outside).
//!
//! # Interpolation
//!
//! Between nodes the field is the trilinear interpolant: for a point with local coordinates
//! `t = (p - origin) / h`, cell `c = floor(t)` (the last cell for points on the far face) and
//! fractions `f = t - c`,
//!
//! `phi(p) = sum_{a,b,c in {0,1}} w_a(f_x) w_b(f_y) w_c(f_z) phi[c + (a, b, c)]`,
//! `w_0(s) = 1 - s`, `w_1(s) = s`,
//!
//! and [`SdfGrid::gradient`] is the exact gradient of that interpolant (piecewise constant in
//! `f` along the differentiated axis, bilinear in the other two).
//!
//! # The exact distance beside the samples
//!
//! A grid made from an analytic shape ([`crate::Shape::to_sdf`]) also keeps the shape's exact
//! distance function ([`SdfGrid::exact`]). The refined cut-cell integrals
//! ([`crate::cutcell`], "Refinement") then read the sub-cell values from it instead of the
//! Catmull-Rom interpolant of the nodes, so that the body's edges and corners stay sharp to a
//! sub-cell (the interpolant rounds a box's edges over about a cell, and a clamp box ending at
//! the end face then misses the face's outer ring: `docs/simulation.md`, "Element"). Grids
//! read from files, resampled, padded or advected have none.
//!
//! # Files
//!
//! * the thesis `.sdf` binary ([`SdfGrid::read_sdf`], [`SdfGrid::write_sdf`]): int32
//!   resolution, `int32[3]` offset, `int32[3]` size, float32 values in voxel units; node `(i, j, k)`
//!   at `(offset + (i, j, k)) / resolution`;
//! * NumPy `.npy` ([`SdfGrid::read_npy`], [`SdfGrid::write_npy`]): a float32/float64 array of
//!   shape `(nz, ny, nx)` in C order (x fastest), values in world units.

mod npy;
mod thesis;

pub use npy::NpyDtype;

use crate::Error;
use rayon::prelude::*;

/// The largest number of grid nodes that [`SdfGrid::covering_grid`] (and so the mesh and shape
/// conversions) accepts: 64 M nodes, i.e. 512 MiB of `f64` values.
pub const MAX_NODES: usize = 1 << 26;

/// A signed distance field on a regular grid of nodes: negative inside, world units.
///
/// Node `(i, j, k)` sits at `origin + spacing * (i, j, k)`; values are stored x fastest, then
/// y, then z (index `i + nx * (j + ny * k)`).
#[derive(Clone, Debug, PartialEq)]
pub struct SdfGrid {
    /// the exact signed distance whose samples `values` are, when known (module docs, "The
    /// exact distance beside the samples")
    pub exact: Option<ExactSdf>,
    /// world position of node (0, 0, 0)
    pub origin: [f64; 3],
    /// distance between neighbouring nodes (the cell size h)
    pub spacing: f64,
    /// number of nodes along x, y, z
    pub dims: [usize; 3],
    /// SDF values in world units, x fastest
    pub values: Vec<f64>,
}

/// An exact signed distance function of world positions (negative inside), shared by the grids
/// sampled from it. Two are equal when they are the same function object.
#[derive(Clone)]
pub struct ExactSdf(pub std::sync::Arc<dyn Fn([f64; 3]) -> f64 + Send + Sync>);

impl ExactSdf {
    /// The distance at `p`.
    pub fn at(&self, p: [f64; 3]) -> f64 {
        (self.0)(p)
    }
}

impl std::fmt::Debug for ExactSdf {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("ExactSdf(..)")
    }
}

impl PartialEq for ExactSdf {
    fn eq(&self, other: &ExactSdf) -> bool {
        std::sync::Arc::ptr_eq(&self.0, &other.0)
    }
}

/// Rounds `x` to the nearest integer when it is within `1e-9` (relative) of it, so that
/// lattice computations are not thrown off by one by round-off (`0.8 * 20 = 16.000000000000004`).
fn snap(x: f64) -> f64 {
    let r = x.round();
    if (x - r).abs() <= 1e-9 * r.abs().max(1.0) {
        r
    } else {
        x
    }
}

impl SdfGrid {
    /// Builds a grid by evaluating `f` at every node position (in parallel).
    ///
    /// No validation is done; call [`SdfGrid::validate`] on the result if needed.
    pub fn from_fn(
        origin: [f64; 3],
        spacing: f64,
        dims: [usize; 3],
        f: impl Fn([f64; 3]) -> f64 + Sync,
    ) -> SdfGrid {
        let mut grid = SdfGrid {
            exact: None,
            origin,
            spacing,
            dims,
            values: Vec::new(),
        };
        let n = dims[0] * dims[1] * dims[2];
        let mut values = vec![0.0; n];
        if n > 0 {
            values.par_chunks_mut(dims[0]).enumerate().for_each(|(row, out)| {
                let (j, k) = (row % dims[1], row / dims[1]);
                for (i, v) in out.iter_mut().enumerate() {
                    *v = f(grid.node_position(i, j, k));
                }
            });
        }
        grid.values = values;
        grid
    }

    /// The origin and node counts of the grid with spacing `1 / resolution` that covers the box
    /// `[min, max]` plus `padding_cells` cells on every side, its nodes on the lattice of
    /// multiples of the spacing: along each axis the first node is
    /// `floor(min * resolution) - padding` and the last `ceil(max * resolution) + padding`
    /// (in units of the spacing), so `origin = floor(min / h - padding) * h`.
    ///
    /// Errors (never a panic) for a non-positive or non-finite resolution, a non-finite or
    /// inverted box, and grids of more than [`MAX_NODES`] nodes (checked before anything is
    /// allocated).
    pub fn covering_grid(
        min: [f64; 3],
        max: [f64; 3],
        resolution: f64,
        padding_cells: usize,
    ) -> Result<([f64; 3], [usize; 3]), Error> {
        // its inverse (the spacing) must be finite too
        if !(resolution.is_finite() && resolution > 0.0 && (1.0 / resolution).is_finite()) {
            return Err(Error::Invalid(format!(
                "body: resolution must be a positive number of cells per unit, found {resolution:?}"
            )));
        }
        if min.iter().chain(max.iter()).any(|x| !x.is_finite()) || (0..3).any(|a| min[a] > max[a]) {
            return Err(Error::Invalid(format!(
                "body: invalid bounding box {min:?} .. {max:?} (non-finite or inverted)"
            )));
        }
        let pad = padding_cells as f64;
        let mut origin = [0.0; 3];
        let mut dims = [0usize; 3];
        let mut total = 1.0f64;
        for a in 0..3 {
            let lo = snap(min[a] * resolution).floor() - pad;
            let hi = snap(max[a] * resolution).ceil() + pad;
            let n = (hi - lo + 1.0).max(2.0);
            total *= n;
            if total.is_nan() || total > MAX_NODES as f64 {
                return Err(Error::Invalid(format!(
                    "body: a grid of resolution {resolution:?} over {min:?} .. {max:?} with {padding_cells} \
                     padding cells needs more than {MAX_NODES} nodes; lower the resolution"
                )));
            }
            origin[a] = lo / resolution;
            dims[a] = n as usize;
        }
        Ok((origin, dims))
    }

    /// Total number of nodes `nx * ny * nz`.
    pub fn node_count(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2]
    }

    /// Number of cells `(nx - 1)(ny - 1)(nz - 1)` (0 for a degenerate grid).
    pub fn cell_count(&self) -> usize {
        self.dims.iter().map(|&n| n.saturating_sub(1)).product()
    }

    /// Flat index `i + nx (j + ny k)` of node `(i, j, k)` into [`SdfGrid::values`].
    #[inline]
    pub fn index(&self, i: usize, j: usize, k: usize) -> usize {
        debug_assert!(i < self.dims[0] && j < self.dims[1] && k < self.dims[2]);
        i + self.dims[0] * (j + self.dims[1] * k)
    }

    /// World position `origin + spacing (i, j, k)` of node `(i, j, k)`.
    #[inline]
    pub fn node_position(&self, i: usize, j: usize, k: usize) -> [f64; 3] {
        [
            self.origin[0] + self.spacing * i as f64,
            self.origin[1] + self.spacing * j as f64,
            self.origin[2] + self.spacing * k as f64,
        ]
    }

    /// Value at node `(i, j, k)` (panics when out of range, like slice indexing).
    #[inline]
    pub fn value(&self, i: usize, j: usize, k: usize) -> f64 {
        self.values[self.index(i, j, k)]
    }

    /// Local cell and fractions of `p`: `None` outside the grid's box (a tolerance of `1e-9`
    /// cells admits points on the boundary despite round-off) or for a degenerate grid.
    pub fn locate(&self, p: [f64; 3]) -> Option<([usize; 3], [f64; 3])> {
        let mut cell = [0usize; 3];
        let mut frac = [0.0; 3];
        for a in 0..3 {
            let n = self.dims[a];
            if n < 2 {
                return None;
            }
            let t = (p[a] - self.origin[a]) / self.spacing;
            let last = (n - 1) as f64;
            if !(t >= -1e-9 && t <= last + 1e-9) {
                return None;
            }
            let t = t.clamp(0.0, last);
            let c = (t.floor() as usize).min(n - 2);
            cell[a] = c;
            frac[a] = t - c as f64;
        }
        Some((cell, frac))
    }

    /// The 8 corner values of cell `c`, indexed `a + 2 b + 4 c` for offsets `(a, b, c)`.
    pub(crate) fn corners(&self, c: [usize; 3]) -> [f64; 8] {
        let mut v = [0.0; 8];
        for (n, out) in v.iter_mut().enumerate() {
            *out = self.value(c[0] + (n & 1), c[1] + ((n >> 1) & 1), c[2] + (n >> 2));
        }
        v
    }

    /// Trilinear interpolation of the field at `p`; `None` outside the grid's box.
    pub fn sample(&self, p: [f64; 3]) -> Option<f64> {
        let (c, f) = self.locate(p)?;
        let v = self.corners(c);
        let lerp = |a: f64, b: f64, s: f64| a + (b - a) * s;
        let x00 = lerp(v[0], v[1], f[0]);
        let x10 = lerp(v[2], v[3], f[0]);
        let x01 = lerp(v[4], v[5], f[0]);
        let x11 = lerp(v[6], v[7], f[0]);
        Some(lerp(lerp(x00, x10, f[1]), lerp(x01, x11, f[1]), f[2]))
    }

    /// Gradient of the trilinear interpolant at `p` (world units per world unit); `None`
    /// outside the grid's box.
    pub fn gradient(&self, p: [f64; 3]) -> Option<[f64; 3]> {
        let (c, f) = self.locate(p)?;
        Some(trilinear_gradient(&self.corners(c), f).map(|x| x / self.spacing))
    }

    /// Number of inside nodes (value `< 0`).
    pub fn inside_count(&self) -> usize {
        self.values.iter().filter(|&&v| v < 0.0).count()
    }

    /// The inside nodes (value `< 0`) as `(i, j, k)`, in storage order.
    pub fn inside_nodes(&self) -> Vec<[usize; 3]> {
        let [nx, ny, _] = self.dims;
        self.values
            .iter()
            .enumerate()
            .filter(|(_, &v)| v < 0.0)
            .map(|(n, _)| [n % nx, (n / nx) % ny, n / (nx * ny)])
            .collect()
    }

    /// World-space bounding box `(min, max)` of the inside nodes; `None` when there is none.
    pub fn bounding_box_of_inside(&self) -> Option<([f64; 3], [f64; 3])> {
        let nodes = self.inside_nodes();
        let first = nodes.first()?;
        let (mut lo, mut hi) = (*first, *first);
        for n in &nodes {
            for a in 0..3 {
                lo[a] = lo[a].min(n[a]);
                hi[a] = hi[a].max(n[a]);
            }
        }
        Some((
            self.node_position(lo[0], lo[1], lo[2]),
            self.node_position(hi[0], hi[1], hi[2]),
        ))
    }

    /// Checks that the grid is usable as a body: at least 2 nodes per axis, a value per node,
    /// a finite positive spacing and finite origin, finite values (the first bad node is
    /// named), and at least one inside node.
    pub fn validate(&self) -> Result<(), Error> {
        if self.dims.iter().any(|&n| n < 2) {
            return Err(Error::Invalid(format!(
                "body: the SDF grid needs at least 2 nodes per axis, found {:?}",
                self.dims
            )));
        }
        let n = self.dims.iter().try_fold(1usize, |acc, &d| acc.checked_mul(d));
        if n != Some(self.values.len()) {
            return Err(Error::Invalid(format!(
                "body: the SDF grid of {:?} nodes has {} values",
                self.dims,
                self.values.len()
            )));
        }
        if !(self.spacing.is_finite() && self.spacing > 0.0) {
            return Err(Error::Invalid(format!(
                "body: the SDF grid spacing must be positive, found {}",
                self.spacing
            )));
        }
        if self.origin.iter().any(|x| !x.is_finite()) {
            return Err(Error::Invalid(format!(
                "body: the SDF grid origin must be finite, found {:?}",
                self.origin
            )));
        }
        if let Some(bad) = self.values.iter().position(|v| !v.is_finite()) {
            let [nx, ny, _] = self.dims;
            return Err(Error::Invalid(format!(
                "body: the SDF value at node ({}, {}, {}) is {}",
                bad % nx,
                (bad / nx) % ny,
                bad / (nx * ny),
                self.values[bad]
            )));
        }
        if !self.values.iter().any(|&v| v < 0.0) {
            return Err(Error::Invalid(
                "body: the SDF has no inside node (empty body)".into(),
            ));
        }
        Ok(())
    }

    /// For a grid sampled from a body whose bounding box is `lo..hi` (a mesh or a shape):
    /// errors, saying why, when no node lies inside. A body thinner than two cells falls
    /// between the nodes (the resolution to raise it to, or a units slip when that is absurd);
    /// a thicker one with no inside node encloses no volume (a flat, open or inside-out
    /// surface).
    pub fn check_sampled_body(&self, lo: [f64; 3], hi: [f64; 3]) -> Result<(), String> {
        if self.values.iter().any(|&v| v < 0.0) {
            return Ok(());
        }
        let extent: [f64; 3] = std::array::from_fn(|a| hi[a] - lo[a]);
        let thin = extent.iter().copied().fold(f64::INFINITY, f64::min);
        let h = self.spacing;
        let size = format!("{:.3e} x {:.3e} x {:.3e}", extent[0], extent[1], extent[2]);
        Err(if thin <= 0.0 {
            format!("body: no grid node lies inside the body: it spans {size}, no volume (a flat surface is not a solid)")
        } else if thin < 2.0 * h {
            format!(
                "body: no grid node lies inside the body: it spans {size} and a grid cell is {h:.3e}; \
                 raise [body] resolution to {:.3e} or more, or check the body's units",
                2.0 / thin
            )
        } else {
            format!(
                "body: no grid node lies inside the body although it spans {size} (cells of {h:.3e}): \
                 its surface encloses no volume (open, flat or inside-out faces?)"
            )
        })
    }
}

/// The gradient of the trilinear interpolant of corner values `v` (indexed `a + 2 b + 4 c`) at
/// unit-cube point `f`, in units of the values per cell.
pub(crate) fn trilinear_gradient(v: &[f64; 8], f: [f64; 3]) -> [f64; 3] {
    let w = |s: f64, bit: usize| if bit == 1 { s } else { 1.0 - s };
    let mut g = [0.0; 3];
    for (n, &val) in v.iter().enumerate() {
        let bits = [n & 1, (n >> 1) & 1, n >> 2];
        for a in 0..3 {
            let sign = if bits[a] == 1 { 1.0 } else { -1.0 };
            let mut weight = sign;
            for b in 0..3 {
                if b != a {
                    weight *= w(f[b], bits[b]);
                }
            }
            g[a] += weight * val;
        }
    }
    g
}
