# A layered character as Blender 3.4's glTF importer sees it, against its
# source: the importer must find an armature, every animation as an action,
# a material with an image texture where the source has one, and, posed
# halfway through the first animation, the mesh must stand where the
# source's does.
#   blender -b --factory-startup --python tests/blender/character_plays.py -- SOURCE.glb RIG.glb
import sys
import numpy as np
if not hasattr(np, "bool"):
    np.bool = bool  # Debian's Blender 3.4 importer predates numpy 1.24
import bpy
from mathutils import Vector

source, rig = sys.argv[sys.argv.index("--") + 1:][:2]


def inspect(path):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if "FINISHED" not in bpy.ops.import_scene.gltf(filepath=path):
        print("FAILED: Blender cannot import", path)
        sys.exit(1)
    armatures = [o for o in bpy.data.objects if o.type == "ARMATURE"]
    meshes = [o for o in bpy.data.objects if o.type == "MESH"]
    textured = [m for m in bpy.data.materials if m.use_nodes and
                any(n.type == "TEX_IMAGE" and n.image is not None for n in m.node_tree.nodes)]
    actions = list(bpy.data.actions)
    frame = None
    if actions:
        start, end = actions[0].frame_range
        frame = int(round(0.5 * (start + end)))
        for a in armatures:
            if a.animation_data is None:
                a.animation_data_create()
            a.animation_data.action = actions[0]
        bpy.context.scene.frame_set(frame)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    lo, hi = Vector((1e30, 1e30, 1e30)), Vector((-1e30, -1e30, -1e30))
    for o in meshes:
        evaluated = o.evaluated_get(depsgraph)
        mesh = evaluated.to_mesh()
        for v in mesh.vertices:
            p = evaluated.matrix_world @ v.co
            lo = Vector(map(min, lo, p))
            hi = Vector(map(max, hi, p))
        evaluated.to_mesh_clear()
    return {"armatures": len(armatures), "actions": len(actions), "textured": len(textured),
            "frame": frame, "lo": lo, "hi": hi}


a = inspect(source)
b = inspect(rig)
print("source", a)
print("rig", b)
diag = (a["hi"] - a["lo"]).length
problems = []
if b["armatures"] < 1:
    problems.append("no armature")
if b["actions"] != a["actions"]:
    problems.append(f"{b['actions']} actions, the source has {a['actions']}")
if a["textured"] and not b["textured"]:
    problems.append("no textured material")
if (b["lo"] - a["lo"]).length > 0.03 * diag or (b["hi"] - a["hi"]).length > 0.03 * diag:
    problems.append(f"posed at frame {a['frame']} it spans {tuple(b['lo'])}..{tuple(b['hi'])}, "
                    f"the source {tuple(a['lo'])}..{tuple(a['hi'])}")
if problems:
    print("FAILED:", "; ".join(problems))
    sys.exit(1)
print("PLAYS: armature, %d actions, %sposed at frame %s within 3%% of the source's box" %
      (b["actions"], "textured, " if a["textured"] else "", a["frame"]))
