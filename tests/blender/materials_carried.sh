#!/usr/bin/env bash
# A capture of two materials, as Blender 3.4's glTF importer sees its rig: a
# sphere whose top is dull white (metallic 0, roughness 0.9) and whose bottom
# is a smooth metal glowing orange (1, 0.3, emissive (1, 0.5, 0)), written
# here as a plain glb, then baked with --control auto.  The rig has one
# material; Blender must find its metallic and roughness read from an image
# (holding both halves' values) and its emission from an image (holding the
# orange and black), as it finds them in the source's two materials' factors.
#   tests/blender/materials_carried.sh BUILD_DIR WORK_DIR
source "$(dirname "$0")/prologue.sh" "$@"
python3 - "$work/spheres.glb" <<'PY'
import json, math, struct, sys
rows, columns = 32, 64
positions, top, bottom = [], [], []
for i in range(rows + 1):
    for j in range(columns + 1):
        t, p = math.pi * i / rows, 2 * math.pi * j / columns
        positions += [math.sin(t) * math.cos(p), math.cos(t), math.sin(t) * math.sin(p)]
for i in range(rows):
    for j in range(columns):
        a = i * (columns + 1) + j
        b = a + columns + 1
        half = bottom if i >= rows // 2 else top
        if i > 0:
            half += [a, a + 1, b]
        if i < rows - 1:
            half += [a + 1, b + 1, b]
blobs = [struct.pack(f"<{len(positions)}f", *positions), struct.pack(f"<{len(top)}I", *top),
         struct.pack(f"<{len(bottom)}I", *bottom)]
views, offset = [], 0
for k, blob in enumerate(blobs):
    views.append({"buffer": 0, "byteOffset": offset, "byteLength": len(blob), "target": 34962 if k == 0 else 34963})
    offset += len(blob)
n = len(positions) // 3
lo = [min(positions[c::3]) for c in range(3)]
hi = [max(positions[c::3]) for c in range(3)]
doc = {
    "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0},
                               {"attributes": {"POSITION": 0}, "indices": 2, "material": 1}]}],
    "materials": [{"pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 0.9}},
                  {"pbrMetallicRoughness": {"metallicFactor": 1.0, "roughnessFactor": 0.3},
                   "emissiveFactor": [1.0, 0.5, 0.0]}],
    "accessors": [{"bufferView": 0, "componentType": 5126, "count": n, "type": "VEC3", "min": lo, "max": hi},
                  {"bufferView": 1, "componentType": 5125, "count": len(top), "type": "SCALAR"},
                  {"bufferView": 2, "componentType": 5125, "count": len(bottom), "type": "SCALAR"}],
    "bufferViews": views, "buffers": [{"byteLength": offset}],
}
text = json.dumps(doc).encode()
text += b" " * (-len(text) % 4)
binary = b"".join(blobs)
with open(sys.argv[1], "wb") as f:
    f.write(struct.pack("<III", 0x46546C67, 2, 12 + 8 + len(text) + 8 + len(binary)))
    f.write(struct.pack("<II", len(text), 0x4E4F534A) + text)
    f.write(struct.pack("<II", len(binary), 0x004E4942) + binary)
PY
"$build/tools/strata-bake" --high "$work/spheres.glb" --control auto -o "$work/rig.glb" >"$work/bake.log" 2>&1 ||
  { tail -5 "$work/bake.log"; exit 1; }
blender -b --factory-startup --python "$here/materials_carried.py" -- "$work/rig.glb" >"$work/blender.log" 2>&1 ||
  { grep -E "FAILED|Error" "$work/blender.log" | head -5; exit 1; }
grep CARRIED "$work/blender.log"
