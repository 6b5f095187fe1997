// Shared helpers of the Eigen peer programs of the `tables` benchmark
// (crates/bench/src/timing.rs and problems.rs hold the Rust twins; keep them identical).
#pragma once

#include <Eigen/Core>
#include <Eigen/Sparse>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace bench {

// Counter-based splitmix64: output i of the sequence started at `seed`.
inline uint64_t splitmix64(uint64_t seed, uint64_t i) {
    uint64_t z = seed + (i + 1) * 0x9E3779B97F4A7C15ull;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}
// A float in [0, 1) from the top 24 bits.
inline float uniform01(uint64_t seed, uint64_t i) {
    return float(splitmix64(seed, i) >> 40) * (1.0f / 16777216.0f);
}
inline float uniform_pm1(uint64_t seed, uint64_t i) { return 2.0f * uniform01(seed, i) - 1.0f; }

const uint64_t RHS_SEED = 42, SPMV_X_SEED = 3, FACTOR_SEED = 7, VECTOR_SEED = 1000;

inline Eigen::VectorXf random_vector(uint64_t seed, long n) {
    Eigen::VectorXf v(n);
    for (long i = 0; i < n; ++i) v[i] = uniform_pm1(seed, uint64_t(i));
    return v;
}

inline double checksum(const Eigen::VectorXf& v) {
    double s = 0;
    for (long i = 0; i < v.size(); ++i) s += double(v[i]);
    return s;
}

// The 5-point Laplacian on a g x g grid, Dirichlet boundary, node (x, y) = row y + x g
// (cuMat's IDX), row-major CSR with int indices.
typedef Eigen::SparseMatrix<float, Eigen::RowMajor, int> SpMat;
inline SpMat poisson(int g) {
    const int n = g * g;
    SpMat m(n, n);
    m.reserve(Eigen::VectorXi::Constant(n, 5));
    for (int x = 0; x < g; ++x)
        for (int y = 0; y < g; ++y) {
            const int row = y + x * g;
            if (x > 0) m.insert(row, row - g) = -1.0f;
            if (y > 0) m.insert(row, row - 1) = -1.0f;
            m.insert(row, row) = 4.0f;
            if (y < g - 1) m.insert(row, row + 1) = -1.0f;
            if (x < g - 1) m.insert(row, row + g) = -1.0f;
        }
    m.makeCompressed();
    return m;
}

// Timing policy: BUDGET_S MIN_SAMPLES MAX_SAMPLES MIN_SAMPLE_S (argv[first..first+3]).
struct Policy {
    double budget = 1.0, min_sample = 0.005;
    int min_samples = 5, max_samples = 50;
};
inline Policy parse_policy(int argc, char** argv, int first) {
    Policy p;
    if (argc < first + 4) {
        std::fprintf(stderr, "usage: ... BUDGET_S MIN_SAMPLES MAX_SAMPLES MIN_SAMPLE_S\n");
        std::exit(2);
    }
    p.budget = std::atof(argv[first]);
    p.min_samples = std::atoi(argv[first + 1]);
    p.max_samples = std::atoi(argv[first + 2]);
    p.min_sample = std::atof(argv[first + 3]);
    return p;
}

struct Measurement {
    double seconds;
    int samples;
    long inner;
};

inline double now_s() {
    using C = std::chrono::steady_clock;
    return std::chrono::duration<double>(C::now().time_since_epoch()).count();
}

// One warm-up call calibrates an inner loop lasting >= min_sample; then repetitions until
// >= min_samples and the budget is spent (or max_samples); minimum of time / inner.
template <class F>
Measurement measure(const Policy& p, F&& f) {
    double t0 = now_s();
    f();
    double first = now_s() - t0;
    long inner = first >= p.min_sample ? 1 : long(std::ceil(p.min_sample / std::max(first, 1e-9)));
    if (inner < 1) inner = 1;
    if (inner > 10000000) inner = 10000000;
    double start = now_s(), best = 1e300;
    int samples = 0;
    while (samples < p.max_samples && (samples < p.min_samples || now_s() - start < p.budget)) {
        double t = now_s();
        for (long i = 0; i < inner; ++i) f();
        best = std::min(best, (now_s() - t) / double(inner));
        ++samples;
    }
    return Measurement{best, samples, inner};
}

// Keeps the optimiser from dropping a computation.
template <class T>
inline void do_not_optimize(T const& value) {
    asm volatile("" : : "r,m"(value) : "memory");
}

}  // namespace bench
