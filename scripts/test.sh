#!/usr/bin/env bash
# Installs the dependencies, builds lisfm and runs the tests with ctest.
#   scripts/test.sh                   # all tests (Release build in build/)
#   scripts/test.sh -R geometry       # extra arguments go to ctest
#   LISFM_WERROR=ON scripts/test.sh   # warnings as errors (CI)
#   scripts/test.sh --sanitize        # AddressSanitizer + UndefinedBehaviorSanitizer build in
#                                     # build-asan/, every test but the `slow` label
#   scripts/test.sh --sanitize --quick  # the same on the subset CI runs (LISFM_SANITIZE_QUICK)
# Under --sanitize any report fails the run: a report in a test process fails that test
# (halt_on_error, no UB recovery), and every report, also from a `lisfm` process that a test
# runs, is written to build-asan/sanitizer_logs/, which must stay empty. Leak reports of
# third-party code are suppressed in scripts/sanitizers/ (one reason per entry).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"

# The sanitizer subset of CI: every reader of untrusted input (core/io, colmap_ext/io,
# importers), the option parser, the CLI end to end on bad input, and the fuzz corpus
# replayed through every fuzz target's entry point.
LISFM_SANITIZE_QUICK=(
  core/options_test core/file_utils_test
  core/io/cloud_io_test core/io/g2o_io_test core/io/lidar_constraints_io_test
  core/io/rig_io_test core/io/trajectory_io_test core/io/rgbd_io_test
  core/io/keyframe_covariances_io_test
  colmap_ext/io/model_io_test colmap_ext/io/database_test colmap_ext/io/rig_config_test
  importers/bag_test importers/bag_message_test importers/point_cloud2_test importers/kitti_test
  tests/e2e/cli_test tests/e2e/option_ranges_test tests/e2e/bad_input_test
  fuzz/replay_corpus
)

sanitize=0
quick=0
while [ $# -gt 0 ]; do
  case "$1" in
    --sanitize) sanitize=1; shift ;;
    --quick) quick=1; shift ;;
    *) break ;;
  esac
done
if [ "$quick" = 1 ] && [ "$sanitize" = 0 ]; then
  echo "error: --quick needs --sanitize" >&2
  exit 2
fi

"$LISFM_ROOT/scripts/install_deps.sh"
if [ ! -d "$LISFM_SHARED_DATA" ]; then
  echo "test.sh: note: $LISFM_SHARED_DATA is missing; real-data tests will be skipped"
fi

if [ "$sanitize" = 0 ]; then
  lisfm_build
  cd "$LISFM_BUILD_DIR"
  ctest --output-on-failure -j"$LISFM_JOBS" --timeout 900 "$@"
  exit 0
fi

# -O1 keeps the instrumented tests fast enough; -g1 gives line numbers in reports;
# NDEBUG as in Release, so that the same code runs.
LISFM_BUILD_DIR="${LISFM_ASAN_BUILD_DIR:-$LISFM_ROOT/build-asan}"
LISFM_BUILD_TYPE=RelWithDebInfo
sanitize_args=(-DLISFM_SANITIZE=address,undefined
  "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1 -DNDEBUG"
  "-DCMAKE_C_FLAGS_RELWITHDEBINFO=-O1 -g1 -DNDEBUG")
ctest_args=(-LE slow)
if [ "$quick" = 1 ]; then
  # Build only what the subset runs: its test programs and lisfm.
  targets=(lisfm)
  regex=""
  for t in "${LISFM_SANITIZE_QUICK[@]}"; do
    case "$t" in
      fuzz/*) targets+=("tests_$(echo "$t" | tr / _)") ;;  # tests/fuzz/ names its ctest fuzz/
      *) targets+=("$(echo "$t" | tr / _)") ;;
    esac
    regex+="${regex:+|}^$t\$"
  done
  lisfm_build "${sanitize_args[@]}" -- "${targets[@]}"
  ctest_args+=(-R "$regex")
else
  lisfm_build "${sanitize_args[@]}"
fi

logs="$LISFM_BUILD_DIR/sanitizer_logs"
rm -rf "$logs"
mkdir -p "$logs"
supp="$LISFM_ROOT/scripts/sanitizers"
export ASAN_OPTIONS="detect_leaks=1:halt_on_error=1:abort_on_error=0:detect_stack_use_after_return=0:log_path=$logs/asan"
export LSAN_OPTIONS="suppressions=$supp/lsan.supp:print_suppressions=0"
# Open MPI's components stay loaded until exit, so that their frames keep their names in
# leak reports (lsan.supp matches them).
export OMPI_MCA_mca_base_component_disable_dlclose=1
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1:suppressions=$supp/ubsan.supp:log_path=$logs/ubsan"
cd "$LISFM_BUILD_DIR"
status=0
ctest --output-on-failure -j"$LISFM_JOBS" --timeout 1800 "${ctest_args[@]}" "$@" || status=$?
if compgen -G "$logs/*" >/dev/null; then
  echo "test.sh: sanitizer reports (from test programs or the lisfm processes they ran):" >&2
  for f in "$logs"/*; do
    echo "---- $f" >&2
    cat "$f" >&2
  done
  status=1
fi
exit "$status"
