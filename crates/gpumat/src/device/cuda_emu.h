// cuda_emu.h: test-only host emulation of the CUDA subset gpumat's kernels use, so the same
// generated sources compile with the system C++ compiler (g++ -std=c++20 -include cuda_emu.h)
// and run on the CPU (tests/emulated.rs).
//
// A launch runs the grid's blocks one after another; a block's threads are OS threads (a pool
// reused by every block), and
// __syncthreads is a std::barrier of the block (a thread that returns drops out of it, as an
// exited CUDA thread no longer takes part). __shared__ is a function-local static: blocks do not
// overlap, so it is the running block's shared memory. Launches are serialised by the caller.
#pragma once
#include <barrier>
#include <cmath>
#include <cstring>
#include <thread>
#include <vector>

#define __global__
#define __device__
#define __host__
#define __forceinline__ inline
#define __restrict__ __restrict
#define __shared__ static

struct dim3 {
    unsigned x = 1, y = 1, z = 1;
};
struct uint3 {
    unsigned x = 0, y = 0, z = 0;
};
inline thread_local uint3 threadIdx, blockIdx;
inline thread_local dim3 blockDim, gridDim;
inline std::barrier<>* gpumat_emu_block_barrier = nullptr;
inline void __syncthreads() { gpumat_emu_block_barrier->arrive_and_wait(); }

struct alignas(16) float4 {
    float x, y, z, w;
};
struct alignas(16) double4 {
    double x, y, z, w;
};

inline float __int_as_float(int i) {
    float f;
    std::memcpy(&f, &i, sizeof f);
    return f;
}
inline double __longlong_as_double(long long i) {
    double d;
    std::memcpy(&d, &i, sizeof d);
    return d;
}
using std::ceil;
using std::cos;
using std::exp;
using std::fabs;
using std::floor;
using std::fmax;
using std::fmin;
using std::isfinite;
using std::log;
using std::log1p;
using std::pow;
using std::sin;
using std::sqrt;
using std::tan;
using std::tanh;
inline float rsqrt(float x) { return 1.0f / std::sqrt(x); }
inline double rsqrt(double x) { return 1.0 / std::sqrt(x); }

// The block's threads: a pool of `bx` OS threads made once (per block size) and reused by every
// block of every launch, so that a launch costs two barrier crossings per block instead of `bx`
// thread creations. Each block gets a fresh __syncthreads barrier (a thread that returns drops
// out of it). The pool is never destroyed: its threads wait at the start barrier until the
// process ends.
struct gpumat_emu_pool {
    unsigned bx = 0;
    std::vector<std::thread> threads;
    std::barrier<>* start = nullptr;
    std::barrier<>* done = nullptr;
    void (*thunk)(void**) = nullptr;
    void** args = nullptr;
    unsigned bk = 0, by = 0, gx = 0, gy = 0;
    bool quit = false;
};

inline gpumat_emu_pool* gpumat_emu_make_pool(unsigned bx) {
    auto* pool = new gpumat_emu_pool;
    pool->bx = bx;
    pool->start = new std::barrier<>(bx + 1);
    pool->done = new std::barrier<>(bx + 1);
    for (unsigned t = 0; t < bx; ++t) {
        pool->threads.emplace_back([pool, t] {
            for (;;) {
                pool->start->arrive_and_wait();
                if (pool->quit) return;
                threadIdx = uint3{t, 0, 0};
                blockIdx = uint3{pool->bk, pool->by, 0};
                blockDim = dim3{pool->bx, 1, 1};
                gridDim = dim3{pool->gx, pool->gy, 1};
                pool->thunk(pool->args);
                gpumat_emu_block_barrier->arrive_and_drop();
                pool->done->arrive_and_wait();
            }
        });
    }
    return pool;
}

// Runs `thunk(args)` (a kernel taking cuLaunchKernel-style arguments: args[i] points at the
// i-th argument's value) on a grid of gx x gy blocks of bx threads.
extern "C" void gpumat_emu_launch(void (*thunk)(void**), void** args, unsigned gx, unsigned gy,
                                  unsigned bx) {
    static gpumat_emu_pool* pool = nullptr;
    if (pool == nullptr || pool->bx != bx) {
        if (pool != nullptr) {
            pool->quit = true;
            pool->start->arrive_and_wait();
            for (auto& th : pool->threads) th.join();
        }
        pool = gpumat_emu_make_pool(bx);
    }
    pool->thunk = thunk;
    pool->args = args;
    pool->gx = gx;
    pool->gy = gy;
    for (unsigned by = 0; by < gy; ++by) {
        for (unsigned bk = 0; bk < gx; ++bk) {
            std::barrier<> bar(bx);
            gpumat_emu_block_barrier = &bar;
            pool->bk = bk;
            pool->by = by;
            pool->start->arrive_and_wait();
            pool->done->arrive_and_wait();
        }
    }
}
