#!/usr/bin/env bash
# Bundle adjustment solvers side by side: `lisfm global_mapper` on the
# same COLMAP database with --BundleAdjustment.solver ceres (Ceres DENSE_SCHUR)
# and schur (lisfm's dense-Schur Levenberg-Marquardt), alternating, REPEATS
# times each; prints one markdown table of the final full bundle adjustment
# (median seconds, iterations, final cost, mean reprojection error) and the
# whole mapping step.
#
#   scripts/bench_bundle_adjustment.sh [--work_dir DIR] [--datasets a,b,...] [--repeats N]
#
# The databases are the ones scripts/compare_colmap.sh builds (WORK_DIR/<name>/
# database.db, same default WORK_DIR); run that script first.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"

WORK_DIR=/tmp/lisfm_compare_colmap
DATASETS=lund_door,fountain,herzjesu,entry,balbianello
REPEATS=3
usage() { sed -n '2,12p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; }
while [ $# -gt 0 ]; do
  case "$1" in
    --work_dir) WORK_DIR=$2; shift 2 ;;
    --datasets) DATASETS=$2; shift 2 ;;
    --repeats) REPEATS=$2; shift 2 ;;
    -h|--help) usage; exit 0 ;;
    *) echo "error: unknown argument '$1'" >&2; usage >&2; exit 2 ;;
  esac
done
[ -x "$LISFM" ] || { echo "error: $LISFM not built (cmake --build $LISFM_BUILD_DIR --target lisfm)" >&2; exit 1; }
command -v jq >/dev/null || { echo "error: jq not found (apt-get install jq)" >&2; exit 1; }
[[ "$REPEATS" =~ ^[1-9][0-9]*$ ]] || { echo "error: --repeats must be a positive integer, found '$REPEATS'" >&2; exit 2; }

median() { sort -g | awk '{v[NR] = $1} END {print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2}'; }

echo "CPU: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) threads; $(uptime)"
echo
echo "| dataset | solver | final BA s (median) | final BA iterations | final cost | mean reproj px | mapping s (median) |"
echo "|---|---|---|---|---|---|---|"
IFS=, read -r -a names <<<"$DATASETS"
for name in "${names[@]}"; do
  db=$WORK_DIR/$name/database.db
  [ -f "$db" ] || { echo "error: $db not found (run scripts/compare_colmap.sh --work_dir $WORK_DIR first)" >&2; exit 1; }
  run_dir=$(mktemp -d)
  for solver in ceres schur; do : >"$run_dir/$solver.ba"; : >"$run_dir/$solver.map"; done
  for ((r = 0; r < REPEATS; ++r)); do
    for solver in ceres schur; do
      out=$run_dir/$solver.$r
      mkdir -p "$out"
      cp "$db" "$out/database.db"
      "$LISFM" global_mapper --database_path "$out/database.db" --output_path "$out/sparse" \
        --Mapper.read_colors 0 --BundleAdjustment.solver "$solver" --quiet 1 >"$out/log.txt" 2>&1 \
        || { echo "error: global_mapper failed on $name ($solver), see $out/log.txt" >&2; exit 1; }
      summary=$out/sparse/global_mapper_summary.json
      jq -r '.components[0].refinement[-1].bundle_adjustment.seconds' "$summary" >>"$run_dir/$solver.ba"
      jq -r '.mapping_seconds_including_io' "$summary" >>"$run_dir/$solver.map"
      jq -r '.components[0].refinement[-1].bundle_adjustment |
             "\(.iterations)\n\(.final_cost)\n\(.solver)"' "$summary" >"$run_dir/$solver.last"
      jq -r '.components[0].model.mean_reprojection_error_px' "$summary" >>"$run_dir/$solver.last"
    done
  done
  for solver in ceres schur; do
    iterations=$(sed -n 1p "$run_dir/$solver.last")
    cost=$(sed -n 2p "$run_dir/$solver.last")
    used=$(sed -n 3p "$run_dir/$solver.last")
    reproj=$(sed -n 4p "$run_dir/$solver.last")
    printf "| %s | %s | %.3f | %s | %.6g | %.4f | %.3f |\n" "$name" "$used" \
      "$(median <"$run_dir/$solver.ba")" "$iterations" "$cost" "$reproj" "$(median <"$run_dir/$solver.map")"
  done
  rm -rf "$run_dir"
done
echo
echo "Same database and options for both rows; only --BundleAdjustment.solver differs (point colours off)."
