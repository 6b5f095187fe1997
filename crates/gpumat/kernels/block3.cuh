// block3.cuh: arithmetic of the 3-lane vector (float4/double4, w = 0) and 3x3 block
// (gpumat_mat3f/d, row-major) scalars, the twin of crates/gpumat/src/block.rs.
//
//   + - /         lane by lane (Vec3 and Mat3)
//   Vec3 * Vec3   lane by lane          (Rust ScalarMul for Vec3)
//   Mat3 * Vec3   matrix-vector product  y_i = sum_j m_ij v_j
//   Mat3 * Mat3   matrix product         c_ij = sum_k a_ik b_kj
//   s * block     scaling
//   gpumat_dot    sum of lane products (Euclidean / Frobenius inner product)
//   gpumat_inverse3  inverse of a 3x3 block by the adjugate, A^-1 = adj(A) / det(A)
// Included by gpumat.cuh (which defines the types and gpumat_map / gpumat_zip).
#pragma once

#define GPUMAT_BLOCK_OPS(V, M, R)                                                             \
    __device__ __forceinline__ V operator+(V a, V b) {                                        \
        V r;                                                                                  \
        r.x = a.x + b.x;                                                                      \
        r.y = a.y + b.y;                                                                      \
        r.z = a.z + b.z;                                                                      \
        r.w = 0;                                                                              \
        return r;                                                                             \
    }                                                                                         \
    __device__ __forceinline__ V operator-(V a, V b) {                                        \
        V r;                                                                                  \
        r.x = a.x - b.x;                                                                      \
        r.y = a.y - b.y;                                                                      \
        r.z = a.z - b.z;                                                                      \
        r.w = 0;                                                                              \
        return r;                                                                             \
    }                                                                                         \
    __device__ __forceinline__ V operator-(V a) {                                             \
        V r;                                                                                  \
        r.x = -a.x;                                                                           \
        r.y = -a.y;                                                                           \
        r.z = -a.z;                                                                           \
        r.w = 0;                                                                              \
        return r;                                                                             \
    }                                                                                         \
    __device__ __forceinline__ V operator*(V a, V b) {                                        \
        V r;                                                                                  \
        r.x = a.x * b.x;                                                                      \
        r.y = a.y * b.y;                                                                      \
        r.z = a.z * b.z;                                                                      \
        r.w = 0;                                                                              \
        return r;                                                                             \
    }                                                                                         \
    __device__ __forceinline__ V operator/(V a, V b) {                                        \
        V r;                                                                                  \
        r.x = a.x / b.x;                                                                      \
        r.y = a.y / b.y;                                                                      \
        r.z = a.z / b.z;                                                                      \
        r.w = 0;                                                                              \
        return r;                                                                             \
    }                                                                                         \
    __device__ __forceinline__ V operator*(V a, R s) {                                        \
        V r;                                                                                  \
        r.x = a.x * s;                                                                        \
        r.y = a.y * s;                                                                        \
        r.z = a.z * s;                                                                        \
        r.w = 0;                                                                              \
        return r;                                                                             \
    }                                                                                         \
    __device__ __forceinline__ V operator*(R s, V a) { return a * s; }                        \
    __device__ __forceinline__ M operator+(M a, M b) {                                        \
        M r;                                                                                  \
        for (int k = 0; k < 9; ++k) r.m[k] = a.m[k] + b.m[k];                                 \
        return r;                                                                             \
    }                                                                                         \
    __device__ __forceinline__ M operator-(M a, M b) {                                        \
        M r;                                                                                  \
        for (int k = 0; k < 9; ++k) r.m[k] = a.m[k] - b.m[k];                                 \
        return r;                                                                             \
    }                                                                                         \
    __device__ __forceinline__ M operator-(M a) {                                             \
        M r;                                                                                  \
        for (int k = 0; k < 9; ++k) r.m[k] = -a.m[k];                                         \
        return r;                                                                             \
    }                                                                                         \
    __device__ __forceinline__ M operator/(M a, M b) {                                        \
        M r;                                                                                  \
        for (int k = 0; k < 9; ++k) r.m[k] = a.m[k] / b.m[k];                                 \
        return r;                                                                             \
    }                                                                                         \
    __device__ __forceinline__ M operator*(M a, R s) {                                        \
        M r;                                                                                  \
        for (int k = 0; k < 9; ++k) r.m[k] = a.m[k] * s;                                      \
        return r;                                                                             \
    }                                                                                         \
    __device__ __forceinline__ M operator*(R s, M a) { return a * s; }                        \
    __device__ __forceinline__ V operator*(M a, V v) {                                        \
        V r;                                                                                  \
        r.x = a.m[0] * v.x + a.m[1] * v.y + a.m[2] * v.z;                                     \
        r.y = a.m[3] * v.x + a.m[4] * v.y + a.m[5] * v.z;                                     \
        r.z = a.m[6] * v.x + a.m[7] * v.y + a.m[8] * v.z;                                     \
        r.w = 0;                                                                              \
        return r;                                                                             \
    }                                                                                         \
    __device__ __forceinline__ M operator*(M a, M b) {                                        \
        M r;                                                                                  \
        for (int i = 0; i < 3; ++i)                                                           \
            for (int j = 0; j < 3; ++j)                                                       \
                r.m[3 * i + j] = a.m[3 * i] * b.m[j] + a.m[3 * i + 1] * b.m[3 + j] +          \
                                 a.m[3 * i + 2] * b.m[6 + j];                                 \
        return r;                                                                             \
    }                                                                                         \
    __device__ __forceinline__ R gpumat_dot(R a, R b) { return a * b; }                       \
    __device__ __forceinline__ R gpumat_dot(V a, V b) { return a.x * b.x + a.y * b.y + a.z * b.z; } \
    __device__ __forceinline__ R gpumat_dot(M a, M b) {                                       \
        R s = a.m[0] * b.m[0];                                                                \
        for (int k = 1; k < 9; ++k) s += a.m[k] * b.m[k];                                     \
        return s;                                                                             \
    }                                                                                         \
    __device__ __forceinline__ R gpumat_squared_norm(R a) { return gpumat_dot(a, a); }        \
    __device__ __forceinline__ R gpumat_squared_norm(V a) { return gpumat_dot(a, a); }        \
    __device__ __forceinline__ R gpumat_squared_norm(M a) { return gpumat_dot(a, a); }        \
    __device__ __forceinline__ R gpumat_transpose(R a) { return a; }                          \
    __device__ __forceinline__ V gpumat_transpose(V a) { return a; }                          \
    __device__ __forceinline__ M gpumat_transpose(M a) {                                      \
        M r;                                                                                  \
        for (int i = 0; i < 3; ++i)                                                           \
            for (int j = 0; j < 3; ++j) r.m[3 * i + j] = a.m[3 * j + i];                      \
        return r;                                                                             \
    }                                                                                         \
    /* the diagonal of a block as a vector (BlockScalar::block_diagonal) */                   \
    __device__ __forceinline__ R gpumat_block_diagonal(R a) { return a; }                     \
    __device__ __forceinline__ V gpumat_block_diagonal(M a) {                                 \
        V r;                                                                                  \
        r.x = a.m[0];                                                                         \
        r.y = a.m[4];                                                                         \
        r.z = a.m[8];                                                                         \
        r.w = 0;                                                                              \
        return r;                                                                             \
    }                                                                                         \
    /* adj(A) / det(A); *ok = false when det is zero or not finite */                         \
    __device__ __forceinline__ M gpumat_inverse3(M a, bool* ok) {                             \
        const R* m = a.m;                                                                     \
        M c;                                                                                  \
        c.m[0] = m[4] * m[8] - m[5] * m[7];                                                   \
        c.m[1] = m[2] * m[7] - m[1] * m[8];                                                   \
        c.m[2] = m[1] * m[5] - m[2] * m[4];                                                   \
        c.m[3] = m[5] * m[6] - m[3] * m[8];                                                   \
        c.m[4] = m[0] * m[8] - m[2] * m[6];                                                   \
        c.m[5] = m[2] * m[3] - m[0] * m[5];                                                   \
        c.m[6] = m[3] * m[7] - m[4] * m[6];                                                   \
        c.m[7] = m[1] * m[6] - m[0] * m[7];                                                   \
        c.m[8] = m[0] * m[4] - m[1] * m[3];                                                   \
        const R det = m[0] * c.m[0] + m[1] * c.m[3] + m[2] * c.m[6];                          \
        *ok = det != 0 && isfinite(det);                                                      \
        const R inv = R(1) / det;                                                             \
        return c * inv;                                                                       \
    }

GPUMAT_BLOCK_OPS(float4, gpumat_mat3f, float)
GPUMAT_BLOCK_OPS(double4, gpumat_mat3d, double)
#undef GPUMAT_BLOCK_OPS

// ---- casts (Rust CastFrom): gpumat_cast<To>(from) -------------------------------------------

template <typename To, typename From>
struct gpumat_caster;
#define GPUMAT_CAST(TO, FROM, BODY)                                                           \
    template <>                                                                               \
    struct gpumat_caster<TO, FROM> {                                                          \
        static __device__ __forceinline__ TO run(FROM a) { BODY }                             \
    };
GPUMAT_CAST(float, float, return a;)
GPUMAT_CAST(double, double, return a;)
GPUMAT_CAST(float, double, return (float)a;)
GPUMAT_CAST(double, float, return (double)a;)
// s -> (s, s, s)
GPUMAT_CAST(float4, float, return gpumat_splat<float4>(a);)
GPUMAT_CAST(double4, double, return gpumat_splat<double4>(a);)
// s -> s I
GPUMAT_CAST(gpumat_mat3f, float, return gpumat_one<gpumat_mat3f>() * a;)
GPUMAT_CAST(gpumat_mat3d, double, return gpumat_one<gpumat_mat3d>() * a;)
// v -> diag(v)
GPUMAT_CAST(gpumat_mat3f, float4, gpumat_mat3f r = gpumat_zero<gpumat_mat3f>(); r.m[0] = a.x;
            r.m[4] = a.y; r.m[8] = a.z; return r;)
GPUMAT_CAST(gpumat_mat3d, double4, gpumat_mat3d r = gpumat_zero<gpumat_mat3d>(); r.m[0] = a.x;
            r.m[4] = a.y; r.m[8] = a.z; return r;)
// precision changes, lane by lane
GPUMAT_CAST(float4, double4, float4 r; r.x = (float)a.x; r.y = (float)a.y; r.z = (float)a.z;
            r.w = 0.0f; return r;)
GPUMAT_CAST(double4, float4, double4 r; r.x = a.x; r.y = a.y; r.z = a.z; r.w = 0.0; return r;)
GPUMAT_CAST(float4, float4, return a;)
GPUMAT_CAST(double4, double4, return a;)
GPUMAT_CAST(gpumat_mat3f, gpumat_mat3d, gpumat_mat3f r;
            for (int k = 0; k < 9; ++k) r.m[k] = (float)a.m[k]; return r;)
GPUMAT_CAST(gpumat_mat3d, gpumat_mat3f, gpumat_mat3d r;
            for (int k = 0; k < 9; ++k) r.m[k] = a.m[k]; return r;)
GPUMAT_CAST(gpumat_mat3f, gpumat_mat3f, return a;)
GPUMAT_CAST(gpumat_mat3d, gpumat_mat3d, return a;)
#undef GPUMAT_CAST

template <typename To, typename From>
__device__ __forceinline__ To gpumat_cast(From a) {
    return gpumat_caster<To, From>::run(a);
}
