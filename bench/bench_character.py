#!/usr/bin/env python3
"""A character through --control auto, against its source, as it moves.

    python3 bench/bench_character.py [--build build] [--work DIR] [--times 3] [--bake-args "FLAGS"] [CHARACTER ...]

Bakes Fox, CesiumMan (tests/data) and the 59-piece robot of bench/make_robot.py
(a stand-in for BrainStem; or the glTF characters named) with `strata-bake --control auto`,
then for every animation prints the bake's own per-frame geometry (RMS and
maximum distance between the layered surface at the recommended level and
the source's mesh, the larger side of each, over 10 evenly spaced times)
and the texture: at `--times` of those times, the source and the rig are
rendered headless by strata-view at one camera (the source's), and the two
pictures compared by PSNR over the pixels either draws; beside it, the
bake's own picture PSNR (its CPU pictures, every one of the 10 times); and
whether the rig is watertight, as an acceptance checks it: the directed edges
of strata-reconstruct's surface at the rig's level and of an adaptive one
(a camera 3 diagonals out, 1 pixel), welded by position, that no edge
matches once the other way (0: closed and manifold).
"""
import argparse
import json
import math
import os
import struct
import subprocess
import sys
import tempfile
import time
import zlib

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def read_png(path):
    """8-bit RGB/RGBA PNG (the viewer's screenshots) as (width, height, rows of RGB tuples)."""
    data = open(path, "rb").read()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", path
    pos, idat, width = 8, b"", 0
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            width, height, depth, colour = struct.unpack(">IIBB", body[:10])
            assert depth == 8 and colour in (2, 6), (path, depth, colour)
            channels = 3 if colour == 2 else 4
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    raw = zlib.decompress(idat)
    stride = width * channels
    rows, prev = [], bytearray(stride)
    for y in range(height):
        f = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - channels] if i >= channels else 0
            b = prev[i]
            c = prev[i - channels] if i >= channels else 0
            if f == 1:
                line[i] = (line[i] + a) & 255
            elif f == 2:
                line[i] = (line[i] + b) & 255
            elif f == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append(bytes(line))
        prev = line
    return width, height, channels, rows


def open_edges(obj_path):
    """Directed edges of an OBJ, its vertices welded by position, not matched by exactly one the other way
    (0: closed, manifold and consistently turned), and its bounds (lowest, highest corner)."""
    key, welded, uses = {}, [], {}
    lo, hi = [math.inf] * 3, [-math.inf] * 3
    for line in open(obj_path):
        if line.startswith("v "):
            p = line.split()[1:4]
            welded.append(key.setdefault(tuple(p), len(key)))
            lo = [min(lo[k], float(p[k])) for k in range(3)]
            hi = [max(hi[k], float(p[k])) for k in range(3)]
        elif line.startswith("f "):
            f = [welded[int(x.split("/")[0]) - 1] for x in line.split()[1:]]
            for k in range(len(f)):
                e = (f[k], f[(k + 1) % len(f)])
                uses[e] = uses.get(e, 0) + 1
    return sum(1 for (a, b), n in uses.items() if n != 1 or uses.get((b, a), 0) != 1), lo, hi


def psnr(a_path, b_path):
    """PSNR (dB) of two renders over the pixels either draws (not the background)."""
    wa, ha, ca, ra = read_png(a_path)
    wb, hb, cb, rb = read_png(b_path)
    assert (wa, ha) == (wb, hb)
    background = ra[0][:3]
    err, n = 0.0, 0
    for y in range(ha):
        for x in range(wa):
            pa = ra[y][x * ca:x * ca + 3]
            pb = rb[y][x * cb:x * cb + 3]
            if pa == background and pb == background:
                continue
            err += sum((int(u) - int(v)) ** 2 for u, v in zip(pa, pb))
            n += 3
    return 10.0 * math.log10(255.0 ** 2 / (err / n)) if n and err else float("inf")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--build", default=os.path.join(ROOT, "build"))
    ap.add_argument("--work", default="")
    ap.add_argument("--times", type=int, default=3)
    ap.add_argument("--bake-args", default="", help="more strata-bake flags, e.g. \"--control-faces 200\"")
    ap.add_argument("characters", nargs="*", default=["Fox", "CesiumMan", "robot"],
                    help="names in tests/data (Fox, CesiumMan), robot (bench/make_robot.py's stand-in for "
                         "BrainStem, made in --work) or paths to glTF characters")
    args = ap.parse_args()
    work = args.work or tempfile.mkdtemp(prefix="strata-character-")
    os.makedirs(work, exist_ok=True)
    bake = os.path.join(args.build, "tools", "strata-bake")
    view = os.path.join(args.build, "viewer", "strata-view")
    print("| character | animation | rig bytes | source bytes | cage faces | bake s | level | RMS mean | RMS worst |"
          " max worst | strata-view PSNR (dB) at " + ", ".join(f"{k}/{args.times - 1}" for k in range(args.times)) +
          " of it | the bake's own picture PSNR (dB), mean and worst of 10 | open edges: at its level, a 1-px view |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for character in args.characters:
        source = character if os.path.exists(character) else os.path.join(ROOT, "tests", "data", character + ".glb")
        if character == "robot":
            source = os.path.join(work, "robot_source.glb")
            subprocess.run([sys.executable, os.path.join(ROOT, "bench", "make_robot.py"), source], check=True,
                           stdout=subprocess.DEVNULL)
        name = os.path.splitext(os.path.basename(character))[0]
        rig = os.path.join(work, name + ".glb")
        report = os.path.join(work, name + ".json")
        started = time.monotonic()
        subprocess.run([bake, "--high", source, "--control", "auto", "-o", rig, "--report", report] +
                       args.bake_args.split(),
                       check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        seconds = time.monotonic() - started
        rep = json.load(open(report))
        # Watertightness as an acceptance checks it: the rig at its level, and
        # adaptive for a camera 3 diagonals out at a 1-pixel tolerance.
        reconstruct = os.path.join(args.build, "tools", "strata-reconstruct")
        surface = os.path.join(work, name + "_surface.obj")
        subprocess.run([reconstruct, rig, "-o", surface], check=True, capture_output=True)
        unmatched, lo, hi = open_edges(surface)
        opened = [unmatched]
        centre = [(lo[k] + hi[k]) / 2 for k in range(3)]
        diagonal = math.dist(lo, hi)
        eye = [centre[0], centre[1], centre[2] + 3 * diagonal]
        eye_view = ",".join(f"{x:.6g}" for x in eye) + ":" + ",".join(f"{x:.6g}" for x in centre) + ":45:1080"
        subprocess.run([reconstruct, rig, "--view", eye_view, "--pixel-error", "1", "-o", surface], check=True,
                       capture_output=True)
        opened.append(open_edges(surface)[0])
        frames = rep["posed"]["frames"]
        level = rep["posed"]["level"]
        for anim in sorted({f["animation"] for f in frames}):
            mine = [f for f in frames if f["animation"] == anim]
            times = [mine[round(k * (len(mine) - 1) / max(args.times - 1, 1))]["time"] for k in range(args.times)]
            scores = []
            for k, t in enumerate(times):
                a = os.path.join(work, f"{name}_{anim}_{k}_source.png")
                b = os.path.join(work, f"{name}_{anim}_{k}_rig.png")
                common = ["--anim", str(anim), "--time", f"{t:.6f}", "--headless", "--size", "480x480", "--no-grid"]
                out = subprocess.run([view, source, "--no-displacement", "--level", "0", "--screenshot", a] + common,
                                     check=True, capture_output=True, text=True).stderr
                camera = out.rsplit("--camera ", 1)[1].split(")")[0]
                subprocess.run([view, rig, "--screenshot", b, "--camera", camera] + common, check=True,
                               capture_output=True, text=True)
                scores.append(psnr(a, b))
            rms = [f["rms"] for f in mine]
            own = [f["psnr"] for f in mine]
            print(f"| {name} | {anim} | {os.path.getsize(rig):,} | {os.path.getsize(source):,} | "
                  f"{rep['control']['triangles']:,} | {seconds:.1f} | {level} | "
                  f"{100 * sum(rms) / len(rms):.3f}% | {100 * max(rms):.3f}% | {100 * max(f['max'] for f in mine):.2f}% | "
                  + ", ".join(f"{s:.1f}" for s in scores) + f" | {sum(own) / len(own):.1f}, {min(own):.1f} | "
                  f"{opened[0]}, {opened[1]} |")
            sys.stdout.flush()


if __name__ == "__main__":
    main()
