#!/usr/bin/env bash
# LiDAR-proxy co-visibility pairs (`lisfm database_importer`) vs stock COLMAP
# exhaustive / spatial / sequential matching on a simulated recording with
# rendered images and stock SIFT. Prints one markdown table for
# docs/BENCHMARKS.md (also written to WORK_DIR/bench_covisibility.md).
#
#   scripts/bench_covisibility.sh [--scene NAME] [--duration S] [--camera_rate HZ]
#                                 [--max_num_features N] [--work_dir DIR] [--skip_mapper]
#                                 [--skip_sequential] [--importer_args "..."] [--list_args "..."]...
#
# Steps (cached in WORK_DIR, keyed by the scene/duration/rate): lisfm simulate
# (default error sources), lisfm lio, lisfm pose_slam (defaults), lisfm
# database_importer (timed), stock feature_extractor on
# its image list, stock exhaustive_matcher once (its two_view_geometries give the
# verified pairs: >= 15 inliers; strong: >= 100). Then, on copies of the
# database with features: matches_importer on our pairs.txt, spatial_matcher on
# the priors (--SpatialMatching.is_gps 0 --SpatialMatching.ignore_z 0,
# max_num_neighbors tuned until its pair count is within 5 % of ours, or the
# closest tried) and sequential_matcher (overlap at the same budget); each
# timed. Per method: pairs matched, matching seconds, recall of the verified
# pairs (all, and strong), and lisfm global_mapper on it (rig, priors,
# constraints; cam_from_rig refined): registered images and camera errors
# against the simulator's ground truth (SE(3) alignment, lisfm model_evaluator).
# --scene defaults to site; an unknown scene falls back to office with a note.
# --importer_args: extra lisfm database_importer options. The features and the
# exhaustive result are reused only while the importer's image list is the same.
# --list_args (repeatable): one more importer run with these options (instead
# of --importer_args: an option may be given once), scored on its pairs.txt
# alone (a "list only" row: pairs and recall, no matching).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"

SCENE=site
DURATION=60
RATE=0.5
FEATURES=1024
WORK_DIR=/tmp/lisfm_bench_covisibility
SKIP_MAPPER=0
SKIP_SEQUENTIAL=0
IMPORTER_ARGS=""
LIST_ARGS=()
usage() { sed -n '2,29p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; }
while [ $# -gt 0 ]; do
  case "$1" in
    --scene) SCENE=$2; shift 2 ;;
    --duration) DURATION=$2; shift 2 ;;
    --camera_rate) RATE=$2; shift 2 ;;
    --max_num_features) FEATURES=$2; shift 2 ;;
    --work_dir) WORK_DIR=$2; shift 2 ;;
    --skip_mapper) SKIP_MAPPER=1; shift ;;
    --skip_sequential) SKIP_SEQUENTIAL=1; shift ;;
    --importer_args) IMPORTER_ARGS=$2; shift 2 ;;
    --list_args) LIST_ARGS+=("$2"); shift 2 ;;
    -h|--help) usage; exit 0 ;;
    *) echo "error: unknown argument '$1'" >&2; usage >&2; exit 2 ;;
  esac
done

command -v colmap >/dev/null || { echo "error: stock colmap not found (apt-get install colmap)" >&2; exit 1; }
command -v jq >/dev/null || { echo "error: jq not found (apt-get install jq)" >&2; exit 1; }
command -v sqlite3 >/dev/null || { echo "error: sqlite3 not found (apt-get install sqlite3)" >&2; exit 1; }
REFMODEL=$LISFM_BUILD_DIR/importers/testing/lisfm_sim_reference_model
for b in "$LISFM" "$REFMODEL"; do
  [ -x "$b" ] || { echo "error: $b not built (cmake --build $LISFM_BUILD_DIR --target lisfm lisfm_sim_reference_model)" >&2; exit 1; }
done
if ! "$LISFM" simulate -h | grep -- "--scene.*\b$SCENE\b" >/dev/null; then
  echo "note: scene '$SCENE' is not known to this lisfm simulate; using office instead" >&2
  SCENE=office
fi
export QT_QPA_PLATFORM=offscreen
mkdir -p "$WORK_DIR"
WORK_DIR=$(cd "$WORK_DIR" && pwd)
W=$WORK_DIR/${SCENE}_${DURATION}s_${RATE}hz
mkdir -p "$W"
SIFT="--SiftExtraction.use_gpu 0 --SiftExtraction.num_threads $LISFM_JOBS --SiftExtraction.max_num_features $FEATURES --SiftExtraction.first_octave 0"
MATCH="--SiftMatching.use_gpu 0 --SiftMatching.num_threads $LISFM_JOBS"
now() { date +%s.%N; }
elapsed() { echo "$2 - $1" | bc; }

[ -d "$W/seq" ] || "$LISFM" simulate --scene "$SCENE" --duration "$DURATION" --camera_rate "$RATE" \
  --output_path "$W/seq" --quiet 1
[ -d "$W/lio" ] || "$LISFM" lio --input_path "$W/seq" --output_path "$W/lio" --quiet 1
[ -d "$W/ps" ] || "$LISFM" pose_slam --input_path "$W/seq" --lio_path "$W/lio" --output_path "$W/ps" \
  --quiet 1
rm -rf "$W/db"
t0=$(now)
"$LISFM" database_importer --input_path "$W/seq" --pose_slam_path "$W/ps" --lio_path "$W/lio" \
  --output_path "$W/db" --DatabaseImporter.num_threads "$LISFM_JOBS" --quiet 1 $IMPORTER_ARGS
IMPORT_S=$(elapsed "$t0" "$(now)")
if [ -f "$W/features.db" ] && ! cmp -s "$W/db/image_list.txt" "$W/features_image_list.txt"; then
  echo "note: the image list changed; extracting features and matching exhaustively again" >&2
  rm -f "$W/features.db" "$W/exhaustive.db"
fi
if [ ! -f "$W/features.db" ]; then
  cp "$W/db/database.db" "$W/features.tmp.db"
  colmap feature_extractor --database_path "$W/features.tmp.db" --image_path "$W/seq" \
    --image_list_path "$W/db/image_list.txt" $SIFT >"$W/features.log" 2>&1
  mv "$W/features.tmp.db" "$W/features.db"
  cp "$W/db/image_list.txt" "$W/features_image_list.txt"
fi
NUM_IMAGES=$(sqlite3 "$W/features.db" "select count(*) from images")
"$REFMODEL" "$W/seq" "$W/features.db" "$W/reference" >/dev/null

# Exhaustive matching once (cached with its time).
if [ ! -f "$W/exhaustive.db" ]; then
  cp "$W/features.db" "$W/exhaustive.tmp.db"
  t0=$(now)
  colmap exhaustive_matcher --database_path "$W/exhaustive.tmp.db" $MATCH >"$W/exhaustive.log" 2>&1
  elapsed "$t0" "$(now)" >"$W/exhaustive.seconds"
  mv "$W/exhaustive.tmp.db" "$W/exhaustive.db"
fi
# Verified pairs: pair_id and inlier count (two_view_geometries.rows).
sqlite3 "$W/exhaustive.db" "select pair_id, rows from two_view_geometries where rows >= 15" \
  | tr '|' ' ' | sort -n >"$W/verified.txt"

# num_pairs DB: matched pairs (rows in the matches table).
num_pairs() { sqlite3 "$1" "select count(*) from matches"; }
# recall DB MIN: fraction of the verified pairs with >= MIN inliers whose pair
# the method matched.
recall() {
  sqlite3 "$1" "select pair_id from matches" | sort >"$W/matched.tmp"
  awk -v min="$2" '$2 >= min {print $1}' "$W/verified.txt" | sort >"$W/verified.tmp"
  local total hit
  total=$(wc -l <"$W/verified.tmp")
  hit=$(comm -12 "$W/matched.tmp" "$W/verified.tmp" | wc -l)
  if [ "$total" -eq 0 ]; then echo "n/a"; else echo "scale=1; 100 * $hit / $total" | bc; fi
}

declare -A SECONDS_OF PAIRS_OF
SECONDS_OF[exhaustive]=$(cat "$W/exhaustive.seconds")
PAIRS_OF[exhaustive]=$(num_pairs "$W/exhaustive.db")

cp "$W/features.db" "$W/ours.db"
t0=$(now)
colmap matches_importer --database_path "$W/ours.db" --match_list_path "$W/db/pairs.txt" \
  --match_type pairs $MATCH >"$W/ours.log" 2>&1
SECONDS_OF[ours]=$(elapsed "$t0" "$(now)")
PAIRS_OF[ours]=$(num_pairs "$W/ours.db")
BUDGET=${PAIRS_OF[ours]}

# Spatial matcher: tune max_num_neighbors to the budget (pairs ~ N k / 2 minus
# the mutual ones), at most 4 tries; keep the closest.
best_k=0; best_diff=1000000000
k=$(( 2 * BUDGET / NUM_IMAGES + 1 ))
for try in 1 2 3 4; do
  cp "$W/features.db" "$W/spatial.tmp.db"
  t0=$(now)
  colmap spatial_matcher --database_path "$W/spatial.tmp.db" --SpatialMatching.is_gps 0 \
    --SpatialMatching.ignore_z 0 --SpatialMatching.max_num_neighbors "$k" \
    --SpatialMatching.max_distance 1000 $MATCH >"$W/spatial.log" 2>&1
  s=$(elapsed "$t0" "$(now)")
  p=$(num_pairs "$W/spatial.tmp.db")
  diff=$(( p > BUDGET ? p - BUDGET : BUDGET - p ))
  if [ "$diff" -lt "$best_diff" ]; then
    best_diff=$diff; best_k=$k; mv "$W/spatial.tmp.db" "$W/spatial.db"
    SECONDS_OF[spatial]=$s; PAIRS_OF[spatial]=$p
  fi
  [ $(( 20 * diff )) -le "$BUDGET" ] && break
  k=$(( k * BUDGET / (p > 0 ? p : 1) ))
  [ "$k" -lt 1 ] && k=1
done
rm -f "$W/spatial.tmp.db"

# Sequential matcher (images in name order: per camera, by time).
overlap=$(( BUDGET / NUM_IMAGES + 1 ))
METHODS="exhaustive ours spatial"
if [ "$SKIP_SEQUENTIAL" = 0 ]; then
  METHODS="$METHODS sequential"
  cp "$W/features.db" "$W/sequential.db"
  t0=$(now)
  colmap sequential_matcher --database_path "$W/sequential.db" \
    --SequentialMatching.overlap "$overlap" --SequentialMatching.loop_detection 0 \
    $MATCH >"$W/sequential.log" 2>&1
  SECONDS_OF[sequential]=$(elapsed "$t0" "$(now)")
  PAIRS_OF[sequential]=$(num_pairs "$W/sequential.db")
fi

# global_mapper on each database: registered images, camera errors (SE(3)).
mapper_row() {
  local db=$1 name=$2
  if [ "$SKIP_MAPPER" = 1 ]; then echo "| n/a | n/a | n/a |"; return; fi
  rm -rf "$W/sparse_$name"
  if ! "$LISFM" global_mapper --database_path "$db" --image_path "$W/seq" \
      --output_path "$W/sparse_$name" --rig_path "$W/db/rig.yaml" \
      --lidar_constraints_path "$W/db/constraints.txt" \
      --BundleAdjustment.refine_cam_from_rig 1 --quiet 1 >"$W/mapper_$name.log" 2>&1; then
    echo "| failed | | |"; return
  fi
  local reg
  reg=$(jq -r '[.components[]?.final_model.num_images // empty] | add // "n/a"' \
    "$W/sparse_$name/global_mapper_summary.json" 2>/dev/null || echo n/a)
  if "$LISFM" model_evaluator --model_path "$W/sparse_$name/0" --reference_path "$W/reference" \
      --alignment se3 --output_path "$W/eval_$name.json" --quiet 1 >/dev/null 2>&1; then
    jq -r --arg reg "$reg" '"| \(.num_registered // $reg) | \(.rotation_error_deg.max * 1000 | round / 1000) | \(.position_error.max * 1000 | round / 10) |"' \
      "$W/eval_$name.json"
  else
    echo "| $reg | n/a | n/a |"
  fi
}

# recall_of_list PAIRS MIN: fraction of the verified pairs with >= MIN inliers
# in the pair list PAIRS (image names; pair_id from the database's image ids).
recall_of_list() {
  sqlite3 "$W/features.db" "select name, image_id from images" | tr '|' ' ' >"$W/ids.tmp"
  awk 'NR == FNR {id[$1] = $2; next}
       {a = id[$1]; b = id[$2]; if (a > b) {t = a; a = b; b = t}; printf "%.0f\n", a * 2147483647 + b}' \
    "$W/ids.tmp" "$1" | sort >"$W/matched.tmp"
  awk -v min="$2" '$2 >= min {print $1}' "$W/verified.txt" | sort >"$W/verified.tmp"
  local total hit
  total=$(wc -l <"$W/verified.tmp")
  hit=$(comm -12 "$W/matched.tmp" "$W/verified.tmp" | wc -l)
  if [ "$total" -eq 0 ]; then echo "n/a"; else echo "scale=1; 100 * $hit / $total" | bc; fi
}

VER_ALL=$(wc -l <"$W/verified.txt")
VER_STRONG=$(awk '$2 >= 100' "$W/verified.txt" | wc -l)
{
  echo "Scene $SCENE, ${DURATION} s at ${RATE} Hz: $NUM_IMAGES images, stock SIFT ($FEATURES features, first_octave 0, CPU); exhaustive verifies $VER_ALL pairs (>= 15 inliers), $VER_STRONG with >= 100. database_importer: $IMPORT_S s."
  echo
  echo "| method | pairs matched | % of exhaustive | matching s | recall verified | recall >= 100 inliers | registered | max rot. err. deg | max pos. err. cm |"
  echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|"
  for m in $METHODS; do
    db=$W/$m.db
    label=$m
    [ "$m" = ours ] && label="LiDAR co-visibility (ours)"
    [ "$m" = spatial ] && label="spatial_matcher (k = $best_k)"
    [ "$m" = sequential ] && label="sequential_matcher (overlap $overlap)"
    pct=$(echo "scale=1; 100 * ${PAIRS_OF[$m]} / ${PAIRS_OF[exhaustive]}" | bc)
    printf "| %s | %s | %s | %.1f | %s | %s %s\n" "$label" "${PAIRS_OF[$m]}" "$pct" \
      "${SECONDS_OF[$m]}" "$(recall "$db" 15)" "$(recall "$db" 100)" "$(mapper_row "$db" "$m")"
  done
  k=0
  for args in "${LIST_ARGS[@]}"; do
    k=$((k + 1))
    rm -rf "$W/db_list$k"
    "$LISFM" database_importer --input_path "$W/seq" --pose_slam_path "$W/ps" --lio_path "$W/lio" \
      --output_path "$W/db_list$k" --DatabaseImporter.num_threads "$LISFM_JOBS" --quiet 1 \
      $args 2>"$W/db_list$k.log" || { echo "error: database_importer $args failed: $W/db_list$k.log" >&2; exit 1; }
    p=$(wc -l <"$W/db_list$k/pairs.txt")
    pct=$(echo "scale=1; 100 * $p / ${PAIRS_OF[exhaustive]}" | bc)
    printf "| ours, \`%s\` (list only) | %s | %s | – | %s | %s | – | – | – |\n" "$args" "$p" "$pct" \
      "$(recall_of_list "$W/db_list$k/pairs.txt" 15)" "$(recall_of_list "$W/db_list$k/pairs.txt" 100)"
  done
} | tee "$WORK_DIR/bench_covisibility.md"
