#!/usr/bin/env python
"""How visible are the true wires of a synthetic scene to the line template, per length?

For a scene of the shared generator (``../shared/scenes``: ``images/``, ``sparse_gt/``,
``gt/wires.json``) the true conductors are projected into some images; the template's
|response| (``detect.line_response``, at the wires' median image direction, best of each
3 × 3 neighbourhood) on the conductors' pixels is compared with its distribution on the
pixels farther than 20 px from every wire. Printed per template length: the share of
conductor pixels above the background's 99th and 99.9th percentiles, and the ratio of the
medians. A share near 1 means a threshold can take the wires and leave the ground; on the
shared ``soil`` preset (wires of the soil's own colour) it stays near 0.2 for every length,
which is why no wire is found there.

    python scripts/wire_visibility.py ../shared/scenes/out/soil_s0.5_seed1 --images 4
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import cv2
import numpy as np
import pycolmap

from colmap_powerline.detect import DetectOptions, line_response


def conductor_pixels(
    rec: pycolmap.Reconstruction,
    image: pycolmap.Image,
    wires: list[dict],
    shape: tuple[int, int],
    kind: str = "phase",
) -> tuple[list[np.ndarray], np.ndarray, float]:
    """Projected wires of one kind (pixel centres at integers), a mask of every wire, their
    direction."""
    cam = rec.cameras[image.camera_id]
    m = image.cam_from_world().matrix()
    drawn = np.zeros(shape, np.uint8)
    conductors, dirs = [], []
    for w in wires:
        p = np.asarray(w["polyline"], float) @ m[:, :3].T + m[:, 3]
        p = p[p[:, 2] > 0]
        if len(p) == 0:
            continue
        uv = np.asarray(cam.img_from_cam(p)) - 0.5  # COLMAP's pixel centres are at +0.5
        inside = (uv[:, 0] >= 0) & (uv[:, 0] < shape[1] - 1) & (uv[:, 1] >= 0)
        inside &= uv[:, 1] < shape[0] - 1
        uv = uv[inside]
        if len(uv) < 50:
            continue
        cv2.polylines(drawn, [np.round(uv * 16).astype(np.int32)], False, 255, 1, cv2.LINE_AA, 4)
        if w["kind"] == kind:
            conductors.append(uv)
            d = uv[-1] - uv[0]
            dirs.append(np.degrees(np.arctan2(d[1], d[0])) % 180.0)
    return conductors, drawn, float(np.median(dirs)) if dirs else float("nan")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("scene", type=Path, help="a scene of the shared generator")
    parser.add_argument("--images", type=int, default=4, help="images seeing most wire (4)")
    parser.add_argument("--lengths", type=int, nargs="+", default=[15, 25, 45, 101, 201])
    parser.add_argument("--kind", choices=["phase", "shield"], default="phase")
    args = parser.parse_args(argv)
    for need in ("images", "sparse_gt", "gt/wires.json"):
        if not (args.scene / need).exists():
            print(f"{args.scene / need}: not found (expected a shared-generator scene)")
            return 2
    rec = pycolmap.Reconstruction(str(args.scene / "sparse_gt"))
    wires = json.loads((args.scene / "gt" / "wires.json").read_text())["wires"]
    cam = next(iter(rec.cameras.values()))
    shape = (cam.height, cam.width)
    seen = []
    for image in rec.images.values():
        projected = conductor_pixels(rec, image, wires, shape, args.kind)
        seen.append((sum(len(c) for c in projected[0]), image.name, projected))
    seen.sort(key=lambda s: -s[0])
    table: dict[int, list[tuple[float, float, float]]] = {n: [] for n in args.lengths}
    used = []
    for n_px, name, (conductors, drawn, direction) in seen[: args.images]:
        if n_px == 0:
            break
        used.append(name)
        gray = cv2.imread(str(args.scene / "images" / name), cv2.IMREAD_GRAYSCALE)
        if gray is None:
            print(f"{args.scene / 'images' / name}: cannot be read")
            return 2
        far = cv2.dilate(drawn, np.ones((41, 41), np.uint8)) == 0
        pix = np.round(np.concatenate(conductors)).astype(int)
        for length in args.lengths:
            r = np.abs(
                line_response(
                    gray.astype(np.float32), direction, DetectOptions(template_length_px=length)
                )
            )
            r = cv2.dilate(r, np.ones((3, 3), np.uint8))
            background = r[far]
            p99, p999 = np.percentile(background, [99.0, 99.9])
            on = r[pix[:, 1], pix[:, 0]]
            table[length].append(
                (
                    float((on > p99).mean()),
                    float((on > p999).mean()),
                    float(np.median(on) / np.median(background)),
                )
            )
    print(f"{args.scene}: images {', '.join(used)}")
    print(f"template px | {args.kind} px above background p99 | above p99.9 | median ratio")
    for length, rows in table.items():
        a = np.mean(rows, axis=0)
        print(f"{length:11d} | {a[0]:33.2f} | {a[1]:11.2f} | {a[2]:12.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
