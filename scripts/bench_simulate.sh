#!/usr/bin/env bash
# Benchmark of `lisfm simulate`: a 120 s office sequence (1200 spinning scans,
# 5 cameras at 2 Hz = 1200 images, IMU 400 Hz) without error sources and with
# three rests (--error_sources none --Walk.num_stops 3, the clean data of
# earlier versions), with and without cameras; the same with every error
# source on (the defaults) and with each of the LiDAR and camera sources alone;
# and the five-minute construction site with every error source on (3000
# scans, 3000 images, ~5 GB). Prints a table for docs/BENCHMARKS.md (simulate
# section): wall time, process CPU seconds (user + sys, which other load on the
# machine inflates less than the wall time), the real-time factor (sequence
# length over wall time) and the folder size.
# Usage: scripts/bench_simulate.sh [build_dir]
set -euo pipefail
BUILD="${1:-build}"
LISFM="$BUILD/apps/lisfm"
OUT="$(mktemp -d)"
trap 'rm -rf "$OUT"' EXIT
CPU="$(lscpu | sed -n 's/^Model name:[[:space:]]*//p' | head -1)"
echo "CPU: $CPU, $(nproc) cores"
echo "load before: $(uptime | sed 's/.*load average/load average/')"
run() {  # name, sequence length (s), simulate options
  local name="$1" duration="$2"; shift 2
  local t0 t1 wall size cpu
  t0=$(date +%s.%N)
  /usr/bin/time -f "%U %S" -o "$OUT/$name.cpu" \
    "$LISFM" simulate --output_path "$OUT/$name" --duration "$duration" "$@" \
    > "$OUT/$name.log" 2>&1
  t1=$(date +%s.%N)
  wall=$(awk -v a="$t0" -v b="$t1" 'BEGIN{print b-a}')
  size=$(du -sh "$OUT/$name" | cut -f1)
  cpu=$(awk '{print $1 + $2}' "$OUT/$name.cpu")
  printf "| %-34s | %8.1f | %8.1f | %5.1fx | %6s |\n" "$name $*" "$wall" "$cpu" \
    "$(awk -v d="$duration" -v w="$wall" 'BEGIN{print d/w}')" "$size"
  grep -o "Time [0-9.]* s (scene.*)" "$OUT/$name.log" | sed 's/^/    /' || true
  grep -o "CPU breakdown.*" "$OUT/$name.log" | sed 's/^/    /' || true
  rm -rf "${OUT:?}/$name"
}
CLEAN=(--error_sources none --Walk.num_stops 3)
echo "| run | wall s | CPU s | real time | size |"
echo "|---|---|---|---|---|"
run office120 120 --scene office --camera_rate 2 --lidars spinning "${CLEAN[@]}"
run office120_lidar_only 120 --scene office --camera_rate 0 --lidars spinning "${CLEAN[@]}"
run office120_all_sources 120 --scene office --camera_rate 2 --lidars spinning
run office120_lidar_source 120 --scene office --camera_rate 2 --lidars spinning \
  --error_sources lidar
run office120_camera_source 120 --scene office --camera_rate 2 --lidars spinning \
  --error_sources camera
run site300_all_sources 300 --scene site --camera_rate 2 --lidars spinning
echo "load after: $(uptime | sed 's/.*load average/load average/')"
