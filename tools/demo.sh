#!/usr/bin/env bash
# Sets up, builds and runs the main job on the built-in procedural example.
# Output folder: first argument, default ./strata-out.
set -euo pipefail
cd "$(dirname "$0")/.."
bash cmake/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j "$(nproc)" --target strata-demo strata-reconstruct strata-view
out="${1:-strata-out}"
./build/tools/strata-demo --out "$out"
# The GPU path, headless (EGL): a picture of the result at level 4.
./build/viewer/strata-view "$out/head.glb" --level 4 --yaw -35 --headless --screenshot "$out/head_level4.png"
