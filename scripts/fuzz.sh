#!/usr/bin/env bash
# Builds the libFuzzer targets (tests/fuzz, CMake option LISFM_FUZZ, clang-14 with
# ASan + UBSan) into build-fuzz/ and runs each for SECONDS (default 60), one after
# the other on one core, then prints a table: target, seconds, executions, exec/s,
# coverage (edges: `cov:` of libFuzzer's last status line), corpus size, crashes.
#   scripts/fuzz.sh [SECONDS] [TARGET...]     # all targets unless named
# The working corpus grows in fuzz_work/corpus/<target>/ (git-ignored, kept between
# runs: a campaign can span several runs), seeded from tests/fuzz/corpus/<target>/;
# a crash, hang (> 10 s per input), leak, out-of-memory (> 2048 MB) or sanitizer
# report is saved as fuzz_work/crashes/<target>-<kind>-<sha1> and its log as
# fuzz_work/logs/<target>.log. Exit 1 when any target crashed.
# Environment: LISFM_FUZZ_BUILD_DIR, LISFM_FUZZ_WORK_DIR, LISFM_JOBS (build jobs, 2).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"

SECONDS_PER_TARGET="${1:-60}"
if ! [[ "$SECONDS_PER_TARGET" =~ ^[1-9][0-9]*$ ]]; then
  echo "error: fuzz.sh: SECONDS must be a positive whole number, found '$SECONDS_PER_TARGET'" >&2
  exit 2
fi
shift || true
BUILD="${LISFM_FUZZ_BUILD_DIR:-$LISFM_ROOT/build-fuzz}"
WORK="${LISFM_FUZZ_WORK_DIR:-$LISFM_ROOT/fuzz_work}"
SEEDS="$LISFM_ROOT/tests/fuzz/corpus"

for tool in clang-14 clang++-14; do
  command -v "$tool" >/dev/null || {
    echo "error: fuzz.sh: $tool not found; run scripts/install_deps.sh" >&2
    exit 1
  }
done
launcher=()
if command -v ccache >/dev/null; then
  launcher=(-DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
fi
mkdir -p "$BUILD"
CC=clang-14 CXX=clang++-14 cmake -S "$LISFM_ROOT" -B "$BUILD" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DLISFM_FUZZ=ON -DLISFM_TESTS_ENABLED=OFF "${launcher[@]}" >"$BUILD/cmake.log" 2>&1 \
  || { cat "$BUILD/cmake.log"; echo "error: fuzz.sh: cmake configure failed" >&2; exit 1; }
cmake --build "$BUILD" --target fuzz_targets -j"$LISFM_JOBS"

if [ $# -gt 0 ]; then
  targets=("$@")
else
  mapfile -t targets <"$BUILD/fuzz_targets.txt"
fi
for t in "${targets[@]}"; do
  [ -x "$BUILD/tests/fuzz/fuzz_$t" ] || {
    echo "error: fuzz.sh: no fuzz target '$t' (see $BUILD/fuzz_targets.txt)" >&2
    exit 2
  }
done

mkdir -p "$WORK/crashes" "$WORK/logs"
rows=()
any_crash=0
load_before="$(cut -d' ' -f1-3 /proc/loadavg)"
for t in "${targets[@]}"; do
  mkdir -p "$WORK/corpus/$t"
  log="$WORK/logs/$t.log"
  before=$(find "$WORK/crashes" -name "$t-*" | wc -l)
  echo "fuzz.sh: $t for ${SECONDS_PER_TARGET} s"
  status=0
  "$BUILD/tests/fuzz/fuzz_$t" -max_total_time="$SECONDS_PER_TARGET" -timeout=10 \
    -rss_limit_mb=2048 -print_final_stats=1 -artifact_prefix="$WORK/crashes/$t-" \
    "$WORK/corpus/$t" "$SEEDS/$t" >"$log" 2>&1 || status=$?
  after=$(find "$WORK/crashes" -name "$t-*" | wc -l)
  crashes=$((after - before))
  if [ "$status" -ne 0 ] && [ "$crashes" -eq 0 ]; then crashes=1; fi  # e.g. a startup failure
  [ "$crashes" -gt 0 ] && any_crash=1
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1)
  cov=$(grep -ao 'cov: [0-9]*' "$log" | tail -1 | cut -d' ' -f2)
  corpus=$(find "$WORK/corpus/$t" -type f | wc -l)
  rows+=("$(printf '%-22s %7s %12s %8s %7s %7s %8s' "$t" "$SECONDS_PER_TARGET" "${execs:-?}" \
    "${rate:-?}" "${cov:-?}" "$corpus" "$crashes")")
done
load_after="$(cut -d' ' -f1-3 /proc/loadavg)"

echo
printf '%-22s %7s %12s %8s %7s %7s %8s\n' target seconds executions exec/s edges corpus crashes
printf '%s\n' "${rows[@]}"
echo "load average (1/5/15 min): $load_before before, $load_after after; $(nproc) cores"
if [ "$any_crash" -ne 0 ]; then
  echo "fuzz.sh: crashes: inputs in $WORK/crashes/, logs in $WORK/logs/" >&2
  exit 1
fi
