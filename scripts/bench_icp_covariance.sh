#!/usr/bin/env bash
# Covariance calibration study (issue 5 item 6): simulated spinning-LiDAR scan
# pairs with exactly known relative pose (sim/, static poses, 1 cm range noise,
# initial-guess error 2 deg / 10 cm per axis) in three office-generator scenes
# (tuning: default, open-plan, narrow; plus a stair tower reported as a tuning check,
# not in the scale fit), the hall and staircase scenes (held out) and a degenerate
# corridor (held out); per method (closed form, Censi, cluster sandwich, Bayesian ICP:
# old model A, i.i.d. sigma, the defaults of sessions 3-5, session 7's try with a
# refinement within 0.2 m, session 9's try with the field-of-view gate, the new
# default, and it with a prior) the coverage of the 95 % ellipsoid, mean and median
# NEES and the time per pair. The new default (session 6:
# Cauchy 0.05 m association with a planarity gate of 0.1 and normals of 20
# neighbours, 48-cell CR1 cluster-sandwich sigma + block tempering; the library's
# defaults) has its scale re-fitted on 4 x PAIRS pairs of each tuning scene only,
# before any held-out scene is simulated. Extra arguments go to the benchmark binary, e.g.
# `--fresh 32 33` adds hall / staircase pairs of those seeds (fresh held-out sets),
# `--timing` times ~25k-point pairs, `--plane` turns on the plane-fit variance.
# Usage: scripts/bench_icp_covariance.sh [PAIRS_PER_SCENE] [BENCH ARGS...]   (default 100)
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
PAIRS="${1:-100}"
shift || true
mkdir -p "$LISFM_BUILD_DIR"
cmake -S "$LISFM_ROOT" -B "$LISFM_BUILD_DIR" -DCMAKE_BUILD_TYPE=Release \
  -DLISFM_BENCHMARKS_ENABLED=ON >"$LISFM_BUILD_DIR/cmake.log" 2>&1 \
  || { cat "$LISFM_BUILD_DIR/cmake.log"; exit 1; }
cmake --build "$LISFM_BUILD_DIR" --target lisfm_icp_covariance_bench -j"$LISFM_JOBS"
echo "CPU: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) threads; $(uptime)"
"$LISFM_BUILD_DIR/icp/lisfm_icp_covariance_bench" "$PAIRS" "$@"
