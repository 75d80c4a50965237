#!/usr/bin/env python3
"""A stand-in for BrainStem, the acceptance's held-out character (61k
triangles, 59 primitives, 18 joints; not redistributable here): a robot of
59 rigid pieces (ellipsoids, cylinders, plates, fingers, bolts), each a
closed shell of its own, weight 1 on one of 18 joints, passing through each
other where they meet, as a robot's parts do; one 2 s walking animation.

    python3 bench/make_robot.py OUT.glb [--triangles N]   (default 60,000)

Deterministic (seeded); standard library only."""
import argparse
import json
import math
import random
import struct

JOINTS = [  # name, parent, translation at rest
    ("root", -1, (0, 0, 0)), ("pelvis", 0, (0, 1.0, 0)), ("spine", 1, (0, 0.15, 0)), ("chest", 2, (0, 0.2, 0)),
    ("neck", 3, (0, 0.25, 0)), ("head", 4, (0, 0.1, 0)),
    ("shoulderL", 3, (0.22, 0.18, 0)), ("elbowL", 6, (0.28, 0, 0)), ("handL", 7, (0.25, 0, 0)),
    ("shoulderR", 3, (-0.22, 0.18, 0)), ("elbowR", 9, (-0.28, 0, 0)), ("handR", 10, (-0.25, 0, 0)),
    ("hipL", 1, (0.1, -0.05, 0)), ("kneeL", 12, (0, -0.42, 0)), ("footL", 13, (0, -0.42, 0)),
    ("hipR", 1, (-0.1, -0.05, 0)), ("kneeR", 15, (0, -0.42, 0)), ("footR", 16, (0, -0.42, 0)),
]


def ellipsoid(c, r, seg, rings):
    pos, nrm, tri = [], [], []
    for i in range(rings + 1):
        th = math.pi * i / rings
        for j in range(seg):
            ph = 2 * math.pi * j / seg
            st = 0.0 if i in (0, rings) else math.sin(th)  # the poles one point each
            d = (st * math.cos(ph), math.cos(th), st * math.sin(ph))
            pos.append(tuple(c[k] + r[k] * d[k] for k in range(3)))
            g = tuple(d[k] / r[k] for k in range(3))
            n = math.sqrt(sum(x * x for x in g)) or 1.0
            nrm.append(tuple(x / n for x in g))
    for i in range(rings):
        for j in range(seg):
            a, b = i * seg + j, i * seg + (j + 1) % seg
            if i > 0:
                tri.append((a, b, a + seg))
            if i < rings - 1:
                tri.append((b, b + seg, a + seg))
    return pos, nrm, tri


def cylinder(c, r, h, axis, seg, stacks):
    """Closed, its caps on rims of their own (a hard edge, as exporters split it)."""
    def place(x, y, z):
        return [(c[0] + y, c[1] + x, c[2] + z), (c[0] + x, c[1] + y, c[2] + z), (c[0] + x, c[1] + z, c[2] + y)][axis]

    def turn(x, y, z):
        return [(y, x, z), (x, y, z), (x, z, y)][axis]
    pos, nrm, tri = [], [], []
    for i in range(stacks + 1):
        y = -h / 2 + h * i / stacks
        for j in range(seg):
            ph = 2 * math.pi * j / seg
            pos.append(place(r * math.cos(ph), y, r * math.sin(ph)))
            nrm.append(turn(math.cos(ph), 0, math.sin(ph)))
    for i in range(stacks):
        for j in range(seg):
            a, b = i * seg + j, i * seg + (j + 1) % seg
            tri += [(a, a + seg, b), (b, a + seg, b + seg)]
    for s, y in ((-1, -h / 2), (1, h / 2)):
        base = len(pos)
        pos.append(place(0, y, 0))
        nrm.append(turn(0, s, 0))
        for j in range(seg):
            ph = 2 * math.pi * j / seg
            pos.append(place(r * math.cos(ph), y, r * math.sin(ph)))
            nrm.append(turn(0, s, 0))
        for j in range(seg):
            a, b = base + 1 + j, base + 1 + (j + 1) % seg
            tri.append((base, b, a) if s > 0 else (base, a, b))
    # Which way the faces turn depends on the axis's handedness: outwards.
    if axis == 0 or axis == 2:
        tri = [(a, c2, b) for a, b, c2 in tri]
    return pos, nrm, tri


def box(c, e, n):
    pos, nrm, tri = [], [], []
    for ax in range(3):
        for s in (-1, 1):
            base, u, v = len(pos), (ax + 1) % 3, (ax + 2) % 3
            for i in range(n + 1):
                for j in range(n + 1):
                    p = [0.0, 0.0, 0.0]
                    p[ax], p[u], p[v] = s * e[ax], -e[u] + 2 * e[u] * i / n, -e[v] + 2 * e[v] * j / n
                    pos.append(tuple(c[k] + p[k] for k in range(3)))
                    q = [0, 0, 0]
                    q[ax] = s
                    nrm.append(tuple(q))
            for i in range(n):
                for j in range(n):
                    a = base + i * (n + 1) + j
                    b, c2 = a + 1, a + n + 1
                    tri += [(a, c2, b), (b, c2, c2 + 1)] if s > 0 else [(a, b, c2), (b, c2 + 1, c2)]
    return pos, nrm, tri


def robot(triangles):
    world = []
    for _, parent, t in JOINTS:
        world.append(list(t) if parent < 0 else [world[parent][k] + t[k] for k in range(3)])
    scale = math.sqrt(triangles / 28384.0)  # the pieces' triangles at scale 1

    def n(k):
        return max(6, int(k * scale))

    def at(j, dx=0.0, dy=0.0, dz=0.0):
        return [world[j][0] + dx, world[j][1] + dy, world[j][2] + dz]
    pieces = []

    def add(joint, shape, material):
        pieces.append((joint, shape, material))
    add(1, ellipsoid(at(1), (0.17, 0.1, 0.12), n(40), n(24)), 0)
    add(2, ellipsoid(at(2, dy=0.08), (0.14, 0.1, 0.1), n(36), n(20)), 1)
    add(3, ellipsoid(at(3, dy=0.1), (0.22, 0.16, 0.14), n(48), n(28)), 0)
    add(3, box(at(3, dy=0.12, dz=0.14), (0.12, 0.08, 0.015), n(10)), 2)
    add(4, cylinder(at(4, dy=0.05), 0.05, 0.1, 1, n(24), n(6)), 1)
    add(5, ellipsoid(at(5, dy=0.12), (0.11, 0.13, 0.12), n(44), n(28)), 0)
    add(5, box(at(5, dy=0.14, dz=0.11), (0.07, 0.025, 0.02), n(6)), 3)
    for sx, (shoulder, elbow, hand) in ((1, (6, 7, 8)), (-1, (9, 10, 11))):
        add(shoulder, ellipsoid(at(shoulder), (0.07, 0.07, 0.07), n(28), n(16)), 1)
        add(shoulder, cylinder(at(shoulder, dx=sx * 0.14), 0.045, 0.22, 0, n(28), n(8)), 0)
        add(elbow, ellipsoid(at(elbow), (0.055, 0.055, 0.055), n(24), n(14)), 1)
        add(elbow, cylinder(at(elbow, dx=sx * 0.125), 0.04, 0.2, 0, n(28), n(8)), 0)
        add(hand, box(at(hand, dx=sx * 0.05), (0.05, 0.02, 0.04), n(6)), 2)
        for f in range(4):
            add(hand, cylinder(at(hand, dx=sx * 0.12, dz=-0.03 + 0.02 * f), 0.008, 0.05, 0, n(10), n(3)), 3)
    for hip, knee, foot in ((12, 13, 14), (15, 16, 17)):
        add(hip, ellipsoid(at(hip), (0.08, 0.08, 0.08), n(28), n(16)), 1)
        add(hip, cylinder(at(hip, dy=-0.21), 0.06, 0.36, 1, n(32), n(10)), 0)
        add(knee, ellipsoid(at(knee), (0.065, 0.065, 0.065), n(24), n(14)), 1)
        add(knee, cylinder(at(knee, dy=-0.21), 0.05, 0.36, 1, n(32), n(10)), 0)
        add(foot, box(at(foot, dy=-0.03, dz=0.05), (0.06, 0.03, 0.11), n(8)), 2)
    rng = random.Random(7)
    while len(pieces) < 59:  # bolts on the plates and shells
        j = rng.choice([1, 2, 3, 3, 5, 6, 7, 9, 10, 12, 13, 15, 16])
        c = [world[j][k] + rng.uniform(-0.05, 0.05) for k in range(3)]
        c[2] += 0.09
        add(j, ellipsoid(c, (0.012, 0.012, 0.012), n(12), n(8)), 3)
    return world, pieces


def write_glb(path, world, pieces):
    buf, views, accessors = bytearray(), [], []

    def view(data, target=None):
        while len(buf) % 4:
            buf.append(0)
        v = {"buffer": 0, "byteOffset": len(buf), "byteLength": len(data)}
        if target:
            v["target"] = target
        buf.extend(data)
        views.append(v)
        return len(views) - 1

    def accessor(data, component, count, kind, target=None, lo=None, hi=None):
        a = {"bufferView": view(data, target), "componentType": component, "count": count, "type": kind}
        if lo is not None:
            a["min"], a["max"] = lo, hi
        accessors.append(a)
        return len(accessors) - 1
    nodes = [{"name": name, "translation": list(t)} for name, _, t in JOINTS]
    for i, (_, parent, _) in enumerate(JOINTS):
        if parent >= 0:
            nodes[parent].setdefault("children", []).append(i)
    materials = [{"pbrMetallicRoughness": {"baseColorFactor": c, "metallicFactor": 0.6, "roughnessFactor": 0.4}}
                 for c in ([0.8, 0.8, 0.85, 1], [0.3, 0.3, 0.35, 1], [0.9, 0.6, 0.1, 1], [0.1, 0.1, 0.1, 1])]
    meshes = []
    for index, (joint, (pos, nrm, tri), material) in enumerate(pieces):
        attributes = {
            "POSITION": accessor(b"".join(struct.pack("<3f", *p) for p in pos), 5126, len(pos), "VEC3", 34962,
                                 [min(p[k] for p in pos) for k in range(3)], [max(p[k] for p in pos) for k in range(3)]),
            "NORMAL": accessor(b"".join(struct.pack("<3f", *p) for p in nrm), 5126, len(nrm), "VEC3", 34962),
            "JOINTS_0": accessor(struct.pack("<4H", joint, 0, 0, 0) * len(pos), 5123, len(pos), "VEC4", 34962),
            "WEIGHTS_0": accessor(struct.pack("<4f", 1, 0, 0, 0) * len(pos), 5126, len(pos), "VEC4", 34962),
        }
        indices = accessor(b"".join(struct.pack("<3I", *t) for t in tri), 5125, 3 * len(tri), "SCALAR", 34963)
        meshes.append({"name": f"piece{index}",
                       "primitives": [{"attributes": attributes, "indices": indices, "material": material}]})
        nodes.append({"name": f"piece{index}", "mesh": index, "skin": 0})
    inverse_bind = b"".join(struct.pack("<16f", 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, -w[0], -w[1], -w[2], 1)
                            for w in world)
    ibm = accessor(inverse_bind, 5126, len(world), "MAT4")
    times = [2.0 * i / 8 for i in range(9)]
    key_times = accessor(b"".join(struct.pack("<f", t) for t in times), 5126, len(times), "SCALAR", None, [0.0], [2.0])
    channels, samplers = [], []
    for joint, axis, amplitude, phase in ((6, (0, 0, 1), 0.6, 0), (9, (0, 0, 1), 0.6, math.pi),
                                          (7, (0, 1, 0), 0.8, 0.5), (10, (0, 1, 0), 0.8, 0.5 + math.pi),
                                          (12, (1, 0, 0), 0.5, math.pi), (15, (1, 0, 0), 0.5, 0),
                                          (13, (1, 0, 0), 0.7, math.pi + 0.8), (16, (1, 0, 0), 0.7, 0.8),
                                          (4, (0, 1, 0), 0.3, 0.2), (2, (0, 1, 0), 0.15, 0)):
        keys = b""
        for t in times:
            angle = amplitude * math.sin(2 * math.pi * t / 2.0 + phase)
            s = math.sin(angle / 2)
            keys += struct.pack("<4f", axis[0] * s, axis[1] * s, axis[2] * s, math.cos(angle / 2))
        samplers.append({"input": key_times, "output": accessor(keys, 5126, len(times), "VEC4"),
                         "interpolation": "LINEAR"})
        channels.append({"sampler": len(samplers) - 1, "target": {"node": joint, "path": "rotation"}})
    gltf = {"asset": {"version": "2.0", "generator": "bench/make_robot.py"}, "scene": 0,
            "scenes": [{"nodes": [0] + list(range(len(JOINTS), len(nodes)))}], "nodes": nodes, "meshes": meshes,
            "materials": materials,
            "skins": [{"joints": list(range(len(JOINTS))), "inverseBindMatrices": ibm, "skeleton": 0}],
            "animations": [{"name": "walk", "channels": channels, "samplers": samplers}],
            "buffers": [{"byteLength": 0}], "bufferViews": views, "accessors": accessors}
    while len(buf) % 4:
        buf.append(0)
    gltf["buffers"][0]["byteLength"] = len(buf)
    text = json.dumps(gltf, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(buf), 0x004E4942) + bytes(buf)
    with open(path, "wb") as f:
        f.write(struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out")
    ap.add_argument("--triangles", type=int, default=60000)
    args = ap.parse_args()
    world, pieces = robot(args.triangles)
    write_glb(args.out, world, pieces)
    print(f"{args.out}: {len(pieces)} pieces, {sum(len(p[1][2]) for p in pieces):,} triangles, {len(JOINTS)} joints")


if __name__ == "__main__":
    main()
