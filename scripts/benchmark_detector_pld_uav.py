#!/usr/bin/env python
"""The wire detector against real pixel labels: the PLD-UAV test sets (PLDU urban, PLDM mountain).

PLD-UAV (github.com/SnorkerHeng/PLD-UAV) holds 540 x 360 drone images with hand-drawn wire
labels; its repository states no licence, so the data is not copied into this one.
``colmap_powerline.detect.detect_wires`` runs on every test image with the package's
default ``DetectOptions`` (nothing is tuned here: test on this data, do not train on it).
The detector needs the wires' image direction; two modes:

* ``given``: the direction the pipeline would have from the camera poses. Here it is the
  dominant direction of the labelled wire pixels (structure tensor of the label mask, one
  direction per cluster of label orientations; the detector runs once per direction and
  the masks are OR-ed). The labels are used for the direction only, never for positions.
* ``estimated``: directions from the image alone, with the pipeline's own
  ``colmap_powerline.pairs._image_directions(gray, PairsOptions())`` (its 3 strongest
  thin-line directions; the masks of all of them are OR-ed). ``estimated-top1`` uses only
  its strongest direction. The images are 540 px wide, below the 800 px analysis width, so
  they are used as they are (the pipeline's integer downscale factor is 1 there too).

Scores (pixels within ``--tolerance_px`` count as matched, cv2.distanceTransform):

* the labels are *boundary* labels, not filled masks: each wire is drawn as its two 1 px
  edges (a 4 px wire is two parallel lines 3-4 px apart, a 15 px wide near wire two lines
  15 px apart); a wire of 1-2 px is one line.
* headline, ``labels`` (as drawn): precision = share of detected pixels within the
  tolerance of a labelled pixel; recall = share of labelled pixels within the tolerance
  of a detected pixel. For wires up to ~4 px wide a detection anywhere on the wire covers
  both edges.
* ``centre``: precision against the wire body (the labels closed with a 7 x 7 disc, which
  fills the inside of wires whose edges are up to ~6 px apart), recall of the body's
  centre line (Zhang-Suen thinning; skimage is not installed). It shows whether the
  wire's middle is found, which matters for 5-6 px wires whose drawn edges are > 2 px from
  their centre. Wires wider than that keep their two edges as "centre line".
* ``chance``: the recall of decoy wires, the labels turned by 180° (same directions, other
  places; decoy pixels within 2 x tolerance + 1 px of a real wire dropped). It is what the
  false detections alone cover, the floor against which the recall is to be read.

Pooled = summed over all pixels of a subset; median = median of the per-image values.
Times are per image, wall clock, on a shared machine.

Data layout, as in the PLD-UAV repository (the script reads it unchanged):

    DATA/PLDU/test/<n>.jpg   DATA/PLDU/test_gt/<n>.mat   (groundTruth{1}.Boundaries, H x W 0/1)
    DATA/PLDM/test/<n>.jpg   DATA/PLDM/test_gt/<n>.mat

``--export_from GIT_DIR`` first writes those files from a (bare) clone of the repository
into DATA. Example:

    python scripts/benchmark_detector_pld_uav.py --data /work/data/pld_uav --json out.json
    python scripts/benchmark_detector_pld_uav.py --data D --export_from PLD-UAV/.git
"""

from __future__ import annotations

import argparse
import json
import subprocess
import time
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

Mask = npt.NDArray[np.bool_]

SUBSETS = ("PLDU", "PLDM")
MODES = ("given", "estimated", "estimated-top1")
BODY_CLOSING_RADIUS_PX = 3  # fills between a wire's two labelled edges up to ~6 px apart


# --------------------------------------------------------------------------------------
# Data


def export_from_git(git_dir: Path, data: Path) -> int:
    """Write the PLDU/PLDM test images and labels of a PLD-UAV clone into ``data``."""
    names = subprocess.run(
        ["git", f"--git-dir={git_dir}", "ls-tree", "-r", "--name-only", "HEAD"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout.splitlines()
    n = 0
    for name in names:
        parts = name.split("/")
        if len(parts) == 3 and parts[0] in SUBSETS and parts[1] in ("test", "test_gt"):
            out = data / name
            out.parent.mkdir(parents=True, exist_ok=True)
            blob = subprocess.run(
                ["git", f"--git-dir={git_dir}", "show", f"HEAD:{name}"],
                check=True,
                capture_output=True,
            ).stdout
            out.write_bytes(blob)
            n += 1
    return n


def load_labels(path: Path) -> Mask:
    """(H, W) wire boundary labels of one ``test_gt/<n>.mat`` (or a .png / .npz mask)."""
    if path.suffix == ".mat":
        from scipy.io import loadmat

        gt = loadmat(str(path))["groundTruth"]
        return np.asarray(gt[0, 0]["Boundaries"][0, 0]).astype(bool)
    if path.suffix == ".npz":
        with np.load(path) as z:
            return z[z.files[0]].astype(bool)
    img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if img is None:
        raise FileNotFoundError(path)
    return img > 127


def load_image(path: Path) -> np.ndarray:
    """RGB uint8, as ``colmap_powerline.scene.read_image`` gives it."""
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise FileNotFoundError(path)
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def test_items(data: Path, subset: str) -> list[tuple[str, Path, Path]]:
    """(name, image path, label path) of a subset's test images, by number."""
    gt_dir = data / subset / "test_gt"
    items = []
    for img in sorted((data / subset / "test").glob("*.jpg"), key=lambda p: int(p.stem)):
        for ext in (".mat", ".npz", ".png"):
            if (gt_dir / (img.stem + ext)).exists():
                items.append((img.stem, img, gt_dir / (img.stem + ext)))
                break
    return items


# --------------------------------------------------------------------------------------
# Truth derived from the boundary labels


def thin(mask: Mask) -> Mask:
    """Zhang-Suen thinning (1 px wide, 8-connected centre lines)."""
    img = np.pad(mask.astype(np.uint8), 1)
    while True:
        changed = False
        for step in (0, 1):
            p2, p3, p4 = img[:-2, 1:-1], img[:-2, 2:], img[1:-1, 2:]
            p5, p6, p7 = img[2:, 2:], img[2:, 1:-1], img[2:, :-2]
            p8, p9 = img[1:-1, :-2], img[:-2, :-2]
            ring = (p2, p3, p4, p5, p6, p7, p8, p9)
            b = sum(p.astype(np.int32) for p in ring)
            a = sum(((ring[i] == 0) & (ring[(i + 1) % 8] == 1)).astype(np.int32) for i in range(8))
            if step == 0:
                c1, c2 = (p2 & p4 & p6) == 0, (p4 & p6 & p8) == 0
            else:
                c1, c2 = (p2 & p4 & p8) == 0, (p2 & p6 & p8) == 0
            remove = (img[1:-1, 1:-1] == 1) & (b >= 2) & (b <= 6) & (a == 1) & c1 & c2
            if remove.any():
                img[1:-1, 1:-1][remove] = 0
                changed = True
        if not changed:
            return img[1:-1, 1:-1].astype(bool)


def wire_body(labels: Mask, radius_px: int = BODY_CLOSING_RADIUS_PX) -> Mask:
    """The labels with the inside of each wire (between its two drawn edges) filled."""
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius_px + 1, 2 * radius_px + 1))
    # Pad so that the closing does not erode at the image border.
    pad = radius_px + 1
    padded = cv2.copyMakeBorder(labels.astype(np.uint8), pad, pad, pad, pad, cv2.BORDER_REPLICATE)
    closed = cv2.morphologyEx(padded, cv2.MORPH_CLOSE, k)[pad:-pad, pad:-pad]
    return closed.astype(bool) | labels


@dataclass(frozen=True, eq=False)
class Truth:
    labels: Mask  # as drawn: the wires' edges
    body: Mask  # edges with the inside of each wire filled
    centre: Mask  # centre line of the body


def make_truth(labels: Mask) -> Truth:
    body = wire_body(labels)
    return Truth(labels, body, thin(body))


def label_directions(
    labels: Mask, min_share: float = 0.1, merge_deg: float = 6.0, max_directions: int = 4
) -> list[float]:
    """Image directions of the labelled wires (degrees, 0 = +x, 90 = down), largest first.

    Local orientation of the label mask (structure tensor) gives a histogram of the coherent
    label pixels; its peaks (±2° windows) are taken greedily, a peak with its ±``merge_deg``
    neighbourhood being one direction when it holds ≥ ``min_share`` of those pixels. The
    angle of each is then refined on the pixels of that cluster (the direction along which
    they fall on the fewest, fullest lines: 0.1° steps within ±3°), since the local
    orientation of 1 px staircase lines is biased by up to ~1.5°.
    """
    g = cv2.GaussianBlur(labels.astype(np.float32), (0, 0), 1.5)
    gx = cv2.Sobel(g, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(g, cv2.CV_32F, 0, 1, ksize=3)
    jxx = cv2.GaussianBlur(gx * gx, (0, 0), 3.0)
    jyy = cv2.GaussianBlur(gy * gy, (0, 0), 3.0)
    jxy = cv2.GaussianBlur(gx * gy, (0, 0), 3.0)
    coherence = np.sqrt((jxx - jyy) ** 2 + 4 * jxy**2) / (jxx + jyy + 1e-12)
    grad = 0.5 * np.rad2deg(np.arctan2(2 * jxy, jxx - jyy))
    sel = labels & (coherence > 0.5)
    angles = (grad[sel] + 90.0) % 180.0
    if angles.size == 0:
        return []
    ys, xs = np.nonzero(sel)
    hist = np.bincount(np.floor(angles).astype(int) % 180, minlength=180).astype(float)
    w = int(round(merge_deg))
    total = hist.sum()
    out: list[float] = []

    def window_sum(h: np.ndarray, r: int) -> np.ndarray:
        return np.convolve(np.r_[h[-r:], h, h[:r]], np.ones(2 * r + 1), "valid")

    def concentration(x: np.ndarray, y: np.ndarray, a_deg: float) -> float:
        a = np.deg2rad(a_deg)
        across = -x * np.sin(a) + y * np.cos(a)
        counts = np.bincount(np.floor(across - across.min()).astype(int))
        return float((counts.astype(float) ** 2).sum())

    for _ in range(max_directions):
        k = int(np.argmax(window_sum(hist, 2)))
        if window_sum(hist, w)[k] < min_share * total:
            break
        diff = (angles - (k + 0.5) + 90.0) % 180.0 - 90.0
        cluster = np.abs(diff) <= merge_deg
        near = angles[np.abs(diff) <= 2.0]
        z = np.exp(2j * np.deg2rad(near if near.size else angles[cluster])).mean()
        start = float(np.rad2deg(np.angle(z)) / 2)
        x, y = xs[cluster].astype(float), ys[cluster].astype(float)
        trials = start + np.arange(-3.0, 3.0 + 1e-9, 0.1)
        best = trials[int(np.argmax([concentration(x, y, a) for a in trials]))]
        out.append(float(best % 180.0))
        hist[[(k + d) % 180 for d in range(-w, w + 1)]] = 0
    return out


# --------------------------------------------------------------------------------------
# Scoring


def _within(mask: Mask, tolerance_px: float) -> Mask:
    """Pixels whose centre is within ``tolerance_px`` of a pixel of ``mask``."""
    if not mask.any():
        return np.zeros_like(mask)
    dist = cv2.distanceTransform((~mask).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    return dist <= tolerance_px + 1e-6


@dataclass
class Counts:
    """Pixel counts of one image (or summed): precision = tp_det / det, recall = tp_gt / gt."""

    det: int = 0
    tp_det: int = 0
    gt: int = 0
    tp_gt: int = 0

    def __add__(self, o: Counts) -> Counts:
        return Counts(
            self.det + o.det, self.tp_det + o.tp_det, self.gt + o.gt, self.tp_gt + o.tp_gt
        )

    @property
    def precision(self) -> float:
        return self.tp_det / self.det if self.det else float("nan")

    @property
    def recall(self) -> float:
        return self.tp_gt / self.gt if self.gt else float("nan")

    @property
    def f1(self) -> float:
        p, r = self.precision, self.recall
        if not self.det:
            return 0.0
        return 2 * p * r / (p + r) if p + r > 0 else 0.0


def score(detected: Mask, truth: Truth, tolerance_px: float = 2.0) -> dict[str, Counts]:
    """Pixel counts of one detection mask: ``labels`` (the headline: against the labels as
    drawn), ``centre`` (precision against the wire body, recall of its centre line) and
    ``chance`` (recall of decoy wires: the labels turned by 180°, away from the real ones)."""
    near_det = _within(detected, tolerance_px)
    n_det = int(detected.sum())

    def counts(for_precision: Mask, for_recall: Mask) -> Counts:
        return Counts(
            det=n_det,
            tp_det=int((detected & _within(for_precision, tolerance_px)).sum()),
            gt=int(for_recall.sum()),
            tp_gt=int((for_recall & near_det).sum()),
        )

    # Chance level of the recall: the labels turned by 180° (same directions, other places;
    # pixels that land near a real wire dropped) are "found" only by clutter.
    decoy = truth.labels[::-1, ::-1] & ~_within(truth.body, 2 * tolerance_px + 1)
    return {
        "labels": counts(truth.labels, truth.labels),
        "centre": counts(truth.body, truth.centre),
        "chance": counts(decoy, decoy),
    }


# --------------------------------------------------------------------------------------
# Detection


@dataclass
class ImageResult:
    subset: str
    name: str
    given_deg: list[float]
    estimated_deg: list[float]
    counts: dict[str, dict[str, Counts]] = field(default_factory=dict)  # mode -> truth -> counts
    seconds: dict[str, float] = field(default_factory=dict)


def detect_or(image: np.ndarray, directions: list[float]) -> tuple[Mask, list[Mask]]:
    """OR of ``detect_wires`` masks (default options) over ``directions``; also each mask."""
    from colmap_powerline.detect import DetectOptions, detect_wires

    masks = [detect_wires(image, d, DetectOptions()).mask for d in directions]
    out = np.zeros(image.shape[:2], bool)
    for m in masks:
        out |= m
    return out, masks


def estimate_directions(image: np.ndarray) -> list[float]:
    """The pipeline's image-only directions (strongest first) at its analysis scale."""
    from colmap_powerline.pairs import PairsOptions, _image_directions

    options = PairsOptions()
    gray = cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
    factor = max(1, int(round(gray.shape[1] / options.analysis_width_px)))
    if factor > 1:  # as pairs.direction_candidates does
        size = (gray.shape[1] // factor, gray.shape[0] // factor)
        gray = cv2.resize(gray, size, interpolation=cv2.INTER_AREA)
    return [a for a, _ in _image_directions(gray.astype(np.float32), options)]


def run_image(
    subset: str, name: str, image: np.ndarray, labels: Mask, tolerance_px: float
) -> tuple[ImageResult, dict[str, Mask], Truth]:
    truth = make_truth(labels)
    given = label_directions(labels)
    t0 = time.perf_counter()
    est = estimate_directions(image)
    t_dir = time.perf_counter() - t0
    res = ImageResult(subset, name, given, est)
    masks: dict[str, Mask] = {}
    t0 = time.perf_counter()
    masks["given"], _ = detect_or(image, given)
    res.seconds["given"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    masks["estimated"], per_direction = detect_or(image, est)
    t_det = time.perf_counter() - t0
    res.seconds["estimated"] = t_det + t_dir
    res.seconds["estimated_directions"] = t_dir
    masks["estimated-top1"] = per_direction[0] if per_direction else np.zeros_like(labels)
    res.seconds["estimated-top1"] = t_dir + t_det / max(len(est), 1)
    for mode in MODES:
        res.counts[mode] = score(masks[mode], truth, tolerance_px)
    return res, masks, truth


def direction_hits(given: list[float], estimated: list[float], tol_deg: float = 3.0) -> int:
    """How many of the labelled directions have an estimated direction within ``tol_deg``."""
    return sum(any(abs((g - e + 90.0) % 180.0 - 90.0) <= tol_deg for e in estimated) for g in given)


def write_overlay(path: Path, image: np.ndarray, detected: Mask, truth: Truth, tol: float) -> None:
    """Left: the image. Right: matched detections green, false detections red, missed
    centre-line pixels blue, found centre-line pixels dark green."""
    near_body = _within(truth.body, tol)
    near_det = _within(detected, tol)
    ov = (image * 0.6).astype(np.uint8)
    ov[truth.centre & near_det] = (0, 110, 0)
    ov[truth.centre & ~near_det] = (40, 90, 255)
    ov[detected & near_body] = (0, 255, 0)
    ov[detected & ~near_body] = (255, 0, 0)
    both = np.hstack([image, ov])
    cv2.imwrite(str(path), cv2.cvtColor(both, cv2.COLOR_RGB2BGR))


# --------------------------------------------------------------------------------------
# Report


def summarize(results: list[ImageResult], mode: str, truth: str) -> dict:
    pooled = Counts()
    for r in results:
        pooled = pooled + r.counts[mode][truth]
    per = [r.counts[mode][truth] for r in results]

    def med(vals: list[float]) -> float:
        vals = [v for v in vals if not np.isnan(v)]
        return float(np.median(vals)) if vals else float("nan")

    return {
        "images": len(results),
        "precision": pooled.precision,
        "recall": pooled.recall,
        "f1": pooled.f1,
        "median_precision": med([c.precision for c in per]),
        "median_recall": med([c.recall for c in per]),
        "median_f1": med([c.f1 for c in per]),
        "images_without_detection": sum(c.det == 0 for c in per),
        "seconds_per_image": float(np.mean([r.seconds[mode] for r in results])),
    }


def print_table(results: list[ImageResult], tolerance_px: float) -> dict:
    groups = {s: [r for r in results if r.subset == s] for s in SUBSETS}
    groups = {k: v for k, v in groups.items() if v}
    groups["all"] = results
    summary: dict = {}
    print(
        "\nPLD-UAV test sets, detect_wires with default DetectOptions, "
        f"tolerance {tolerance_px:g} px"
    )
    print("  given          : wire direction(s) from the labels' orientation. The labels are used")
    print("                   for the direction only, as the pipeline uses the camera poses.")
    print("  estimated      : directions from the image alone (pairs._image_directions, its 3")
    print("                   strongest directions, masks OR-ed); estimated-top1: strongest only")
    print("  P R F1         : HEADLINE, against the labels as drawn (the wires' edges); pooled")
    print("                   over pixels, and medP medR medF1: median of the per-image values")
    print("  P_bdy R_ctr    : P against the wire body (edges + inside), R of its centre line")
    print("  R_chc          : chance recall: R of decoy wires (the labels turned by 180°, away")
    print("                   from the real wires), i.e. what the clutter alone would cover")
    hdr = (
        f"{'mode':<15} {'subset':<6} {'imgs':>4} | {'P':>5} {'R':>5} {'F1':>5} "
        f"{'medP':>5} {'medR':>5} {'medF1':>5} | {'P_bdy':>5} {'R_ctr':>5} {'F1':>5} "
        f"| {'R_chc':>5} {'none':>4} {'s/img':>6}"
    )
    print("\n" + hdr)
    print("-" * len(hdr))
    for mode in MODES:
        for g, rs in groups.items():
            e = summarize(rs, mode, "labels")
            c = summarize(rs, mode, "centre")
            ch = summarize(rs, mode, "chance")
            summary.setdefault(mode, {})[g] = {"labels": e, "centre": c, "chance": ch}
            print(
                f"{mode:<15} {g:<6} {e['images']:>4} | {e['precision']:5.3f} {e['recall']:5.3f} "
                f"{e['f1']:5.3f} {e['median_precision']:5.3f} {e['median_recall']:5.3f} "
                f"{e['median_f1']:5.3f} | {c['precision']:5.3f} {c['recall']:5.3f} "
                f"{c['f1']:5.3f} | {ch['recall']:5.3f} {e['images_without_detection']:>4} "
                f"{e['seconds_per_image']:6.3f}"
            )
        print()
    print("none = images without any detected pixel; s/img = detection time per image (estimated:")
    print("including the direction estimate).")
    n_given = sum(len(r.given_deg) for r in results)
    hit1 = sum(direction_hits(r.given_deg, r.estimated_deg[:1]) for r in results)
    hit3 = sum(direction_hits(r.given_deg, r.estimated_deg) for r in results)
    print(
        f"labelled directions: {n_given} in {len(results)} images; within 3° of the strongest "
        f"estimated direction: {hit1}, of one of the 3 estimated: {hit3}"
    )
    summary["directions"] = {"labelled": n_given, "hit_top1": hit1, "hit_top3": hit3}
    return summary


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--data", type=Path, required=True, help="folder with PLDU/ and PLDM/")
    parser.add_argument("--export_from", type=Path, help="PLD-UAV git dir to export DATA from")
    parser.add_argument("--json", type=Path, help="write the summary and per-image results")
    parser.add_argument("--tolerance_px", type=float, default=2.0)
    parser.add_argument("--subsets", nargs="+", default=list(SUBSETS), choices=SUBSETS)
    parser.add_argument("--limit", type=int, help="only the first N images of each subset")
    parser.add_argument("--overlays", type=Path, help="write <subset>_<n>_<mode>.png overlays")
    args = parser.parse_args()

    if args.export_from is not None:
        n = export_from_git(args.export_from, args.data)
        print(f"exported {n} files from {args.export_from} to {args.data}")
    if args.overlays:
        args.overlays.mkdir(parents=True, exist_ok=True)
    results: list[ImageResult] = []
    for subset in args.subsets:
        items = test_items(args.data, subset)[: args.limit]
        if not items:
            raise SystemExit(f"{args.data / subset}: no test/*.jpg with test_gt/*.mat")
        for name, img_path, gt_path in items:
            image, labels = load_image(img_path), load_labels(gt_path)
            if image.shape[:2] != labels.shape:
                raise SystemExit(f"{img_path}: image {image.shape} but labels {labels.shape}")
            res, masks, truth = run_image(subset, name, image, labels, args.tolerance_px)
            results.append(res)
            if args.overlays:
                for mode in ("given", "estimated"):
                    path = args.overlays / f"{subset}_{name}_{mode}.png"
                    write_overlay(path, image, masks[mode], truth, args.tolerance_px)
    summary = print_table(results, args.tolerance_px)
    if args.json:
        per_image = [
            {
                "subset": r.subset,
                "name": r.name,
                "given_deg": r.given_deg,
                "estimated_deg": r.estimated_deg,
                "seconds": r.seconds,
                "scores": {
                    m: {
                        t: {**vars(c), "precision": c.precision, "recall": c.recall, "f1": c.f1}
                        for t, c in tc.items()
                    }
                    for m, tc in r.counts.items()
                },
            }
            for r in results
        ]
        out = {"tolerance_px": args.tolerance_px, "summary": summary, "images": per_image}
        args.json.write_text(json.dumps(out, indent=1, allow_nan=True))
        print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
