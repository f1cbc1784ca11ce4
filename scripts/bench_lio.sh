#!/usr/bin/env bash
# LIO benchmark: per-scan time (median, p95), real-time factor and ATE/RPE of
# `lisfm lio` (iterated EKF) side by side with its LiDAR-only frame-to-map ICP
# baseline (`--method lidar_only`), on simulated HILTI-style sequences:
#   office driven by the real HILTI 2022 exp04 handheld motion (120 s),
#   the two-storey staircase (LiDAR-degenerate) and the large hall (generated walks).
#   scripts/bench_lio.sh [WORK_DIR] [DURATION_S]     (defaults: /tmp/lisfm_bench_lio, 120)
# LISFM_LIO_ARGS adds options to every `lisfm lio` run, e.g. the pre-fix plane
# gates: LISFM_LIO_ARGS="--Lio.max_plane_residual 0.1 --Lio.max_point_residual 1e9".
# Assumes a built tree (scripts/test.sh or scripts/demo.sh builds it).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
WORK="${1:-/tmp/lisfm_bench_lio}"
DURATION="${2:-120}"
read -r -a LIO_ARGS <<< "${LISFM_LIO_ARGS:-}"
EXP04="$LISFM_SHARED_DATA/hilti2022_groundtruth/exp_04_construction_upper_level_easy_2_2022-03-03-11-48-59_imu.txt"
[ -x "$LISFM" ] || { echo "bench_lio: build first ($LISFM missing)" >&2; exit 1; }
mkdir -p "$WORK"

simulate() {  # name, extra args
  local name=$1; shift
  if [ ! -f "$WORK/$name/groundtruth.txt" ]; then
    "$LISFM" simulate --duration "$DURATION" --camera_rate 0 --output_path "$WORK/$name" \
      --error_sources none --overwrite 1 --quiet "$@"
  fi
}
simulate office_exp04 --scene office --trajectory_path "$EXP04" --error_sources none
simulate staircase --scene staircase --error_sources none --Walk.num_stops 3
simulate hall --scene hall --error_sources none --Walk.num_stops 3

rows=()
for seq in office_exp04 staircase hall; do
  for method in iekf lidar_only; do
    out="$WORK/out_${seq}_${method}"
    rm -rf "$out"
    start=$(date +%s%N)
    "$LISFM" lio --input_path "$WORK/$seq" --output_path "$out" --method "$method" \
      --write_keyframes 0 --quiet ${LIO_ARGS[@]+"${LIO_ARGS[@]}"}
    wall=$(( $(date +%s%N) - start ))
    "$LISFM" evaluate --reference_path "$WORK/$seq/groundtruth.txt" \
      --estimate_path "$out/trajectory.txt" --max_dt 0.006 --output_path "$out/eval" --quiet > /dev/null
    rows+=("$(/usr/bin/python3 - "$seq" "$method" "$out" "$wall" <<'PY'
import csv, json, statistics, sys
seq, method, out, wall = sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4]) * 1e-9
rows = [r for r in csv.reader(open(out + "/scans.csv")) if not r[0].startswith("#")]
done = [r for r in rows if r[1] == "1"]
t = sorted(float(r[6]) for r in done)
weak = sum(1 for r in done if int(r[7]) > 0)
m = json.load(open(out + "/eval/metrics.json"))
span = (int(rows[-1][0]) - int(rows[0][0])) * 1e-9
ate = m["ate"]["translation_m"]
rpe1 = [w for w in m["rpe"]["distance"] if abs(w["distance_m"] - 1.0) < 1e-9]
rpe1 = rpe1[0]["translation_m"]["rmse"] if rpe1 else float("nan")
print(f"| {seq} | {method} | {len(done)}/{len(rows)} | {statistics.median(t):.2f} | "
      f"{t[int(0.95 * (len(t) - 1))]:.2f} | {span / (sum(t) / 1000):.0f}x | {span / wall:.1f}x | "
      f"{ate['rmse'] * 100:.2f} | {ate['max'] * 100:.2f} | {rpe1 * 100:.2f} | {weak} |")
PY
)")
  done
done

echo
echo "lisfm lio benchmark ${LISFM_LIO_ARGS:+(${LISFM_LIO_ARGS}) }($(nproc) cores, $(lscpu | sed -n 's/Model name: *//p' | head -1), load $(cut -d' ' -f1-3 /proc/loadavg)); sequences ${DURATION} s"
echo
echo "| sequence | method | frames used | median ms/scan | p95 ms | filter RTF | wall RTF (with I/O) | ATE rmse cm | ATE max cm | RPE 1 m cm | scans with weak dirs |"
echo "|---|---|---|---|---|---|---|---|---|---|---|"
printf '%s\n' "${rows[@]}"
