#!/usr/bin/env bash
# Fox, CesiumMan and a capture of rigid parts its nodes animate (no skin)
# baked with --control auto, then opened in Blender 3.4's glTF importer
# against their sources (character_plays.py).
#   tests/blender/character_plays.sh BUILD_DIR WORK_DIR
source "$(dirname "$0")/prologue.sh" "$@"
python3 "$here/../tools/rigid_parts_capture.py" "$work/rigid_parts_source.glb"
for name in Fox CesiumMan rigid_parts; do
  source=$data/$name.glb
  [ "$name" = rigid_parts ] && source=$work/rigid_parts_source.glb
  "$build/tools/strata-bake" --high "$source" --control auto -o "$work/$name.glb" >/dev/null
  blender -b --factory-startup --python "$here/character_plays.py" -- "$source" "$work/$name.glb" \
    >"$work/$name.log" 2>&1 || { grep -E "FAILED|Error" "$work/$name.log" | head -5; exit 1; }
  grep PLAYS "$work/$name.log" | sed "s/^/$name: /"
done
