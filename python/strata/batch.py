"""Bake a manifest of (high, control) pairs on a Dask cluster.

    python -m strata.batch MANIFEST -o OUTDIR [--workers N | --scheduler tcp://HOST:PORT]

MANIFEST is CSV with a header row ``high,control`` and optional columns named
after strata.bake's keywords (tolerance, size, scheme, mesh_coding, ...; an
empty cell leaves the default), or JSON: a list of objects with the same
keys.  Relative paths are relative to the manifest's folder.  Each rig is
written as ``OUTDIR/<name of the high file>.glb``.

The run is resumable: a pair whose rig exists and whose inputs and options
hash as when it was baked is skipped.  A failed pair is retried once, and a
failure never stops the other pairs.  OUTDIR/batch_report.csv and .json give,
per pair, the status, bytes, closed-loop RMS, level, seconds, worker and
error.  Without --scheduler a local cluster of N worker processes runs the
bakes (N defaults to the cores / 2); with it, any Dask cluster does, provided
its workers can import strata and read the paths (a shared file system).
The exit code is 0 when every pair is baked or skipped, 1 when any failed,
2 for a bad manifest or command line.
"""
from __future__ import annotations

import argparse
import csv
import hashlib
import json
import os
import sys
import time
from typing import Any, Dict, List, Optional

STATE = ".strata-batch.json"
REPORT_FIELDS = ["high", "control", "output", "status", "bytes", "rms", "level", "seconds", "worker", "error"]


class ManifestError(Exception):
    pass


def _hash(path: str) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def read_manifest(path: str) -> List[Dict[str, str]]:
    """The pairs of a CSV or JSON manifest, paths made absolute."""
    base = os.path.dirname(os.path.abspath(path))
    try:
        if path.lower().endswith(".json"):
            with open(path, encoding="utf-8") as f:
                rows = json.load(f)
            if not isinstance(rows, list) or not all(isinstance(r, dict) for r in rows):
                raise ManifestError(f"{path}: a JSON manifest is a list of objects")
            rows = [{str(k): ("" if v is None else str(v) if not isinstance(v, bool) else str(v).lower())
                     for k, v in r.items()} for r in rows]
        else:
            with open(path, newline="", encoding="utf-8") as f:
                reader = csv.DictReader(f)
                if not reader.fieldnames or "high" not in reader.fieldnames or "control" not in reader.fieldnames:
                    raise ManifestError(f"{path}: the header row must name the columns high and control")
                rows = [dict(r) for r in reader]
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, csv.Error) as e:
        raise ManifestError(f"{path}: cannot read the manifest ({e})") from None
    import strata

    keywords = _bake_keywords(strata)
    pairs, names = [], {}
    for n, row in enumerate(rows, start=2 if not path.lower().endswith(".json") else 1):
        if not row.get("high") or not row.get("control"):
            raise ManifestError(f"{path}: entry {n} has no high or no control")
        unknown = [k for k in row if k not in ("high", "control") and k not in keywords]
        if unknown:
            raise ManifestError(f"{path}: entry {n}: {unknown[0]} is not a strata.bake option "
                                f"(see help(strata.bake))")
        pair = {"high": os.path.join(base, row["high"]),
                "control": row["control"] if row["control"] == "auto" else os.path.join(base, row["control"]),
                "options": {k: v for k, v in row.items() if k not in ("high", "control") and v not in ("", None)}}
        name = os.path.splitext(os.path.basename(pair["high"]))[0]
        if name in names:
            raise ManifestError(f"{path}: entries {names[name]} and {n} would both write {name}.glb")
        names[name] = n
        pair["name"] = name
        pairs.append(pair)
    return pairs


def _bake_keywords(strata) -> set:
    return {o["keyword"] for o in strata.bake_options() if not o["required"]}


def _fingerprint(pair: Dict[str, Any]) -> Dict[str, Any]:
    return {"high": _hash(pair["high"]),
            "control": "auto" if pair["control"] == "auto" else _hash(pair["control"]),
            "options": pair["options"]}


def bake_pair(high: str, control: str, output: str, options: Dict[str, str], threads: int) -> Dict[str, Any]:
    """One bake on a worker: the report's figures, or the exception (which
    Dask's retry sees)."""
    import strata

    worker = "local"
    try:
        from distributed import get_worker

        worker = get_worker().address
    except (ImportError, ValueError):
        pass
    kw = dict(options)
    kw.setdefault("threads", threads)
    t0 = time.monotonic()
    report = strata.bake(high, control, output, progress=None, **kw)
    return {"bytes": os.path.getsize(output), "rms": report["rms"],
            "level": report.get("recommendedLevel"), "seconds": round(time.monotonic() - t0, 3), "worker": worker}


def _progress(done: int, total: int, line: str, tty: bool) -> None:
    bar = "#" * (30 * done // max(total, 1))
    if tty:
        sys.stderr.write(f"\r[{bar:<30}] {done}/{total} {100 * done // max(total, 1):3d}%  {line[:60]:<60}")
        if done == total:
            sys.stderr.write("\n")
    else:
        sys.stderr.write(f"strata.batch: {done}/{total} {line}\n")
    sys.stderr.flush()


def run(manifest: str, outdir: str, workers: Optional[int] = None, scheduler: Optional[str] = None,
        retries: int = 1, threads: Optional[int] = None) -> List[Dict[str, Any]]:
    """Bakes every pair of the manifest into outdir; returns the report rows."""
    pairs = read_manifest(manifest)
    os.makedirs(outdir, exist_ok=True)
    state_path = os.path.join(outdir, STATE)
    try:
        with open(state_path, encoding="utf-8") as f:
            state = json.load(f)
    except (OSError, json.JSONDecodeError):
        state = {}
    rows: Dict[str, Dict[str, Any]] = {}
    todo = []
    for pair in pairs:
        output = os.path.join(os.path.abspath(outdir), pair["name"] + ".glb")
        pair["output"] = output
        row = {"high": pair["high"], "control": pair["control"], "output": output, "status": "", "bytes": "",
               "rms": "", "level": "", "seconds": "", "worker": "", "error": ""}
        rows[pair["name"]] = row
        try:
            pair["fingerprint"] = _fingerprint(pair)
        except OSError as e:
            row.update(status="failed", error=f"cannot read an input ({e.strerror}: {e.filename})")
            continue
        previous = state.get(pair["name"])
        if os.path.exists(output) and previous and previous.get("fingerprint") == pair["fingerprint"]:
            row.update(status="skipped", **{k: previous.get(k, "") for k in ("bytes", "rms", "level")})
            continue
        todo.append(pair)

    tty = sys.stderr.isatty()
    total, done = len(pairs), len(pairs) - len(todo)
    if todo:
        from distributed import Client, LocalCluster, as_completed

        cluster = None
        if scheduler:
            client = Client(scheduler)
        else:
            n = workers or max(1, (os.cpu_count() or 2) // 2)
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None)
            client = Client(cluster)
        try:
            nworkers = max(1, len(client.scheduler_info().get("workers", {})) or (workers or 1))
            per_task = threads or max(1, (os.cpu_count() or 2) // nworkers)
            futures = {}
            for pair in todo:
                f = client.submit(bake_pair, pair["high"], pair["control"], pair["output"], pair["options"], per_task,
                                  retries=retries, pure=False, key=f"strata-bake-{pair['name']}-{time.time_ns()}")
                futures[f] = pair
            for f in as_completed(futures):
                pair = futures[f]
                row = rows[pair["name"]]
                if f.status == "error":
                    e = f.exception()
                    row.update(status="failed", error=str(e).splitlines()[0] if str(e) else type(e).__name__)
                else:
                    result = f.result()
                    row.update(status="baked", **result)
                    state[pair["name"]] = {"fingerprint": pair["fingerprint"],
                                           **{k: result[k] for k in ("bytes", "rms", "level")}}
                    tmp = state_path + ".tmp"
                    with open(tmp, "w", encoding="utf-8") as out:
                        json.dump(state, out, indent=1)
                    os.replace(tmp, state_path)
                done += 1
                _progress(done, total, f"{pair['name']}: {row['status']}", tty)
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    report = [rows[p["name"]] for p in pairs]
    for ext in ("csv", "json"):
        tmp = os.path.join(outdir, f"batch_report.{ext}.tmp")
        with open(tmp, "w", newline="", encoding="utf-8") as out:
            if ext == "csv":
                w = csv.DictWriter(out, fieldnames=REPORT_FIELDS)
                w.writeheader()
                w.writerows(report)
            else:
                json.dump(report, out, indent=1)
        os.replace(tmp, os.path.join(outdir, f"batch_report.{ext}"))
    return report


def main(argv: Optional[List[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m strata.batch", description=__doc__.split("\n\n")[0])
    parser.add_argument("manifest", help="CSV (header: high,control[,option...]) or JSON manifest")
    parser.add_argument("-o", "--outdir", required=True, help="folder for the rigs and the report")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, help="local cluster of N worker processes (default: cores / 2)")
    where.add_argument("--scheduler", help="address of a running Dask scheduler, tcp://HOST:PORT")
    parser.add_argument("--threads", type=int, help="bake threads per pair (default: cores / workers)")
    parser.add_argument("--retries", type=int, default=1, help="retries of a failed pair (default 1)")
    args = parser.parse_args(argv)
    if args.workers is not None and not 1 <= args.workers <= 1024:
        parser.error("--workers expects 1..1024")
    try:
        report = run(args.manifest, args.outdir, args.workers, args.scheduler, args.retries, args.threads)
    except ManifestError as e:
        print(f"strata.batch: error: {e}", file=sys.stderr)
        return 2
    counts = {s: sum(1 for r in report if r["status"] == s) for s in ("baked", "skipped", "failed")}
    print(f"strata.batch: {counts['baked']} baked, {counts['skipped']} skipped, {counts['failed']} failed -> "
          f"{os.path.join(args.outdir, 'batch_report.csv')}", file=sys.stderr)
    for r in report:
        if r["status"] == "failed":
            print(f"strata.batch: failed: {os.path.basename(r['high'])}: {r['error']}", file=sys.stderr)
    return 1 if counts["failed"] else 0


if __name__ == "__main__":
    sys.exit(main())
