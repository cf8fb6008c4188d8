#!/usr/bin/env python
"""Accuracy, completeness, speed and memory of the reconstruction on synthetic spans.

For each background preset and image scale, renders a span (cached under --work_path),
runs the whole pipeline on its bundle-adjusted-like model (``sparse/0``) and prints, per
true wire: completeness, median / RMS point error, catenary RMS, sag error; then ghost
wires, outlier share, time per stage, images decoded, the time to only decode those same
images, and peak memory. Each configuration runs in its own process so that peak RSS is
its own.

    python scripts/benchmark.py                       # vegetation, bare_soil, mixed at 1.0 and 0.5
    python scripts/benchmark.py --scales 0.5 --backgrounds vegetation
"""

from __future__ import annotations

import argparse
import json
import logging
import multiprocessing as mp
import resource
import time
from pathlib import Path

import cv2


def _run_one(span_dir: Path, out_dir: Path, overrides: dict, queue: mp.Queue) -> None:
    from colmap_powerline.evaluate import evaluate
    from colmap_powerline.pipeline import ReconstructionOptions, reconstruct
    from colmap_powerline.synthetic import load_true_wires

    logging.basicConfig(
        level=logging.INFO, format="%(asctime)s %(name)s: %(message)s", datefmt="%H:%M:%S"
    )
    options = ReconstructionOptions(show_progress=False)
    for key, value in overrides.items():
        stage, name = key.split(".", 1)
        setattr(getattr(options, stage), name, value)
    t0 = time.perf_counter()
    result = reconstruct(span_dir / "images", span_dir / "sparse" / "0", out_dir, options)
    total = time.perf_counter() - t0
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    t0 = time.perf_counter()
    for path in result.decoded:
        cv2.imread(str(path), cv2.IMREAD_COLOR)
    decode_s = time.perf_counter() - t0
    truth = load_true_wires(span_dir / "truth" / "wires.json")
    ev = evaluate(result.verified.pts_in_world, result.wires, truth)
    queue.put(
        {
            "table": ev.summary_table(),
            "targets": ev.meets_targets(),
            "timings_s": result.timings_s,
            "total_s": total,
            "images_decoded": len(result.decoded),
            "decode_only_s": decode_s,
            "peak_rss_mb": peak_mb,
            "num_pairs": len(result.pairs),
            "num_primitives": int(sum(len(p) for p in result.primitives)),
            "num_verified": len(result.verified),
            "num_wires": len(result.wires),
        }
    )


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--work_path", type=Path, default=Path("bench_work"))
    parser.add_argument("--scales", type=float, nargs="+", default=[1.0, 0.5])
    parser.add_argument("--backgrounds", nargs="+", default=["vegetation", "bare_soil", "mixed"])
    parser.add_argument("--flight", default="across")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--set",
        nargs="*",
        default=[],
        metavar="STAGE.FIELD=VALUE",
        help="option overrides, e.g. verify.min_hit_ratio=0.8 (values as JSON)",
    )
    parser.add_argument("--json", type=Path, help="also write all results to this file")
    args = parser.parse_args(argv)
    overrides = {}
    for item in args.set:
        key, value = item.split("=", 1)
        overrides[key] = json.loads(value)

    from colmap_powerline.synthetic import SyntheticSpanOptions, generate_span

    logging.basicConfig(level=logging.WARNING)
    results = {}
    for scale in args.scales:
        for background in args.backgrounds:
            name = f"{background}_{args.flight}_s{scale:g}_seed{args.seed}"
            span_dir = args.work_path / "spans" / name
            if not (span_dir / "truth" / "wires.json").exists():
                t0 = time.perf_counter()
                generate_span(
                    span_dir,
                    SyntheticSpanOptions(
                        scale=scale,
                        background=background,
                        flight=args.flight,
                        seed=args.seed,
                        show_progress=False,
                    ),
                )
                print(f"[{name}] rendered in {time.perf_counter() - t0:.0f} s", flush=True)
            queue: mp.Queue = mp.get_context("spawn").Queue()
            proc = mp.get_context("spawn").Process(
                target=_run_one, args=(span_dir, args.work_path / "out" / name, overrides, queue)
            )
            proc.start()
            proc.join()
            if proc.exitcode != 0:
                print(f"[{name}] FAILED (exit code {proc.exitcode})", flush=True)
                continue
            r = queue.get()
            results[name] = r
            stages = ", ".join(f"{k} {v:.1f} s" for k, v in r["timings_s"].items())
            print(
                f"\n=== {name}: {r['num_pairs']} pairs, {r['num_primitives']} primitives, "
                f"{r['num_verified']} verified points, {r['num_wires']} wires"
            )
            print(r["table"])
            print(f"targets: {r['targets']}")
            print(
                f"time: total {r['total_s']:.1f} s ({stages}); {r['images_decoded']} images "
                f"decoded, decode-only {r['decode_only_s']:.1f} s → "
                f"{r['total_s'] / max(r['decode_only_s'], 1e-9):.1f}x; "
                f"peak RSS {r['peak_rss_mb']:.0f} MB",
                flush=True,
            )
    if args.json:
        args.json.write_text(json.dumps(results, indent=1, default=str))


if __name__ == "__main__":
    main()
