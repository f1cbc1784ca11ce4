# Sourced by the scripts: paths and the build step shared by demo.sh, test.sh and bench_*.sh.
LISFM_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
LISFM_BUILD_DIR="${LISFM_BUILD_DIR:-$LISFM_ROOT/build}"
LISFM_SHARED_DATA="${LISFM_SHARED_DATA:-$(cd "$LISFM_ROOT/.." && pwd)/shared/data}"
LISFM_JOBS="${LISFM_JOBS:-2}"
LISFM="$LISFM_BUILD_DIR/apps/lisfm"

# lisfm_build [extra cmake args...] [-- target...]: configures ($LISFM_BUILD_TYPE, default
# Release) and builds the targets (default: everything).
lisfm_build() {
  local cmake_args=() targets=()
  while [ $# -gt 0 ] && [ "$1" != "--" ]; do cmake_args+=("$1"); shift; done
  [ $# -gt 0 ] && shift
  for t in "$@"; do targets+=(--target "$t"); done
  mkdir -p "$LISFM_BUILD_DIR"
  cmake -S "$LISFM_ROOT" -B "$LISFM_BUILD_DIR" -DCMAKE_BUILD_TYPE="${LISFM_BUILD_TYPE:-Release}" \
    -DLISFM_WERROR="${LISFM_WERROR:-OFF}" "${cmake_args[@]}" >"$LISFM_BUILD_DIR/cmake.log" 2>&1 \
    || { cat "$LISFM_BUILD_DIR/cmake.log"; echo "cmake configure failed" >&2; return 1; }
  cmake --build "$LISFM_BUILD_DIR" "${targets[@]}" -j"$LISFM_JOBS"
}

# lisfm_build_bench TARGET...: configures with the benchmark programs
# (LISFM_BENCHMARKS_ENABLED=ON, bench/) and builds the named targets.
lisfm_build_bench() {
  mkdir -p "$LISFM_BUILD_DIR"
  cmake -S "$LISFM_ROOT" -B "$LISFM_BUILD_DIR" -DCMAKE_BUILD_TYPE=Release \
    -DLISFM_BENCHMARKS_ENABLED=ON >"$LISFM_BUILD_DIR/cmake.log" 2>&1 \
    || { cat "$LISFM_BUILD_DIR/cmake.log"; echo "cmake configure failed" >&2; return 1; }
  local targets=()
  for t in "$@"; do targets+=(--target "$t"); done
  cmake --build "$LISFM_BUILD_DIR" "${targets[@]}" -j"$LISFM_JOBS"
}
