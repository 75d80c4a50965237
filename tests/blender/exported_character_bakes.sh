#!/usr/bin/env bash
# Fox as an artist's pipeline hands it over: through Blender 3.4 (import,
# export, default settings: every vertex split at its faces, each face's
# normal written, animations sampled at every frame), then baked with
# --control auto.  The rig must stay faceted as glTF draws the export (its
# pictures within a few dB of Fox's own, 31-33 dB; 26 dB while the normals
# were read as smooth), and smaller than the export (its animation keys'
# times written once, not once per channel).
#   tests/blender/exported_character_bakes.sh BUILD_DIR WORK_DIR
source "$(dirname "$0")/prologue.sh" "$@"
blender -b --factory-startup --python "$here/../../tools/blender_roundtrip.py" -- "$data/Fox.glb" "$work/fox_blender.glb" \
  >"$work/blender.log" 2>&1 || { grep -E "FAILED|Error" "$work/blender.log" | head -5; exit 1; }
"$build/tools/strata-bake" --high "$work/fox_blender.glb" --control auto -o "$work/rig.glb" \
  --report "$work/report.json" >"$work/bake.log" 2>&1 || { tail -5 "$work/bake.log"; exit 1; }
python3 - "$work" <<'PY'
import json, os, struct, sys
work = sys.argv[1]
report = json.load(open(os.path.join(work, "report.json")))
psnr = [f["psnr"] for f in report["posed"]["frames"]]
mean = sum(psnr) / len(psnr)
with open(os.path.join(work, "rig.glb"), "rb") as f:
    glb = f.read()
length = struct.unpack("<I", glb[12:16])[0]
doc = json.loads(glb[20:20 + length])
layer = [m["extensions"]["STRATA_layered_displacement"] for m in doc["meshes"]
         if "STRATA_layered_displacement" in m.get("extensions", {})]
rig, source = os.path.getsize(os.path.join(work, "rig.glb")), os.path.getsize(os.path.join(work, "fox_blender.glb"))
print(f"Fox through Blender: pictures {mean:.1f} dB mean, {min(psnr):.1f} worst; shading {layer[0].get('shading')}; "
      f"rig {rig} bytes against the export's {source}")
ok = mean >= 30.0 and layer and layer[0].get("shading") == "flat" and rig < source
sys.exit(0 if ok else 1)
PY
