#!/usr/bin/env bash
# Stock `colmap mapper` (COLMAP 3.8) vs `lisfm global_mapper` vs COLMAP 4's
# `colmap global_mapper` (the former GLOMAP) on the same COLMAP database, per
# real data set, side by side. Prints one markdown table for
# docs/BENCHMARKS.md (also written to WORK_DIR/compare_colmap.md).
#
#   scripts/compare_colmap.sh [--work_dir DIR] [--datasets a,b,...] [--rebuild]
#                             [--keep_stock] [--colmap4 PATH] [--mappers a,b,...]
#
# Data sets (../shared/data): lund_door (COLMAP reference model), fountain,
# herzjesu, entry (Strecha ground-truth cameras), balbianello (Bundler model).
# Per data set: one database from stock COLMAP (SIFT on the CPU with the known
# intrinsics, one shared camera, exhaustive matching), reused from WORK_DIR
# when present (--rebuild re-extracts); then one copy of it per mapper (COLMAP 4
# adds its rig/frame tables to the database it reads), timed (wall clock of the
# mapping step only). Every model is measured with stock `colmap
# model_analyzer` and scored with `lisfm model_evaluator` against the
# reference (Sim(3) alignment: no mapper is metric here).
# --keep_stock reuses a stock model and its time from an earlier run.
# --colmap4 PATH (or env COLMAP4): COLMAP 4's `colmap` executable, built by
# ../shared/peers/build_colmap4.sh (default build/peers/colmap4/bin/colmap when
# present); without one its rows are left out with a note. It runs with its
# default options and thread count. --mappers (default stock,lisfm,colmap4):
# which mappers run, in that order (the speed-up and observation ratios need
# stock); lisfm_noba / colmap4_noba run lisfm / COLMAP 4 without bundle
# adjustment and retriangulation (skip options of both), so that their rows
# score the rotations of rotation averaging and the positions of translation
# averaging / global positioning.
# When `lisfm global_mapper` is not available yet, its row shows n/a.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"

WORK_DIR=/tmp/lisfm_compare_colmap
DATASETS=lund_door,fountain,herzjesu,entry,balbianello
REBUILD=0
KEEP_STOCK=0
MAPPERS=stock,lisfm,colmap4
COLMAP4=${COLMAP4:-}
usage() { awk 'NR > 1 && !/^#/ {exit} NR > 1 {sub(/^# ?/, ""); print}' "${BASH_SOURCE[0]}"; }
while [ $# -gt 0 ]; do
  case "$1" in
    --work_dir) WORK_DIR=$2; shift 2 ;;
    --datasets) DATASETS=$2; shift 2 ;;
    --rebuild) REBUILD=1; shift ;;
    --keep_stock) KEEP_STOCK=1; shift ;;
    --colmap4) COLMAP4=$2; shift 2 ;;
    --mappers) MAPPERS=$2; shift 2 ;;
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

if [ -z "$COLMAP4" ] && [ -x "$LISFM_ROOT/build/peers/colmap4/bin/colmap" ]; then
  COLMAP4=$LISFM_ROOT/build/peers/colmap4/bin/colmap
fi
HAVE_COLMAP4=0
COLMAP4_VERSION=""
if [ -n "$COLMAP4" ]; then
  [ -x "$COLMAP4" ] || { echo "error: --colmap4 $COLMAP4 is not an executable" >&2; exit 2; }
  HAVE_COLMAP4=1
  COLMAP4_VERSION=$("$COLMAP4" help 2>&1 | sed -n 's/^COLMAP \(.*\)/\1/p' | head -1)
else
  echo "note: COLMAP 4 not found (build it with ../shared/peers/build_colmap4.sh or pass" \
    "--colmap4 PATH); its rows are left out" >&2
fi

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

# evaluate MODEL JSON: "rot_err pos_err auc1 auc5 rel_rot_median rel_rot_max"
# (n/a when the evaluation fails).
evaluate() {
  if "$LISFM" model_evaluator --model_path "$1" --reference_path "$REFERENCE" \
      --output_path "$2" --quiet 1 >"${2%.json}.log" 2>&1; then
    jq -r '"\(.rotation_error_deg.mean) \(.position_error.mean) \(.auc["1"]) \(.auc["5"]) \(.relative_rotation_error_deg.median) \(.relative_rotation_error_deg.max)"' "$2" |
      awk '{for (i = 1; i <= 6; ++i) $i = ($i ~ /^[-0-9.eE+]+$/) ? sprintf(i == 2 ? "%.4g" : (i == 1 || i >= 5) ? "%.4f" : "%.3f", $i) : "n/a"; print}'
  else
    echo "n/a n/a n/a n/a n/a n/a"
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
  elif [ "$side" = colmap4 ] || [ "$side" = colmap4_noba ]; then
    local extra=()
    [ "$side" = colmap4_noba ] && extra=(--GlobalMapper.skip_bundle_adjustment 1
      --GlobalMapper.skip_retriangulation 1)
    "$COLMAP4" global_mapper --database_path "$dir/database.db" --image_path "$IMAGES" \
      --output_path "$dir/sparse" --log_target stderr "${extra[@]}" >"$dir/mapper.log" 2>&1 || rc=$?
  else
    local extra=()
    [ "$side" = lisfm_noba ] && extra=(--Mapper.skip_bundle_adjustment 1
      --Mapper.skip_retriangulation 1)
    "$LISFM" global_mapper --database_path "$dir/database.db" --image_path "$IMAGES" \
      --output_path "$dir/sparse" "${extra[@]}" >"$dir/mapper.log" 2>&1 || rc=$?
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
IFS=',' read -r -a MAPPER_LIST <<<"$MAPPERS"
for side in "${MAPPER_LIST[@]}"; do
  case "$side" in
    stock|lisfm|colmap4|lisfm_noba|colmap4_noba) ;;
    *) echo "error: --mappers: unknown mapper '$side' (stock, lisfm, colmap4, lisfm_noba," \
         "colmap4_noba)" >&2; exit 2 ;;
  esac
done
for name in "${DATASET_LIST[@]}"; do
  dataset_config "$name"
  dir=$WORK_DIR/$name
  mkdir -p "$dir/logs"
  build_database "$name" "$dir"
  num_images=$(find "$IMAGES" -maxdepth 1 -type f | wc -l)

  stock_s=n/a s_obs=n/a
  for side in "${MAPPER_LIST[@]}"; do
    case "$side" in
      stock) label="colmap mapper" ;;
      lisfm) label="lisfm global_mapper"
        [ "$HAVE_GLOBAL_MAPPER" = 1 ] || { ROWS+=("| $name | $label | n/a$(printf ' | n/a%.0s' {1..15}) |"); continue; } ;;
      lisfm_noba) label="lisfm global_mapper, no BA"; [ "$HAVE_GLOBAL_MAPPER" = 1 ] || continue ;;
      colmap4) label="colmap 4 global_mapper"; [ "$HAVE_COLMAP4" = 1 ] || continue ;;
      colmap4_noba) label="colmap 4 global_mapper, no BA"; [ "$HAVE_COLMAP4" = 1 ] || continue ;;
    esac
    wall_s=$(run_mapper "$name" "$side" "$dir")
    model=$(largest_model "$dir/$side/sparse")
    if [ -n "$model" ]; then
      read -r m_reg m_pts m_obs m_tl m_rep <<<"$(analyze "$model")"
      read -r m_rot m_pos m_a1 m_a5 m_rmed m_rmax <<<"$(evaluate "$model" "$dir/$side/metrics.json")"
    else
      m_reg=0 m_pts=n/a m_obs=n/a m_tl=n/a m_rep=n/a m_rot=n/a m_pos=n/a m_a1=n/a m_a5=n/a
      m_rmed=n/a m_rmax=n/a
    fi
    if [ "$side" = stock ]; then stock_s=$wall_s s_obs=$m_obs; fi
    ROWS+=("| $name | $label | $wall_s | $(ratio "$stock_s" "$wall_s") | $m_reg/$num_images | $m_pts | $m_obs | $(ratio "$m_obs" "$s_obs") | $m_tl | $m_rep | $m_rot | $m_rmed | $m_rmax | $m_pos | $m_a1 | $m_a5 |")
  done
done

{
  printf "machine: %s cores, %s; colmap %s; colmap 4: %s; %s; load at the end: %s\n\n" "$(nproc)" \
    "$(lscpu | sed -n 's/^Model name: *//p' | head -1)" \
    "$("$COLMAP" help 2>&1 | sed -n 's/^COLMAP \([^ ]*\).*/\1/p' | head -1)" \
    "${COLMAP4_VERSION:-not run}" "$(date -u +%Y-%m-%dT%H:%MZ)" "$(cut -d' ' -f1-3 /proc/loadavg)"
  echo "| dataset | mapper | wall s | speed-up vs stock | registered | points | observations | obs ratio vs stock | mean track length | reproj px | rot err deg | rel rot err median deg | rel rot err max deg | pos err | AUC@1° | AUC@5° |"
  echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
  printf "%s\n" "${ROWS[@]}"
  echo
  echo "wall s: mapping step only (same database copy per mapper); registered/points/observations/"
  echo "track length/reprojection error: stock colmap model_analyzer on the largest model; rot err:"
  echo "mean over registered images after an L1 rotation alignment; rel rot err: median / max over"
  echo "all pairs of registered images of the angle of R_est_ij R_ref_ij^T (alignment-free); pos err:"
  echo "mean camera-centre error after a Sim(3) alignment of the centres (reference units: metres"
  echo "for Strecha); AUC: relative-pose AUC over all image pairs (lisfm model_evaluator)."
  echo "Work folder: $WORK_DIR"
} | tee "$WORK_DIR/compare_colmap.md"
