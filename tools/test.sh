#!/usr/bin/env bash
# Sets up (Debian packages + gltf-validator, idempotent), builds and runs the
# whole test suite.  The one test command of README.md and of .ci/run.
#   STRATA_BUILD_DIR (default build), STRATA_BUILD_TYPE (default Release),
#   STRATA_SANITIZE (e.g. address,undefined), STRATA_WERROR (ON/OFF).
set -euo pipefail
cd "$(dirname "$0")/.."
bash cmake/install-deps.sh
build="${STRATA_BUILD_DIR:-build}"
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE="${STRATA_BUILD_TYPE:-Release}" \
  -DSTRATA_WERROR="${STRATA_WERROR:-OFF}" -DSTRATA_SANITIZE="${STRATA_SANITIZE:-}" \
  -DSTRATA_BUILD_BENCH="${STRATA_BENCH:-ON}" -DSTRATA_BUILD_TESTS=ON >/dev/null
cmake --build "$build" -j "$(nproc)"
ctest --test-dir "$build" --output-on-failure -j "$(nproc)"
