#!/usr/bin/env bash
# Read + write of a synthetic COLMAP model (default 1000 images, 500k points,
# track length 4) with `lisfm model_converter` and stock `colmap model_converter`
# on the same files, side by side. Prints a table for docs/BENCHMARKS.md.
#
#   scripts/bench_colmap_io.sh [num_images] [num_points] [repeats]
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
IMAGES=${1:-1000}
POINTS=${2:-500000}
REPEATS=${3:-3}
lisfm_build_bench lisfm lisfm_colmap_synth
SYNTH="$LISFM_BUILD_DIR/bench/lisfm_colmap_synth"
COLMAP=$(command -v colmap || true)
[ -n "$COLMAP" ] || echo "warning: stock colmap not found; only lisfm is timed" >&2
export QT_QPA_PLATFORM=offscreen
WORK=$(mktemp -d /tmp/bench_colmap_io.XXXXXX)
trap 'rm -rf "$WORK"' EXIT

"$SYNTH" "$WORK/bin" "$IMAGES" "$POINTS" 4 bin >/dev/null
mkdir -p "$WORK/txt"
"$LISFM" model_converter --input_path "$WORK/bin" --output_path "$WORK/txt" --output_type TXT --quiet 1

# best-of-N wall time in seconds
timeit() {
  local best=""
  for _ in $(seq "$REPEATS"); do
    local t0 t1
    t0=$(date +%s.%N); "$@" >/dev/null 2>&1; t1=$(date +%s.%N)
    local dt; dt=$(echo "$t1 - $t0" | bc -l)
    if [ -z "$best" ] || (( $(echo "$dt < $best" | bc -l) )); then best=$dt; fi
  done
  printf "%.2f" "$best"
}

printf "model: %s images, %s points, %s MB binary, %s MB text; best of %s runs\n" \
  "$IMAGES" "$POINTS" "$(du -sm "$WORK/bin" | cut -f1)" "$(du -sm "$WORK/txt" | cut -f1)" "$REPEATS"
printf "machine: %s cores, %s\n\n" "$(nproc)" "$(lscpu | sed -n 's/^Model name: *//p' | head -1)"
printf "| conversion | lisfm (s) | colmap 3.8 (s) |\n|---|---|---|\n"
for conv in "bin BIN" "bin TXT" "txt BIN" "txt TXT" "bin PLY"; do
  set -- $conv
  src="$WORK/$1"; type=$2
  out="$WORK/out_$1_$type"; [ "$type" = PLY ] && out="$WORK/out_$1.ply"
  mkdir -p "$WORK/out_$1_$type"
  # --overwrite 1: each timed repetition replaces the previous (lisfm-written) output folder.
  l=$(timeit "$LISFM" model_converter --input_path "$src" --output_path "$out" --output_type "$type" \
        --overwrite 1 --quiet 1)
  c="n/a"
  [ -n "$COLMAP" ] && c=$(timeit "$COLMAP" model_converter --input_path "$src" --output_path "$out" --output_type "$type")
  printf "| %s -> %s | %s | %s |\n" "$1" "$type" "$l" "$c"
done
