// Eigen peer of Table B.3-bsr: y = K x with the held cuboid's stiffness matrix read from the
// file `tables` writes (crates/bench/src/table_bsr.rs: u64 block rows n, u64 blocks nnz, u64 row
// pointers [n + 1], u32 block columns [nnz], f64 row-major 3x3 blocks [9 nnz]), as a scalar
// row-major CSR SparseMatrix<double> (Eigen has no block format), every block's 9 entries
// stored. x_j = 2 u(SPMV_X_SEED, j) - 1 (f32, widened). Built with OpenMP, Eigen runs this
// row-major product on all threads.
// usage: bsr_spmv FILE BUDGET_S MIN_SAMPLES MAX_SAMPLES MIN_SAMPLE_S
#include "common.hpp"

using namespace bench;

int main(int argc, char** argv) {
    if (argc < 2) {
        std::fprintf(stderr, "usage: bsr_spmv FILE BUDGET_S MIN_SAMPLES MAX_SAMPLES MIN_SAMPLE_S\n");
        return 2;
    }
    const Policy pol = parse_policy(argc, argv, 2);
    std::FILE* f = std::fopen(argv[1], "rb");
    if (!f) {
        std::fprintf(stderr, "bsr_spmv: cannot open %s\n", argv[1]);
        return 1;
    }
    uint64_t n = 0, nnz = 0;
    bool ok = std::fread(&n, 8, 1, f) == 1 && std::fread(&nnz, 8, 1, f) == 1;
    std::vector<uint64_t> row_ptr(n + 1);
    std::vector<uint32_t> col(nnz);
    std::vector<double> val(9 * nnz);
    ok = ok && std::fread(row_ptr.data(), 8, n + 1, f) == n + 1 && std::fread(col.data(), 4, nnz, f) == nnz &&
         std::fread(val.data(), 8, 9 * nnz, f) == 9 * nnz;
    std::fclose(f);
    if (!ok) {
        std::fprintf(stderr, "bsr_spmv: %s is truncated\n", argv[1]);
        return 1;
    }
    typedef Eigen::SparseMatrix<double, Eigen::RowMajor, int> DMat;
    DMat a(long(3 * n), long(3 * n));
    a.reserve(Eigen::VectorXi::Constant(long(3 * n), 0));
    std::vector<Eigen::Triplet<double, int>> t;
    t.reserve(9 * nnz);
    for (uint64_t br = 0; br < n; ++br)
        for (uint64_t e = row_ptr[br]; e < row_ptr[br + 1]; ++e)
            for (int r = 0; r < 3; ++r)
                for (int c = 0; c < 3; ++c)
                    t.emplace_back(int(3 * br + r), int(3 * col[e] + c), val[9 * e + 3 * r + c]);
    a.setFromTriplets(t.begin(), t.end());
    a.makeCompressed();
    Eigen::VectorXd x = random_vector(SPMV_X_SEED, long(3 * n)).cast<double>();
    Eigen::VectorXd y = Eigen::VectorXd::Zero(long(3 * n));
    Measurement m = measure(pol, [&]() {
        y.noalias() = a * x;
        do_not_optimize(y.data());
        do_not_optimize(y[0]);
    });
    std::printf("time_s=%.9g samples=%d inner=%ld nnz=%ld checksum=%.17g threads=%d\n", m.seconds, m.samples,
                m.inner, long(a.nonZeros()), y.sum(), Eigen::nbThreads());
    return 0;
}
