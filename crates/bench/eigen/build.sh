#!/usr/bin/env bash
# Builds the Eigen peer programs of the `tables` benchmark into OUTDIR (skipping programs that
# are up to date) and writes OUTDIR/info.txt (compiler, flags, Eigen version).
#
#   usage: crates/bench/eigen/build.sh OUTDIR
#
# Flags: -O3 -march=native -fopenmp. OpenMP matters only for the sparse products: Eigen then
# runs row-major sparse * dense vector products (SpMV, and the SpMV inside CG with
# Lower|Upper) on all cores; its coefficient-wise vector expressions stay single-threaded.
# Environment: CXX (default g++), EIGEN_INCLUDE (default /usr/include/eigen3).
# Exit status 2: no compiler; 3: no Eigen headers (apt-get install libeigen3-dev).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
out="${1:?usage: build.sh OUTDIR}"
CXX="${CXX:-g++}"
EIGEN_INCLUDE="${EIGEN_INCLUDE:-/usr/include/eigen3}"
FLAGS="-O3 -march=native -fopenmp -DNDEBUG -std=c++17"

if ! command -v "$CXX" >/dev/null 2>&1; then
    echo "no C++ compiler ($CXX not found)" >&2
    exit 2
fi
if [ ! -f "$EIGEN_INCLUDE/Eigen/Core" ]; then
    echo "Eigen headers not found in $EIGEN_INCLUDE (apt-get install libeigen3-dev)" >&2
    exit 3
fi
mkdir -p "$out"
for src in "$here"/*.cpp; do
    name="$(basename "$src" .cpp)"
    bin="$out/$name"
    if [ -x "$bin" ] && [ "$bin" -nt "$src" ] && [ "$bin" -nt "$here/common.hpp" ] && [ "$bin" -nt "$here/build.sh" ]; then
        continue
    fi
    # shellcheck disable=SC2086
    "$CXX" $FLAGS -I"$EIGEN_INCLUDE" "$src" -o "$bin.tmp"
    mv "$bin.tmp" "$bin"
done
macros="$EIGEN_INCLUDE/Eigen/src/Core/util/Macros.h"
ver() { sed -n "s/^#define EIGEN_$1_VERSION \([0-9]*\).*/\1/p" "$macros" | head -1; }
{
    echo "compiler=$("$CXX" --version | head -1)"
    echo "flags=$FLAGS"
    echo "eigen=$(ver WORLD).$(ver MAJOR).$(ver MINOR)"
} >"$out/info.txt"
