#!/usr/bin/env python
"""A corridor of many spans: wall time with 0, 1 and 2 Dask workers, peak memory of the
run and of its largest worker, time per span, the decode floor, whether the outputs of
every run are the same, and how complete each span's wires are.

The corridor is the package's renderer with ``--spans`` spans of 100 m in a straight line
(lattice towers, a double circuit and two shield wires), flown as a 3-strip corridor
mission at reduced scale; it is rendered once into the work folder and reused. Each run
goes in a fresh process (``benchmark_workers.py``), so its peak memory is its own; 0
workers is everything in the run's own process.

    python scripts/benchmark_corridor.py                       # 10 spans, quarter scale
    python scripts/benchmark_corridor.py --spans 12 --workers 0 2 --json corridor.json
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

# scripts/ is on the path when run as a script
from benchmark_flights import score_package, score_supports
from benchmark_workers import measure


def render(args: argparse.Namespace) -> Path:
    from colmap_powerline.synthetic import SyntheticSpanOptions, generate_span

    scene = args.work_path / f"corridor_{args.spans}spans_{args.background}_s{args.seed}"
    if not (scene / "truth" / "wires.json").exists():
        generate_span(
            scene,
            SyntheticSpanOptions(
                seed=args.seed,
                scale=args.scale,
                background=args.background,
                flight="corridor",
                num_spans=args.spans,
                line_azimuth_deg=args.azimuth,
                show_progress=False,
            ),
        )
    return scene


def score(scene: Path, out: Path) -> dict:
    """Per-span completeness (length-weighted, conductors and shields apart), the run's
    overall accuracy, and the towers found within 0.5 m in plan and 1 m in height."""
    from colmap_powerline.synthetic import load_true_wires

    truth = load_true_wires(scene / "truth" / "wires.json")
    r = score_package(scene, out)
    per_span: dict[int, dict[str, list[float]]] = {}
    for t, w in zip(truth, r["wires"], strict=True):
        d = per_span.setdefault(t.span, {"conductor": [], "shield": []})
        d[t.kind].append(w["completeness"])
    towers = json.loads((scene / "truth" / "wires.json").read_text())["supports"]
    found = json.loads((out / "wires.json").read_text())["supports"]
    supports = score_supports(found, towers)
    return {
        "spans": {
            s: {k: float(np.mean(v)) if v else None for k, v in d.items()}
            for s, d in sorted(per_span.items())
        },
        "conductors_found": sum(
            w["found"] for t, w in zip(truth, r["wires"], strict=True) if t.kind == "conductor"
        ),
        "conductors": sum(t.kind == "conductor" for t in truth),
        "median_m": r["median_m"],
        "outlier_share": r["outlier_share"],
        "ghosts": r["ghosts"],
        **supports,
    }


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--spans", type=int, default=10)
    ap.add_argument("--scale", type=float, default=0.25)
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--background", default="mixed")
    ap.add_argument("--azimuth", type=float, default=80.0)
    ap.add_argument("--workers", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--work_path", type=Path, default=Path("benchmark_corridor_out"))
    ap.add_argument("--json", type=Path, help="write the results here too")
    args = ap.parse_args(argv)
    scene = render(args)
    rows = measure(scene / "images", scene / "sparse" / "0", args.workers, args.work_path)
    s = score(scene, Path(rows[0]["out"]))
    floor = rows[0]["decode_floor_s"]
    print(
        f"\n{scene}: {args.spans} spans, {rows[0]['images_read']} images read; decode floor "
        f"{floor:.1f} s (each image the run read, decoded once)\n"
    )
    print("| workers | wall s | per span s | × floor | peak MB: run / worker | decodes | outputs |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['workers']} | {r['total_s']:.0f} | {r['total_s'] / args.spans:.1f} | "
            f"{r['total_s'] / floor:.1f} | {r['peak_rss_mb']:.0f} / {r['peak_child_rss_mb']:.0f} | "
            f"{r['decoded']} | {'same' if r['identical'] else 'DIFFERENT'} |"
        )
    print(
        f"\nconductors found {s['conductors_found']}/{s['conductors']}, median "
        f"{100 * (s['median_m'] or 0):.1f} cm, {100 * (s['outlier_share'] or 0):.2f} % of the "
        f"points > 30 cm off, {s['ghosts']} ghosts; towers {s['supports_right']}/"
        f"{s['supports_true']} right ({s['supports_found']} found)"
    )
    print(
        "per span, share of the length within 10 cm (conductors / shields): "
        + ", ".join(
            f"{k} {100 * (v['conductor'] or 0):.0f}/{100 * (v['shield'] or 0):.0f}"
            for k, v in s["spans"].items()
        )
    )
    if args.json:
        args.json.write_text(json.dumps({"runs": rows, "score": s}, indent=1))


if __name__ == "__main__":
    main()
