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
run() {
  local name=$1 truth=$2 start=$3 radius=$4 noise=$5
  shift 5
  for sigma in 0 "$noise"; do
    local tag="$name-noise$sigma"
    $SB observe "$truth" --out "$OUT/$tag.csv" --radius "$radius" --noise "$sigma" --seed 1 --json > "$OUT/$tag.observe.json"
    for opt in gauss-newton lbfgs; do
      $SB fit "$start" --observations "$OUT/$tag.csv" --optimizer "$opt" --out "$OUT/$tag-$opt" --json "$@" \
        > "$OUT/$tag-$opt.json"
      python3 -c "import json,sys; d=json.load(open('$OUT/$tag-$opt.json')); print('$tag', '$opt', d['parameters'], 'rms', d['rms'], d['iterations'], d['termination'], round(d['seconds'],1), 's')"
    done
  done
}

run torus_material $S/swinging_torus.toml $S/fit/torus_material.toml 3 0.025
run torus_damping  $S/swinging_torus.toml $S/fit/torus_damping.toml 3 0.025
run bunny_ground   $S/fit/bunny_tilted_ground.toml $S/fit/bunny_ground_start.toml 12 0.1
run dragon_young   $S/dragon_swing.toml $S/fit/dragon_young.toml 12 0.05
