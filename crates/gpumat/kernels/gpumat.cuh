// gpumat.cuh: the device twins of gpumat's element types and the helpers every generated
// kernel uses (the text emitted by gpumat::cuda_codegen and by build.rs includes this file).
//
// Element types (layouts equal to the Rust types, checked below and by gpumat's tests):
//   real      float / double
//   Vec3<R>   float4 / double4: lanes x, y, z; w is padding and always 0 (16-byte aligned)
//   Mat3<R>   gpumat_mat3f / gpumat_mat3d: 9 lanes, row-major m[3*i + j] (Rust [[R; 3]; 3])
//
// Lane-wise operations of the op table act on blocks through gpumat_map / gpumat_zip, which
// apply a functor to x, y, z (Vec3) or to all nine lanes (Mat3) and keep w = 0.
//
// Reductions are deterministic: gpumat_block_sum / gpumat_block_reduce combine the values of a
// block's threads in a fixed binary tree in shared memory (no atomics), so the same input and
// launch shape give the same bits run to run.
#pragma once

#ifndef GPUMAT_BLOCK
// threads per block of the reduction kernels (a power of two; the launch code uses the same)
#define GPUMAT_BLOCK 256
#endif

typedef unsigned long long gpumat_index;

struct gpumat_mat3f {
    float m[9];
};
struct gpumat_mat3d {
    double m[9];
};

static_assert(sizeof(float4) == 16 && alignof(float4) == 16, "Vec3<f32> is a 16-byte float4");
static_assert(sizeof(double4) == 32 && alignof(double4) >= 16, "Vec3<f64> is a double4");
static_assert(sizeof(gpumat_mat3f) == 36, "Mat3<f32> is 9 floats");
static_assert(sizeof(gpumat_mat3d) == 72, "Mat3<f64> is 9 doubles");

// ---- lane-wise map / zip -------------------------------------------------------------------

template <typename F>
__device__ __forceinline__ float gpumat_map(F f, float a) {
    return (float)f(a);
}
template <typename F>
__device__ __forceinline__ double gpumat_map(F f, double a) {
    return (double)f(a);
}
template <typename F>
__device__ __forceinline__ float4 gpumat_map(F f, float4 a) {
    float4 r;
    r.x = (float)f(a.x);
    r.y = (float)f(a.y);
    r.z = (float)f(a.z);
    r.w = 0.0f;
    return r;
}
template <typename F>
__device__ __forceinline__ double4 gpumat_map(F f, double4 a) {
    double4 r;
    r.x = (double)f(a.x);
    r.y = (double)f(a.y);
    r.z = (double)f(a.z);
    r.w = 0.0;
    return r;
}
template <typename F>
__device__ __forceinline__ gpumat_mat3f gpumat_map(F f, gpumat_mat3f a) {
    gpumat_mat3f r;
#pragma unroll
    for (int k = 0; k < 9; ++k) r.m[k] = (float)f(a.m[k]);
    return r;
}
template <typename F>
__device__ __forceinline__ gpumat_mat3d gpumat_map(F f, gpumat_mat3d a) {
    gpumat_mat3d r;
#pragma unroll
    for (int k = 0; k < 9; ++k) r.m[k] = (double)f(a.m[k]);
    return r;
}

template <typename F>
__device__ __forceinline__ float gpumat_zip(F f, float a, float b) {
    return (float)f(a, b);
}
template <typename F>
__device__ __forceinline__ double gpumat_zip(F f, double a, double b) {
    return (double)f(a, b);
}
template <typename F>
__device__ __forceinline__ float4 gpumat_zip(F f, float4 a, float4 b) {
    float4 r;
    r.x = (float)f(a.x, b.x);
    r.y = (float)f(a.y, b.y);
    r.z = (float)f(a.z, b.z);
    r.w = 0.0f;
    return r;
}
template <typename F>
__device__ __forceinline__ double4 gpumat_zip(F f, double4 a, double4 b) {
    double4 r;
    r.x = (double)f(a.x, b.x);
    r.y = (double)f(a.y, b.y);
    r.z = (double)f(a.z, b.z);
    r.w = 0.0;
    return r;
}
template <typename F>
__device__ __forceinline__ gpumat_mat3f gpumat_zip(F f, gpumat_mat3f a, gpumat_mat3f b) {
    gpumat_mat3f r;
#pragma unroll
    for (int k = 0; k < 9; ++k) r.m[k] = (float)f(a.m[k], b.m[k]);
    return r;
}
template <typename F>
__device__ __forceinline__ gpumat_mat3d gpumat_zip(F f, gpumat_mat3d a, gpumat_mat3d b) {
    gpumat_mat3d r;
#pragma unroll
    for (int k = 0; k < 9; ++k) r.m[k] = (double)f(a.m[k], b.m[k]);
    return r;
}

// ---- zero, one, splat ----------------------------------------------------------------------

// gpumat_splat<T>(s): every meaningful lane equal to s (w = 0; a Mat3 gets all nine lanes).
template <typename T>
struct gpumat_traits;
template <>
struct gpumat_traits<float> {
    typedef float real;
    static __device__ __forceinline__ float splat(float s) { return s; }
    static __device__ __forceinline__ float one() { return 1.0f; }
};
template <>
struct gpumat_traits<double> {
    typedef double real;
    static __device__ __forceinline__ double splat(double s) { return s; }
    static __device__ __forceinline__ double one() { return 1.0; }
};
template <>
struct gpumat_traits<float4> {
    typedef float real;
    static __device__ __forceinline__ float4 splat(float s) {
        float4 r;
        r.x = s;
        r.y = s;
        r.z = s;
        r.w = 0.0f;
        return r;
    }
    static __device__ __forceinline__ float4 one() { return splat(1.0f); }
};
template <>
struct gpumat_traits<double4> {
    typedef double real;
    static __device__ __forceinline__ double4 splat(double s) {
        double4 r;
        r.x = s;
        r.y = s;
        r.z = s;
        r.w = 0.0;
        return r;
    }
    static __device__ __forceinline__ double4 one() { return splat(1.0); }
};
template <>
struct gpumat_traits<gpumat_mat3f> {
    typedef float real;
    static __device__ __forceinline__ gpumat_mat3f splat(float s) {
        gpumat_mat3f r;
#pragma unroll
        for (int k = 0; k < 9; ++k) r.m[k] = s;
        return r;
    }
    static __device__ __forceinline__ gpumat_mat3f one() {
        gpumat_mat3f r = splat(0.0f);
        r.m[0] = r.m[4] = r.m[8] = 1.0f;
        return r;
    }
};
template <>
struct gpumat_traits<gpumat_mat3d> {
    typedef double real;
    static __device__ __forceinline__ gpumat_mat3d splat(double s) {
        gpumat_mat3d r;
#pragma unroll
        for (int k = 0; k < 9; ++k) r.m[k] = s;
        return r;
    }
    static __device__ __forceinline__ gpumat_mat3d one() {
        gpumat_mat3d r = splat(0.0);
        r.m[0] = r.m[4] = r.m[8] = 1.0;
        return r;
    }
};

// Scalar::ZERO
template <typename T>
__device__ __forceinline__ T gpumat_zero() {
    return gpumat_traits<T>::splat(0);
}
// Scalar::ONE: 1, (1, 1, 1), the identity block
template <typename T>
__device__ __forceinline__ T gpumat_one() {
    return gpumat_traits<T>::one();
}
template <typename T>
__device__ __forceinline__ T gpumat_splat(typename gpumat_traits<T>::real s) {
    return gpumat_traits<T>::splat(s);
}

#include "block3.cuh"

// ---- reductions within one block (fixed tree, deterministic) --------------------------------

struct gpumat_op_add {
    template <typename T>
    __device__ __forceinline__ T operator()(T a, T b) const {
        return a + b;
    }
};

// Combines the `v` of the blockDim.x (a power of two) threads of a block with `op` in a fixed
// binary tree: s[t] = op(s[t], s[t + h]) for h = blockDim.x / 2, ..., 1. Every thread gets the
// result. `s` is shared memory of at least blockDim.x elements.
template <typename T, typename Op>
__device__ __forceinline__ T gpumat_block_reduce(T v, T* s, Op op) {
    const unsigned t = threadIdx.x;
    s[t] = v;
    __syncthreads();
    for (unsigned h = blockDim.x / 2; h > 0; h >>= 1) {
        if (t < h) s[t] = op(s[t], s[t + h]);
        __syncthreads();
    }
    T r = s[0];
    __syncthreads();
    return r;
}
template <typename T>
__device__ __forceinline__ T gpumat_block_sum(T v, T* s) {
    return gpumat_block_reduce(v, s, gpumat_op_add());
}

// ---- sparse rows ---------------------------------------------------------------------------

// The entry (r, c) of a CSR/BSR matrix (zero off the pattern): binary search of row r's sorted
// columns. `vals` points at the batch's values.
template <typename T>
__device__ __forceinline__ T gpumat_csr_get(const gpumat_index* __restrict__ row_ptr,
                                            const unsigned int* __restrict__ col_idx,
                                            const T* __restrict__ vals, gpumat_index r,
                                            gpumat_index c) {
    gpumat_index lo = row_ptr[r], hi = row_ptr[r + 1];
    while (lo < hi) {
        const gpumat_index mid = lo + (hi - lo) / 2;
        const gpumat_index col = col_idx[mid];
        if (col == c) return vals[mid];
        if (col < c)
            lo = mid + 1;
        else
            hi = mid;
    }
    return gpumat_zero<T>();
}
