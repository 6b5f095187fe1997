// Eigen peer of Table B.4: CG on the g x g 2D diffusion (Poisson) matrix, f32, Jacobi
// (DiagonalPreconditioner), relative tolerance 1e-4, zero initial guess, right-hand side
// uniform01(42, node) on boundary nodes. Lower|Upper makes Eigen use the full row-major matrix
// in a plain (OpenMP-parallel) SpMV instead of the single-threaded symmetric product; the
// vector operations of Eigen's CG are single-threaded. Timed: preconditioner setup + solve.
// usage: cg G BUDGET_S MIN_SAMPLES MAX_SAMPLES MIN_SAMPLE_S
#include <Eigen/IterativeLinearSolvers>

#include "common.hpp"

using namespace bench;

int main(int argc, char** argv) {
    if (argc < 2) {
        std::fprintf(stderr, "usage: cg G BUDGET_S MIN_SAMPLES MAX_SAMPLES MIN_SAMPLE_S\n");
        return 2;
    }
    const int g = std::atoi(argv[1]);
    const Policy pol = parse_policy(argc, argv, 2);
    const long n = long(g) * g;
    SpMat a = poisson(g);
    Eigen::VectorXf rhs = Eigen::VectorXf::Zero(n);
    for (int x = 0; x < g; ++x)
        for (int y = 0; y < g; ++y)
            if (x == 0 || y == 0 || x == g - 1 || y == g - 1) {
                const long row = y + long(x) * g;
                rhs[row] = uniform01(RHS_SEED, uint64_t(row));
            }
    Eigen::VectorXf result = Eigen::VectorXf::Zero(n);
    long iterations = 0;
    double error = 0;
    bool ok = true;
    typedef Eigen::ConjugateGradient<SpMat, Eigen::Lower | Eigen::Upper, Eigen::DiagonalPreconditioner<float>> Cg;
    Measurement m = measure(pol, [&]() {
        Cg cg(a);
        cg.setTolerance(1e-4f);
        cg.setMaxIterations(2 * n);
        result.noalias() = cg.solve(rhs);
        iterations = cg.iterations();
        error = cg.error();
        ok = cg.info() == Eigen::Success;
        do_not_optimize(result.data());
    });
    // Eigen's loop breaks on convergence before counting the iteration that converged, so
    // `iterations()` is one less than the number of updates (SpMVs in the loop) it made.
    const long updates = ok ? iterations + 1 : iterations;
    std::printf("time_s=%.9g samples=%d inner=%ld iterations=%ld updates=%ld error=%.6g converged=%d "
                "rhs_checksum=%.9g threads=%d\n",
                m.seconds, m.samples, m.inner, iterations, updates, error, ok ? 1 : 0, checksum(rhs),
                Eigen::nbThreads());
    return 0;
}
