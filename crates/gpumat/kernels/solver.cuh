// solver.cuh: the device building blocks of the kernels gpumat always needs (reductions, sparse
// rows, CG steps). build.rs instantiates them as `extern "C"` entry points for f32 and f64,
// with the element-wise parts written from gpumat's op table (see build.rs and
// gpumat::cuda::catalogue()).
//
// Layouts (as on the host): a vector of n elements and B batches is n x 1 x B column-major,
// element (i, b) at i + n b. Sparse values are nnz per batch; `vals_stride` is nnz when the
// matrix has B value sets and 0 when one set is shared by all batches.
//
// Reductions (deterministic, no atomics): a batch's n elements are cut over gridDim.x blocks of
// blockDim.x = GPUMAT_BLOCK threads; thread t of block k accumulates elements
// i = k * GPUMAT_BLOCK + t + j * gridDim.x * GPUMAT_BLOCK (j = 0, 1, ...) in order, the block
// combines its threads in the fixed tree of gpumat_block_reduce and writes partial[b, k]; a
// finish kernel (one block per batch) folds the partials the same way. The result depends
// only on the input and gridDim.x, never on scheduling.
#pragma once
#include "gpumat.cuh"

// Two reals reduced together (CG's fused r.z and r.r).
template <typename R>
struct gpumat_pair {
    R a, b;
};
template <typename R>
__device__ __forceinline__ gpumat_pair<R> gpumat_pair_zero() {
    gpumat_pair<R> p;
    p.a = R(0);
    p.b = R(0);
    return p;
}

// Global thread index of a 1D launch.
__device__ __forceinline__ gpumat_index gpumat_thread_index() {
    return blockIdx.x * (gpumat_index)blockDim.x + threadIdx.x;
}

// Phase 1 of a reduction over each batch: partials[b * gridDim.x + blockIdx.x], batch b =
// blockIdx.y. `load(i, b)` gives the (already mapped) value of element i of batch b.
template <typename R, typename Load, typename Op>
__device__ __forceinline__ void gpumat_reduce_partial(Load load, gpumat_index n, R identity, Op op,
                                                      R* __restrict__ partials) {
    __shared__ R s[GPUMAT_BLOCK];
    const gpumat_index b = blockIdx.y;
    const gpumat_index stride = (gpumat_index)gridDim.x * blockDim.x;
    R acc = identity;
    for (gpumat_index i = blockIdx.x * (gpumat_index)blockDim.x + threadIdx.x; i < n; i += stride)
        acc = op(acc, load(i, b));
    const R total = gpumat_block_reduce(acc, s, op);
    if (threadIdx.x == 0) partials[b * gridDim.x + blockIdx.x] = total;
}

// Phase 2: out[b] = fold of partials[b * parts .. (b + 1) * parts], one block per batch.
template <typename R, typename Op>
__device__ __forceinline__ void gpumat_reduce_finish(const R* __restrict__ partials,
                                                     gpumat_index parts, R identity, Op op,
                                                     R* __restrict__ out) {
    __shared__ R s[GPUMAT_BLOCK];
    const gpumat_index b = blockIdx.x;
    R acc = identity;
    for (gpumat_index k = threadIdx.x; k < parts; k += blockDim.x)
        acc = op(acc, partials[b * parts + k]);
    const R total = gpumat_block_reduce(acc, s, op);
    if (threadIdx.x == 0) out[b] = total;
}

// y_r = sum_{k in row r} A_k * x_{col_k} for one (row, batch): the CSR/BSR row product.
template <typename V, typename M>
__device__ __forceinline__ V gpumat_spmv_row(const gpumat_index* __restrict__ row_ptr,
                                             const unsigned int* __restrict__ col_idx,
                                             const M* __restrict__ vals, const V* __restrict__ x,
                                             gpumat_index r) {
    V acc = gpumat_zero<V>();
    for (gpumat_index k = row_ptr[r]; k < row_ptr[r + 1]; ++k) acc = acc + vals[k] * x[col_idx[k]];
    return acc;
}

// (A^T x)_c = sum over the entries of column c of A_k^T * x_{row_k}, through the transpose map
// (col_ptr, row_idx, entry) that the host builds once per pattern.
template <typename V, typename M>
__device__ __forceinline__ V gpumat_spmv_col(const gpumat_index* __restrict__ col_ptr,
                                             const gpumat_index* __restrict__ row_idx,
                                             const gpumat_index* __restrict__ entry,
                                             const M* __restrict__ vals, const V* __restrict__ x,
                                             gpumat_index c) {
    V acc = gpumat_zero<V>();
    for (gpumat_index j = col_ptr[c]; j < col_ptr[c + 1]; ++j)
        acc = acc + gpumat_transpose(vals[entry[j]]) * x[row_idx[j]];
    return acc;
}
