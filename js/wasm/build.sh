#!/usr/bin/env bash
# Builds js/dist/strata.mjs + strata.wasm: Strata's runtime and rig reader
# compiled with Emscripten (Debian's emscripten 3.1.6).  Dependencies that
# Debian ships only as native libraries are compiled from Debian's own
# source packages, the versions the native build links (apt-get source; a
# deb-src line is added when missing).  Idempotent; STRATA_WASM_BUILD
# (default build-wasm) holds the sources and objects.
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
build="${STRATA_WASM_BUILD:-$root/build-wasm}"
mkdir -p "$build/deps" "$build/headers"
export NODE_PATH="${NODE_PATH:-/usr/share/nodejs}"

if ! command -v emcmake >/dev/null; then
  echo "strata: emscripten is missing (bash cmake/install-deps.sh installs it)" >&2
  exit 1
fi

sudo=""
[ "$(id -u)" = 0 ] || sudo="sudo"
# apt-get source needs deb-src lines; Debian's images ship only deb ones.
enable_sources() {
  if [ -f /etc/apt/sources.list.d/debian.sources ] && ! grep -q "deb-src" /etc/apt/sources.list.d/debian.sources; then
    $sudo sed -i 's/^Types: deb$/Types: deb deb-src/' /etc/apt/sources.list.d/debian.sources
  elif [ -f /etc/apt/sources.list ] && ! grep -qs "^deb-src" /etc/apt/sources.list /etc/apt/sources.list.d/*.list; then
    sed -n 's/^deb /deb-src /p' /etc/apt/sources.list | $sudo tee /etc/apt/sources.list.d/strata-deb-src.list >/dev/null
  fi
  $sudo apt-get update -qq >/dev/null
}

fetch() {  # fetch PACKAGE FOLDER: Debian's source of PACKAGE unpacked as deps/FOLDER
  local package="$1" folder="$2"
  [ -d "$build/deps/$folder" ] && return 0
  local work="$build/deps/.fetch-$package"
  rm -rf "$work" && mkdir -p "$work"
  if ! (cd "$work" && apt-get source --download-only "$package" >/dev/null 2>&1); then
    enable_sources
    # The newest version first; a mirror may list a security update's
    # source it does not serve (libzstd 1.5.4+dfsg2-5+deb12u1, 404 on
    # 2026-11-29): then each older version the index lists.
    local fetched=0 newest="" version
    for version in $(apt-cache showsrc "$package" | sed -n 's/^Version: //p' | sort -rV); do
      [ -n "$newest" ] || newest="$version"
      rm -rf "$work" && mkdir -p "$work"
      if (cd "$work" && apt-get source --download-only "$package=$version" >/dev/null 2>&1); then
        [ "$version" = "$newest" ] ||
          echo "strata: took Debian's source of $package $version ($newest is listed but could not be fetched)" >&2
        fetched=1
        break
      fi
    done
    if [ "$fetched" = 0 ]; then
      echo "strata: could not fetch Debian's source of $package (apt-get source; enable deb-src lines)" >&2
      exit 1
    fi
  fi
  local archive
  archive="$(ls "$work"/*.orig.tar.* | grep -v '\.asc$' | head -1)"
  mkdir -p "$work/x"
  tar xf "$archive" -C "$work/x" --exclude='*/testdata/*' --exclude='*/tests/*' --exclude='*/documentation/*'
  mv "$work/x/"* "$build/deps/$folder"
  rm -rf "$work"
}
fetch opensubdiv opensubdiv
fetch meshoptimizer meshoptimizer
fetch draco draco
fetch libzstd zstd
fetch zlib zlib

# Header-only dependencies, from the system, without the rest of /usr/include.
for h in glm nlohmann stb tiny_gltf.h; do
  [ -e "$build/headers/$h" ] || cp -r "/usr/include/$h" "$build/headers/$h"
done

emcmake cmake -S "$root/js/wasm" -B "$build/cmake" -G Ninja -DCMAKE_BUILD_TYPE=Release \
  -DSTRATA_DEPS="$build/deps" -DSTRATA_HEADERS="$build/headers" >/dev/null
cmake --build "$build/cmake" -j "$(nproc)"
mkdir -p "$root/js/dist"
cp "$build/cmake/strata.mjs" "$build/cmake/strata.wasm" "$root/js/dist/"
echo "js/dist/strata.wasm: $(stat -c %s "$root/js/dist/strata.wasm") bytes, $(gzip -9c "$root/js/dist/strata.wasm" | wc -c) gzipped"
