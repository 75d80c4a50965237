# Imports a glTF with Blender's own glTF importer and prints what it found:
# armatures and bones, meshes and polygons, materials, actions, images, and
# the posed mesh's bounds at two frames (it moves when the skin plays).
# A manual check for strata-reconstruct's skinned output (not run by CI):
#   blender -b --factory-startup --python tools/blender_check.py -- OUT.glb
import numpy as np
if not hasattr(np, "bool"): np.bool = bool  # Debian: Blender 3.4 importer predates numpy 1.24
import bpy, sys
bpy.ops.wm.read_factory_settings(use_empty=True)
path = sys.argv[sys.argv.index("--") + 1]
bpy.ops.import_scene.gltf(filepath=path)
arm = [o for o in bpy.data.objects if o.type == 'ARMATURE']
meshes = [o for o in bpy.data.objects if o.type == 'MESH']
print("RESULT armatures", len(arm), "bones", sum(len(a.data.bones) for a in arm))
print("RESULT meshes", len(meshes), "polygons", sum(len(m.data.polygons) for m in meshes))
print("RESULT materials", [m.name for m in bpy.data.materials])
print("RESULT actions", [a.name for a in bpy.data.actions])
print("RESULT images", [i.name for i in bpy.data.images])
for m in meshes:
    print("RESULT mesh", m.name, "vertex groups", len(m.vertex_groups), "armature modifier", any(md.type == 'ARMATURE' for md in m.modifiers))
# Pose at frame 10 and measure the evaluated mesh's bounds (it moves with the bones).
scene = bpy.context.scene
dg = bpy.context.evaluated_depsgraph_get()
def bounds(frame):
    scene.frame_set(frame)
    dg = bpy.context.evaluated_depsgraph_get()
    ev = meshes[0].evaluated_get(dg)
    co = [ev.matrix_world @ v.co for v in ev.data.vertices]
    return (min(c.z for c in co), max(c.z for c in co), min(c.x for c in co), max(c.x for c in co))
print("RESULT bounds frame 1", bounds(1))
print("RESULT bounds frame 15", bounds(15))
