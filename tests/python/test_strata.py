"""The Python module against the tools and closed forms.

Run by ctest (PYTHONPATH=build/python); the data test reads the penguin
from tests/data, which ships with the repository.
"""
import math
import time
import os
import subprocess
import sys

import numpy as np
import pytest

import strata

SHARED = os.environ.get("STRATA_SHARED_DATA") or os.path.join(os.path.dirname(__file__), "..", "data")
RECONSTRUCT = os.environ.get("STRATA_RECONSTRUCT_EXE", "")


def write_obj(path, vertices, faces):
    with open(path, "w") as f:
        for v in vertices:
            f.write("v %.9g %.9g %.9g\n" % tuple(v))
        for t in faces:
            f.write("f %d %d %d\n" % (t[0] + 1, t[1] + 1, t[2] + 1))


def icosphere(levels):
    """Unit icosphere: the 12-vertex icosahedron split `levels` times."""
    p = (1 + 5 ** 0.5) / 2
    v = [(-1, p, 0), (1, p, 0), (-1, -p, 0), (1, -p, 0), (0, -1, p), (0, 1, p),
         (0, -1, -p), (0, 1, -p), (p, 0, -1), (p, 0, 1), (-p, 0, -1), (-p, 0, 1)]
    v = [np.array(x, float) / np.linalg.norm(x) for x in v]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
         (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
         (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    for _ in range(levels):
        mid = {}

        def m(a, b):
            key = (min(a, b), max(a, b))
            if key not in mid:
                x = v[a] + v[b]
                v.append(x / np.linalg.norm(x))
                mid[key] = len(v) - 1
            return mid[key]

        nf = []
        for a, b, c in f:
            ab, bc, ca = m(a, b), m(b, c), m(c, a)
            nf += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        f = nf
    return np.array(v), np.array(f)


def bumpy(v):
    """A sphere with smooth bumps: radius 1 + 0.05 sin(3x) sin(3y) sin(3z)."""
    r = 1.0 + 0.05 * np.sin(3 * v[:, 0]) * np.sin(3 * v[:, 1]) * np.sin(3 * v[:, 2])
    return v * r[:, None]


@pytest.fixture(scope="module")
def baked(tmp_path_factory):
    d = tmp_path_factory.mktemp("bake")
    hv, hf = icosphere(5)
    cv, cf = icosphere(1)
    write_obj(d / "high.obj", bumpy(hv), hf)
    write_obj(d / "control.obj", cv, cf)
    report = strata.bake(str(d / "high.obj"), str(d / "control.obj"), str(d / "rig.glb"), threads=2)
    return d, report


def test_version():
    assert strata.__version__.count(".") == 2


def test_bake_returns_the_report(baked):
    d, report = baked
    assert report["written"] == [str(d / "rig.glb")]
    assert report["recommendedLevel"] >= 0
    rms = [max(e["forwardRms"], e["backwardRms"]) for e in report["closedLoop"]
           if e["level"] == report["recommendedLevel"]]
    assert rms and rms[0] < 1e-3


def test_reconstruction_is_the_bumpy_sphere(baked):
    d, report = baked
    rig = strata.load_rig(str(d / "rig.glb"))
    assert rig.recommended_level == report["recommendedLevel"]
    assert rig.joint_names == [] and rig.animations == []
    # An OBJ capture is drawn smooth (only a glTF one without NORMAL is flat).
    assert rig.shading == "smooth" and report["shading"] == "smooth"
    v, t = rig.reconstruct(level=4)
    assert v.dtype == np.float32 and v.shape[1] == 3
    assert t.dtype == np.uint32 and t.shape == (80 * 4 ** 4, 3)
    assert t.max() < len(v)
    # Closed form: every reconstructed vertex lies on the bumpy sphere.
    n = v / np.linalg.norm(v, axis=1)[:, None]
    expected = 1.0 + 0.05 * np.sin(3 * n[:, 0]) * np.sin(3 * n[:, 1]) * np.sin(3 * n[:, 2])
    radial = np.linalg.norm(v, axis=1) - expected
    assert math.sqrt(np.mean(radial ** 2)) < 2e-3


def test_a_view_gives_the_adaptive_mesh(baked):
    d, _ = baked
    rig = strata.load_rig(str(d / "rig.glb"))
    level = rig.recommended_level
    fine, _ = rig.reconstruct()
    near, near_t = rig.reconstruct(view=((0.0, 0.0, 3.0), (0.0, 0.0, 0.0), 45.0, 1080.0))
    far, far_t = rig.reconstruct(view=((0.0, 0.0, 40.0), (0.0, 0.0, 0.0), 45.0, 1080.0), pixel_error=2.0)
    # Farther away fewer vertices, never more than the finest level; closed
    # meshes on the sphere (V - E + F = 2 with E = 3F / 2).
    assert len(far) < len(near) <= len(fine)
    for v, t in ((near, near_t), (far, far_t)):
        assert t.max() < len(v)
        assert len(v) - len(t) // 2 == 2
        assert np.all(np.abs(np.linalg.norm(v, axis=1) - 1.0) < 0.1)
    with pytest.raises(strata.Error, match="not a view"):
        rig.reconstruct(view=((0.0, 0.0, 1.0), (0.0, 0.0, 1.0), 45.0, 1080.0))
    assert level >= 1


def test_shading_is_as_gltf_draws_the_file():
    # Fox has no NORMAL (glTF draws it with face normals), CesiumMan has them.
    assert strata.load_rig(os.path.join(SHARED, "Fox.glb")).shading == "flat"
    assert strata.load_rig(os.path.join(SHARED, "CesiumMan.glb")).shading == "smooth"


def test_same_numbers_as_strata_reconstruct(baked, tmp_path):
    if not RECONSTRUCT:
        pytest.fail("STRATA_RECONSTRUCT_EXE is not set (ctest sets it)")
    d, _ = baked
    out = tmp_path / "level3.obj"
    subprocess.run([RECONSTRUCT, str(d / "rig.glb"), "--level", "3", "-o", str(out)], check=True,
                   capture_output=True)
    tool = np.array([[float(x) for x in line.split()[1:4]] for line in open(out) if line.startswith("v ")])
    v, _ = strata.load_rig(str(d / "rig.glb")).reconstruct(level=3)
    assert tool.shape == v.shape
    assert np.max(np.abs(tool - v)) < 1e-5


def test_errors_are_exceptions_with_the_message(tmp_path):
    with pytest.raises(strata.Error, match="missing.glb"):
        strata.load_rig(str(tmp_path / "missing.glb"))
    with pytest.raises(strata.Error, match="unknown option"):
        strata.bake("a.obj", "b.obj", str(tmp_path / "r.glb"), colour="red")
    with pytest.raises(strata.Error, match="nothere.obj"):
        strata.bake(str(tmp_path / "nothere.obj"), "auto", str(tmp_path / "r.glb"))
    assert not (tmp_path / "r.glb").exists()


def test_penguin_in_a_few_lines(tmp_path):
    high = os.path.join(SHARED, "penguin_hr.obj")
    assert os.path.exists(high), "tests/data/penguin_hr.obj is missing (it ships with the repository)"
    control = os.path.join(SHARED, "penguin_control_mesh.obj")
    report = strata.bake(high, control, str(tmp_path / "penguin.glb"))
    vertices, triangles = strata.load_rig(str(tmp_path / "penguin.glb")).reconstruct(level=3)
    assert report["recommendedLevel"] == 3
    assert vertices.shape == (12738, 3) and triangles.shape == (25472, 3)


def test_keywords_are_validated_as_the_cli_does(baked, tmp_path):
    d, _ = baked
    for kw in ({"threads": 100000}, {"threads": 0}, {"tolerance": -1.0}, {"size": 3}):
        with pytest.raises(strata.Error):
            strata.bake(str(d / "high.obj"), str(d / "control.obj"), str(tmp_path / "r.glb"), **kw)
        assert not (tmp_path / "r.glb").exists()


def test_eight_threads_reconstruct_at_once_without_warm_up(baked):
    # A fresh interpreter, so that nothing has made an array yet: the first
    # arrays are made by eight threads at once (this deadlocked when numpy's
    # API was looked up lazily under a static guard).
    d, _ = baked
    script = (
        "import sys, threading\n"
        "import strata\n"
        "out = []\n"
        "def work():\n"
        "    v, t = strata.load_rig(sys.argv[1]).reconstruct(level=2)\n"
        "    out.append(len(v))\n"
        "ts = [threading.Thread(target=work) for _ in range(8)]\n"
        "[t.start() for t in ts]\n"
        "[t.join() for t in ts]\n"
        "print(len(out), len(set(out)))\n")
    for _ in range(5):
        r = subprocess.run([sys.executable, "-c", script, str(d / "rig.glb")], capture_output=True, text=True,
                           timeout=60, env=dict(os.environ))
        assert r.returncode == 0, r.stderr
        assert r.stdout.split() == ["8", "1"]


def test_a_gltf_without_the_layer_is_refused_unless_asked(baked, tmp_path):
    # The layer stripped as tools that do not know the extension do: the
    # surface would be the bare cage, so reconstruct refuses by default.
    import json, struct
    d, _ = baked
    glb = (d / "rig.glb").read_bytes()
    n = struct.unpack("<I", glb[12:16])[0]
    doc = json.loads(glb[20:20 + n])
    for mesh in doc["meshes"]:
        mesh.pop("extensions", None)
    doc["extensionsUsed"] = [e for e in doc.get("extensionsUsed", []) if e != "STRATA_layered_displacement"]
    if not doc["extensionsUsed"]:
        del doc["extensionsUsed"]
    doc["asset"]["generator"] = "some tool 1.0"
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)
    binary = glb[20 + n:]
    out = struct.pack("<4sII", b"glTF", 2, 20 + len(text) + len(binary)) + struct.pack("<I4s", len(text), b"JSON")
    (tmp_path / "stripped.glb").write_bytes(out + text + binary)
    rig = strata.load_rig(str(tmp_path / "stripped.glb"))
    with pytest.raises(strata.Error, match="no displacement layer .*some tool 1.0"):
        rig.reconstruct(level=1)
    v, t = rig.reconstruct(level=1, displacement=False)
    assert len(v) > 0 and len(t) > 0


def test_ctrl_c_cancels_a_bake_and_leaves_no_file(tmp_path):
    # A bake that runs for tens of seconds (a forced 4096 map on one thread);
    # SIGINT once its first stage has run a second.  KeyboardInterrupt comes
    # within a second or two, and the folder is as it was: no rig, no
    # staging file.
    import signal
    script = (
        "import sys, strata\n"
        "def progress(stage, seconds):\n"
        "    print('stage', stage, seconds, flush=True)\n"
        "try:\n"
        "    strata.bake(sys.argv[1], sys.argv[2], sys.argv[3], size=4096, threads=1, progress=progress)\n"
        "    print('finished', flush=True)\n"
        "except KeyboardInterrupt:\n"
        "    print('cancelled', flush=True)\n"
        "    sys.exit(3)\n")
    out = tmp_path / "out"
    out.mkdir()
    p = subprocess.Popen([sys.executable, "-c", script, os.path.join(SHARED, "penguin_hr.obj"),
                          os.path.join(SHARED, "penguin_control_mesh.obj"), str(out / "penguin.glb")],
                         stdout=subprocess.PIPE, text=True, env=dict(os.environ))
    first = p.stdout.readline()
    assert first.startswith("stage "), first
    sent = time.monotonic()
    p.send_signal(signal.SIGINT)
    rest = p.communicate(timeout=60)[0]
    elapsed = time.monotonic() - sent
    assert p.returncode == 3, rest
    assert "cancelled" in rest and "finished" not in rest
    # Within a second or two on an idle machine; the bound leaves room for
    # a loaded one (ctest -j2 beside other bakes), and is still well under
    # the 15 s the whole bake takes here on one thread.
    assert elapsed < 6.0, f"the bake took {elapsed:.2f} s to stop"
    assert os.listdir(out) == []


def test_two_threads_bake_at_once(baked, tmp_path):
    # The GIL is released while a bake runs: two threads bake together, each
    # to its own file, and get the same bytes from the same inputs.  (The
    # progress callback is exercised by the Ctrl-C test, whose first line it
    # prints.)
    import threading
    d, _ = baked
    errors = []

    def work(name):
        try:
            strata.bake(d / "high.obj", d / "control.obj", tmp_path / name, threads=1)
        except Exception as e:  # noqa: BLE001 - reported below
            errors.append(e)

    threads = [threading.Thread(target=work, args=(n,)) for n in ("a.glb", "b.glb")]
    [t.start() for t in threads]
    [t.join() for t in threads]
    assert not errors, errors
    assert (tmp_path / "a.glb").read_bytes() == (tmp_path / "b.glb").read_bytes()


def test_help_lists_every_keyword_with_its_type_and_default():
    doc = strata.bake.__doc__
    for keyword in ("tolerance", "control_faces", "uv", "size", "scheme", "overlap", "threads", "error_levels",
                    "skeleton", "map_coding", "mesh_coding", "compress", "exr", "float_exr", "png", "layers",
                    "close_holes", "fit", "max_memory", "report", "progress"):
        assert f"\n    {keyword} (" in doc or f"{keyword} (callable" in doc, keyword
    assert "default" in doc and "--tolerance" in doc
