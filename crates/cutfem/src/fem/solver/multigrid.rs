//! The `multigrid` preconditioner's part of the [`LinearSolver`]: the grid lattice it coarsens,
//! the hierarchy kept per pattern of `A` and refreshed with its values at every solve (module
//! docs of [`super`]).

use super::LinearSolver;
use crate::error::Error;
use gpumat::solve::lattice_prolongations;
use gpumat::{Mat3, Multigrid, MultigridParams, SparseMatrix};

/// The options of the `multigrid` preconditioner: V(3,3) with Chebyshev smoothing of degree 3
/// over `[0.1, 1.1] lambda_max(D^-1 A)`, coarsest level at most 2000 nodes. CG iterations per
/// step (tolerance 1e-6) on the cut cuboid of `examples/scenes/cuboid_dirichlet.toml` at 16 / 24
/// cells per unit (3105 / 7623 nodes) and the aligned Table 4.1 cuboid at r = 10 (4131 nodes):
/// degree 2 over `[0.1, 1.1]` 42-54 / 25-31 / 8-9, degree 3 32-42 / 20-24 / 6-7 (the least work),
/// degree 4 28-35 / 17-20 / 5-6, degree 3 over `[0.2, 1.1]` 38-48 / 23-28 / 6-8, and over
/// `[0.03, 1.1]` 28-35 / 17-20 but 24-25 on the aligned cuboid.
pub const MULTIGRID: MultigridParams = MultigridParams {
    max_levels: 12,
    smoother: gpumat::solve::Smoother::Chebyshev,
    sweeps: 3,
    omega: 0.7,
    chebyshev_lower: 0.1,
    max_coarse: 2000,
};

impl LinearSolver {
    /// This solver with the lattice of the block rows: `nodes[i]` is the lattice index
    /// `i + dims[0] (j + dims[1] k)` of block row `i` (the `multigrid` preconditioner's
    /// coarsening).
    pub fn with_lattice(mut self, dims: [usize; 3], nodes: &[usize]) -> Self {
        self.lattice = Some((dims, nodes.to_vec()));
        self.multigrid = None;
        self
    }

    /// The multigrid hierarchy for `a`: built when `a`'s pattern is new, else refreshed with
    /// `a`'s values. `Ok(false)`: it could not be made from these values (block-Jacobi serves
    /// this step).
    pub(super) fn refresh_multigrid(
        &mut self,
        a: &SparseMatrix<Mat3<f64>>,
        params: &MultigridParams,
    ) -> Result<bool, Error> {
        let Some((dims, nodes)) = &self.lattice else {
            return Err(Error::Invalid(
                "linear solve: preconditioner \"multigrid\" needs a grid's lattice (a grid simulation)"
                    .into(),
            ));
        };
        if nodes.len() != a.rows() {
            return Err(Error::Invalid(format!(
                "linear solve: preconditioner \"multigrid\": the lattice has {} nodes for {} block rows",
                nodes.len(),
                a.rows()
            )));
        }
        let made = match &mut self.multigrid {
            Some(mg) if mg.pattern().same_as(a.pattern()) && mg.params() == params => mg.refresh(a),
            _ => {
                let p = lattice_prolongations(*dims, nodes, params);
                Multigrid::new(a, p, *params).map(|mg| self.multigrid = Some(mg))
            }
        };
        Ok(made.is_ok())
    }

    /// Levels of the multigrid hierarchy kept (block rows of each, finest first), if any.
    pub fn multigrid_levels(&self) -> Option<Vec<usize>> {
        self.multigrid.as_ref().map(|m| m.level_rows())
    }

    /// The multigrid hierarchy's estimates of `lambda_max(D^-1 A)` per smoothed level, if one
    /// is kept.
    pub fn multigrid_lambda_max(&self) -> Option<Vec<f64>> {
        self.multigrid.as_ref().map(|m| m.lambda_max())
    }
}
