#!/usr/bin/env python
"""Speed and memory of ``fill`` on large dense clouds (COLMAP fused.ply format).

Writes a synthetic fused.ply of N million points (ground with relief, plus a halo of
stray points around one 100 m wire), a wires.json with that wire, then runs ``fill`` (with
``--drop_stray`` and ``--las``) in its own process and prints the time and peak RSS. Peak
memory should stay near a constant (chunks of a million points) plus a small per-point
mask, not grow with the cloud's size in proportion to it.

    python scripts/benchmark_fill.py --millions 1 5 10
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import resource
import time
from pathlib import Path

import numpy as np


def _write_cloud(path: Path, n: int) -> None:
    from colmap_powerline.dense import FUSED_PLY_DTYPE as dtype
    from colmap_powerline.files import ply_header

    rng = np.random.default_rng(0)
    with path.open("wb") as f:
        f.write(ply_header(dtype, n))
        for k in range(0, n, 1_000_000):
            m = min(1_000_000, n - k)
            pts = np.zeros(m, dtype)
            pts["x"] = rng.uniform(-50, 150, m)
            pts["y"] = rng.uniform(-60, 60, m)
            pts["z"] = 0.02 * pts["x"] + np.sin(pts["y"] / 9.0) + rng.normal(0, 0.02, m)
            halo = rng.random(m) < 0.001
            pts["y"][halo] = rng.uniform(-0.8, 0.8, halo.sum())
            pts["z"][halo] = 12.0 + rng.choice([-0.6, 0.6], halo.sum())
            pts["nz"], pts["green"] = 1.0, 120
            f.write(pts.tobytes())


def _run(dense: Path, wires: Path, out: Path, queue: mp.Queue) -> None:
    from colmap_powerline.dense import fill

    t0 = time.perf_counter()
    r = fill(dense, wires, out, drop_stray=True, las=True)
    queue.put(
        {
            "seconds": time.perf_counter() - t0,
            "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
            "dropped": r.num_dropped,
        }
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--work_path", type=Path, default=Path("bench_work/fill"))
    parser.add_argument("--millions", type=float, nargs="+", default=[1, 5, 10])
    args = parser.parse_args()
    args.work_path.mkdir(parents=True, exist_ok=True)

    from colmap_powerline.clearance import measure_wire
    from colmap_powerline.export import export_results
    from colmap_powerline.scene import GroundModel
    from colmap_powerline.wires import FittedWire

    wire = FittedWire(
        wire_id=0,
        plane_origin_xy=np.array([0.0, 0.0]),
        plane_direction_xy=np.array([1.0, 0.0]),
        catenary_a=600.0,
        s0=50.0,
        z0=12.0,
        s_range=(0.0, 100.0),
        point_indices=np.arange(10),
        rms_residual=0.01,
    )
    ground = GroundModel(np.array([[0.0, -50], [100, -50], [50, 50]]), np.zeros(3), 50.0)
    export_results(
        args.work_path / "wires",
        wires=[wire],
        points=wire.polyline(1.0),
        labels=np.zeros(101, np.int64),
        primitives=None,
        metadata={},
        measures=[measure_wire(wire, ground)],
    )
    for millions in args.millions:
        n = int(millions * 1_000_000)
        dense = args.work_path / f"fused_{n}.ply"
        if not dense.exists():
            _write_cloud(dense, n)
        queue: mp.Queue = mp.get_context("spawn").Queue()
        proc = mp.get_context("spawn").Process(
            target=_run,
            args=(dense, args.work_path / "wires" / "wires.json",
                  args.work_path / f"merged_{n}.ply", queue),
        )  # fmt: skip
        proc.start()
        proc.join()
        r = queue.get()
        print(
            f"{n / 1e6:g} M points ({dense.stat().st_size / 1e6:.0f} MB): fill + LAS in "
            f"{r['seconds']:.1f} s, peak RSS {r['peak_rss_mb']:.0f} MB, "
            f"{r['dropped']} stray points dropped",
            flush=True,
        )


if __name__ == "__main__":
    main()
