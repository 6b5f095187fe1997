#!/usr/bin/env bash
# Reproduces the reconstruction experiments of docs/results.md (thesis sec. 5.8):
# virtual cameras observe a simulation with known parameters, then `softbody fit` recovers
# them from a wrong start, without and with depth noise of half a voxel.
#
#   bash examples/experiments.sh [OUT]      (default OUT: out/experiments)
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${1:-out/experiments}
mkdir -p "$OUT"
cargo build --release -p softbody
SB=target/release/softbody
S=examples/scenes

# name | truth scene | start scene | camera radius | noise (half a voxel) | extra fit flags
# Noise-free: 4 cameras of 32x32 pixels, Gauss-Newton and L-BFGS. With noise: 8 cameras of
# 64x64 pixels (about 8x the points, so the statistical error halves twice), Gauss-Newton.
# `observe` writes the camera eyes beside the CSV, so `fit` measures residuals along the rays.
run() {
  local name=$1 truth=$2 start=$3 radius=$4 noise=$5
  shift 5
  local tag="$name-noise0"
  $SB observe "$truth" --out "$OUT/$tag.csv" --radius "$radius" --seed 1 --json > "$OUT/$tag.observe.json"
  for opt in gauss-newton lbfgs; do
    fit "$tag" "$start" "$opt" "$@"
  done
  tag="$name-noise$noise"
  $SB observe "$truth" --out "$OUT/$tag.csv" --radius "$radius" --noise "$noise" --seed 1 \
    --cameras 8 --pixels 64 --json > "$OUT/$tag.observe.json"
  fit "$tag" "$start" gauss-newton "$@"
}

fit() {
  local tag=$1 start=$2 opt=$3
  shift 3
  $SB fit "$start" --observations "$OUT/$tag.csv" --optimizer "$opt" --out "$OUT/$tag-$opt" --json "$@" \
    > "$OUT/$tag-$opt.json"
  python3 -c "import json; d=json.load(open('$OUT/$tag-$opt.json')); print('$tag', '$opt', d['parameters'], 'se', d['standard_errors'], 'rms', d['rms'], d['iterations'], d['termination'], round(d['seconds'],1), 's')"
}

run torus_material $S/swinging_torus.toml $S/fit/torus_material.toml 3 0.025
run torus_damping  $S/swinging_torus.toml $S/fit/torus_damping.toml 3 0.025
run bunny_ground   $S/fit/bunny_tilted_ground.toml $S/fit/bunny_ground_start.toml 12 0.1
run dragon_young   $S/dragon_swing.toml $S/fit/dragon_young.toml 12 0.05
