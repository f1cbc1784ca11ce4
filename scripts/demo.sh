#!/usr/bin/env bash
# The lisfm demo: installs what is missing, builds, and runs the main job on the
# embedded default data, then prints a summary.
#   scripts/demo.sh [OUTPUT_DIR]     (default: ./demo_output)
#
# Today the main job is trajectory evaluation on real HILTI 2022 data:
#   1. the real FAST-LIO2 trajectory of exp04 (../shared/data/hilti_exp4_small)
#      against the dense exp04 ground truth (ATE/RPE after SE(3) alignment);
#   2. the same FAST-LIO2 trajectory scored like the HILTI 2022 challenge against
#      the surveyed control points;
#   3. the dense ground truth itself against the control points (the ceiling).
# Later stages (simulate -> lio -> pose_slam -> SfM) are added here as they land.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
OUT="${1:-$PWD/demo_output}"

"$LISFM_ROOT/scripts/install_deps.sh"
mkdir -p "$LISFM_BUILD_DIR"
lisfm_build

GT_DIR="$LISFM_SHARED_DATA/hilti2022_groundtruth"
LIO="$LISFM_SHARED_DATA/hilti_exp4_small/lidar/fastlio2_odom.txt"
if [ ! -d "$GT_DIR" ] || [ ! -f "$LIO" ]; then
  echo "demo.sh: $LISFM_SHARED_DATA (hilti2022_groundtruth, hilti_exp4_small) is missing" >&2
  exit 1
fi
DENSE="$GT_DIR/exp_04_construction_upper_level_easy_2_2022-03-03-11-48-59_imu.txt"
CONTROL="$GT_DIR/exp04_construction_upper_level.txt"
mkdir -p "$OUT"

echo "== 1/3 FAST-LIO2 (real, exp04) vs dense ground truth =="
"$LISFM" evaluate --reference "$DENSE" --estimate "$LIO" --align se3 --max_dt 0.05 \
  --output_path "$OUT/fastlio2_vs_gt"
echo "== 2/3 FAST-LIO2 (real, exp04) HILTI 2022 score against the control points =="
"$LISFM" evaluate --reference "$CONTROL" --reference_type control_points --estimate "$LIO" \
  --output_path "$OUT/fastlio2_hilti_score"
echo "== 3/3 dense ground truth HILTI 2022 score against the control points =="
"$LISFM" evaluate --reference "$CONTROL" --reference_type control_points --estimate "$DENSE" \
  --output_path "$OUT/gt_hilti_score"

echo
echo "demo summary: outputs in $OUT"
for d in fastlio2_vs_gt fastlio2_hilti_score gt_hilti_score; do
  echo "  $d: $(ls "$OUT/$d" | tr '\n' ' ')"
done
