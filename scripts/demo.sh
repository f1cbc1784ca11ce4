#!/usr/bin/env bash
# The lisfm demo: installs what is missing, builds, and runs the product's main job,
# `lisfm pipeline`, on a simulated recording, then prints the report's summary.
#   scripts/demo.sh [OUTPUT_DIR]     (default: demo_output/ in the checkout, ignored by git)
# Re-running replaces the earlier demo outputs.
#
# Steps:
#   1. lisfm simulate: a 60 s HILTI-style office recording (IMU, XT-32-like LiDAR, the
#      HILTI 2022 5-camera rig at 0.5 Hz) with the simulator's default (realistic) error
#      sources -- calibration, IMU, LiDAR, camera and people -- and exact ground truth;
#   2. lisfm pipeline --compare_stock 1 (configs/pipeline_sim.yaml): lio -> pose_slam ->
#      database_importer -> stock colmap feature_extractor + matches_importer on the
#      LiDAR co-visibility pair list -> lisfm global_mapper (rig, priors, LiDAR
#      constraints, refined camera extrinsics) -> stock colmap mapper on the same
#      matches -> evaluation against the ground truth -> report.md / report.json;
#   3. real data (when ../shared/data is there): the published FAST-LIO2 trajectory of
#      HILTI 2022 exp04 against the dense ground truth and the surveyed control points.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
OUT="${1:-$LISFM_ROOT/demo_output}"

"$LISFM_ROOT/scripts/install_deps.sh"
mkdir -p "$LISFM_BUILD_DIR"
lisfm_build
mkdir -p "$OUT"
start=$(date +%s)

echo "== 1/3 simulate a 60 s office recording (5 cameras at 0.5 Hz, realistic errors) =="
"$LISFM" simulate --scene office --duration 60 --camera_rate 0.5 --seed 1 --quiet 1 \
  --output_path "$OUT/sequence" --overwrite 1
echo "== 2/3 lisfm pipeline: recording -> COLMAP model, side by side with stock COLMAP =="
rm -rf "$OUT/pipeline"
"$LISFM" pipeline --input_path "$OUT/sequence" --output_path "$OUT/pipeline" \
  --config_path "$LISFM_ROOT/configs/pipeline_sim.yaml" --compare_stock 1

GT_DIR="$LISFM_SHARED_DATA/hilti2022_groundtruth"
LIO="$LISFM_SHARED_DATA/hilti_exp4_small/lidar/fastlio2_odom.txt"
if [ -d "$GT_DIR" ] && [ -f "$LIO" ]; then
  echo "== 3/3 real data: FAST-LIO2 on HILTI 2022 exp04 vs ground truth =="
  DENSE="$GT_DIR/exp_04_construction_upper_level_easy_2_2022-03-03-11-48-59_imu.txt"
  "$LISFM" evaluate --quiet 1 --reference_path "$DENSE" --estimate_path "$LIO" --max_dt 0.05 \
    --output_path "$OUT/fastlio2_exp04_eval" --overwrite 1 > /dev/null
  "$LISFM" evaluate --quiet 1 --reference_path "$GT_DIR/exp04_construction_upper_level.txt" \
    --reference_type control_points --estimate_path "$LIO" \
    --output_path "$OUT/fastlio2_exp04_score" --overwrite 1 > /dev/null
else
  echo "== 3/3 skipped: $LISFM_SHARED_DATA is missing =="
fi

echo
echo "== report ($OUT/pipeline/report.md) =="
# The report's tables: trajectories, the models side by side, the refined extrinsics.
sed -n '/^## Trajectories/,/^## Plots/p;' "$OUT/pipeline/report.md" | grep -v '^## Plots'
if [ -d "$OUT/fastlio2_exp04_eval" ]; then
  /usr/bin/python3 - "$OUT" <<'EOF' || true
import json, sys
out = sys.argv[1]
ate = json.load(open(out + "/fastlio2_exp04_eval/metrics.json"))["ate"]["translation_m"]["rmse"]
score = json.load(open(out + "/fastlio2_exp04_score/metrics.json"))["hilti2022"]["score"]
print(f"Real data: FAST-LIO2 on HILTI 2022 exp04: ATE rmse {ate:.4f} m, HILTI score {score:.2f}/100")
EOF
fi
echo
echo "demo outputs in $OUT (after the build: $(( $(date +%s) - start )) s):"
echo "  recording        $OUT/sequence"
echo "  model            $OUT/pipeline/sparse/0"
echo "  report           $OUT/pipeline/report.md, report.json, plots/"
echo "  open in COLMAP   $(grep -A1 '^```' "$OUT/pipeline/report.md" | grep 'colmap gui' || true)"
