#!/usr/bin/env bash
# Builds the libFuzzer targets (clang, ASan + UBSan) and runs each for a
# fixed time on a copy of its seed corpus (fuzz/corpus/TARGET).  CI runs it
# briefly on every run; run it for hours with a larger SECONDS:
#   bash tools/fuzz.sh 3600          # each target an hour
#   bash tools/fuzz.sh 60 fuzz_mesh  # one target
# Targets run side by side, one a core.  A crash, leak or timeout exits
# non-zero and leaves the input in BUILD/artifacts/ (build-fuzz by default),
# beside each target's log; turn it into a regression test.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-60}"
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(fuzz_rig fuzz_mesh fuzz_joints fuzz_map fuzz_exr fuzz_bake_input)
bash cmake/install-deps.sh  # clang and its libFuzzer runtime among them
# Any build configured with -DSTRATA_FUZZ=ON will do (.ci/run passes its
# sanitizer build, whose libraries are instrumented for both); by default
# one of its own, of which only the fuzz targets are built.
build="${STRATA_FUZZ_BUILD_DIR:-build-fuzz}"
if ! grep -qs '^STRATA_FUZZ:BOOL=ON' "$build/CMakeCache.txt"; then
  CC=clang CXX=clang++ cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSTRATA_FUZZ=ON \
    -DSTRATA_BUILD_BENCH=OFF >/dev/null
fi
cmake --build "$build" -j "$(nproc)" --target "${targets[@]}"
mkdir -p "$build/artifacts"
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
# One target a core at a time (each libFuzzer process runs on one), each to
# a log of its own, reported in order once all have run.
fuzz_one() {
  local t="$1" corpus="$build/corpus/$1"
  mkdir -p "$corpus"
  cp -n fuzz/corpus/"${t#fuzz_}"/* "$corpus"/ 2>/dev/null || true
  "$build/fuzz/$t" "$corpus" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -malloc_limit_mb=512 \
    -max_len=262144 -artifact_prefix="$build/artifacts/$t-" -print_final_stats=1 >"$build/artifacts/$t.log" 2>&1 || true
}
for t in "${targets[@]}"; do
  while [ "$(jobs -rp | wc -l)" -ge "$(nproc)" ]; do wait -n || true; done
  fuzz_one "$t" &
done
wait
failed=0
for t in "${targets[@]}"; do
  echo "=== $t for ${seconds} s"
  grep -E "^#[0-9]+.*DONE|stat::number_of_executed_units|ERROR|SUMMARY" "$build/artifacts/$t.log" || true
  if ls "$build/artifacts/$t-"* >/dev/null 2>&1; then
    echo "strata: $t found a failing input: $(ls "$build/artifacts/$t-"* | head -1)" >&2
    failed=1
  fi
done
[ "$failed" = 0 ] || exit 1
echo "fuzz: every target ran ${seconds} s without a crash, leak or timeout"
