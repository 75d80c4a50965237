"""python -m strata.batch on a local Dask cluster of two workers, over the
real pairs in tests/data plus two broken ones."""
import csv
import json
import os
import shutil
import subprocess
import sys

import strata
import strata.batch

SHARED = os.environ.get("STRATA_SHARED_DATA") or os.path.join(os.path.dirname(__file__), "..", "data")


def batch(*args):
    return subprocess.run([sys.executable, "-m", "strata.batch", *args], capture_output=True, text=True,
                          timeout=600, env=dict(os.environ))


def test_a_manifest_bakes_on_two_workers_resumes_and_reports(tmp_path):
    for name in ("penguin_hr.obj", "penguin_control_mesh.obj", "spot_triangulated.obj", "spot_control_mesh.obj",
                 "hand_closed.obj", "hand_lowres.obj"):
        shutil.copy(os.path.join(SHARED, name), tmp_path / name)
    (tmp_path / "garbage.obj").write_text("not a mesh\n")
    (tmp_path / "pairs.csv").write_text(
        "high,control,tolerance\n"
        "penguin_hr.obj,penguin_control_mesh.obj,\n"
        "spot_triangulated.obj,spot_control_mesh.obj,0.05%\n"
        "hand_closed.obj,hand_lowres.obj,\n"
        "missing.obj,spot_control_mesh.obj,\n"
        "garbage.obj,spot_control_mesh.obj,\n")
    out = tmp_path / "rigs"
    r = batch(str(tmp_path / "pairs.csv"), "-o", str(out), "--workers", "2")
    assert r.returncode == 1, r.stderr  # two pairs fail; the others are baked regardless
    assert "3 baked, 0 skipped, 2 failed" in r.stderr
    with open(out / "batch_report.csv", newline="") as f:
        rows = {os.path.basename(row["high"]): row for row in csv.DictReader(f)}
    assert json.loads((out / "batch_report.json").read_text())[0]["high"].endswith("penguin_hr.obj")
    for name, stem in (("penguin_hr.obj", "penguin_hr"), ("spot_triangulated.obj", "spot_triangulated"),
                       ("hand_closed.obj", "hand_closed")):
        row = rows[name]
        assert row["status"] == "baked", row
        assert int(row["bytes"]) == os.path.getsize(out / (stem + ".glb")) > 0
        assert 0.0 < float(row["rms"]) < 0.01 and int(row["level"]) >= 0 and float(row["seconds"]) > 0.0
        assert row["worker"].startswith("tcp://"), row
        assert strata.load_rig(out / (stem + ".glb")).recommended_level == int(row["level"])
    assert float(rows["spot_triangulated.obj"]["rms"]) <= 0.0005 * 1.0001  # its own tolerance column
    assert "missing.obj" in rows["missing.obj"]["error"] and rows["missing.obj"]["status"] == "failed"
    assert "garbage.obj" in rows["garbage.obj"]["error"] and rows["garbage.obj"]["status"] == "failed"

    # Resumable: the same run skips what is done; a changed input is baked again.
    r = batch(str(tmp_path / "pairs.csv"), "-o", str(out), "--workers", "2")
    assert "0 baked, 3 skipped, 2 failed" in r.stderr, r.stderr
    with open(tmp_path / "spot_control_mesh.obj", "a") as f:
        f.write("# touched\n")
    r = batch(str(tmp_path / "pairs.csv"), "-o", str(out), "--workers", "1")
    assert "1 baked, 2 skipped, 2 failed" in r.stderr, r.stderr


def test_json_manifests_and_bad_manifests(tmp_path):
    (tmp_path / "pairs.json").write_text(json.dumps(
        [{"high": os.path.join(SHARED, "spot_triangulated.obj"), "control": os.path.join(SHARED, "spot_control_mesh.obj"),
          "tolerance": "0.05%", "exr": True}]))
    pairs = strata.batch.read_manifest(str(tmp_path / "pairs.json"))
    assert pairs[0]["name"] == "spot_triangulated" and pairs[0]["options"] == {"tolerance": "0.05%", "exr": "true"}
    (tmp_path / "bad.csv").write_text("high,control,speed\na.obj,b.obj,fast\n")
    r = batch(str(tmp_path / "bad.csv"), "-o", str(tmp_path / "o"))
    assert r.returncode == 2 and "speed is not a strata.bake option" in r.stderr, r.stderr
    (tmp_path / "twice.csv").write_text("high,control\nx/a.obj,b.obj\ny/a.obj,b.obj\n")
    r = batch(str(tmp_path / "twice.csv"), "-o", str(tmp_path / "o"))
    assert r.returncode == 2 and "would both write a.glb" in r.stderr, r.stderr
