#!/usr/bin/env python3
"""Writes a capture of rigid parts and no skin, one moved by its node's animation.

    python3 tests/tools/rigid_parts_capture.py OUT.glb

A body sphere (radius 1) at the origin and an arm sphere at x = 3, each a
mesh on a node of its own; the animation "wave" turns the arm's node a
quarter about z over one second.  Python's standard library only, so that
the Blender and three.js checks can make it anywhere.
"""
import json
import math
import struct
import sys


def sphere(cx, rings=16, segments=32):
    points = [(cx, 1.0, 0.0)]
    for i in range(1, rings):
        t = math.pi * i / rings
        for j in range(segments):
            p = 2.0 * math.pi * j / segments
            points.append((cx + math.sin(t) * math.cos(p), math.cos(t), math.sin(t) * math.sin(p)))
    points.append((cx, -1.0, 0.0))
    ring = lambda i, j: 1 + (i - 1) * segments + j % segments
    triangles = [(0, ring(1, j + 1), ring(1, j)) for j in range(segments)]
    for i in range(1, rings - 1):
        for j in range(segments):
            a, b, c, d = ring(i, j), ring(i, j + 1), ring(i + 1, j), ring(i + 1, j + 1)
            triangles += [(a, b, c), (b, d, c)]
    bottom = len(points) - 1
    triangles += [(bottom, ring(rings - 1, j), ring(rings - 1, j + 1)) for j in range(segments)]
    return points, triangles


def main(out):
    data, views, accessors = bytearray(), [], []

    def add(fmt, values, component, kind, count, bounds=None):
        blob = struct.pack("<" + fmt * len(values), *values)
        views.append({"buffer": 0, "byteOffset": len(data), "byteLength": len(blob)})
        data.extend(blob + b"\0" * (-len(blob) % 4))
        accessor = {"bufferView": len(views) - 1, "componentType": component, "count": count, "type": kind}
        if bounds:
            accessor["min"], accessor["max"] = bounds
        accessors.append(accessor)
        return len(accessors) - 1

    meshes, nodes = [], []
    for name, cx in (("body", 0.0), ("arm", 3.0)):
        points, triangles = sphere(cx)
        flat = [x for p in points for x in p]
        lo = [min(p[k] for p in points) for k in range(3)]
        hi = [max(p[k] for p in points) for k in range(3)]
        position = add("f", flat, 5126, "VEC3", len(points), (lo, hi))
        indices = add("I", [i for t in triangles for i in t], 5125, "SCALAR", 3 * len(triangles))
        meshes.append({"primitives": [{"attributes": {"POSITION": position}, "indices": indices}]})
        nodes.append({"name": name, "mesh": len(meshes) - 1})
    s = math.sin(math.pi / 4)
    times = add("f", [0.0, 1.0], 5126, "SCALAR", 2, ([0.0], [1.0]))
    turns = add("f", [0, 0, 0, 1, 0, 0, s, s], 5126, "VEC4", 2)
    gltf = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 1]}], "nodes": nodes,
            "meshes": meshes, "accessors": accessors, "bufferViews": views,
            "buffers": [{"byteLength": len(data)}],
            "animations": [{"name": "wave", "samplers": [{"input": times, "output": turns}],
                            "channels": [{"sampler": 0, "target": {"node": 1, "path": "rotation"}}]}]}
    text = json.dumps(gltf, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    with open(out, "wb") as f:
        f.write(struct.pack("<III", 0x46546C67, 2, 28 + len(text) + len(data)))
        f.write(struct.pack("<II", len(text), 0x4E4F534A) + text)
        f.write(struct.pack("<II", len(data), 0x004E4942) + bytes(data))


if __name__ == "__main__":
    main(sys.argv[1])
