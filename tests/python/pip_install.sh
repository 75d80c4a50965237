#!/usr/bin/env bash
# pip install . into a fresh virtual environment (numpy and the build
# backend from PyPI, the C++ dependencies from Debian), then the README's
# three lines: bake the penguin, load the rig, reconstruct it.
#   pip_install.sh SOURCE_DIR WORK_DIR DATA_DIR
set -euo pipefail
src="$1" work="$2" data="$3"
rm -rf "$work"
/usr/bin/python3 -m venv "$work/venv"
# The wheel's CMake build compiles as the main build does (the compiler CMake
# picks by default, not Python's sysconfig one; warnings as errors where that
# is on), so a compiler cache (tools/test.sh sets ccache as the launcher when
# present) serves it the main build's objects.
export CC="${CC:-cc}" CXX="${CXX:-c++}"
"$work/venv/bin/pip" install -q --disable-pip-version-check \
  --config-settings=cmake.define.STRATA_WERROR="${STRATA_WERROR:-OFF}" "$src"
cd "$work"
"$work/venv/bin/python" - "$data" <<'PY'
import sys, strata
strata.bake(sys.argv[1] + "/penguin_hr.obj", sys.argv[1] + "/penguin_control_mesh.obj", "penguin.glb")
vertices, triangles = strata.load_rig("penguin.glb").reconstruct(level=3)
assert vertices.shape == (12738, 3) and triangles.shape == (25472, 3), (vertices.shape, triangles.shape)
assert str(vertices.dtype) == "float32" and str(triangles.dtype) == "uint32"
import importlib.metadata as md, pathlib
assert any(r.startswith("numpy") for r in md.requires("strata")), "numpy is not declared"
package = pathlib.Path(strata.__file__).parent
assert (package / "py.typed").exists() and (package / "_strata.pyi").exists(), "type stubs are not installed"
assert "max_memory (int, default 2048" in strata.bake.__doc__
print("pip install . works:", strata.__version__, vertices.shape, "from", package)
PY
