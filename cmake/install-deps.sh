#!/usr/bin/env bash
# Installs Strata's build and test dependencies from Debian 12's archive.
# Idempotent and quiet: packages already present are skipped, so a second run
# costs a dpkg query and nothing else.  Needs root (or sudo) for apt-get.
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config git ccache
  libosd-dev libopenmesh-dev libglfw3-dev libglm-dev libopenexr-dev
  libtinygltf-dev nlohmann-json3-dev libstb-dev zlib1g-dev libgtest-dev libmeshoptimizer-dev libdraco-dev libzstd-dev libeigen3-dev
  libwebp-dev libavif-dev
  pybind11-dev python3-dev python3-numpy python3-pytest python3-venv python3-distributed
  libegl-dev libegl1-mesa-dev libgl1-mesa-dri libosmesa6-dev xvfb xauth libimgui-dev
  draco gltfpack blender chromium emscripten
  nodejs npm
  clang libclang-rt-14-dev
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

# node/npm may come from elsewhere (nvm, upstream tarball): accept any working node.
if command -v node >/dev/null 2>&1 && command -v npm >/dev/null 2>&1; then
  filtered=()
  for p in "${missing[@]}"; do [[ "$p" == nodejs || "$p" == npm ]] || filtered+=("$p"); done
  missing=("${filtered[@]+"${filtered[@]}"}")
fi

if ((${#missing[@]})); then
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  echo "strata: installing ${#missing[@]} Debian packages: ${missing[*]}" >&2
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -qq >/dev/null
  $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# The Khronos glTF-Validator (npm package gltf-validator), used by the tests to
# check every rig the project writes.  Installed once into build-tools/.
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
tools="$here/build-tools/node"
validator_version=2.0.0-dev.3.10
if [ ! -f "$tools/node_modules/gltf-validator/package.json" ]; then
  mkdir -p "$tools"
  echo "strata: installing gltf-validator from npm into $tools" >&2
  (cd "$tools" && npm install --no-audit --no-fund --loglevel=error "gltf-validator@$validator_version" >/dev/null)
fi

# glTF Transform and Strata's extension for it (js/, from js/package-lock.json),
# for the ecosystem matrix and js's own tests.
if [ ! -x "$here/js/node_modules/.bin/gltf-transform" ]; then
  echo "strata: installing js/ dependencies from npm (glTF Transform)" >&2
  (cd "$here/js" && npm ci --no-audit --no-fund --loglevel=error >/dev/null)
fi
