"""scipy peer of Table B.3-bsr: y = K x with the held cuboid's stiffness matrix, as scipy's
bsr_matrix (blocksize 3) and as csr_matrix of the same matrix (every block's 9 entries).

The matrix file is the one `tables` writes (crates/bench/src/table_bsr.rs: u64 block rows n,
u64 blocks nnz, u64 row pointers [n + 1], u32 block columns [nnz], f64 row-major 3x3 blocks
[9 nnz]); x_j = 2 u(SPMV_X_SEED, j) - 1 as in lincomb.py's generator (f32, widened). The timing
policy is the one of crates/bench/src/timing.rs (lincomb.py's measure).

usage: python3 bsr_spmv.py FILE BUDGET_S MIN_SAMPLES MAX_SAMPLES MIN_SAMPLE_S
prints: time_s=... (bsr) csr_s=... samples=... checksum=... (sum of y, bsr) csr_checksum=...
"""

import os
import sys

import numpy as np
import scipy
import scipy.sparse

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from lincomb import measure, uniform01  # noqa: E402

SPMV_X_SEED = 3


def main(argv):
    if len(argv) != 6:
        print(__doc__, file=sys.stderr)
        return 2
    budget, min_samples, max_samples, min_sample = float(argv[2]), int(argv[3]), int(argv[4]), float(argv[5])
    raw = open(argv[1], "rb").read()
    n, nnz = np.frombuffer(raw, dtype="<u8", count=2)
    n, nnz = int(n), int(nnz)
    off = 16
    row_ptr = np.frombuffer(raw, dtype="<u8", count=n + 1, offset=off).astype(np.int64)
    off += 8 * (n + 1)
    col = np.frombuffer(raw, dtype="<u4", count=nnz, offset=off).astype(np.int32)
    off += 4 * nnz
    val = np.frombuffer(raw, dtype="<f8", count=9 * nnz, offset=off).reshape(nnz, 3, 3)
    if off + 72 * nnz != len(raw):
        print(f"bsr_spmv.py: {argv[1]} has {len(raw)} bytes, expected {off + 72 * nnz}", file=sys.stderr)
        return 1
    bsr = scipy.sparse.bsr_matrix((val, col, row_ptr), shape=(3 * n, 3 * n))
    csr = bsr.tocsr()
    x = (np.float32(2.0) * uniform01(SPMV_X_SEED, np.arange(3 * n, dtype=np.uint64)) - np.float32(1.0)).astype(np.float64)
    out = {}

    def run_bsr():
        out["b"] = bsr @ x

    def run_csr():
        out["c"] = csr @ x

    tb, samples, inner = measure(budget, min_samples, max_samples, min_sample, run_bsr)
    tc, _, _ = measure(budget, min_samples, max_samples, min_sample, run_csr)
    print(
        f"time_s={tb:.9g} csr_s={tc:.9g} samples={samples} inner={inner} nnz={csr.nnz} "
        f"checksum={float(out['b'].sum()):.17g} csr_checksum={float(out['c'].sum()):.17g} scipy={scipy.__version__}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
