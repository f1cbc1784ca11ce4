#!/usr/bin/env bash
# Benchmark of `lisfm simulate`: a 120 s office sequence (1200 spinning scans,
# 5 cameras at 2 Hz = 1200 images, IMU 400 Hz) with all error sources (the
# default), with none (the clean data of earlier versions) and with each of the
# LiDAR and camera sources alone; then LiDAR only. Prints a table for
# docs/BENCHMARKS.md (simulate section), wall time and process CPU seconds
# (user + sys, which other load on the machine inflates less than the wall
# time).  Usage: scripts/bench_simulate.sh [build_dir]
set -euo pipefail
BUILD="${1:-build}"
LISFM="$BUILD/apps/lisfm"
OUT="$(mktemp -d)"
trap 'rm -rf "$OUT"' EXIT
CPU="$(lscpu | sed -n 's/^Model name:[[:space:]]*//p' | head -1)"
echo "CPU: $CPU, $(nproc) cores"
echo "load before: $(uptime | sed 's/.*load average/load average/')"
run() {
  local name="$1"; shift
  local t0 t1
  t0=$(date +%s.%N)
  /usr/bin/time -f "%U %S" -o "$OUT/$name.cpu" \
    "$LISFM" simulate --output_path "$OUT/$name" "$@" > "$OUT/$name.log" 2>&1
  t1=$(date +%s.%N)
  local size cpu
  size=$(du -sh "$OUT/$name" | cut -f1)
  cpu=$(awk '{print $1 + $2}' "$OUT/$name.cpu")
  printf "| %-34s | %8.1f | %8.1f | %6s |\n" "$name $*" \
    "$(awk -v a="$t0" -v b="$t1" 'BEGIN{print b-a}')" "$cpu" "$size"
  rm -rf "${OUT:?}/$name"
  grep -o "Time [0-9.]* s (scene.*)" "$OUT/$name.log" | sed 's/^/    /' || true
  grep -o "CPU breakdown.*" "$OUT/$name.log" | sed 's/^/    /' || true
}
echo "| run | wall s | CPU s | size |"
echo "|---|---|---|---|"
run office120 --scene office --duration 120 --camera_rate 2 --lidars spinning
run office120_none --scene office --duration 120 --camera_rate 2 --lidars spinning \
  --error_sources none
run office120_lidar_source --scene office --duration 120 --camera_rate 2 --lidars spinning \
  --error_sources lidar
run office120_camera_source --scene office --duration 120 --camera_rate 2 --lidars spinning \
  --error_sources camera
run office120_lidar_only --scene office --duration 120 --camera_rate 0 --lidars spinning
echo "load after: $(uptime | sed 's/.*load average/load average/')"
