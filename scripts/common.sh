# Sourced by the scripts: paths and the build step shared by demo.sh, test.sh and bench_*.sh.
LISFM_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
LISFM_BUILD_DIR="${LISFM_BUILD_DIR:-$LISFM_ROOT/build}"
LISFM_SHARED_DATA="${LISFM_SHARED_DATA:-$(cd "$LISFM_ROOT/.." && pwd)/shared/data}"
LISFM_JOBS="${LISFM_JOBS:-2}"
LISFM="$LISFM_BUILD_DIR/apps/lisfm"

# lisfm_build [extra cmake args...]: configures (Release) and builds everything.
lisfm_build() {
  mkdir -p "$LISFM_BUILD_DIR"
  cmake -S "$LISFM_ROOT" -B "$LISFM_BUILD_DIR" -DCMAKE_BUILD_TYPE=Release \
    -DLISFM_WERROR="${LISFM_WERROR:-OFF}" "$@" >"$LISFM_BUILD_DIR/cmake.log" 2>&1 \
    || { cat "$LISFM_BUILD_DIR/cmake.log"; echo "cmake configure failed" >&2; return 1; }
  cmake --build "$LISFM_BUILD_DIR" -j"$LISFM_JOBS"
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
