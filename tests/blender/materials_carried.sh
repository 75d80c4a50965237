#!/usr/bin/env bash
# A capture of two materials, as Blender 3.4's glTF importer sees its rig: a
# sphere whose top is dull white (metallic 0, roughness 0.9) and whose bottom
# is a smooth metal glowing orange (1, 0.3, emissive (1, 0.5, 0)), both
# with a normal texture that tilts every normal (one texel, (173, 93, 242)),
# written here as a plain glb, then baked with --control auto.  The rig has
# one material; Blender must find its metallic and roughness read from an
# image (holding both halves' values), its emission from an image (holding
# the orange and black), as it finds them in the source's two materials'
# factors, and its normal through a Normal Map node from an image that
# holds the tilt.
#   tests/blender/materials_carried.sh BUILD_DIR WORK_DIR
source "$(dirname "$0")/prologue.sh" "$@"
python3 - "$work/spheres.glb" <<'PY'
import json, math, struct, sys, zlib
rows, columns = 32, 64
positions, uvs, top, bottom = [], [], [], []
for i in range(rows + 1):
    for j in range(columns + 1):
        t, p = math.pi * i / rows, 2 * math.pi * j / columns
        positions += [math.sin(t) * math.cos(p), math.cos(t), math.sin(t) * math.sin(p)]
        uvs += [j / columns, i / rows]
for i in range(rows):
    for j in range(columns):
        a = i * (columns + 1) + j
        b = a + columns + 1
        half = bottom if i >= rows // 2 else top
        if i > 0:
            half += [a, a + 1, b]
        if i < rows - 1:
            half += [a + 1, b + 1, b]


def png(width, height, rgba):
    """An 8-bit RGBA PNG of `rgba` (rows of width * 4 bytes)."""
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    rows_ = b"".join(b"\0" + bytes(rgba[4 * width * y:4 * width * (y + 1)]) for y in range(height))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0)) +
            chunk(b"IDAT", zlib.compress(rows_)) + chunk(b"IEND", b""))


normal = png(2, 2, [173, 93, 242, 255] * 4)
normal += b"\0" * (-len(normal) % 4)
blobs = [struct.pack(f"<{len(positions)}f", *positions), struct.pack(f"<{len(uvs)}f", *uvs),
         struct.pack(f"<{len(top)}I", *top), struct.pack(f"<{len(bottom)}I", *bottom), normal]
views, offset = [], 0
for k, blob in enumerate(blobs):
    view = {"buffer": 0, "byteOffset": offset, "byteLength": len(blob)}
    if k < 4:
        view["target"] = 34962 if k < 2 else 34963
    views.append(view)
    offset += len(blob)
n = len(positions) // 3
lo = [min(positions[c::3]) for c in range(3)]
hi = [max(positions[c::3]) for c in range(3)]
doc = {
    "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0},
                               {"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 3, "material": 1}]}],
    "materials": [{"pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 0.9},
                   "normalTexture": {"index": 0}},
                  {"pbrMetallicRoughness": {"metallicFactor": 1.0, "roughnessFactor": 0.3},
                   "emissiveFactor": [1.0, 0.5, 0.0], "normalTexture": {"index": 0}}],
    "textures": [{"source": 0}], "images": [{"bufferView": 4, "mimeType": "image/png"}],
    "accessors": [{"bufferView": 0, "componentType": 5126, "count": n, "type": "VEC3", "min": lo, "max": hi},
                  {"bufferView": 1, "componentType": 5126, "count": n, "type": "VEC2"},
                  {"bufferView": 2, "componentType": 5125, "count": len(top), "type": "SCALAR"},
                  {"bufferView": 3, "componentType": 5125, "count": len(bottom), "type": "SCALAR"}],
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
