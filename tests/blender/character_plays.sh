#!/usr/bin/env bash
# Fox and CesiumMan baked with --control auto, then opened in Blender 3.4's
# glTF importer against their sources (character_plays.py).
#   tests/blender/character_plays.sh BUILD_DIR WORK_DIR
source "$(dirname "$0")/prologue.sh" "$@"
for name in Fox CesiumMan; do
  "$build/tools/strata-bake" --high "$data/$name.glb" --control auto -o "$work/$name.glb" >/dev/null
  blender -b --factory-startup --python "$here/character_plays.py" -- "$data/$name.glb" "$work/$name.glb" \
    >"$work/$name.log" 2>&1 || { grep -E "FAILED|Error" "$work/$name.log" | head -5; exit 1; }
  grep PLAYS "$work/$name.log" | sed "s/^/$name: /"
done
