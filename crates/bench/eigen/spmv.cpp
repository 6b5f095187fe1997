// Eigen peer of Table B.3: y = A x with A the g x g 5-point Poisson matrix (row-major CSR,
// f32 values, int indices). Built with OpenMP, Eigen runs this row-major product on all
// threads (it parallelises sparse row-major * dense when nnz > 20000).
// usage: spmv G BUDGET_S MIN_SAMPLES MAX_SAMPLES MIN_SAMPLE_S
#include "common.hpp"

using namespace bench;

int main(int argc, char** argv) {
    if (argc < 2) {
        std::fprintf(stderr, "usage: spmv G BUDGET_S MIN_SAMPLES MAX_SAMPLES MIN_SAMPLE_S\n");
        return 2;
    }
    const int g = std::atoi(argv[1]);
    const Policy pol = parse_policy(argc, argv, 2);
    SpMat a = poisson(g);
    Eigen::VectorXf x = random_vector(SPMV_X_SEED, long(g) * g);
    Eigen::VectorXf y = Eigen::VectorXf::Zero(long(g) * g);
    Measurement m = measure(pol, [&]() {
        y.noalias() = a * x;
        do_not_optimize(y.data());
        do_not_optimize(y[0]);
    });
    std::printf("time_s=%.9g samples=%d inner=%ld nnz=%ld checksum=%.9g threads=%d\n", m.seconds, m.samples,
                m.inner, long(a.nonZeros()), checksum(y), Eigen::nbThreads());
    return 0;
}
