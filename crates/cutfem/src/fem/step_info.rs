//! What a step (or a frame of `substeps` steps) did: iterations, residual, timings.

/// What one step did.
#[derive(Clone, Debug, Default)]
pub struct StepInfo {
    /// CG iterations
    pub iterations: usize,
    /// final relative CG residual
    pub residual: f64,
    /// true when CG failed and the direct solver was used
    pub fallback: bool,
    /// true when block-Jacobi stood in for the chosen preconditioner ([`super::SolveInfo`])
    pub substituted: bool,
    /// numeric factorizations of the preconditioner (IC(0), Cholesky) or direct solver
    pub factorizations: usize,
    /// the part of `solve_s` spent in those factorizations
    pub factor_s: f64,
    /// crossings in contact with the ground
    pub contacts: usize,
    /// Newton iterations of the penalty contact beyond each step's first solve
    pub newton: usize,
    /// seconds in assembly (rotations, stiffness, corotation forces, A and b)
    pub assembly_s: f64,
    /// the part of `assembly_s` spent on rotations and stiffness values (the thesis' "matrix
    /// assembly"; in a grid step the one pass over cells and rows, which also computes `K u`,
    /// the corotation and body forces, all blocks of `A` and most of `b`, all counted here;
    /// a step's `K` values go into `A` without being stored)
    pub stiffness_s: f64,
    /// seconds in collision forces
    pub collision_s: f64,
    /// seconds in the linear solve (factorizations included)
    pub solve_s: f64,
}

impl StepInfo {
    /// Adds the info of the next integrator step of the same frame: sums the iterations,
    /// factorizations and seconds, keeps the largest residual and the latest contact count.
    pub fn then(&mut self, s: StepInfo) {
        self.iterations += s.iterations;
        self.residual = self.residual.max(s.residual);
        self.fallback |= s.fallback;
        self.substituted |= s.substituted;
        self.factorizations += s.factorizations;
        self.factor_s += s.factor_s;
        self.contacts = s.contacts;
        self.newton += s.newton;
        self.assembly_s += s.assembly_s;
        self.stiffness_s += s.stiffness_s;
        self.collision_s += s.collision_s;
        self.solve_s += s.solve_s;
    }
}
