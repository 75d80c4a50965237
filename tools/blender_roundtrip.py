# Blender's glTF round trip as an artist does it: import with the default
# settings, export with the default settings (File > Export > glTF 2.0).
#   blender -b --factory-startup --python tools/blender_roundtrip.py -- IN.glb OUT.glb
# Exits 1 when the import fails (Blender cannot open the file).
import sys
import numpy as np
if not hasattr(np, "bool"):
    np.bool = bool  # Debian's Blender 3.4 importer predates numpy 1.24
import bpy

src, dst = sys.argv[sys.argv.index("--") + 1:][:2]
bpy.ops.wm.read_factory_settings(use_empty=True)
try:
    result = bpy.ops.import_scene.gltf(filepath=src)
except Exception as e:  # the importer raises on files it cannot read
    print("BLENDER-IMPORT-FAILED", str(e).splitlines()[-1] if str(e) else type(e).__name__)
    sys.exit(1)
if "FINISHED" not in result:
    print("BLENDER-IMPORT-FAILED", result)
    sys.exit(1)
print("BLENDER-IMPORTED", len([o for o in bpy.data.objects if o.type == 'MESH']), "meshes")
bpy.ops.export_scene.gltf(filepath=dst)
print("BLENDER-EXPORTED", dst)
