#!/usr/bin/env bash
# Stock COLMAP on simulated construction-site images, with and without the camera error sources:
# `lisfm simulate --scene site` (default rig: the 5 HILTI 2022 cameras; LiDAR off), then
# `colmap feature_extractor` (CPU SIFT, one camera per camK/ folder), `colmap exhaustive_matcher`
# (CPU) and `colmap mapper`, all at COLMAP's defaults otherwise. Per run: images, SIFT features
# per image (mean, median, 10th percentile, min), images registered in the largest model, number
# of models, and the wall time of each COLMAP step.
#   scripts/bench_sim_colmap.sh [WORK_DIR] [DURATION_S] [CAMERA_RATE_HZ] [SEED] [SOURCE_LISTS]
#   (defaults: /tmp/lisfm_bench_sim_colmap, 60, 0.25, 4,
#   "all calibration,imu,dynamics")
# The recordings differ only in --error_sources: by default "all" and every source except the
# camera one (and lidar, which needs a LiDAR: none is simulated here). CPU matching costs about
# (features per image)^2 per pair: the clean images (~8k SIFT each) take ~4x as long as those
# with the camera sources. Rows are appended to WORK_DIR/colmap.md as each run ends (a list
# already there is skipped).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
WORK="${1:-/tmp/lisfm_bench_sim_colmap}"
DURATION="${2:-60}"
RATE="${3:-0.25}"
SEED="${4:-4}"
SOURCE_LISTS="${5:-all calibration,imu,dynamics}"
[ -x "$LISFM" ] || { echo "bench_sim_colmap: build first ($LISFM missing)" >&2; exit 1; }
command -v colmap > /dev/null || { echo "bench_sim_colmap: colmap not found" >&2; exit 1; }
mkdir -p "$WORK"
TABLE="$WORK/colmap.md"
if [ ! -f "$TABLE" ]; then
  {
    echo "site ${DURATION} s, 5 cameras at ${RATE} Hz, seed ${SEED}; $(nproc) cores," \
      "$(lscpu | sed -n 's/Model name: *//p' | head -1); $(colmap help 2>&1 | head -1)"
    echo
    echo "| error sources | images | SIFT per image: mean | median | 10th pct | min |" \
      "registered (largest model) | models | extract / match / map s |"
    echo "|---|---|---|---|---|---|---|---|---|"
  } > "$TABLE"
fi

seconds() { awk -v a="$1" -v b="$2" 'BEGIN{printf "%.0f", b - a}'; }

for sources in $SOURCE_LISTS; do
  if grep -q "^| $sources |" "$TABLE"; then continue; fi
  run="$WORK/${sources//,/_}"
  rm -rf "$run"
  mkdir -p "$run"
  "$LISFM" simulate --scene site --duration "$DURATION" --camera_rate "$RATE" --lidars none \
    --seed "$SEED" --error_sources "$sources" --output_path "$run/seq" --quiet
  mkdir -p "$run/images"
  for cam in "$run"/seq/cam*; do mv "$cam/data" "$run/images/$(basename "$cam")"; done
  t0=$(date +%s.%N)
  colmap feature_extractor --database_path "$run/database.db" --image_path "$run/images" \
    --ImageReader.single_camera_per_folder 1 --SiftExtraction.use_gpu 0 > "$run/extract.log" 2>&1
  t1=$(date +%s.%N)
  colmap exhaustive_matcher --database_path "$run/database.db" --SiftMatching.use_gpu 0 \
    > "$run/match.log" 2>&1
  t2=$(date +%s.%N)
  mkdir -p "$run/sparse"
  colmap mapper --database_path "$run/database.db" --image_path "$run/images" \
    --output_path "$run/sparse" > "$run/map.log" 2>&1
  t3=$(date +%s.%N)
  registered=0
  models=0
  for model in "$run"/sparse/*/; do
    [ -f "$model/images.bin" ] || continue
    models=$((models + 1))
    n=$(colmap model_analyzer --path "$model" 2>&1 | sed -n 's/.*Registered images: *//p')
    if [ "${n:-0}" -gt "$registered" ]; then registered=$n; fi
  done
  /usr/bin/python3 - "$run/database.db" "$sources" "$registered" "$models" \
    "$(seconds "$t0" "$t1") / $(seconds "$t1" "$t2") / $(seconds "$t2" "$t3")" >> "$TABLE" <<'PY'
import sqlite3, statistics, sys
db, sources, registered, models, times = sys.argv[1:6]
counts = sorted(r[0] for r in sqlite3.connect(db).execute("SELECT rows FROM keypoints"))
n = len(counts)
print(f"| {sources} | {n} | {statistics.mean(counts):.0f} | {statistics.median(counts):.0f} | "
      f"{counts[int(0.1 * (n - 1))]} | {counts[0]} | {registered} / {n} | {models} | {times} |")
PY
  tail -1 "$TABLE"
  rm -rf "$run/seq"
done
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)" >> "$TABLE"
cat "$TABLE"
