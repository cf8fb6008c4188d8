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
    python scripts/benchmark.py --sfm --scales 1.0 --backgrounds vegetation   # SfM model

With ``--sfm`` the model comes from pycolmap SfM on the images (georeferenced from their
EXIF GPS); the accuracy tables are then measured on that model aligned to the true frame by
camera centres (relative accuracy), and the georeferencing error is printed as well.
"""

from __future__ import annotations

import argparse
import json
import logging
import multiprocessing as mp
import resource
import time
from pathlib import Path

from benchmark_flights import decode_floor  # scripts/ is on the path when run as a script


def _sfm_models(span_dir: Path, work: Path) -> dict:
    """SfM + GPS georeferencing on the span's images (cached), and a copy of that model
    aligned to the true frame by camera centres. Returns the paths and the errors."""
    import numpy as np
    import pycolmap

    from colmap_powerline.georef import GeoreferenceOptions
    from colmap_powerline.sfm import SfmOptions, run_sfm

    georef_path, aligned_path = work / "sparse", work / "aligned"
    info_path = work / "sfm.json"
    if info_path.exists():
        return json.loads(info_path.read_text())
    origin = tuple(json.loads((span_dir / "truth" / "wires.json").read_text())["origin_wgs84"])
    t0 = time.perf_counter()
    sfm = run_sfm(
        span_dir / "images",
        georef_path,
        SfmOptions(georeference=GeoreferenceOptions(origin_wgs84=origin), show_progress=False),
    )
    total = time.perf_counter() - t0
    gt = pycolmap.Reconstruction(span_dir / "sparse_gt")
    rec = sfm.reconstruction
    names = [im.name for im in gt.images.values() if rec.find_image_with_name(im.name)]
    err = np.array(
        [
            rec.find_image_with_name(n).projection_center()
            - gt.find_image_with_name(n).projection_center()
            for n in names
        ]
    )
    aligned = pycolmap.Reconstruction(georef_path)
    gt_from_georef = pycolmap.align_reconstructions_via_proj_centers(aligned, gt, 1.0)
    aligned.transform(gt_from_georef)
    aligned_path.mkdir(parents=True, exist_ok=True)
    aligned.write_binary(aligned_path)
    rel = [
        np.linalg.norm(
            aligned.find_image_with_name(n).projection_center()
            - gt.find_image_with_name(n).projection_center()
        )
        for n in names
    ]
    info = {
        "sparse": str(georef_path),
        "aligned": str(aligned_path),
        "registered": f"{sfm.num_registered}/{sfm.num_images}",
        "reprojection_error_px": rec.compute_mean_reprojection_error(),
        "points": rec.num_points3D(),
        "sfm_s": total,
        "sfm_timings_s": sfm.timings_s,
        "georef_centre_rms_h_m": float(np.sqrt(np.mean(np.sum(err[:, :2] ** 2, axis=1)))),
        "georef_centre_rms_v_m": float(np.sqrt(np.mean(err[:, 2] ** 2))),
        "georef_scale_error": float(gt_from_georef.scale) - 1.0,
        "aligned_centre_median_m": float(np.median(rel)),
        # matrix of the similarity georeferenced-from-aligned, to carry results back
        "georef_from_aligned": np.asarray(gt_from_georef.inverse().matrix()).tolist(),
    }
    info_path.write_text(json.dumps(info, indent=1))
    return info


def _run_one(
    span_dir: Path, out_dir: Path, overrides: dict, use_sfm: bool, queue: mp.Queue
) -> None:
    import numpy as np

    from colmap_powerline.evaluate import distance_to_polyline, evaluate
    from colmap_powerline.pipeline import ReconstructionOptions, reconstruct
    from colmap_powerline.scene import load_scene
    from colmap_powerline.synthetic import load_true_wires

    logging.basicConfig(
        level=logging.INFO, format="%(asctime)s %(name)s: %(message)s", datefmt="%H:%M:%S"
    )
    options = ReconstructionOptions(show_progress=False)
    for key, value in overrides.items():
        stage, name = key.split(".", 1)
        setattr(getattr(options, stage), name, value)
    model = span_dir / "sparse" / "0"
    sfm_info = None
    if use_sfm:
        sfm_info = _sfm_models(span_dir, out_dir.parent.parent / "sfm" / span_dir.name)
        model = Path(sfm_info["aligned"])
    t0 = time.perf_counter()
    result = reconstruct(span_dir / "images", model, out_dir, options)
    total = time.perf_counter() - t0
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    decode_s = decode_floor(result.decoded)
    truth = load_true_wires(span_dir / "truth" / "wires.json")
    # Where the flight measures each wire, from the true poses: the targets are held there.
    views = load_scene(span_dir / "sparse_gt", span_dir / "images", check_images=False).images
    ev = evaluate(result.verified.pts_in_world[result.labels >= 0], result.wires, truth, views)
    if sfm_info is not None:
        # Absolute error: the same points carried into the GPS-georeferenced frame.
        m = np.array(sfm_info["georef_from_aligned"])
        pts = result.verified.pts_in_world @ m[:, :3].T + m[:, 3]
        d = np.min([distance_to_polyline(pts, w.polyline(0.05)) for w in truth], axis=0)
        sfm_info["georef_wire_points_median_m"] = float(np.median(d))
    queue.put(
        {
            "sfm": sfm_info,
            "table": ev.summary_table(),
            "targets": ev.meets_targets(),
            "timings_s": result.timings_s,
            "total_s": total,
            "image_reads": len(result.decoded),
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
    parser.add_argument(
        "--flight",
        default="across",
        choices=["corridor", "along4", "grid", "across"],
        help="flight pattern of the synthetic spans (default %(default)s; see "
        "scripts/benchmark_flights.py for a matrix of flights)",
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--set",
        nargs="*",
        default=[],
        metavar="STAGE.FIELD=VALUE",
        help="option overrides, e.g. verify.min_posterior=0.999 (values as JSON)",
    )
    parser.add_argument(
        "--sfm",
        action="store_true",
        help="orient the images with pycolmap SfM + EXIF GPS first (cached); reconstruct on "
        "that model aligned to the true frame by camera centres (relative accuracy) and "
        "report the georeferencing (absolute) error",
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
                target=_run_one,
                args=(span_dir, args.work_path / "out" / name, overrides, args.sfm, queue),
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
            if r["sfm"]:
                f = r["sfm"]
                print(
                    f"SfM: {f['registered']} registered, {f['points']} points, "
                    f"{f['reprojection_error_px']:.2f} px, {f['sfm_s']:.0f} s "
                    f"({', '.join(f'{k} {v:.0f} s' for k, v in f['sfm_timings_s'].items())}); "
                    "after similarity to the truth: centres "
                    f"{100 * f['aligned_centre_median_m']:.1f}"
                    f" cm (median)\nabsolute (GPS georeferencing): centres RMS "
                    f"{f['georef_centre_rms_h_m']:.2f} m horizontal, "
                    f"{f['georef_centre_rms_v_m']:.2f} m vertical, scale error "
                    f"{100 * f['georef_scale_error']:+.2f} %, wire points "
                    f"{f['georef_wire_points_median_m']:.2f} m from the true wires (median)"
                )
            print(r["table"])
            print(f"targets: {r['targets']}")
            print(
                f"time: total {r['total_s']:.1f} s ({stages}); {r['image_reads']} image "
                f"reads, decode-only {r['decode_only_s']:.1f} s → "
                f"{r['total_s'] / max(r['decode_only_s'], 1e-9):.1f}x; "
                f"peak RSS {r['peak_rss_mb']:.0f} MB",
                flush=True,
            )
    if args.json:
        args.json.write_text(json.dumps(results, indent=1, default=str))


if __name__ == "__main__":
    main()
