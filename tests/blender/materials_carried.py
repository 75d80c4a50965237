# The rig of materials_carried.sh as Blender 3.4's glTF importer reads it:
# the Principled BSDF's Metallic, Roughness and Emission each fed from an
# image, the metallic-roughness image holding both halves' values (B 0 and
# 1, G 0.9 and 0.3) and the emissive image the orange glow and black; its
# Normal through a Normal Map node from an image whose texels tilt the
# normal as the source's did (most of them well off (0.5, 0.5, 1)).
#   blender -b --factory-startup --python tests/blender/materials_carried.py -- RIG.glb
import sys
import numpy as np
if not hasattr(np, "bool"):
    np.bool = bool  # Debian's Blender 3.4 importer predates numpy 1.24
import bpy

rig = sys.argv[sys.argv.index("--") + 1]
bpy.ops.wm.read_factory_settings(use_empty=True)
if "FINISHED" not in bpy.ops.import_scene.gltf(filepath=rig):
    print("FAILED: Blender cannot import", rig)
    sys.exit(1)
problems = []
materials = [m for m in bpy.data.materials if m.use_nodes]
bsdfs = [n for m in materials for n in m.node_tree.nodes if n.type == "BSDF_PRINCIPLED"]
if len(bsdfs) != 1:
    print(f"FAILED: {len(bsdfs)} Principled BSDFs, expected the rig's one material's")
    sys.exit(1)
bsdf = bsdfs[0]


def image_behind(socket):
    """The image whose texture node feeds `socket`, through any nodes between."""
    seen, todo = set(), [l.from_node for l in socket.links]
    while todo:
        node = todo.pop()
        if node.name in seen:
            continue
        seen.add(node.name)
        if node.type == "TEX_IMAGE" and node.image is not None:
            return node.image
        for i in node.inputs:
            todo += [l.from_node for l in i.links]
    return None


def channel_values(image, channel):
    pixels = np.array(image.pixels[:], dtype=np.float32).reshape(-1, 4)
    return np.round(pixels[:, channel], 2)


metallic = image_behind(bsdf.inputs["Metallic"])
roughness = image_behind(bsdf.inputs["Roughness"])
emission = image_behind(bsdf.inputs["Emission"])
for name, image in (("Metallic", metallic), ("Roughness", roughness), ("Emission", emission)):
    if image is None:
        problems.append(f"{name} is not read from an image")
if metallic is not None:
    b = channel_values(metallic, 2)
    g = channel_values(metallic, 1)
    # Each half's values over at least a tenth of the texels (Blender keeps
    # this data image's values linear).
    for value, what in ((0.0, "metallic 0"), (1.0, "metallic 1")):
        if np.mean(np.abs(b - value) <= 0.02) < 0.1:
            problems.append(f"the metallic-roughness image holds {what} on under a tenth of its texels")
    for value, what in ((0.9, "roughness 0.9"), (0.3, "roughness 0.3")):
        if np.mean(np.abs(g - value) <= 0.02) < 0.1:
            problems.append(f"the metallic-roughness image holds {what} on under a tenth of its texels")
if emission is not None:
    pixels = np.array(emission.pixels[:], dtype=np.float32).reshape(-1, 4)
    # Blender's pixels are the stored sRGB codes: orange (1, 0.735, 0) and black.
    orange = np.mean((pixels[:, 0] > 0.97) & (np.abs(pixels[:, 1] - 0.735) < 0.03) & (pixels[:, 2] < 0.03))
    black = np.mean(np.all(pixels[:, :3] < 0.03, axis=1))
    if orange < 0.1 or black < 0.1:
        problems.append(f"the emissive image is {orange:.0%} orange and {black:.0%} black")
normal_maps = [l.from_node for l in bsdf.inputs["Normal"].links if l.from_node.type == "NORMAL_MAP"]
normal = image_behind(normal_maps[0].inputs["Color"]) if normal_maps else None
if normal is None:
    problems.append("the Normal is not read from an image through a Normal Map node")
else:
    pixels = np.array(normal.pixels[:], dtype=np.float32).reshape(-1, 4)
    tilted = np.mean(np.hypot(pixels[:, 0] - 0.5, pixels[:, 1] - 0.5) > 0.1)
    if tilted < 0.5:
        problems.append(f"the normal image tilts {tilted:.0%} of its texels")
if problems:
    print("FAILED: " + "; ".join(problems))
    sys.exit(1)
print(f"CARRIED: one material, metallic and roughness from {metallic.name}, emission from {emission.name}, "
      f"normal from {normal.name} ({tilted:.0%} of its texels tilted)")
