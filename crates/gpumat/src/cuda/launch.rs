//! Launch geometry of gpumat's kernels: how many blocks of how many threads each kind of kernel
//! runs on. The emulated logic check (`tests/emulated.rs`) launches through these functions;
//! the devices of [`crate::device`] launch on the same ones.
//!
//! - element-wise kernels (expression kernels, vector updates, SpMV rows): one thread per
//!   output element, `ceil(len / BLOCK)` blocks;
//! - reductions: phase 1 on `parts x batches` blocks, `parts = min(ceil(n / BLOCK), MAX_PARTS)`;
//!   phase 2 (`*_finish`) on `batches` blocks, each folding its batch's `parts` partials. The
//!   partial sums depend on `parts`, so a result is reproducible bit for bit for a given `n`.

/// Threads per block (`GPUMAT_BLOCK` in `kernels/gpumat.cuh`).
pub const BLOCK: u32 = 256;
/// At most this many partial results per batch in a reduction's first phase.
pub const MAX_PARTS: u32 = 64;

/// A launch shape: `blocks.0 x blocks.1` blocks of `threads` threads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Grid {
    /// blocks in x and y
    pub blocks: (u32, u32),
    /// threads per block (x)
    pub threads: u32,
}

fn blocks_for(len: usize) -> u32 {
    (len.div_ceil(BLOCK as usize).max(1)).min(u32::MAX as usize) as u32
}

/// One thread per element of `len` elements.
pub fn elementwise(len: usize) -> Grid {
    Grid {
        blocks: (blocks_for(len), 1),
        threads: BLOCK,
    }
}

/// The number of partial results per batch of a reduction over `n` elements.
pub fn reduction_parts(n: usize) -> u32 {
    blocks_for(n).min(MAX_PARTS)
}

/// Phase 1 of a reduction over `n` elements in each of `batches` batches.
pub fn reduction(n: usize, batches: usize) -> Grid {
    Grid {
        blocks: (reduction_parts(n), batches.max(1) as u32),
        threads: BLOCK,
    }
}

/// Phase 2 of a reduction: one block per batch.
pub fn reduction_finish(batches: usize) -> Grid {
    Grid {
        blocks: (batches.max(1) as u32, 1),
        threads: BLOCK,
    }
}
