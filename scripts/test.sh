#!/usr/bin/env bash
# Installs the dependencies, builds lisfm (Release) and runs every test with ctest.
#   scripts/test.sh                 # all tests
#   scripts/test.sh -R geometry     # extra arguments go to ctest
#   LISFM_WERROR=ON scripts/test.sh # warnings as errors (CI)
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"

"$LISFM_ROOT/scripts/install_deps.sh"
mkdir -p "$LISFM_BUILD_DIR"
lisfm_build
if [ ! -d "$LISFM_SHARED_DATA" ]; then
  echo "test.sh: note: $LISFM_SHARED_DATA is missing; real-data tests will be skipped"
fi
cd "$LISFM_BUILD_DIR"
ctest --output-on-failure -j"$LISFM_JOBS" --timeout 900 "$@"
