#!/usr/bin/env bash
# Packs bench_gpu with every shared library it needs (its own loader and C
# library included) into one folder that runs on a bare x86-64 Linux
# machine with an NVIDIA driver and no network, headless through EGL:
#
#   tools/gpu/pack.sh BUILD_DIR OUT_DIR      # here, after building bench_gpu
#   OUT_DIR/run.sh [--level N] [--size WxH] [--frames N] [--json FILE]   # there
#
# run.sh starts bench_gpu --adaptive through the packed loader, so the
# machine's own libraries never mix in, except the EGL vendor: glvnd (packed)
# reads the machine's vendor list (/usr/share/glvnd/egl_vendor.d) and loads
# NVIDIA's libEGL_nvidia there, Mesa's on a machine without a GPU (how the
# tests run it, on llvmpipe).  It prints the JSON of a million-vertex
# displaced animated frame, uniform and adaptive, stage by stage.
set -euo pipefail

build=${1:?usage: tools/gpu/pack.sh BUILD_DIR OUT_DIR}
out=${2:?usage: tools/gpu/pack.sh BUILD_DIR OUT_DIR}
exe="$build/bench/bench_gpu"
if [ ! -x "$exe" ]; then
  echo "pack.sh: $exe is not built (configure with the GL path, STRATA_BUILD_GL, and build bench_gpu)" >&2
  exit 2
fi
if [ "$(uname -m)" != x86_64 ]; then
  echo "pack.sh: packs x86-64 builds only (this is $(uname -m))" >&2
  exit 2
fi
loader=/lib64/ld-linux-x86-64.so.2
stage="$out.partial.$$"
trap 'rm -rf "$stage"' EXIT
rm -rf "$stage"
mkdir -p "$stage/bin" "$stage/lib"
cp -L "$exe" "$stage/bin/bench_gpu"

# Every library the dynamic linker resolves for bench_gpu.  The GPU driver's
# own libraries (vendor EGL/GL, NVIDIA's, Mesa's) are never packed: they
# must be the machine's.
libs=$(ldd "$exe" | awk '$2 == "=>" && $3 ~ /^\// { print $3 }')
for lib in $libs; do
  case "$(basename "$lib")" in
    libEGL_*|libGLX*|libGL.so*|libnvidia*|libcuda*|libgallium*|libglapi*|libdrm*|libgbm*) continue ;;
  esac
  cp -L "$lib" "$stage/lib/"
done
# The loader, and the C library's other parts that a driver may ask for by
# name (they must come from the same glibc as the packed libc.so.6).
cp -L "$loader" "$stage/lib/"
libc_dir=$(dirname "$(ldd "$exe" | awk '$1 == "libc.so.6" { print $3 }')")
for part in libdl.so.2 libpthread.so.0 librt.so.1 libm.so.6 libresolv.so.2; do
  [ -e "$libc_dir/$part" ] && cp -L "$libc_dir/$part" "$stage/lib/"
done

cat > "$stage/run.sh" <<'RUN'
#!/bin/sh
# bench_gpu --adaptive through the packed loader and libraries (pack.sh).
here=$(cd "$(dirname "$0")" && pwd)
exec "$here/lib/ld-linux-x86-64.so.2" --library-path "$here/lib" "$here/bin/bench_gpu" --adaptive "$@"
RUN
chmod +x "$stage/run.sh"
{
  echo "bench_gpu packed by tools/gpu/pack.sh on $(date -u +%Y-%m-%dT%H:%M:%SZ) from $(cd "$build" && pwd)"
  echo "run: ./run.sh [--level N] [--size WxH] [--frames N] [--json FILE]   (defaults: level 6, 1920x1080, 120 moving frames)"
  echo "needs: x86-64 Linux, a GPU driver with an EGL vendor in /usr/share/glvnd/egl_vendor.d"
  (cd "$stage" && find bin lib -type f | sort | xargs sha256sum)
} > "$stage/MANIFEST.txt"
rm -rf "$out"
mv "$stage" "$out"
trap - EXIT
echo "pack.sh: $out ($(du -sh "$out" | cut -f1)): run $out/run.sh" >&2
