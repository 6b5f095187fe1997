// Eigen peer of Tables B.1/B.2: d = sum_i alpha_i v_i, k f32 vectors of length n, evaluated by
// Eigen's expression templates into a preallocated d (one fused loop, single-threaded: Eigen
// does not parallelise coefficient-wise expressions).
// usage: lincomb N K BUDGET_S MIN_SAMPLES MAX_SAMPLES MIN_SAMPLE_S
#include "common.hpp"

using namespace bench;

int main(int argc, char** argv) {
    if (argc < 3) {
        std::fprintf(stderr, "usage: lincomb N K BUDGET_S MIN_SAMPLES MAX_SAMPLES MIN_SAMPLE_S\n");
        return 2;
    }
    const long n = std::atol(argv[1]);
    const int k = std::atoi(argv[2]);
    const Policy pol = parse_policy(argc, argv, 3);
    if (k < 1 || k > 10) {
        std::fprintf(stderr, "lincomb: K must be in 1..10\n");
        return 2;
    }
    std::vector<Eigen::VectorXf> v(k);
    float a[10];
    for (int i = 0; i < k; ++i) {
        v[i] = random_vector(VECTOR_SEED + i, n);
        a[i] = uniform01(FACTOR_SEED, uint64_t(i));
    }
    Eigen::VectorXf d = Eigen::VectorXf::Zero(n);
    auto run = [&]() {
        switch (k) {
            case 1: d.noalias() = v[0] * a[0]; break;
            case 2: d.noalias() = v[0] * a[0] + v[1] * a[1]; break;
            case 3: d.noalias() = v[0] * a[0] + v[1] * a[1] + v[2] * a[2]; break;
            case 4: d.noalias() = v[0] * a[0] + v[1] * a[1] + v[2] * a[2] + v[3] * a[3]; break;
            case 5: d.noalias() = v[0] * a[0] + v[1] * a[1] + v[2] * a[2] + v[3] * a[3] + v[4] * a[4]; break;
            case 6:
                d.noalias() = v[0] * a[0] + v[1] * a[1] + v[2] * a[2] + v[3] * a[3] + v[4] * a[4] + v[5] * a[5];
                break;
            case 7:
                d.noalias() = v[0] * a[0] + v[1] * a[1] + v[2] * a[2] + v[3] * a[3] + v[4] * a[4] + v[5] * a[5] +
                              v[6] * a[6];
                break;
            case 8:
                d.noalias() = v[0] * a[0] + v[1] * a[1] + v[2] * a[2] + v[3] * a[3] + v[4] * a[4] + v[5] * a[5] +
                              v[6] * a[6] + v[7] * a[7];
                break;
            case 9:
                d.noalias() = v[0] * a[0] + v[1] * a[1] + v[2] * a[2] + v[3] * a[3] + v[4] * a[4] + v[5] * a[5] +
                              v[6] * a[6] + v[7] * a[7] + v[8] * a[8];
                break;
            case 10:
                d.noalias() = v[0] * a[0] + v[1] * a[1] + v[2] * a[2] + v[3] * a[3] + v[4] * a[4] + v[5] * a[5] +
                              v[6] * a[6] + v[7] * a[7] + v[8] * a[8] + v[9] * a[9];
                break;
        }
        do_not_optimize(d.data());
        do_not_optimize(d[n / 2]);
    };
    Measurement m = measure(pol, run);
    std::printf("time_s=%.9g samples=%d inner=%ld checksum=%.9g threads=1\n", m.seconds, m.samples, m.inner,
                checksum(d));
    return 0;
}
