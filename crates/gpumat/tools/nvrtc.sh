#!/usr/bin/env bash
# Installs NVIDIA's NVRTC (the CUDA runtime compiler, no GPU needed) from its pinned PyPI wheel
# into a local folder, for gpumat's compile check (crates/gpumat/tests/nvrtc_compile.rs).
#
#   crates/gpumat/tools/nvrtc.sh            # installs if missing, prints the library folder
#   export GPUMAT_NVRTC_DIR=$(crates/gpumat/tools/nvrtc.sh)
#
# Target: $CARGO_TARGET_DIR/nvrtc, else <workspace>/target/nvrtc. Idempotent: a second run with
# the same pin finds the stamp file and only prints the folder. Everything but the folder goes
# to stderr, so the script's stdout can be captured.
set -euo pipefail
PIN="nvidia-cuda-nvrtc-cu12==12.9.86"
ROOT="$(cd "$(dirname "$0")/../../.." && pwd)"
DEST="${CARGO_TARGET_DIR:-$ROOT/target}/nvrtc"
STAMP="$DEST/.installed"
find_lib_dir() {
    local lib
    lib="$(find "$DEST" -name 'libnvrtc.so*' -not -name '*builtins*' -print -quit 2>/dev/null || true)"
    [ -n "$lib" ] && dirname "$lib"
}
if [ ! -f "$STAMP" ] || [ "$(cat "$STAMP")" != "$PIN" ] || [ -z "$(find_lib_dir)" ]; then
    PY="$(command -v python3 || command -v python || true)"
    if [ -z "$PY" ]; then
        echo "nvrtc.sh: python3 not found (needed for pip)" >&2
        exit 1
    fi
    echo "nvrtc.sh: installing $PIN into $DEST" >&2
    rm -rf "$DEST"
    mkdir -p "$DEST"
    "$PY" -m pip install --quiet --disable-pip-version-check --no-deps --target "$DEST" "$PIN" >&2
    echo "$PIN" >"$STAMP"
fi
DIR="$(find_lib_dir)"
if [ -z "$DIR" ]; then
    echo "nvrtc.sh: $PIN installed but no libnvrtc.so* under $DEST" >&2
    exit 1
fi
echo "$DIR"
