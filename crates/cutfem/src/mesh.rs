//! Triangle meshes.

/// An indexed triangle mesh.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    /// vertex positions
    pub vertices: Vec<[f64; 3]>,
    /// triangles as vertex indices (counter-clockwise seen from outside)
    pub faces: Vec<[u32; 3]>,
}
