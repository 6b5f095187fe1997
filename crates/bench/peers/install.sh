#!/usr/bin/env bash
# Installs the peers of the `tables` benchmark the way a user would, so that `tables` can run
# them side by side with ours:
#
#   - numpy, scipy and scikit-fem in a local virtual environment from PyPI
#     (target/bench-venv; `tables` uses its python when it exists, else $PYTHON, else python3);
#   - Eigen from Debian's libeigen3-dev (apt; needs root), built by crates/bench/eigen/build.sh
#     with g++ -O3 -march=native when `tables` starts;
#   - faer needs nothing: it is a crates.io dependency, run in-process.
#
#   usage: crates/bench/peers/install.sh [--python-only] [VENV]   (default VENV: target/bench-venv)
#
# --python-only: the python peers only (what .ci/run installs for the step-peer test).
#
# A peer that cannot be installed is reported here and shows as null / "not available" in the
# tables; nothing is estimated. Versions: crates/bench/peers/requirements.txt.
set -uo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../../.." && pwd)"
python_only=0
if [ "${1:-}" = "--python-only" ]; then
    python_only=1
    shift
fi
venv="${1:-$root/target/bench-venv}"
status=0

make_venv() {
    [ -x "$venv/bin/pip" ] || python3 -m venv "$venv" >/dev/null 2>&1
}
# Debian's python3 makes virtual environments only with python3-venv
if ! make_venv && [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    { DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-venv >/dev/null 2>&1 \
        || { apt-get update -qq >/dev/null 2>&1 && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-venv >/dev/null 2>&1; }; } \
        && rm -rf "$venv"
fi
if make_venv; then
    if "$venv/bin/pip" install --quiet --disable-pip-version-check -r "$here/requirements.txt"; then
        "$venv/bin/python" -c "import numpy, scipy, skfem; print('python peers:', 'numpy', numpy.__version__, 'scipy', scipy.__version__, 'scikit-fem', skfem.__version__)"
    else
        echo "python peers not available: pip install -r $here/requirements.txt failed" >&2
        status=1
    fi
else
    echo "python peers not available: python3 -m venv failed (Debian: apt-get install python3-venv)" >&2
    status=1
fi

if [ $python_only = 1 ]; then
    exit $status
fi
if [ -f /usr/include/eigen3/Eigen/Core ]; then
    echo "Eigen: found in /usr/include/eigen3"
elif [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    if DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libeigen3-dev g++ >/dev/null 2>&1 \
        || { apt-get update -qq >/dev/null 2>&1 && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libeigen3-dev g++ >/dev/null 2>&1; }; then
        echo "Eigen: installed libeigen3-dev"
    else
        echo "Eigen not available: apt-get install libeigen3-dev failed" >&2
        status=1
    fi
else
    echo "Eigen not available: run as root, or: sudo apt-get install libeigen3-dev g++" >&2
    status=1
fi
exit $status
