#!/usr/bin/env bash
# Covariance calibration study (docs/BENCHMARKS.md, "Bayesian ICP covariance
# calibration"): simulated spinning-LiDAR scan pairs with exactly known relative pose
# (sim/, static poses, 1 cm range noise, initial-guess error 2 deg / 10 cm per axis) in
# three office-generator scenes (tuning: default, open-plan, narrow; plus a stair tower
# and a crate corridor reported as tuning checks, not in the scale fit), the hall and
# staircase scenes (held out) and a degenerate corridor (held out); per method (closed
# form, Censi, cluster sandwich, Bayesian ICP: old model A, i.i.d. sigma, alternative
# noise models and association variants, the new default, and it with a prior) the
# coverage of the 95 % ellipsoid, mean and median NEES and the time per pair. The new
# default (the library's defaults: Cauchy 0.05 m association with a planarity gate of
# 0.1, the field-of-view and visibility gates and normals of 20 neighbours, 48-cell CR3
# cluster-sandwich sigma + block tempering) has its scale re-fitted on 4 x PAIRS pairs
# of each tuning scene only, before any held-out scene is simulated. Extra arguments go
# to the benchmark binary, e.g. `--fresh 162 163` adds hall / staircase pairs of those
# seeds (fresh held-out sets), `--timing` times ~25k-point pairs, `--plane` turns on the
# plane-fit variance.
# Usage: scripts/bench_icp_covariance.sh [PAIRS_PER_SCENE] [BENCH ARGS...]   (default 100)
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
PAIRS="${1:-100}"
shift || true
lisfm_build_bench lisfm_icp_covariance_bench
echo "CPU: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) threads; $(uptime)"
"$LISFM_BUILD_DIR/bench/lisfm_icp_covariance_bench" "$PAIRS" "$@"
