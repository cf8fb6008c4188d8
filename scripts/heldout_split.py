#!/usr/bin/env python
"""Split a held-out check's misses into "off a visible wire" and "nothing there to hit".

    python scripts/heldout_split.py OUT_DIR IMAGES_DIR MODEL_DIR --holdout A.jpg,B.jpg \
        --heldout ../shared/scenes/heldout.py

The held-out check (``heldout.py``) counts a sample of a drawn wire as a hit when a ridge
stands out within 1.5 px of it. A miss can mean the wire is drawn off a wire the image shows,
or that the image shows no wire there at all (a bright wire over bright soil, blur): a longer
wire lowers the hit share in the second case without being wrong. Here each miss is looked at
again within ±20 px at SNR ≥ 4: a ridge there is a visible wire the drawing is off; none is
a place the image cannot judge. Wires in the model's frame (the check's ``--same_frame``).
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path

import cv2
import numpy as np
import pycolmap

WIDE_SEARCH_PX = 20.0
WIDE_MIN_SNR = 4.0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out_dir", type=Path)
    ap.add_argument("images", type=Path)
    ap.add_argument("model", type=Path)
    ap.add_argument("--holdout", required=True, help="comma-separated image names")
    ap.add_argument("--heldout", type=Path, required=True, help="path of heldout.py")
    args = ap.parse_args(argv)
    spec = importlib.util.spec_from_file_location("heldout", args.heldout)
    if spec is None or spec.loader is None:
        print(f"{args.heldout}: not a Python file", file=sys.stderr)
        return 2
    sys.path.insert(0, str(args.heldout.parent))
    h = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(h)
    rec = pycolmap.Reconstruction(str(args.model))
    by_name = {im.name: im for im in rec.images.values()}
    wires = h.load_wires(str(args.out_dir))
    total = np.zeros(3, np.int64)
    print("image            wire    hit  off-visible  nothing-there (px)")
    for name in args.holdout.split(","):
        if name not in by_name:
            print(f"{args.model}: no image {name}", file=sys.stderr)
            return 2
        im = by_name[name]
        cam = rec.cameras[im.camera_id]
        gray = cv2.imread(str(args.images / name), cv2.IMREAD_GRAYSCALE)
        if gray is None:
            print(f"{args.images / name}: cannot be read as an image", file=sys.stderr)
            return 2
        gray = gray.astype(np.float32)
        search = h.SEARCH
        for label, poly in wires:
            counts = np.zeros(3, np.int64)
            for run in h.curve_samples(cam, im.cam_from_world(), poly):
                nrm = h.normals(run)
                h.SEARCH = search
                _, hit, _, _ = h.ridge_test(gray, run, nrm, None, 61, 2.5, 1.5)
                h.SEARCH = WIDE_SEARCH_PX
                _, near, _, _ = h.ridge_test(gray, run, nrm, None, 61, WIDE_MIN_SNR, WIDE_SEARCH_PX)
                counts += [hit.sum(), (~hit & near).sum(), (~hit & ~near).sum()]
            h.SEARCH = search
            if counts.sum():
                print(f"{name:16s} {label:>4s} {counts[0]:6d} {counts[1]:12d} {counts[2]:14d}")
            total += counts
    print(f"{'all':16s} {'':4s} {total[0]:6d} {total[1]:12d} {total[2]:14d}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
