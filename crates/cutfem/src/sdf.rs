//! Signed distance fields sampled on a regular grid.

/// A signed distance field on a regular grid of nodes: negative inside, world units.
///
/// Node `(i, j, k)` sits at `origin + spacing * (i, j, k)`; values are stored x fastest, then
/// y, then z (index `i + nx * (j + ny * k)`).
#[derive(Clone, Debug, PartialEq)]
pub struct SdfGrid {
    /// world position of node (0, 0, 0)
    pub origin: [f64; 3],
    /// distance between neighbouring nodes (the cell size h)
    pub spacing: f64,
    /// number of nodes along x, y, z
    pub dims: [usize; 3],
    /// SDF values in world units, x fastest
    pub values: Vec<f64>,
}
