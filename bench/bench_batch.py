"""Batch baking throughput: pairs per minute on a local Dask cluster of 1
and 2 workers, over the real pairs in tests/data (penguin, spot, hand), each
pair twice under another name, so that both workers have work to the end.

    PYTHONPATH=build/python python3 bench/bench_batch.py [--data tests/data] [--copies 2]

Prints a Markdown table (docs/RESULTS.md).  Each run bakes into a fresh
folder, so nothing is skipped; threads per pair are the cores / workers.
"""
import argparse
import os
import shutil
import sys
import tempfile
import time

import strata.batch

PAIRS = [("penguin_hr.obj", "penguin_control_mesh.obj"), ("spot_triangulated.obj", "spot_control_mesh.obj"),
         ("hand_closed.obj", "hand_lowres.obj")]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", default=os.path.join(os.path.dirname(__file__), "..", "tests", "data"))
    ap.add_argument("--copies", type=int, default=2)
    ap.add_argument("--workers", default="1,2")
    args = ap.parse_args()
    work = tempfile.mkdtemp(prefix="strata-bench-batch-")
    lines = ["high,control"]
    for c in range(args.copies):
        for high, control in PAIRS:
            name = f"{os.path.splitext(high)[0]}_{c}.obj"
            shutil.copy(os.path.join(args.data, high), os.path.join(work, name))
            shutil.copy(os.path.join(args.data, control), os.path.join(work, control))
            lines.append(f"{name},{control}")
    manifest = os.path.join(work, "pairs.csv")
    with open(manifest, "w") as f:
        f.write("\n".join(lines) + "\n")
    n = len(lines) - 1
    print(f"{n} pairs (penguin, spot, hand x {args.copies}), {os.cpu_count()} cores\n")
    print("| workers | threads per pair | wall s | pairs per minute | sum of bake s | failed |")
    print("|---|---|---|---|---|---|")
    for w in [int(x) for x in args.workers.split(",")]:
        out = os.path.join(work, f"out{w}")
        t0 = time.monotonic()
        report = strata.batch.run(manifest, out, workers=w)
        wall = time.monotonic() - t0
        failed = sum(r["status"] == "failed" for r in report)
        bake = sum(float(r["seconds"] or 0.0) for r in report)
        print(f"| {w} | {max(1, (os.cpu_count() or 2) // w)} | {wall:.1f} | {60.0 * n / wall:.1f} | {bake:.1f} | {failed} |")
        sys.stdout.flush()
    shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
