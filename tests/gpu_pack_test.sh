#!/usr/bin/env bash
# tools/gpu/pack.sh end to end on this machine (llvmpipe): pack bench_gpu,
# move the folder (nothing may point back into the build), run it with an
# empty environment, and check the JSON rows it prints and writes.
set -euo pipefail
source_dir=${1:?source dir}; build_dir=${2:?build dir}; work=${3:?work dir}
rm -rf "$work"
mkdir -p "$work"
bash "$source_dir/tools/gpu/pack.sh" "$build_dir" "$work/packed"
mv "$work/packed" "$work/moved"
if ls "$work/moved/lib" | grep -E '^(libEGL_|libGLX|libgallium|libnvidia)'; then
  echo "gpu_pack_test: a driver library was packed" >&2
  exit 1
fi
env -i PATH=/usr/bin:/bin "$work/moved/run.sh" --level 3 --size 96x54 --frames 12 --json "$work/rows.json" > "$work/stdout.txt"
python3 - "$work/rows.json" "$work/stdout.txt" <<'PY'
import json, sys
rows = json.load(open(sys.argv[1]))
printed = open(sys.argv[2]).read()
assert '"gpu_adaptive"' in printed, "the JSON is not printed"
assert len(rows) == 9, len(rows)
for fill in (1.0, 0.3, 0.1):
    moving = [r for r in rows if r["table"] == "gpu_adaptive_moving" and abs(r["fill"] - fill) < 1e-6]
    assert len(moving) == 1 and moving[0]["frames"] == 12, moving
    m = moving[0]
    assert 0 < m["adaptive_ms_per_frame"] and 0 < m["uniform_ms_per_frame"], m
    assert 0 < m["mean_vertices"] < 500 * 64 // 2 + 2 and 0 <= m["frames_set"] <= 12, m
    byMode = {r["mode"]: r for r in rows if r["table"] == "gpu_adaptive" and abs(r["fill"] - fill) < 1e-6}
    u, a = byMode["uniform"], byMode["adaptive"]
    assert u["vertices"] == 500 * 64 // 2 + 2, u["vertices"]  # a closed mesh at level 3: F 4^3 / 2 + 2
    for r in (u, a):
        for k in ("upload_ms", "stencils_displace_ms", "normals_ms", "draw_ms", "gpu_frame_ms", "cpu_frame_ms"):
            assert r[k] is not None and r[k] >= 0, (k, r)
    assert a["vertices"] < u["vertices"], (fill, a["vertices"], u["vertices"])
print("gpu_pack_test: %d rows, uniform %d vertices" % (len(rows), rows[0]["vertices"]))
PY
