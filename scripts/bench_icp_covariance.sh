#!/usr/bin/env bash
# Covariance calibration study (issue 5 item 6): simulated spinning-LiDAR scan
# pairs with exactly known relative pose (sim/, static poses, 1 cm range noise,
# initial-guess error 2 deg / 10 cm per axis) in the office (tuning), hall and
# staircase (held out) scenes and a degenerate corridor (held out); per method
# (closed form, Censi, cluster sandwich, Bayesian ICP: old model A, i.i.d. sigma,
# per-pair cluster-sandwich sigma = the default, and the default with a prior) the
# coverage of the 95 % ellipsoid, mean and median NEES and the time per pair. The
# two constants of the default noise model (cells per pair, scale) are re-fitted
# on the office pairs only, before the held-out scenes are simulated.
# Usage: scripts/bench_icp_covariance.sh [PAIRS_PER_SCENE]   (default 100: 300 pairs)
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
PAIRS="${1:-100}"
mkdir -p "$LISFM_BUILD_DIR"
cmake -S "$LISFM_ROOT" -B "$LISFM_BUILD_DIR" -DCMAKE_BUILD_TYPE=Release \
  -DLISFM_BENCHMARKS_ENABLED=ON >"$LISFM_BUILD_DIR/cmake.log" 2>&1 \
  || { cat "$LISFM_BUILD_DIR/cmake.log"; exit 1; }
cmake --build "$LISFM_BUILD_DIR" --target lisfm_icp_covariance_bench -j"$LISFM_JOBS"
echo "CPU: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) threads; $(uptime)"
"$LISFM_BUILD_DIR/icp/lisfm_icp_covariance_bench" "$PAIRS"
