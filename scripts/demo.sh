#!/usr/bin/env bash
# The lisfm demo: installs what is missing, builds, and runs the main job on the
# embedded default data, then prints a summary.
#   scripts/demo.sh [OUTPUT_DIR]     (default: demo_output/ in the checkout, ignored by git)
# Re-running replaces the earlier demo outputs (--overwrite 1).
#
# Steps (later stages of the pipeline join as they land):
#   1. lisfm simulate: a 30 s HILTI-style office recording (IMU, XT-32-like LiDAR,
#      the real HILTI 2022 5-camera rig at 0.5 Hz) with exact ground truth;
#   2. lisfm lio: LiDAR-inertial odometry on it;
#   3. lisfm evaluate: ATE/RPE of the lio trajectory and its HILTI-style score;
#   4. real data: the published FAST-LIO2 trajectory of HILTI 2022 exp04
#      (../shared/data/hilti_exp4_small) against the dense exp04 ground truth and
#      the surveyed control points.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
OUT="${1:-$LISFM_ROOT/demo_output}"

"$LISFM_ROOT/scripts/install_deps.sh"
mkdir -p "$LISFM_BUILD_DIR"
lisfm_build
mkdir -p "$OUT"

echo "== 1/4 simulate a 30 s office recording =="
"$LISFM" simulate --scene office --duration 30 --camera_rate 0.5 --seed 1 \
  --error_sources none --Walk.num_stops 3 --output_path "$OUT/sequence" --overwrite 1
echo "== 2/4 LiDAR-inertial odometry =="
"$LISFM" lio --input_path "$OUT/sequence" --output_path "$OUT/lio" --overwrite 1
echo "== 3/4 evaluate the odometry against the simulator's ground truth =="
"$LISFM" evaluate --reference_path "$OUT/sequence/groundtruth.txt" \
  --estimate_path "$OUT/lio/trajectory.txt" --max_dt 0.006 --output_path "$OUT/lio_eval" --overwrite 1
"$LISFM" evaluate --reference_path "$OUT/sequence/controlpoints.txt" \
  --reference_type control_points --estimate_path "$OUT/lio/trajectory.txt" --output_path "$OUT/lio_score" --overwrite 1

GT_DIR="$LISFM_SHARED_DATA/hilti2022_groundtruth"
LIO="$LISFM_SHARED_DATA/hilti_exp4_small/lidar/fastlio2_odom.txt"
if [ -d "$GT_DIR" ] && [ -f "$LIO" ]; then
  echo "== 4/4 real data: FAST-LIO2 on HILTI 2022 exp04 vs ground truth =="
  DENSE="$GT_DIR/exp_04_construction_upper_level_easy_2_2022-03-03-11-48-59_imu.txt"
  "$LISFM" evaluate --reference_path "$DENSE" --estimate_path "$LIO" --max_dt 0.05 \
    --output_path "$OUT/fastlio2_exp04_eval" --overwrite 1
  "$LISFM" evaluate --reference_path "$GT_DIR/exp04_construction_upper_level.txt" \
    --reference_type control_points --estimate_path "$LIO" --output_path "$OUT/fastlio2_exp04_score" --overwrite 1
else
  echo "== 4/4 skipped: $LISFM_SHARED_DATA is missing =="
fi

ate() { /usr/bin/python3 -c "import json,sys; m=json.load(open(sys.argv[1])); print(round(m['ate']['translation_m']['rmse'],4))" "$1" 2>/dev/null || echo "?"; }
score() { /usr/bin/python3 -c "import json,sys; m=json.load(open(sys.argv[1])); print(round(m['hilti2022']['score'],2))" "$1" 2>/dev/null || echo "?"; }
echo
echo "demo summary (outputs in $OUT):"
echo "  simulated sequence:        $OUT/sequence ($(ls "$OUT/sequence/lidar0/data" | wc -l) LiDAR scans, $(cat "$OUT"/sequence/cam*/data.csv 2>/dev/null | grep -vc '^#') images)"
echo "  lio on it:                 ATE rmse $(ate "$OUT/lio_eval/metrics.json") m, HILTI-style score $(score "$OUT/lio_score/metrics.json")/100"
if [ -d "$OUT/fastlio2_exp04_eval" ]; then
  echo "  FAST-LIO2 on real exp04:   ATE rmse $(ate "$OUT/fastlio2_exp04_eval/metrics.json") m, HILTI score $(score "$OUT/fastlio2_exp04_score/metrics.json")/100"
fi
