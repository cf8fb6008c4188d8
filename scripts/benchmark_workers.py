#!/usr/bin/env python
"""Wall time and memory of one run in this process and on Dask workers, and whether the
outputs are the same.

For each number of workers (0: everything in the run's own process), runs the whole
pipeline on a model and its images, in a fresh process so that its peak memory is its own,
and prints the wall time per stage, the peak resident memory of the run's process and of
its largest child (a Dask worker), the decode floor (each image the run read, decoded
once) and the ratio to it. The outputs of every run are compared byte for byte with the
first one's (wires.csv, supports.csv, wires.ply, wire_points.ply).

    python scripts/benchmark_workers.py --image_path SCENE/images --input_path SCENE/sparse/0
    python scripts/benchmark_workers.py --image_path … --input_path … --workers 0 1 2
"""

from __future__ import annotations

import argparse
import filecmp
import json
import multiprocessing as mp
import resource
import time
from pathlib import Path

from benchmark_flights import decode_floor  # scripts/ is on the path when run as a script

COMPARED = ("wires.csv", "supports.csv", "wires.ply", "wire_points.ply")


def _run_one(image_path: str, input_path: str, out: str, workers: int, queue: mp.Queue) -> None:
    from colmap_powerline import ExecutionOptions, ReconstructionOptions, reconstruct

    t0 = time.perf_counter()
    result = reconstruct(
        image_path,
        input_path,
        out,
        ReconstructionOptions(show_progress=False),
        execution=ExecutionOptions(workers=workers),
    )
    total = time.perf_counter() - t0
    unique = sorted(set(result.decoded))
    queue.put(
        {
            "workers": workers,
            "total_s": total,
            "timings_s": result.timings_s,
            "wires": len(result.wires),
            "decoded": len(result.decoded),
            "unique": [str(p) for p in unique],
            "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
            "peak_child_rss_mb": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024,
        }
    )


def measure(image_path: Path, input_path: Path, workers: list[int], work_path: Path) -> list[dict]:
    """One run per number of workers, each in a fresh process (its peak memory its own):
    a row per run with its times, memory, decodes, the decode floor and whether its outputs
    are byte for byte those of the first run."""
    ctx = mp.get_context("spawn")
    rows = []
    for w in workers:
        out = work_path / f"workers_{w}"
        queue = ctx.Queue()
        proc = ctx.Process(
            target=_run_one, args=(str(image_path), str(input_path), str(out), w, queue)
        )
        proc.start()
        row = queue.get()
        proc.join()
        row["out"] = str(out)
        rows.append(row)
    floor = decode_floor(Path(p) for p in rows[0]["unique"])
    first = Path(rows[0]["out"])
    for r in rows:
        r["decode_floor_s"] = floor
        r["images_read"] = len(r.pop("unique"))
        r["identical"] = all(
            filecmp.cmp(first / name, Path(r["out"]) / name, shallow=False) for name in COMPARED
        )
    return rows


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--image_path", type=Path, required=True)
    ap.add_argument("--input_path", type=Path, required=True)
    ap.add_argument("--workers", type=int, nargs="+", default=[0, 2])
    ap.add_argument("--work_path", type=Path, default=Path("benchmark_workers_out"))
    ap.add_argument("--json", type=Path, help="write the rows here too")
    args = ap.parse_args(argv)
    rows = measure(args.image_path, args.input_path, args.workers, args.work_path)
    floor = rows[0]["decode_floor_s"]
    print(
        f"{args.input_path}: {rows[0]['images_read']} images read, decode floor {floor:.1f} s "
        "(each image the run read, decoded once)"
    )
    for r in rows:
        stages = ", ".join(f"{k} {v:.1f}" for k, v in r["timings_s"].items())
        print(
            f"workers {r['workers']}: {r['total_s']:.1f} s = {r['total_s'] / floor:.1f}x the "
            f"floor; peak RSS {r['peak_rss_mb']:.0f} MB (largest child "
            f"{r['peak_child_rss_mb']:.0f} MB); {r['wires']} wires, {r['decoded']} decodes; "
            f"outputs {'identical to' if r['identical'] else 'DIFFERENT from'} workers "
            f"{rows[0]['workers']}\n    stages (s): {stages}"
        )
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
