//! Test hooks: counts of evaluation passes and matrix allocations on the calling thread.
//!
//! Every loop over memory (an assignment, a reduction, a sparse assignment) counts one pass;
//! every new matrix buffer counts one allocation. The fusion tests use them to prove that
//! `d.assign(a + b*2 + c.sqrt())` is one pass and allocates nothing. Counters are
//! thread-local (the calling thread's work, whatever threads rayon used inside), so tests
//! running in parallel do not disturb each other. They count only with the `pass-counter`
//! feature (gpumat's own tests turn it on); without it they stay at zero and cost nothing.

use std::cell::Cell;

thread_local! {
    static PASSES: Cell<usize> = const { Cell::new(0) };
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

#[inline(always)]
pub(crate) fn count_pass() {
    #[cfg(feature = "pass-counter")]
    PASSES.with(|p| p.set(p.get() + 1));
}
#[inline(always)]
pub(crate) fn count_allocation() {
    #[cfg(feature = "pass-counter")]
    ALLOCATIONS.with(|p| p.set(p.get() + 1));
}

/// Passes over memory made by this thread since the last [`reset`].
pub fn passes() -> usize {
    PASSES.with(|p| p.get())
}
/// Matrix buffers allocated by this thread since the last [`reset`].
pub fn allocations() -> usize {
    ALLOCATIONS.with(|p| p.get())
}
/// Resets both counters of this thread.
pub fn reset() {
    PASSES.with(|p| p.set(0));
    ALLOCATIONS.with(|p| p.set(0));
}
