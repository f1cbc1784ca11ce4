#!/usr/bin/env bash
# ICP benchmark: lisfm point-to-plane / Bayesian ICP vs PCL
# IterativeClosestPointWithNormals, PCL GICP and Open3D point-to-plane on the real
# pairs of ../shared/data (registration_lidar_pair, bunny bun0->bun4, consecutive
# lidar_balm_realworld_subset scans 30..39). Whole process per method: load,
# voxel downsampling, normals, registration (median of REPEATS runs).
# Usage: scripts/bench_icp.sh [REPEATS]   (prints markdown tables for docs/BENCHMARKS.md)
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
REPEATS="${1:-3}"
lisfm_build_bench lisfm_icp_bench
# The methods run interleaved (every round runs each once). PCL and Open3D use
# OpenMP, whose idle worker threads spin by default for a while after each
# parallel region: on 2 cores they then steal the next method's cores (our whole
# process measured 20-40 % slower right after a PCL / Open3D run). Passive waiting
# removes that cross-library artefact; PCL's own times are unchanged by it
# (docs/BENCHMARKS.md, "ICP registration vs PCL and Open3D"). Set OMP_WAIT_POLICY to
# override.
export OMP_WAIT_POLICY="${OMP_WAIT_POLICY:-passive}"
echo "CPU: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) threads; $(uptime); OMP_WAIT_POLICY=$OMP_WAIT_POLICY"
"$LISFM_BUILD_DIR/bench/lisfm_icp_bench" "$LISFM_SHARED_DATA" "$REPEATS" --knn --stages
