#!/usr/bin/env bash
# Stock `colmap mapper` vs `lisfm global_mapper` on the same COLMAP database,
# per real data set, side by side. Prints one markdown table for
# docs/BENCHMARKS.md (also written to WORK_DIR/compare_colmap.md).
#
#   scripts/compare_colmap.sh [--work_dir DIR] [--datasets a,b,...] [--rebuild]
#                             [--keep_stock]
#
# Data sets (../shared/data): lund_door (COLMAP reference model), fountain,
# herzjesu, entry (Strecha ground-truth cameras), balbianello (Bundler model).
# Per data set: one database from stock COLMAP (SIFT on the CPU with the known
# intrinsics, one shared camera, exhaustive matching), reused from WORK_DIR
# when present (--rebuild re-extracts); then two copies of it, one per mapper,
# timed (wall clock of the mapping step only). Both models are measured with
# stock `colmap model_analyzer` and scored with `lisfm model_evaluator`
# against the reference (Sim(3) alignment: neither mapper is metric here).
# --keep_stock reuses a stock model and its time from an earlier run.
# When `lisfm global_mapper` is not available yet, its row shows n/a.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"

WORK_DIR=/tmp/lisfm_compare_colmap
DATASETS=lund_door,fountain,herzjesu,entry,balbianello
REBUILD=0
KEEP_STOCK=0
usage() { sed -n '2,19p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; }
while [ $# -gt 0 ]; do
  case "$1" in
    --work_dir) WORK_DIR=$2; shift 2 ;;
    --datasets) DATASETS=$2; shift 2 ;;
    --rebuild) REBUILD=1; shift ;;
    --keep_stock) KEEP_STOCK=1; shift ;;
    -h|--help) usage; exit 0 ;;
    *) echo "error: unknown argument '$1'" >&2; usage >&2; exit 2 ;;
  esac
done

COLMAP=$(command -v colmap || true)
[ -n "$COLMAP" ] || { echo "error: stock colmap not found (apt-get install colmap)" >&2; exit 1; }
[ -x "$LISFM" ] || { echo "error: $LISFM not built (cmake --build $LISFM_BUILD_DIR --target lisfm)" >&2; exit 1; }
command -v jq >/dev/null || { echo "error: jq not found (apt-get install jq)" >&2; exit 1; }
export QT_QPA_PLATFORM=offscreen
mkdir -p "$WORK_DIR"
WORK_DIR=$(cd "$WORK_DIR" && pwd)

HAVE_GLOBAL_MAPPER=1
if ! "$LISFM" global_mapper -h >/dev/null 2>&1; then
  HAVE_GLOBAL_MAPPER=0
  echo "note: 'lisfm global_mapper' is not available in $LISFM; its rows show n/a" >&2
fi

# dataset_config NAME: sets IMAGES, CAMERA_MODEL, CAMERA_PARAMS, REFERENCE.
dataset_config() {
  local d=$LISFM_SHARED_DATA
  case "$1" in
    lund_door)
      IMAGES=$d/sfm_lund_door/images
      REFERENCE=$d/sfm_lund_door/colmap_ground_truth
      # The reference model's own camera: SIMPLE_RADIAL f cx cy k.
      CAMERA_MODEL=SIMPLE_RADIAL
      CAMERA_PARAMS=$(awk '!/^#/ && NF >= 8 {print $5","$6","$7","$8; exit}' "$REFERENCE/cameras.txt")
      ;;
    fountain|herzjesu|entry)
      local scene
      case "$1" in
        fountain) scene=fountain-P11 ;; herzjesu) scene=Herz-Jesus-P8 ;; entry) scene=entry-P10 ;;
      esac
      IMAGES=$d/sfm_strecha/$scene/images_half
      REFERENCE=$d/sfm_strecha/$scene/gt_dense_cameras
      # K of the full-resolution images halved (README). Strecha's K uses
      # pixel centres at integers; a 2x2 box downscale then maps x_full to
      # (x_full - 0.5) / 2 in that convention, i.e. x_full / 2 + 0.25 in
      # COLMAP's (centre of the top-left pixel at 0.5).
      CAMERA_MODEL=PINHOLE
      CAMERA_PARAMS=$(awk 'NR == 1 {fx = $1; cx = $3} NR == 2 {fy = $2; cy = $3}
        END {printf "%.4f,%.4f,%.4f,%.4f", fx / 2, fy / 2, cx / 2 + 0.25, cy / 2 + 0.25}' \
        "$d/sfm_strecha/$scene/K_full_resolution.txt")
      ;;
    balbianello)
      IMAGES=$d/sfm_balbianello/images
      REFERENCE=$d/sfm_balbianello/Balbianello.out
      # One shared SIMPLE_RADIAL camera: the mean Bundler focal length and k1
      # (camera lines 3, 8, 13, ... hold `f k1 k2`); principal point at the
      # centre of the 640 x 427 images.
      CAMERA_MODEL=SIMPLE_RADIAL
      CAMERA_PARAMS=$(awk 'NR == 2 {n = $1} NR > 2 && (NR - 3) % 5 == 0 && (NR - 3) / 5 < n {f += $1; k += $2; m++}
        END {printf "%.4f,320,213.5,%.6f", f / m, k / m}' "$REFERENCE")
      ;;
    *) echo "error: unknown data set '$1' (lund_door, fountain, herzjesu, entry, balbianello)" >&2; exit 2 ;;
  esac
  [ -d "$IMAGES" ] || { echo "error: $IMAGES not found (LISFM_SHARED_DATA=$LISFM_SHARED_DATA)" >&2; exit 1; }
}

now() { date +%s.%N; }
elapsed() { echo "$2 - $1" | bc -l | xargs printf "%.2f"; }

# build_database NAME DIR: stock feature extraction + exhaustive matching.
build_database() {
  local db=$2/database.db
  if [ -f "$db" ] && [ "$REBUILD" = 0 ]; then
    echo "[$1] reusing $db" >&2
    return
  fi
  rm -f "$db" "$db.tmp"
  echo "[$1] colmap feature_extractor + exhaustive_matcher ($CAMERA_MODEL $CAMERA_PARAMS)" >&2
  "$COLMAP" feature_extractor --database_path "$db.tmp" --image_path "$IMAGES" \
    --SiftExtraction.use_gpu 0 --ImageReader.single_camera 1 \
    --ImageReader.camera_model "$CAMERA_MODEL" --ImageReader.camera_params "$CAMERA_PARAMS" \
    >"$2/logs/feature_extractor.log" 2>&1
  "$COLMAP" exhaustive_matcher --database_path "$db.tmp" --SiftMatching.use_gpu 0 \
    >"$2/logs/exhaustive_matcher.log" 2>&1
  mv "$db.tmp" "$db"
}

# largest_model DIR: the numbered model folder with the most registered images.
largest_model() {
  local best="" best_n=-1 m n
  for m in "$1"/*/; do
    m=${m%/}
    [ -f "$m/images.bin" ] || [ -f "$m/images.txt" ] || continue
    n=$("$COLMAP" model_analyzer --path "$m" 2>&1 | sed -n 's/.*Registered images: *//p' | head -1)
    if [ -n "$n" ] && [ "$n" -gt "$best_n" ]; then best=$m; best_n=$n; fi
  done
  echo "$best"
}

# analyze MODEL: "registered points observations track_length reproj_px"
analyze() {
  local out
  out=$("$COLMAP" model_analyzer --path "$1" 2>&1)
  printf "%s %s %s %s %s\n" \
    "$(sed -n 's/.*Registered images: *//p' <<<"$out" | head -1)" \
    "$(sed -n 's/.*Points: *//p' <<<"$out" | head -1)" \
    "$(sed -n 's/.*Observations: *//p' <<<"$out" | head -1)" \
    "$(sed -n 's/.*Mean track length: *//p' <<<"$out" | head -1 | xargs printf "%.2f")" \
    "$(sed -n 's/.*Mean reprojection error: *\([0-9.eE+-]*\)px.*/\1/p' <<<"$out" | head -1 | xargs printf "%.3f")"
}

# evaluate MODEL JSON: "rot_err pos_err auc1 auc5" (n/a when the evaluation fails).
evaluate() {
  if "$LISFM" model_evaluator --model_path "$1" --reference_path "$REFERENCE" \
      --output_path "$2" --quiet 1 >"${2%.json}.log" 2>&1; then
    jq -r '"\(.rotation_error_deg.mean) \(.position_error.mean) \(.auc["1"]) \(.auc["5"])"' "$2" |
      awk '{for (i = 1; i <= 4; ++i) $i = ($i ~ /^[-0-9.eE+]+$/) ? sprintf(i == 2 ? "%.4g" : "%.3f", $i) : "n/a"; print}'
  else
    echo "n/a n/a n/a n/a"
  fi
}

# run_mapper NAME SIDE DIR: copies the database, runs one mapper, prints wall s.
run_mapper() {
  local name=$1 side=$2 dir=$3/$2
  if [ "$side" = stock ] && [ "$KEEP_STOCK" = 1 ] && [ -f "$dir/wall_s.txt" ] && [ -n "$(largest_model "$dir/sparse")" ]; then
    echo "[$name] reusing the stock model in $dir/sparse" >&2
    cat "$dir/wall_s.txt"
    return
  fi
  rm -rf "$dir"
  mkdir -p "$dir/sparse"
  cp "$3/database.db" "$dir/database.db"
  echo "[$name] $side mapper" >&2
  local t0 t1 rc=0
  t0=$(now)
  if [ "$side" = stock ]; then
    "$COLMAP" mapper --database_path "$dir/database.db" --image_path "$IMAGES" \
      --output_path "$dir/sparse" >"$dir/mapper.log" 2>&1 || rc=$?
  else
    "$LISFM" global_mapper --database_path "$dir/database.db" --image_path "$IMAGES" \
      --output_path "$dir/sparse" >"$dir/mapper.log" 2>&1 || rc=$?
  fi
  t1=$(now)
  if [ "$rc" != 0 ]; then
    echo "[$name] $side mapper failed (exit $rc), see $dir/mapper.log" >&2
    echo "failed"
    return
  fi
  elapsed "$t0" "$t1" | tee "$dir/wall_s.txt"
}

ratio() { # ratio A B -> A / B with 2 decimals, n/a when not numeric
  if [[ "$1" =~ ^[0-9.]+$ ]] && [[ "$2" =~ ^[0-9.]+$ ]] && [ "$(echo "$2 > 0" | bc -l)" = 1 ]; then
    echo "$1 / $2" | bc -l | xargs printf "%.2f"
  else
    echo "n/a"
  fi
}

ROWS=()
IFS=',' read -r -a DATASET_LIST <<<"$DATASETS"
for name in "${DATASET_LIST[@]}"; do
  dataset_config "$name"
  dir=$WORK_DIR/$name
  mkdir -p "$dir/logs"
  build_database "$name" "$dir"
  num_images=$(find "$IMAGES" -maxdepth 1 -type f | wc -l)

  stock_s=$(run_mapper "$name" stock "$dir")
  stock_model=$(largest_model "$dir/stock/sparse")
  if [ -n "$stock_model" ]; then
    read -r s_reg s_pts s_obs s_tl s_rep <<<"$(analyze "$stock_model")"
    read -r s_rot s_pos s_a1 s_a5 <<<"$(evaluate "$stock_model" "$dir/stock/metrics.json")"
  else
    s_reg=0 s_pts=n/a s_obs=n/a s_tl=n/a s_rep=n/a s_rot=n/a s_pos=n/a s_a1=n/a s_a5=n/a
  fi
  ROWS+=("| $name | colmap mapper | $stock_s | 1.0 | $s_reg/$num_images | $s_pts | $s_obs | 1.00 | $s_tl | $s_rep | $s_rot | $s_pos | $s_a1 | $s_a5 |")

  if [ "$HAVE_GLOBAL_MAPPER" = 1 ]; then
    ours_s=$(run_mapper "$name" lisfm "$dir")
    ours_model=$(largest_model "$dir/lisfm/sparse")
  else
    ours_s=n/a ours_model=""
  fi
  if [ -n "$ours_model" ]; then
    read -r o_reg o_pts o_obs o_tl o_rep <<<"$(analyze "$ours_model")"
    read -r o_rot o_pos o_a1 o_a5 <<<"$(evaluate "$ours_model" "$dir/lisfm/metrics.json")"
    ROWS+=("| $name | lisfm global_mapper | $ours_s | $(ratio "$stock_s" "$ours_s") | $o_reg/$num_images | $o_pts | $o_obs | $(ratio "$o_obs" "$s_obs") | $o_tl | $o_rep | $o_rot | $o_pos | $o_a1 | $o_a5 |")
  else
    ROWS+=("| $name | lisfm global_mapper | $ours_s | n/a | n/a | n/a | n/a | n/a | n/a | n/a | n/a | n/a | n/a | n/a |")
  fi
done

{
  printf "machine: %s cores, %s; colmap %s; %s\n\n" "$(nproc)" \
    "$(lscpu | sed -n 's/^Model name: *//p' | head -1)" \
    "$("$COLMAP" help 2>&1 | sed -n 's/^COLMAP \([^ ]*\).*/\1/p' | head -1)" "$(date -u +%Y-%m-%d)"
  echo "| dataset | mapper | wall s | speed-up | registered | points | observations | obs ratio vs stock | mean track length | reproj px | rot err deg | pos err | AUC@1° | AUC@5° |"
  echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
  printf "%s\n" "${ROWS[@]}"
  echo
  echo "wall s: mapping step only (same database copy per mapper); registered/points/observations/"
  echo "track length/reprojection error: stock colmap model_analyzer on the largest model; rot err:"
  echo "mean over registered images after an L1 rotation alignment; pos err: mean after a Sim(3)"
  echo "alignment of the camera centres (reference units: metres for Strecha); AUC: relative-pose"
  echo "AUC over all image pairs (lisfm model_evaluator). Work folder: $WORK_DIR"
} | tee "$WORK_DIR/compare_colmap.md"
