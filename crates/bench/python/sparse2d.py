"""scipy peer of Tables B.3 and B.4: the g x g 5-point Poisson matrix (f32, node (x, y) = row
y + x g, Dirichlet boundary; crates/bench/src/problems.rs) as scipy's csr_matrix.

  spmv G  y = A x, x_j = 2 u(SPMV_X_SEED, j) - 1; prints time_s, checksum (sum of y), nnz
  cg G    scipy.sparse.linalg.cg with a Jacobi preconditioner, relative tolerance 1e-4, x0 = 0,
          right-hand side u(RHS_SEED, node) on boundary nodes; timed: preconditioner setup +
          solve; prints time_s, iterations (updates of x, as gpumat counts them), rhs_checksum

The timing policy is the one of crates/bench/src/timing.rs (lincomb.py's measure).
usage: python3 sparse2d.py spmv|cg G BUDGET_S MIN_SAMPLES MAX_SAMPLES MIN_SAMPLE_S
"""

import os
import sys

import numpy as np
import scipy
import scipy.sparse
import scipy.sparse.linalg as spla

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from lincomb import measure, uniform01  # noqa: E402

SPMV_X_SEED, RHS_SEED = 3, 42


def poisson(g):
    t = scipy.sparse.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(g, g), dtype=np.float32)
    eye = scipy.sparse.identity(g, dtype=np.float32)
    return (scipy.sparse.kron(t, eye) + scipy.sparse.kron(eye, t)).tocsr().astype(np.float32)


def main(argv):
    if len(argv) != 7 or argv[1] not in ("spmv", "cg"):
        print(__doc__, file=sys.stderr)
        return 2
    mode, g = argv[1], int(argv[2])
    budget, min_samples, max_samples, min_sample = float(argv[3]), int(argv[4]), int(argv[5]), float(argv[6])
    a = poisson(g)
    a.sort_indices()
    n = g * g
    out = {}
    if mode == "spmv":
        x = np.float32(2.0) * uniform01(SPMV_X_SEED, np.arange(n, dtype=np.uint64)) - np.float32(1.0)

        def run():
            out["y"] = a @ x

        t, samples, inner = measure(budget, min_samples, max_samples, min_sample, run)
        y = out["y"]
        assert y.dtype == np.float32
        print(
            f"time_s={t:.9g} samples={samples} inner={inner} nnz={a.nnz} "
            f"checksum={float(y.astype(np.float64).sum()):.9g} scipy={scipy.__version__}"
        )
        return 0
    node = np.arange(n)
    xs, ys = node // g, node % g
    boundary = (xs == 0) | (ys == 0) | (xs == g - 1) | (ys == g - 1)
    b = np.where(boundary, uniform01(RHS_SEED, node.astype(np.uint64)), np.float32(0.0)).astype(np.float32)

    def run():
        inv = (np.float32(1.0) / a.diagonal()).astype(np.float32)
        jacobi = spla.LinearOperator(a.shape, matvec=lambda r: inv * r, dtype=np.float32)
        count = [0]

        def counter(_xk):
            count[0] += 1

        try:
            x, info = spla.cg(a, b, rtol=1e-4, atol=0.0, maxiter=2 * n, M=jacobi, callback=counter)
        except TypeError:  # scipy < 1.12
            x, info = spla.cg(a, b, tol=1e-4, atol=0.0, maxiter=2 * n, M=jacobi, callback=counter)
        out["x"], out["info"], out["its"] = x, info, count[0]

    t, samples, inner = measure(budget, min(min_samples, 3), max_samples, min_sample, run)
    r = b - a @ out["x"]
    residual = float(np.linalg.norm(r) / np.linalg.norm(b))
    print(
        f"time_s={t:.9g} samples={samples} inner={inner} iterations={out['its']} "
        f"converged={int(out['info'] == 0)} residual={residual:.6g} "
        f"rhs_checksum={float(b.astype(np.float64).sum()):.9g} scipy={scipy.__version__}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
