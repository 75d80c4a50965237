#!/usr/bin/env bash
# Sets up (Debian packages + gltf-validator, idempotent), builds and runs the
# whole test suite.  The one test command of README.md and of .ci/run.
#   STRATA_BUILD_DIR (default build), STRATA_BUILD_TYPE (default Release),
#   STRATA_SANITIZE (e.g. address,undefined), STRATA_WERROR (ON/OFF),
#   STRATA_CTEST_EXCLUDE (a ctest -E regex: tests this pass leaves to another;
#   .ci/run's sanitizer pass leaves it the release pass's slowest repeats),
#   STRATA_FUZZ (ON: the libFuzzer targets too, for tools/fuzz.sh; needs
#   CC=clang CXX=clang++), STRATA_UNITY_LIBS (ON: the libraries eight
#   sources to a unit).
set -euo pipefail
cd "$(dirname "$0")/.."
bash cmake/install-deps.sh
build="${STRATA_BUILD_DIR:-build}"
# A compiler cache: the wheel pip builds in python.pip_install compiles the
# same sources with the same flags as this build, and gets its objects.
if command -v ccache >/dev/null 2>&1; then
  export CMAKE_C_COMPILER_LAUNCHER="${CMAKE_C_COMPILER_LAUNCHER:-ccache}"
  export CMAKE_CXX_COMPILER_LAUNCHER="${CMAKE_CXX_COMPILER_LAUNCHER:-ccache}"
fi
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE="${STRATA_BUILD_TYPE:-Release}" \
  -DSTRATA_WERROR="${STRATA_WERROR:-OFF}" -DSTRATA_SANITIZE="${STRATA_SANITIZE:-}" \
  -DSTRATA_BUILD_BENCH="${STRATA_BENCH:-ON}" -DSTRATA_FUZZ="${STRATA_FUZZ:-OFF}" \
  -DSTRATA_UNITY_LIBS="${STRATA_UNITY_LIBS:-OFF}" -DSTRATA_BUILD_TESTS=ON >/dev/null
cmake --build "$build" -j "$(nproc)"
# A skipped test is not a passed one: ctest exits 0 on skips, so its log is
# read too (every test runs from a fresh clone; none may skip).
log="$(mktemp)"
trap 'rm -f "$log"' EXIT
exclude=()
[ -z "${STRATA_CTEST_EXCLUDE:-}" ] || exclude=(-E "$STRATA_CTEST_EXCLUDE")
ctest --test-dir "$build" --output-on-failure -j "$(nproc)" "${exclude[@]}" | tee "$log"
if grep -q "tests did not run" "$log"; then
  echo "strata: some tests were skipped (see above); a skipped test does not pass" >&2
  exit 1
fi
