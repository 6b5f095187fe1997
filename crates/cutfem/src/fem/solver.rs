//! The linear solve of a step, `A x = b`: preconditioned CG warm-started at `u + dt v`
//! (thesis 4.4.18), falling back to a sparse Cholesky factorization when CG fails.
//!
//! Preconditioners ([`Preconditioner`], scene key `[numerics] preconditioner`):
//!
//! - `block_jacobi`: the inverse 3x3 diagonal blocks of `A`, rebuilt every step (the
//!   thesis' choice; on the Table B.5 / B.6 cuboid at r = 20 with tolerance 1e-6 about 195 /
//!   147 iterations per step, the thesis had 167 / 82).
//! - `block_ic0`: block incomplete Cholesky of `A` on its own 3x3 pattern, relaxed-modified
//!   ([`IC0_RELAXATION`], [`gpumat::BlockIc0`]), rebuilt every step (a few percent of a step).
//!   About 27 / 29 iterations at r = 20 and, with its sequential triangular solves, about half
//!   of block-Jacobi's CG time including the factorization: the fastest of the three, and the
//!   default (`softbody demo`: 111 s with block-Jacobi, 91 s with IC(0)).
//! - `rest_cholesky`: a sparse Cholesky factor (nested-dissection order from the node
//!   positions) of the first step's `A` (the rest state), reused as the preconditioner on later
//!   steps while rotations stay moderate. The symbolic analysis is done once; the numeric
//!   factorization is redone ([`gpumat::SparseCholesky::refactor`]) at the step after one whose
//!   CG needed more than [`SolverSettings::refactor_iterations`] iterations, when CG fails
//!   with a factor of an earlier matrix, and the analysis is redone when `A`'s pattern
//!   changes. Fewest iterations (about 6 / 12 at r = 20, one factorization per 30-step run),
//!   but each costs a triangular solve of a factor with 8e7 entries and the factorization
//!   costs seconds, so it is not faster than block-Jacobi on this machine.
//!
//! - `multigrid`: a geometric multigrid V-cycle ([`gpumat::Multigrid`]): trilinear
//!   prolongations of the grid lattice (every second node per axis, down to at most
//!   [`MULTIGRID`]`.max_coarse` nodes, [`gpumat::solve::lattice_prolongations`]), Galerkin coarse
//!   operators `P^T A P`, V(3,3) Chebyshev smoothing on `D^-1 A` and a sparse Cholesky solve of the
//!   coarsest level. The hierarchy's patterns are built once per pattern of `A` and kept between
//!   steps; every solve recomputes its values ([`gpumat::Multigrid::refresh`], counted as a
//!   factorization). Its CG iterations barely grow with the resolution (docs/simulation.md).
//!   Needs the grid lattice ([`LinearSolver::with_lattice`], given by a grid
//!   [`Simulation`](super::Simulation)); without it the solve is an error.
//!
//! **A matrix that outlives its time step is factored and solved directly**
//! ([`SolverSettings::reuse_factor`], scene key `[numerics] reuse_factor`, on by default). A
//! linear model without contact has the same Newmark matrix `A = M/(theta dt)^2 ... + K` (eq.
//! 2.6.2) at every step, and the adjoint (eq. 5.5.x, `A` symmetric) and tangent-linear passes
//! solve with it again. When the solver sees the values of the previous solve's matrix again
//! (a 64-bit fingerprint of the pattern and the values' bits) at a later time step than the one
//! where it first met them ([`LinearSolver::new_step`], called by every integrator step), it
//! factors it (sparse Cholesky, nested dissection, the symbolic
//! analysis kept while the pattern stays) and solves every further system with that matrix by
//! two triangular solves, checking the relative residual against the CG tolerance (a mismatch
//! falls back to CG from the direct solution). Factors above
//! [`SolverSettings::max_reused_factor`] entries (default [`MAX_REUSED_FACTOR`]; scene key
//! `[numerics] reuse_factor_mb`) are not made. On the 1.05 x 0.22 x 0.22 bar at resolution 20 (about 3 300 unknowns; IC(0)-CG
//! needed about 30 iterations per solve) a diagnosis' evaluations got several times faster
//! (docs/effects.md, "Speed"). The solves within one step do not count, unless at least
//! [`MIN_SOLVES_AHEAD`] are announced ([`LinearSolver::expect_solves`]): a corotated model's
//! matrix changes every step, and its tangent-linear pass solves with each step's matrix once
//! per fitted parameter (to a relative residual of 1e-8, `adjoint::tangent`); factoring it
//! there for two solves made the swinging torus' fit (Table D, 2 parameters) slower, 132.8 s
//! against 97.8 s with CG (docs/simulation.md), while fits of many parameters (a stiffness
//! field's) solve many times per step and gain from the factor.
//!
//! [`StepInfo`](super::StepInfo) counts the factorizations of a step and their seconds.

use crate::error::Error;
use gpumat::{
    cg, nested_dissection, BlockIc0, BlockJacobi, CgError, CgInfo, CgParams, Ic0Params, Mat3, Matrix,
    Multigrid, MultigridParams, SparseCholesky, SparseMatrix, Vec3,
};

mod multigrid;
pub use multigrid::MULTIGRID;
use std::time::Instant;

/// The CG preconditioner of the step's linear solve (module docs); in a scene,
/// `[numerics] preconditioner` by its [`Preconditioner::name`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Preconditioner {
    /// inverse 3x3 diagonal blocks, every step (the thesis')
    BlockJacobi,
    /// block incomplete Cholesky IC(0) on `A`'s pattern, every step
    #[default]
    BlockIc0,
    /// sparse Cholesky factor of the rest-state `A`, refactored when CG needs many iterations
    RestCholesky,
    /// geometric multigrid V-cycle on the grid lattice, values refreshed every step
    Multigrid,
}

impl Preconditioner {
    /// Every preconditioner, in the order of the docs.
    pub const ALL: [Preconditioner; 4] = [
        Self::BlockJacobi,
        Self::BlockIc0,
        Self::RestCholesky,
        Self::Multigrid,
    ];

    /// The scene name (`block_jacobi`, `block_ic0`, `rest_cholesky`, `multigrid`).
    pub fn name(self) -> &'static str {
        match self {
            Self::BlockJacobi => "block_jacobi",
            Self::BlockIc0 => "block_ic0",
            Self::RestCholesky => "rest_cholesky",
            Self::Multigrid => "multigrid",
        }
    }
}

/// Linear-solver settings of a simulation.
#[derive(Clone, Copy, Debug)]
pub struct SolverSettings {
    /// CG parameters
    pub cg: CgParams<f64>,
    /// fall back to a direct solve when CG fails (else the error is returned)
    pub fallback: bool,
    /// solve directly (sparse Cholesky) instead of CG
    pub direct: bool,
    /// the CG preconditioner
    pub preconditioner: Preconditioner,
    /// `rest_cholesky`: refactor at the next step when CG needed more iterations than this
    pub refactor_iterations: usize,
    /// factor a matrix met twice in a row and solve with it directly while it stays the same
    /// (module docs)
    pub reuse_factor: bool,
    /// the most entries of such a factor (8 bytes each); a larger one is not made
    pub max_reused_factor: usize,
    /// the `multigrid` preconditioner's options (default [`MULTIGRID`])
    pub multigrid: MultigridParams,
}

impl Default for SolverSettings {
    fn default() -> Self {
        Self {
            cg: CgParams {
                max_iterations: 2000,
                tolerance: 1e-8,
                absolute_tolerance: 0.0,
            },
            fallback: true,
            direct: false,
            preconditioner: Preconditioner::BlockJacobi,
            refactor_iterations: 25,
            reuse_factor: true,
            max_reused_factor: MAX_REUSED_FACTOR,
            multigrid: MULTIGRID,
        }
    }
}

/// What one linear solve did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SolveInfo {
    /// CG iterations
    pub iterations: usize,
    /// final relative residual
    pub residual: f64,
    /// true when CG failed and the direct solver was used
    pub fallback: bool,
    /// true when the chosen preconditioner (IC(0) with every shift, or the multigrid
    /// hierarchy) could not be made from these values and block-Jacobi preconditioned CG
    pub substituted: bool,
    /// numeric factorizations done (Cholesky or IC(0))
    pub factorizations: usize,
    /// seconds in those factorizations (and the ordering)
    pub factor_s: f64,
}

/// Relaxation of the modified block IC(0) (`gpumat::Ic0Params`): 0.95 needed about 40% fewer
/// iterations than plain IC(0) (0) on the Table B.5/B.6 cuboid, and a few percent fewer than
/// 0.9.
pub const IC0_RELAXATION: f64 = 0.95;

/// `(shift, relaxation)` tried in turn when IC(0) meets a pivot that is not positive definite.
const IC0_TRIES: [(f64, f64); 6] = [
    (0.0, IC0_RELAXATION),
    (0.0, 0.0),
    (1e-3, 0.0),
    (1e-2, 0.0),
    (1e-1, 0.0),
    (1.0, 0.0),
];

/// The solver state kept between steps: the reused Cholesky factor and the node positions
/// that order it.
#[derive(Debug, Default)]
pub struct LinearSolver {
    coords: Option<Vec<[f64; 3]>>,
    chol: Option<SparseCholesky<Mat3<f64>>>,
    /// the factor was made from an earlier matrix than the one being solved
    old: bool,
    /// refactor before the next solve
    stale: bool,
    factorizations: usize,
    /// the fingerprint of the previous solve's matrix
    last_key: Option<u64>,
    /// the time step at which the run of solves with the `last_key` matrix began
    last_key_step: u64,
    /// time steps begun ([`LinearSolver::new_step`])
    step: u64,
    /// solves announced with the coming matrix ([`LinearSolver::expect_solves`])
    ahead: usize,
    /// the direct factor of a repeated matrix and its fingerprint
    repeated: Option<(u64, SparseCholesky<Mat3<f64>>)>,
    /// a pattern whose factor exceeded [`MAX_REUSED_FACTOR`]: not analysed again
    too_large: Option<std::sync::Arc<gpumat::SparsityPattern>>,
    /// solves on a device (`[numerics] backend = "cuda"`, [`super::device_solve`])
    device: Option<super::device_solve::DeviceSolver>,
    /// the lattice dims and the lattice node of each block row (`multigrid`)
    lattice: Option<([usize; 3], Vec<usize>)>,
    /// the multigrid hierarchy of the last pattern
    multigrid: Option<Multigrid>,
}

/// The next solve's matrix is factored (when not kept already) if at least this many solves
/// with it are announced ([`LinearSolver::expect_solves`]): two tangent solves per step of the
/// corotated torus (Table D) were faster by CG to 1e-8 (module docs).
pub const MIN_SOLVES_AHEAD: usize = 3;

/// The most entries of a factor made for a repeated matrix (8 bytes each: 200 MB).
pub const MAX_REUSED_FACTOR: usize = 25_000_000;

/// A 64-bit fingerprint of a matrix: its pattern's shape and every value's bits (three
/// independent lanes, one per row of each block, so that the multiplications overlap).
fn fingerprint(a: &SparseMatrix<Mat3<f64>>) -> u64 {
    const K: u64 = 0x9E37_79B9_7F4A_7C15;
    let mix = |h: u64, w: u64| (h ^ w).wrapping_mul(K).rotate_left(29);
    let p = a.pattern();
    let mut lanes = [mix(0, p.rows() as u64), mix(0, p.nnz() as u64), mix(1, 1)];
    for m in a.values() {
        for (h, r) in lanes.iter_mut().zip(&m.m) {
            *h = mix(mix(mix(*h, r[0].to_bits()), r[1].to_bits()), r[2].to_bits());
        }
    }
    mix(mix(lanes[0], lanes[1]), lanes[2])
}

impl LinearSolver {
    /// A solver for matrices whose block row `i` is the node at `positions[i]` (orders the
    /// Cholesky factor by nested dissection); without positions the order is AMD.
    pub fn new(positions: Option<&[Vec3<f64>]>) -> Self {
        Self {
            coords: positions.map(|p| p.iter().map(|v| [v.x, v.y, v.z]).collect()),
            ..Self::default()
        }
    }

    /// Solves on `device` from now on (`None`: on the host), [`super::device_solve`].
    pub fn set_device(&mut self, device: Option<std::sync::Arc<dyn gpumat::device::Device>>) {
        self.device = device.map(super::device_solve::DeviceSolver::new);
    }

    /// The device the solves run on, by name (`None`: the host).
    pub fn device_name(&self) -> Option<String> {
        self.device.as_ref().map(|d| d.name())
    }

    /// A time step begins: a matrix counts as repeated when it is met again at a later step
    /// (module docs).
    pub fn new_step(&mut self) {
        self.step += 1;
    }

    /// The next `n` solves are with one matrix (the tangent-linear pass' directions): with at
    /// least [`MIN_SOLVES_AHEAD`] the first of them counts as a repeat (module docs).
    pub fn expect_solves(&mut self, n: usize) {
        self.ahead = n;
    }

    /// Numeric factorizations done so far.
    pub fn factorizations(&self) -> usize {
        self.factorizations
    }

    /// Entries of the kept factor of a repeated matrix (module docs), 0 without one.
    pub fn reused_factor_entries(&self) -> usize {
        self.repeated.as_ref().map_or(0, |(_, c)| c.factor_nnz())
    }

    /// Drops the reused factor (the next `rest_cholesky` solve factors afresh).
    pub fn reset(&mut self) {
        self.chol = None;
        self.stale = false;
    }

    /// A new run starts: forgets the repeated matrix and its factor, so that a run's solves
    /// depend on its own matrices only (a run's first solve is CG, whatever ran before).
    pub fn new_run(&mut self) {
        self.last_key = None;
        self.repeated = None;
        self.ahead = 0;
    }

    /// The model changed: the next solve does not count as a repeat of the last one (a kept
    /// factor still serves a matrix equal to its own). A step after [`Simulation::set_model`]
    /// then solves as a fresh simulation's first step does, unless the factor of that very
    /// matrix is kept.
    ///
    /// [`Simulation::set_model`]: crate::fem::Simulation::set_model
    pub fn model_changed(&mut self) {
        self.last_key = None;
    }

    /// A fresh Cholesky factor of `a` (nested dissection when positions are known).
    fn factor(&self, a: &SparseMatrix<Mat3<f64>>) -> Result<SparseCholesky<Mat3<f64>>, Error> {
        Ok(SparseCholesky::with_ordering(a, self.order(a).as_deref())?)
    }

    /// The nested-dissection order of `a`'s block rows when the node positions are known.
    fn order(&self, a: &SparseMatrix<Mat3<f64>>) -> Option<Vec<usize>> {
        self.coords
            .as_ref()
            .filter(|c| c.len() == a.rows())
            .map(|c| nested_dissection(a.pattern(), c))
    }

    /// Solves `a x = b` from the given `x` (module docs).
    pub fn solve(
        &mut self,
        a: &SparseMatrix<Mat3<f64>>,
        b: &Matrix<Vec3<f64>>,
        x: &mut Matrix<Vec3<f64>>,
        settings: &SolverSettings,
    ) -> Result<SolveInfo, Error> {
        let mut info = SolveInfo::default();
        // an announcement serves the next solve only, whichever path it takes
        let announced = std::mem::take(&mut self.ahead) >= MIN_SOLVES_AHEAD;
        if settings.direct {
            let t = Instant::now();
            let chol = self.factor(a)?;
            info.factor_s = t.elapsed().as_secs_f64();
            info.factorizations = 1;
            self.factorizations += 1;
            info.residual = direct(&chol, a, b, x);
            return Ok(info);
        }
        if let Some(device) = self.device.as_mut() {
            let outcome = device.solve(a, b, x, &settings.cg)?;
            return self.finish(outcome, a, b, x, settings, info);
        }
        if settings.reuse_factor && self.solve_repeated(a, b, x, settings, &mut info, announced)? {
            return Ok(info);
        }
        let outcome = match settings.preconditioner {
            Preconditioner::BlockJacobi => cg(a, b, x, &BlockJacobi::new(a)?, &settings.cg),
            Preconditioner::BlockIc0 => {
                let t = Instant::now();
                let ic = IC0_TRIES.iter().find_map(|&(shift, relaxation)| {
                    BlockIc0::with_params(a, Ic0Params { shift, relaxation }).ok()
                });
                info.factor_s = t.elapsed().as_secs_f64();
                match ic {
                    Some(ic) => {
                        info.factorizations = 1;
                        self.factorizations += 1;
                        cg(a, b, x, &ic, &settings.cg)
                    }
                    // no shift made IC(0) exist: block-Jacobi this step
                    None => {
                        info.substituted = true;
                        cg(a, b, x, &BlockJacobi::new(a)?, &settings.cg)
                    }
                }
            }
            Preconditioner::RestCholesky => return self.solve_rest_cholesky(a, b, x, settings, info),
            Preconditioner::Multigrid => {
                let t = Instant::now();
                let made = self.refresh_multigrid(a, &settings.multigrid)?;
                info.factor_s = t.elapsed().as_secs_f64();
                match self.multigrid.as_ref().filter(|_| made) {
                    Some(mg) => {
                        info.factorizations = 1;
                        self.factorizations += 1;
                        cg(a, b, x, &mg.preconditioner(a), &settings.cg)
                    }
                    // the hierarchy could not be made from these values: block-Jacobi
                    None => {
                        info.substituted = true;
                        cg(a, b, x, &BlockJacobi::new(a)?, &settings.cg)
                    }
                }
            }
        };
        self.finish(outcome, a, b, x, settings, info)
    }

    /// The repeated-matrix rule's account of a solve with `a` (module docs): records it, and
    /// factors `a` when it repeats; true when a factor of `a` is kept.
    /// `announced`: enough solves with `a` are announced to count it as a repeat at once.
    fn meet(
        &mut self,
        a: &SparseMatrix<Mat3<f64>>,
        info: &mut SolveInfo,
        announced: bool,
        max_entries: usize,
    ) -> bool {
        let key = fingerprint(a);
        // met again at a later time step than the run of solves with it began (the tangent
        // passes' solves with the step's own matrix do not count unless enough are announced:
        // module docs)
        let repeat = announced || (self.last_key == Some(key) && self.last_key_step != self.step);
        if self.last_key != Some(key) {
            self.last_key = Some(key);
            self.last_key_step = self.step;
        }
        let known = self
            .repeated
            .as_ref()
            .is_some_and(|(k, c)| *k == key && c.pattern().same_as(a.pattern()));
        if !known {
            let big = self.too_large.as_ref().is_some_and(|p| p.same_as(a.pattern()));
            if !repeat || big {
                return false;
            }
            let t = Instant::now();
            let chol = match self.repeated.take() {
                Some((_, mut c)) if c.pattern().same_as(a.pattern()) => c.refactor(a).map(|_| Some(c)),
                _ => self.analysed(a, max_entries),
            };
            info.factor_s += t.elapsed().as_secs_f64();
            match chol {
                Ok(Some(c)) => {
                    info.factorizations += 1;
                    self.factorizations += 1;
                    self.repeated = Some((key, c));
                }
                Ok(None) => {
                    self.too_large = Some(a.pattern().clone());
                    return false;
                }
                // not positive definite: CG decides what that means
                Err(_) => return false,
            }
        }
        true
    }

    /// Accounts for a solve with `a` that a replayed step does not make
    /// ([`crate::fem::Simulation::replay_substep`]): the repeated-matrix rule's state (and a
    /// factor it makes) is then what the solve would have left.
    pub fn replay(&mut self, a: &SparseMatrix<Mat3<f64>>, settings: &SolverSettings) {
        if settings.reuse_factor && !settings.direct && self.device.is_none() {
            self.meet(a, &mut SolveInfo::default(), false, settings.max_reused_factor);
        }
    }

    /// The direct solve of a repeated matrix (module docs): true when `x` solves `a x = b`
    /// to the CG tolerance.
    fn solve_repeated(
        &mut self,
        a: &SparseMatrix<Mat3<f64>>,
        b: &Matrix<Vec3<f64>>,
        x: &mut Matrix<Vec3<f64>>,
        settings: &SolverSettings,
        info: &mut SolveInfo,
        announced: bool,
    ) -> Result<bool, Error> {
        if !self.meet(a, info, announced, settings.max_reused_factor) {
            return Ok(false);
        }
        let chol = &self.repeated.as_ref().expect("factored above").1;
        info.residual = direct(chol, a, b, x);
        Ok(info.residual <= settings.cg.tolerance)
    }

    /// A factor of `a`, or `None` when its analysis exceeds `max_entries` entries.
    fn analysed(
        &self,
        a: &SparseMatrix<Mat3<f64>>,
        max_entries: usize,
    ) -> Result<Option<SparseCholesky<Mat3<f64>>>, gpumat::Error> {
        let c = SparseCholesky::analyse(a, self.order(a).as_deref())?;
        if c.factor_nnz() > max_entries {
            return Ok(None);
        }
        c.factored(a).map(Some)
    }

    fn solve_rest_cholesky(
        &mut self,
        a: &SparseMatrix<Mat3<f64>>,
        b: &Matrix<Vec3<f64>>,
        x: &mut Matrix<Vec3<f64>>,
        settings: &SolverSettings,
        mut info: SolveInfo,
    ) -> Result<SolveInfo, Error> {
        let same = self
            .chol
            .as_ref()
            .is_some_and(|c| c.pattern().same_as(a.pattern()));
        if !same || self.stale {
            self.refactor(a, !same, &mut info)?;
        } else {
            self.old = true;
        }
        loop {
            let chol = self.chol.as_ref().expect("factored above");
            match cg(a, b, x, chol, &settings.cg) {
                Ok(ci) => {
                    self.stale = ci.max_iterations() > settings.refactor_iterations;
                    return self.finish(Ok(ci), a, b, x, settings, info);
                }
                // a factor of an earlier matrix may be too far off: refactor and go on from x
                Err(_) if self.old => self.refactor(a, false, &mut info)?,
                Err(e) => return self.finish(Err(e), a, b, x, settings, info),
            }
        }
    }

    /// Factors `a` into the reused factor (analysis included when `symbolic`).
    fn refactor(
        &mut self,
        a: &SparseMatrix<Mat3<f64>>,
        symbolic: bool,
        info: &mut SolveInfo,
    ) -> Result<(), Error> {
        let t = Instant::now();
        match (&mut self.chol, symbolic) {
            (Some(c), false) => c.refactor(a)?,
            _ => self.chol = Some(self.factor(a)?),
        }
        info.factor_s += t.elapsed().as_secs_f64();
        info.factorizations += 1;
        self.factorizations += 1;
        self.old = false;
        self.stale = false;
        Ok(())
    }

    /// The CG outcome as a [`SolveInfo`], with the direct fallback when CG failed.
    fn finish(
        &mut self,
        outcome: Result<CgInfo<f64>, CgError<f64>>,
        a: &SparseMatrix<Mat3<f64>>,
        b: &Matrix<Vec3<f64>>,
        x: &mut Matrix<Vec3<f64>>,
        settings: &SolverSettings,
        mut info: SolveInfo,
    ) -> Result<SolveInfo, Error> {
        match outcome {
            Ok(ci) => {
                info.iterations = ci.max_iterations();
                info.residual = ci.max_residual();
                Ok(info)
            }
            Err(e) if settings.fallback => {
                info.iterations = match &e {
                    CgError::NoConvergence { info } => info.max_iterations(),
                    _ => settings.cg.max_iterations,
                };
                info.fallback = true;
                // the rest-Cholesky factor is of this very matrix by now (see above)
                let t = Instant::now();
                let fresh;
                let chol = match (&self.chol, settings.preconditioner) {
                    (Some(c), Preconditioner::RestCholesky) if !self.old => c,
                    _ => {
                        fresh = self.factor(a)?;
                        info.factorizations += 1;
                        self.factorizations += 1;
                        &fresh
                    }
                };
                info.factor_s += t.elapsed().as_secs_f64();
                info.residual = direct(chol, a, b, x);
                Ok(info)
            }
            Err(e) => Err(Error::Invalid(format!("linear solve: {e}"))),
        }
    }
}

/// `x = A^-1 b` with a factor of `a`; returns the relative residual.
fn direct(
    chol: &SparseCholesky<Mat3<f64>>,
    a: &SparseMatrix<Mat3<f64>>,
    b: &Matrix<Vec3<f64>>,
    x: &mut Matrix<Vec3<f64>>,
) -> f64 {
    *x = chol.solve(b);
    let mut r = Matrix::zeros_shape(b.shape());
    r.assign(b - a * &*x);
    r.ex().norm() / b.ex().norm().max(f64::MIN_POSITIVE)
}

/// Solves `A x = b` once, without state kept between calls (a `rest_cholesky` factor is
/// made for this matrix). Returns `(iterations, relative residual, fallback used)`.
pub fn solve(
    a: &SparseMatrix<Mat3<f64>>,
    b: &Matrix<Vec3<f64>>,
    x: &mut Matrix<Vec3<f64>>,
    settings: &SolverSettings,
) -> Result<(usize, f64, bool), Error> {
    let info = LinearSolver::new(None).solve(a, b, x, settings)?;
    Ok((info.iterations, info.residual, info.fallback))
}
