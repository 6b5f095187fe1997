"""numpy peer of Tables B.1/B.2: d = sum_i alpha_i v_i over k float32 vectors of length n.

Written as a numpy user writes it, ``d = a[0] * v[0] + a[1] * v[1] + ...``: every product and
every sum is its own pass with a temporary (as in the thesis' numpy column). Inputs are the
counter-based splitmix64 numbers of crates/bench/src/problems.rs; the timing policy is the one
of crates/bench/src/timing.rs.

usage: python3 lincomb.py N K BUDGET_S MIN_SAMPLES MAX_SAMPLES MIN_SAMPLE_S [f32|f64]
(f64: the same numbers widened to float64, the dtype numpy users get by default)
prints: time_s=... samples=... inner=... checksum=... numpy=...
"""

import math
import sys
import time

import numpy as np

FACTOR_SEED = 7
VECTOR_SEED = 1000
GOLDEN = np.uint64(0x9E3779B97F4A7C15)
M1 = np.uint64(0xBF58476D1CE4E5B9)
M2 = np.uint64(0x94D049BB133111EB)


def splitmix64(seed, idx):
    """Output idx (a uint64 array) of the splitmix64 sequence started at seed."""
    with np.errstate(over="ignore"):
        z = np.uint64(seed) + (idx + np.uint64(1)) * GOLDEN
        z = (z ^ (z >> np.uint64(30))) * M1
        z = (z ^ (z >> np.uint64(27))) * M2
        return z ^ (z >> np.uint64(31))


def uniform01(seed, idx):
    return (splitmix64(seed, idx) >> np.uint64(40)).astype(np.float32) * np.float32(1.0 / 16777216.0)


def measure(budget, min_samples, max_samples, min_sample, f):
    t0 = time.perf_counter()
    f()
    first = time.perf_counter() - t0
    inner = 1 if first >= min_sample else min(10_000_000, max(1, math.ceil(min_sample / max(first, 1e-9))))
    start = time.perf_counter()
    best = math.inf
    samples = 0
    while samples < max_samples and (samples < min_samples or time.perf_counter() - start < budget):
        t = time.perf_counter()
        for _ in range(inner):
            f()
        best = min(best, (time.perf_counter() - t) / inner)
        samples += 1
    return best, samples, inner


def main(argv):
    if len(argv) not in (7, 8) or (len(argv) == 8 and argv[7] not in ("f32", "f64")):
        print(__doc__, file=sys.stderr)
        return 2
    dtype = np.float64 if len(argv) == 8 and argv[7] == "f64" else np.float32
    n, k = int(argv[1]), int(argv[2])
    budget, min_samples, max_samples, min_sample = float(argv[3]), int(argv[4]), int(argv[5]), float(argv[6])
    idx = np.arange(n, dtype=np.uint64)
    v = [(np.float32(2.0) * uniform01(VECTOR_SEED + i, idx) - np.float32(1.0)).astype(dtype) for i in range(k)]
    a = [dtype(x) for x in uniform01(FACTOR_SEED, np.arange(k, dtype=np.uint64))]
    out = {}

    def run():
        d = a[0] * v[0]
        for i in range(1, k):
            d = d + a[i] * v[i]
        out["d"] = d

    best, samples, inner = measure(budget, min_samples, max_samples, min_sample, run)
    d = out["d"]
    assert d.dtype == dtype
    print(
        f"time_s={best:.9g} samples={samples} inner={inner} "
        f"checksum={float(d.astype(np.float64).sum()):.9g} numpy={np.__version__}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
