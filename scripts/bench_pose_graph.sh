#!/usr/bin/env bash
# Pose-graph optimisation on the SE-Sync benchmark graphs (docs/BENCHMARKS.md,
# "Pose graph"): `lisfm pose_graph` (chordal initialisation, then Levenberg-
# Marquardt on SE-Sync's objective) against the published optimum F* (Rosen et
# al., IJRR 2019, Tables 1-2; ../shared/data/pose_graphs/OPTIMA.md), and on the 3D
# graphs the formulation of Ceres' pose_graph_3d example (bench/
# pose_graph_ceres_example.cc: full-information g2o residuals, quaternion
# manifold) timed beside it with the same thread count, from the file's vertices
# (as the example runs) and from our chordal initialisation. Times are medians of
# REPEATS runs (seconds, wall clock: reading + initialisation + solve for ours;
# the solve for the example, plus the chordal initialisation when it starts there).
# Usage: scripts/bench_pose_graph.sh [REPEATS]   (default 3)
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
REPEATS="${1:-3}"
DATA="$LISFM_SHARED_DATA/pose_graphs"
THREADS="$(nproc)"
lisfm_build_bench lisfm lisfm_pose_graph_ceres_example >/dev/null
EXAMPLE="$LISFM_BUILD_DIR/bench/lisfm_pose_graph_ceres_example"
[ -d "$DATA" ] || { echo "bench_pose_graph.sh: $DATA is missing" >&2; exit 1; }
echo "CPU: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $THREADS threads; $(uptime)"

# field KEY: the value of "KEY: value" on stdin.
field() { awk -v k="$1" 'index($0, k ": ") == 1 { print substr($0, length(k) + 3); exit }'; }
median() { sort -g | awk '{ v[NR] = $1 } END { print v[int((NR + 1) / 2)] }'; }

# Published F* (OPTIMA.md); "-" = none published.
declare -A OPTIMUM=(
  [sphere2500]=1687 [parking-garage]=1.263 [cubicle]=717.1
  [manhattan]=6432 [city10000]=638.6 [CSAIL]=31.70 [intel]=52.35 [ais2klinik]=188.5
)
SETS=(sphere2500 parking-garage cubicle smallGrid3D manhattan city10000 CSAIL intel ais2klinik
      MIT kitti_00 kitti_02 kitti_05)

echo
echo "| dataset | D | poses | edges | F chordal init | F final | F* (published) | (F - F*) / F* | iterations | init s | solve s | total s |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
for name in "${SETS[@]}"; do
  file="$DATA/$name.g2o"
  [ -f "$file" ] || continue
  totals=(); solves=(); inits=()
  for ((r = 0; r < REPEATS; ++r)); do
    out="$("$LISFM" pose_graph --input_path "$file" --quiet)"
    times="$(echo "$out" | field time_s)"
    inits+=("$(echo "$times" | awk '{ print $4 }')")
    solves+=("$(echo "$times" | awk '{ print $6 }')")
    totals+=("$(echo "$times" | awk '{ print $10 }')")
  done
  f_star="${OPTIMUM[$name]:-}"
  f_final="$(echo "$out" | field F_final)"
  gap="-"
  [ -n "$f_star" ] && gap="$(awk -v f="$f_final" -v s="$f_star" 'BEGIN { printf "%+.1e", (f - s) / s }')"
  converged="$(echo "$out" | field converged)"
  iterations="$(echo "$out" | field iterations)"
  [ "$converged" = "true" ] || iterations="$iterations (not converged)"
  printf "| %s | %s | %s | %s | %.7g | %.7g | %s | %s | %s | %.3f | %.3f | %.3f |\n" \
    "$name" "$(echo "$out" | field dimension)" "$(echo "$out" | field poses)" \
    "$(echo "$out" | field edges)" "$(echo "$out" | field F_initial)" "$f_final" \
    "${f_star:--}" "$gap" "$iterations" \
    "$(printf '%s\n' "${inits[@]}" | median)" "$(printf '%s\n' "${solves[@]}" | median)" \
    "$(printf '%s\n' "${totals[@]}" | median)"
done

echo
echo "3D graphs: lisfm pose_graph vs the Ceres pose_graph_3d example formulation ($THREADS threads each)"
echo
echo "| dataset | ours: iterations | ours: init + solve s | example from vertices: iterations | s | F at its solution | example from chordal: iterations | init + solve s | F at its solution | full-information edges not PD |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
for name in sphere2500 parking-garage cubicle smallGrid3D; do
  file="$DATA/$name.g2o"
  [ -f "$file" ] || continue
  ours=(); from_vertices=(); from_chordal=()
  for ((r = 0; r < REPEATS; ++r)); do
    out="$("$LISFM" pose_graph --input_path "$file" --quiet --Solver.num_threads "$THREADS")"
    ours+=("$(echo "$out" | field time_s | awk '{ print $4 + $6 }')")
    ex="$("$EXAMPLE" "$file" --threads "$THREADS")"
    from_vertices+=("$(echo "$ex" | field solve_s)")
    exc="$("$EXAMPLE" "$file" --threads "$THREADS" --init chordal)"
    from_chordal+=("$(echo "$exc" | awk '/^init_s:/ { i = $2 } /^solve_s:/ { s = $2 } END { print i + s }')")
  done
  printf "| %s | %s | %.3f | %s | %.3f | %.7g | %s | %.3f | %.7g | %s |\n" "$name" \
    "$(echo "$out" | field iterations)" "$(printf '%s\n' "${ours[@]}" | median)" \
    "$(echo "$ex" | field iterations)" "$(printf '%s\n' "${from_vertices[@]}" | median)" \
    "$(echo "$ex" | field F_final)" "$(echo "$exc" | field iterations)" \
    "$(printf '%s\n' "${from_chordal[@]}" | median)" "$(echo "$exc" | field F_final)" \
    "$(echo "$ex" | field edges_block_diagonal)"
done
