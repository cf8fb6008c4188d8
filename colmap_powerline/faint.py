"""Wires too faint for the line detector, found from the line evidence of every view at once.

The pairs match what the line detector marks in each image, and tracing looks for a wire
where a curve predicts it. A shield wire half a pixel wide over ploughed soil stays under the
detector's contrast threshold in every image, so no pair matches it and no curve predicts
it; yet all the views together see it. The line template's response, divided by its local
level (the detector's contrast normalisation), averaged along a wire's whole projection and
over every view that sees it, stands far out of its surroundings: on the shared generator's
two-strip flight over soil (seed 11), the normalised response averages 0.6-1.0 of its local
level along the shield's true place in each view, where a single template finds it at 6 %
of its places.

So each line's cross-section is swept. Hypotheses are the line's longest wire moved across
and up, with its sag changed (the catenary through its ends' heights, moved up as much).
A line of several spans (a corridor tile holds 3-5) is swept along each stretch a confirmed
wire covers that the sweeps before did not: the longest wire's first, then the longest of
the rest that runs mostly past what is swept (:func:`sweep_refs`), each across the wires
that run along some of its stretch. On the real road flight the longest wire covers one
span and 10 m of the next, and the other spans' line evidence went unswept.
Each is sampled along its stretch and projected into every view; its evidence is the mean
normalised response over every sample every view sees of it (a view of an area survey sees
a fifth of a span, one of a corridor most of it), with every confirmed wire's image masked
out (a hypothesis lying along a confirmed wire's image in some views would otherwise borrow
its response). A view's response is taken as its highest (bright wires) or lowest (dark)
within half a step across the wire's image, so that a wire between two cells, or a pixel off
in a view's pose, is not missed: a blur would cancel the template's ridge against its
negative side lobes. Each hypothesis is judged against the median of those within
``BACKGROUND`` of it (what varies slowly over the cross-section, the number of views, a
mask's edge, the ground under it, is no wire; a wire is a narrow peak), times the square
root of its samples, in robust standard deviations of the whole sweep (median absolute
deviation): chance peaks of a sweep of 10^4-10^5 cells stay near 4.5, so a hypothesis is
taken where its evidence is ``TraceOptions.faint_min_z`` or more. On soil seed 11 the shield
is the sweep's strongest peak, 15 sd, its hypothesis 2 cm from it after the refinement (a
quarter step apart, on the views' extremes within a pixel). Hypotheses a few metres off a
wire reach 6-10 sd too: the views of one strip see a wire as well from a few heights.

A hypothesis is only that: tracing then measures it in every view, with the response peaks
that stand out counted (the evidence is what the detector's length filter gives elsewhere),
and keeps it only where the views that would fix it find it, and more often than copies of
it moved across (``pipeline._faint_wires``).

Memory holds one view's maps per thread: each view is read, scored and let go, once for the
coarse sweep and once for the refinement.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt
from scipy.ndimage import median_filter

from .detect import DetectOptions, _to_gray, line_response
from .geometry import across_of
from .scene import Scene, SceneImage, read_image
from .wires import FittedWire

logger = logging.getLogger(__name__)

F64 = npt.NDArray[np.float64]
F32 = npt.NDArray[np.float32]

# Samples along a hypothesis (its projection is sampled there in every view).
NUM_SAMPLES = 100
# A view counts for a hypothesis where it sees at least this many of its samples (clear of
# the confirmed wires' images), and for the sweep where it sees as many of the line's
# longest wire's.
MIN_VIEW_SAMPLES = 10
# A hypothesis is judged where at least this many views see it.
MIN_VIEWS = 3
# The normalised response is clipped to this many local levels: a tower member or a road
# marking the hypothesis crosses adds no more than a wire would.
CLIP = 3.0
# The sweep's steps (model units): across, up, and the change of sag. Across the wire a
# step moves its image by the most (in a view overhead, up moves it only by the ratio of
# the view's offset to its distance), so across is swept finer.
STEP_ACROSS = 0.1
STEP = 0.2
SAG_STEPS = np.arange(-5, 6) * STEP
# The cross-section swept: this far beside the line's outer wires, below its lowest and above
# its highest (shield wires hang 3-10 m above the top conductors).
MARGIN_ACROSS = 3.0
MARGIN_BELOW = 2.0
MARGIN_ABOVE = 10.0
# A hypothesis's evidence is judged against the median of the hypotheses this far around it.
BACKGROUND = 1.0
# At most this many hypotheses per line, each this far (across or up) from the others.
MAX_HYPOTHESES = 4
SEPARATION = 1.0
# OpenCV's remap takes images and maps of fewer rows and columns than this.
SHRT_MAX = 32767
# A view's confirmed wires are masked this many pixels beyond the template's side taps.
MASK_PAD_PX = 2


@dataclass(frozen=True)
class _View:
    """One view's normalised line response over the swept region, as the highest (bright
    wires) and lowest (dark wires) value within ``radius`` pixels across the wire's image,
    so that a wire between two cells, or a pixel off in this view's pose, is not missed
    (NaN: masked). The response's side lobes are negative, so a blur would cancel the wire's
    ridge: the neighbourhood's extreme keeps it."""

    image: SceneImage
    maps: tuple[F32, F32]  # (bright, dark)
    x0: int
    y0: int


@dataclass(frozen=True)
class _Lattice:
    """Hypotheses to score: every (across, up, sag step), sampled along the ref's stretch
    (``points``: the middle sag step's, one extra height row for the derivative)."""

    shape: tuple[int, int, int]  # (A, Z, K)
    points: F64  # (A, Z + 1, S, 3)
    delta: F32  # (K, S) each sag step's height minus the middle one's


@dataclass(frozen=True)
class FaintHypothesis:
    """A wire the views' line evidence puts in the line's cross-section."""

    wire: FittedWire  # without points, over its sweep's ref's stretch
    z_score: float  # its evidence in robust standard deviations of the sweep's
    cells: int  # how many hypotheses the sweep judged (both polarities)
    ref_id: int  # the wire_id of the confirmed wire whose stretch was swept


def _through_ends(ref: FittedWire, k: int) -> tuple[float, float, float]:
    """(a, s0, z0): the catenary through the ref's end heights with its sag changed by
    ``SAG_STEPS[k]`` (parabola approximation for ``a``: sag = span^2 / (8 a))."""
    lo, hi = ref.s_range
    span, mid = hi - lo, 0.5 * (lo + hi)
    z_lo, z_hi = (float(v) for v in ref.z_at(np.array([lo, hi])))
    sag = 0.5 * (z_lo + z_hi) - float(ref.z_at(np.array([mid]))[0])
    a = span**2 / (8.0 * max(sag + float(SAG_STEPS[k]), 1e-3 * span))
    # z(hi) - z(lo) = 2 a sinh((mid - s0) / a) sinh(span / (2 a)).
    s0 = mid - a * float(np.arcsinh((z_hi - z_lo) / (2.0 * a * np.sinh(span / (2.0 * a)))))
    z0 = z_lo - a * (float(np.cosh((lo - s0) / a)) - 1.0)
    return a, s0, z0


def _sag_heights(ref: FittedWire, s: F64) -> F64:
    """(K, S) the heights at ``s`` of the catenaries through the ref's ends, one per sag
    step."""
    out = np.empty((len(SAG_STEPS), len(s)))
    for k in range(len(SAG_STEPS)):
        a, s0, z0 = _through_ends(ref, k)
        out[k] = z0 + a * (np.cosh((s - s0) / a) - 1.0)
    return out


def _hypothesis(ref: FittedWire, across: float, dz: float, k: int) -> FittedWire:
    """The swept cell (across, dz, sag step k) as a catenary without points."""
    a, s0, z0 = _through_ends(ref, k)
    return dataclasses.replace(
        ref,
        wire_id=-1,
        plane_origin_xy=ref.plane_origin_xy + across * across_of(ref.plane_direction_xy),
        catenary_a=float(a),
        s0=float(s0),
        z0=float(z0 + dz),
        point_indices=np.zeros(0, np.int64),
        rms_residual=0.0,
    )


def _stretch(ref: FittedWire, w: FittedWire) -> tuple[float, float]:
    """Where ``w`` runs along ``ref``'s plane (its ends' positions along it)."""
    s, _, _ = ref.plane_coords(w.points(np.array(w.s_range)))
    return float(s.min()), float(s.max())


def _past(covered: Sequence[tuple[float, float]], lo: float, hi: float) -> float:
    """How much of (lo, hi) lies outside every stretch in ``covered``."""
    edges = np.unique(np.clip([lo, hi, *[v for c in covered for v in c]], lo, hi))
    mids = 0.5 * (edges[1:] + edges[:-1])
    out = np.ones(len(mids), bool)
    for a, b in covered:
        out &= (mids < a) | (mids > b)
    return float(np.sum(np.diff(edges)[out]))


def sweep_refs(wires: Sequence[FittedWire]) -> list[FittedWire]:
    """The wires whose stretches are swept: the longest, then each next longest that runs
    at least half its length past the stretches taken before (the next span's conductor
    beside one traced across a pole; not a piece within a wire's stretch)."""
    by_length = sorted(wires, key=lambda w: w.s_range[0] - w.s_range[1])
    taken: list[FittedWire] = []
    covered: list[tuple[float, float]] = []
    for w in by_length:
        lo, hi = _stretch(by_length[0], w)
        if not taken or _past(covered, lo, hi) >= 0.5 * (hi - lo):
            taken.append(w)
            covered.append((lo, hi))
    return taken


def _cross_section(ref: FittedWire, wires: Sequence[FittedWire]) -> tuple[F64, F64]:
    """The swept offsets from the ref: across (A,) ``STEP_ACROSS`` apart and up (Z,)
    ``STEP`` apart, around the wires that run along some of the ref's stretch."""
    across = []
    up = []
    for w in wires:
        lo, hi = _stretch(ref, w)
        if hi < ref.s_range[0] or lo > ref.s_range[1]:
            continue
        _, a, dz = ref.plane_coords(w.points(np.array([0.5 * sum(w.s_range)])))
        across.append(float(a[0]))
        up.append(float(dz[0]))
    a_lo, a_hi = min(across) - MARGIN_ACROSS, max(across) + MARGIN_ACROSS
    z_lo, z_hi = min(up) - MARGIN_BELOW, max(up) + MARGIN_ABOVE
    return (
        np.arange(np.floor(a_lo / STEP_ACROSS), np.ceil(a_hi / STEP_ACROSS) + 1) * STEP_ACROSS,
        np.arange(np.floor(z_lo / STEP), np.ceil(z_hi / STEP) + 1) * STEP,
    )


def _view(
    image: SceneImage,
    ref: FittedWire,
    wires: Sequence[FittedWire],
    corners: F64,
    detect: DetectOptions,
    coarse: bool,
) -> _View | None:
    """The view's normalised line response over the region the swept hypotheses cover
    (``coarse``: its extremes within half a coarse step, else within a pixel), or None where
    it sees fewer than ``MIN_VIEW_SAMPLES`` of the line's longest wire's samples."""
    s = np.linspace(*ref.s_range, NUM_SAMPLES)
    uv, depth, inside = image.project(ref.points(s))
    if inside.sum() < MIN_VIEW_SAMPLES:
        return None
    # The region: every corner of the swept cross-section along the in-view stretch.
    q, _, ok = image.project(corners)
    q = q[ok & np.all(np.isfinite(q), axis=1)]
    if len(q) == 0:
        return None
    pad = detect.template_length_px + detect.side_offset_px
    x0, y0 = (max(int(v) - pad, 0) for v in q.min(axis=0))
    x1 = min(int(q[:, 0].max()) + pad, image.width)
    y1 = min(int(q[:, 1].max()) + pad, image.height)
    if x1 - x0 < 2 * pad or y1 - y0 < 2 * pad:
        return None
    grey = _to_gray(read_image(image.path, cv2.IMREAD_GRAYSCALE))[y0:y1, x0:x1]
    d = uv[inside][-1] - uv[inside][0]  # the wire's direction in the view
    response = line_response(grey, float(np.degrees(np.arctan2(d[1], d[0]))), detect)
    win = detect.contrast_window_px
    level = cv2.blur(np.abs(response), (win, win), borderType=cv2.BORDER_REFLECT)
    sharp = np.clip(response / np.maximum(level, 1e-6), -CLIP, CLIP).astype(np.float32)
    px_per_unit = image.focal_px / float(np.median(depth[inside]))
    mask = np.zeros(sharp.shape, np.uint8)
    width = 2 * (detect.side_offset_px + MASK_PAD_PX) + 1 + int(np.ceil(STEP_ACROSS * px_per_unit))
    for w in wires:
        p, _, okw = image.project(w.polyline(2.0 / px_per_unit))
        p = p[okw] - [x0, y0]
        if len(p) > 1:
            cv2.polylines(mask, [np.round(p).astype(np.int32)], False, 1, thickness=width)
    sharp[mask > 0] = 0.0

    def extremes(radius: int) -> tuple[F32, F32]:
        # Across the wire's image only: along it the template has averaged already, and
        # every pixel more in the neighbourhood raises the noise's extreme.
        size = 2 * radius + 1
        across = np.zeros((size, size), np.uint8)
        t = np.array([-d[1], d[0]]) / max(float(np.hypot(*d)), 1e-9)
        ends = np.round(radius + np.outer([-radius, radius], t)).astype(np.int32)
        cv2.line(across, tuple(int(v) for v in ends[0]), tuple(int(v) for v in ends[1]), 1)
        hi, lo = cv2.dilate(sharp, across), cv2.erode(sharp, across)
        hi[mask > 0] = np.nan
        lo[mask > 0] = np.nan
        return hi, lo

    # Half a coarse step, in pixels at the wire's distance in this view.
    radius = max(int(round(0.5 * STEP_ACROSS * px_per_unit)), 1) if coarse else 1
    return _View(image, extremes(radius), x0, y0)


def _lattice(ref: FittedWire, across: F64, up: F64, sag_steps: Sequence[int]) -> _Lattice:
    """The hypotheses (across, up, sag step) to score, as :class:`_Lattice`."""
    s = np.linspace(*ref.s_range, NUM_SAMPLES)
    heights = _sag_heights(ref, s)[list(sag_steps)]  # (K, S)
    mid = len(sag_steps) // 2
    normal = across_of(ref.plane_direction_xy)
    xy = (
        ref.plane_origin_xy
        + across[:, None, None] * normal
        + s[None, :, None] * ref.plane_direction_xy
    )
    points = np.empty((len(across), len(up) + 1, len(s), 3))
    points[..., :2] = xy[:, None]
    # One extra height above the last: the derivative in height at every row.
    points[..., 2] = np.r_[up, up[-1] + STEP][None, :, None] + heights[mid][None, None, :]
    return _Lattice(
        (len(across), len(up), len(sag_steps)),
        points,
        (heights - heights[mid]).astype(np.float32),
    )


def _remap(image: F32, x: F32, y: F32) -> F32:
    """``image`` sampled (bilinear) at (x, y), of any shape: OpenCV's remap takes fewer than
    2^15 rows and columns, so the rows go in blocks."""
    rows = SHRT_MAX - 1
    return np.concatenate(
        [
            cv2.remap(
                image,
                x[i : i + rows],
                y[i : i + rows],
                cv2.INTER_LINEAR,
                borderMode=cv2.BORDER_REPLICATE,
            )  # fmt: skip
            for i in range(0, len(x), rows)
        ]
    )


def _view_scores(view: _View, lattice: _Lattice) -> tuple[F64, F64]:
    """(2, A, Z, K) the sum of the view's response over each hypothesis's samples it sees,
    bright and dark, and (A, Z, K) how many it sees (0 where fewer than
    ``MIN_VIEW_SAMPLES``: a few metres at an image's edge say little).

    The view projects the hypotheses of the middle sag step once; the others' images are
    that moved by the projection's derivative in height times their height difference
    (under a metre: the derivative changes by the ratio of that to the view's distance)."""
    pts = lattice.points
    n_s = pts.shape[2]
    uv, _, ok = view.image.project(pts.reshape(-1, 3))
    uv = uv.reshape(pts.shape[:3] + (2,)).astype(np.float32)
    ok = ok.reshape(pts.shape[:3])
    base, der = uv[:, :-1], (uv[:, 1:] - uv[:, :-1]) / STEP  # (A, Z, S, 2)
    ok = (ok[:, :-1] & ok[:, 1:]).reshape(-1, n_s)
    h, w = view.maps[0].shape
    total = np.zeros((2,) + lattice.shape)
    seen = np.zeros(lattice.shape)
    for j, delta in enumerate(lattice.delta):
        pos = base + der * delta[None, None, :, None]
        x = (pos[..., 0] - view.x0).reshape(-1, n_s)
        y = (pos[..., 1] - view.y0).reshape(-1, n_s)
        inside = ok & (x >= 0) & (y >= 0) & (x <= w - 1) & (y <= h - 1)
        vals = [np.where(inside, _remap(m, x, y), np.nan) for m in view.maps]
        n = np.isfinite(vals[0]).sum(axis=1)
        use = n >= MIN_VIEW_SAMPLES
        for p, v in enumerate(vals):
            total[p, ..., j] = np.where(use, np.nansum(v, axis=1), 0.0).reshape(lattice.shape[:2])
        seen[..., j] = np.where(use, n, 0).reshape(lattice.shape[:2])
    return total, seen


def _evidence(
    scene: Scene,
    ref: FittedWire,
    wires: Sequence[FittedWire],
    corners: F64,
    detect: DetectOptions,
    lattices: Sequence[_Lattice],
    coarse: bool,
    num_threads: int,
) -> tuple[list[tuple[F64, F64, F64]], list[Path]]:
    """Per lattice, (2, A, Z, K) each hypothesis's evidence, bright and dark (its mean
    normalised response over every sample every view sees of it: a view of a grid flight
    sees a fifth of a span, one of a corridor flight most of it), (A, Z, K) the number of
    those samples and the number of views; and the images decoded. Each view's maps are
    made, used and let go in turn: memory holds a view per thread, whatever the survey."""

    def one(image: SceneImage) -> list[tuple[F64, F64]] | None:
        view = _view(image, ref, wires, corners, detect, coarse)
        return None if view is None else [_view_scores(view, lat) for lat in lattices]

    totals = [
        (np.zeros((2,) + lat.shape), np.zeros(lat.shape), np.zeros(lat.shape)) for lat in lattices
    ]
    decoded = []
    with ThreadPoolExecutor(max_workers=num_threads) as pool:
        for image, res in zip(scene.images, pool.map(one, scene.images), strict=True):
            if res is None:
                continue
            decoded.append(image.path)
            for (total, count, views), (t, n) in zip(totals, res, strict=True):
                total += t
                count += n
                views += n > 0
    out = [(np.where(n > 0, t / np.maximum(n, 1), 0.0), n, v) for t, n, v in totals]
    return out, decoded


def faint_hypotheses(
    scene: Scene,
    wires: Sequence[FittedWire],
    detect: DetectOptions,
    min_z: float,
    num_threads: int = 2,
) -> tuple[list[FaintHypothesis], list[Path]]:
    """Wires of the line the views' line evidence puts in its cross-section, apart from the
    confirmed ``wires`` (module docstring): each sweep's best first, the sweeps in the order
    of :func:`sweep_refs`; and the images decoded (each once)."""
    out: list[FaintHypothesis] = []
    decoded: dict[Path, None] = {}
    for ref in sweep_refs(wires):
        hyps, dec = _sweep(scene, ref, wires, detect, min_z, num_threads)
        out += hyps
        decoded.update(dict.fromkeys(dec))
    return out, list(decoded)


def _sweep(
    scene: Scene,
    ref: FittedWire,
    wires: Sequence[FittedWire],
    detect: DetectOptions,
    min_z: float,
    num_threads: int,
) -> tuple[list[FaintHypothesis], list[Path]]:
    """The hypotheses of the sweep along ``ref``'s stretch, best first; and the images
    decoded."""
    across, up = _cross_section(ref, wires)
    s = np.linspace(*ref.s_range, NUM_SAMPLES)
    heights = _sag_heights(ref, s)
    base = ref.points(s)[:, :2]
    normal = across_of(ref.plane_direction_xy)
    corners = np.concatenate(
        [
            np.c_[base + a * normal, h + dz]
            for a in (across[0], across[-1])
            for dz in (up[0], up[-1])
            for h in (heights.min(axis=0), heights.max(axis=0))
        ]
    )
    ks = list(range(len(SAG_STEPS)))
    [(scores, count, n_views)], decoded = _evidence(
        scene, ref, wires, corners, detect, [_lattice(ref, across, up, ks)], True, num_threads
    )
    if len(decoded) < MIN_VIEWS:
        return [], decoded
    # Per polarity, the evidence in robust standard deviations of the sweep's own; the
    # dark one's sign turned, so that a wire stands out upwards in both.
    valid = n_views >= MIN_VIEWS
    if valid.sum() < 100:
        return [], decoded
    z_scores = []
    for bright, score in zip((True, False), scores, strict=True):
        # Against the evidence of the hypotheses around it (within BACKGROUND across and
        # up): what varies slowly over the cross-section (more or fewer views, a confirmed
        # wire's mask, the ground's texture under it) is no wire; a wire is a narrow peak.
        # The mean over n samples is sqrt(n) times steadier than one.
        filled = np.where(valid, score, float(np.median(score[valid])))
        size = (
            2 * int(round(BACKGROUND / STEP_ACROSS)) + 1,
            2 * int(round(BACKGROUND / STEP)) + 1,
            1,
        )
        local = median_filter(filled, size=size, mode="nearest")
        t = (score - local) * np.sqrt(count)
        spread = 1.4826 * float(np.median(np.abs(t[valid] - np.median(t[valid]))))
        sign = 1.0 if bright else -1.0
        z_scores.append(np.where(valid, sign * t / spread, 0.0) if spread > 0 else 0 * score)
    z_all = np.stack(z_scores)  # (2, A, Z, K)
    n_cells = 2 * int(valid.sum())
    peaks: list[tuple[int, int, int, int]] = []
    for flat in np.argsort(-z_all, axis=None):
        p, i, j, k = (int(v) for v in np.unravel_index(flat, z_all.shape))
        if z_all[p, i, j, k] < min_z or len(peaks) >= MAX_HYPOTHESES:
            break
        if not any(
            abs(across[i] - across[b]) < SEPARATION and abs(up[j] - up[c]) < SEPARATION
            for _, b, c, _ in peaks
        ):
            peaks.append((p, i, j, k))
    if not peaks:
        return [], decoded
    # Each refined on the fine maps, around its cell: a quarter step apart across and up,
    # and each neighbouring sag step projected as it is (no derivative).
    grids = []
    for _, i, j, k in peaks:
        fine_a = across[i] + np.arange(-4, 5) * STEP_ACROSS / 4
        fine_u = up[j] + np.arange(-6, 7) * STEP / 4
        for kk in (k - 1, k, k + 1):
            if 0 <= kk < len(SAG_STEPS):
                grids.append((fine_a, fine_u, kk))
    fine, _ = _evidence(
        scene,
        ref,
        wires,
        corners,
        detect,
        [_lattice(ref, a, u, [kk]) for a, u, kk in grids],
        False,
        num_threads,
    )
    out: list[FaintHypothesis] = []
    for p, i, j, k in peaks:
        sign = 1.0 if p == 0 else -1.0
        best, where = -np.inf, (0.0, 0.0, k)
        for (a, u, kk), (f, _, n) in zip(grids, fine, strict=True):
            if abs(a[4] - across[i]) > 1e-9 or abs(u[6] - up[j]) > 1e-9:
                continue  # another peak's grid
            cell = np.where(n >= MIN_VIEWS, sign * f[p], -np.inf)[..., 0]
            b, c = np.unravel_index(int(np.argmax(cell)), cell.shape)
            if cell[b, c] > best:
                best, where = float(cell[b, c]), (float(a[b]), float(u[c]), kk)
        hyp = _hypothesis(ref, *where)
        out.append(FaintHypothesis(hyp, float(z_all[p, i, j, k]), n_cells, ref.wire_id))
        logger.info(
            "faint: %s line evidence %.1f sd at %.2f across and %.2f up from wire %d's ends "
            "(sag %+.1f), in %d views",
            "bright" if p == 0 else "dark",
            z_all[p, i, j, k],
            where[0],
            where[1],
            ref.wire_id,
            SAG_STEPS[where[2]],
            int(n_views[i, j, k]),
        )
    return out, decoded
