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
from collections.abc import Collection, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt
from scipy.interpolate import RegularGridInterpolator
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
    grey_image: F32 | None = None,
) -> _View | None:
    """The view's normalised line response over the region the swept hypotheses cover
    (``coarse``: its extremes within half a coarse step, else within a pixel), or None where
    it sees fewer than ``MIN_VIEW_SAMPLES`` of the line's longest wire's samples.
    ``grey_image``: the view's grey image, where it was read already."""
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
    if grey_image is None:
        grey_image = _to_gray(read_image(image.path, cv2.IMREAD_GRAYSCALE))
    grey = grey_image[y0:y1, x0:x1]
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


# --- Stretches of a known wire that no single view shows -----------------------------------
#
# Tracing measures a place where three views or more each find the wire; a wire at 2-3 sd
# per metre in each view (the package's `angle` layout's 20 mm shields over vegetation) is
# found at some places and not at the next. Along a span-wire's curve the views' line
# evidence summed over a stretch still stands out of its surroundings where tracing found
# nothing: on that layout's shields, 4-6.7 robust sd over 2 m in 4-5 views along 12-16 m
# past where tracing stopped, the curve continued lying within 0.02-0.08 m of the wire.
# So each unmeasured stretch between a span-wire's attachments, next to a measured one, is
# judged by that evidence, at the curve against the offsets around it.
STRETCH_M = 2.0  # model units
STRETCH_SAMPLES = 20
# The curve's neighbourhood (the wire within it) and the offsets that are its background.
NEAR_M = 0.15
FAR_M = 0.35
# The offsets scored: every STEP_ACROSS out to 1.5 across and 1.0 up, and within NEAR_M
# every FINE_STEP (the peak's place: a pixel is 2-5 cm at the half-scale GSD).
FINE_STEP = 0.025


def _offsets(reach: float) -> F64:
    coarse = np.arange(np.ceil((NEAR_M + 1e-9) / STEP_ACROSS), round(reach / STEP_ACROSS) + 1)
    fine = np.arange(-round(NEAR_M / FINE_STEP), round(NEAR_M / FINE_STEP) + 1) * FINE_STEP
    return np.round(np.r_[-coarse[::-1] * STEP_ACROSS, fine, coarse * STEP_ACROSS], 6)


OFFSETS_ACROSS = _offsets(1.5)
OFFSETS_UP = _offsets(1.0)
# Stretches this close to a wire's attachment are left alone (its insulator, the support's
# members: past a tower the same evidence runs on along the members).
ATTACHMENT_MARGIN_M = 1.0


@dataclass(frozen=True)
class _Stretches:
    """One wire's stretches: the samples' positions along it, which stretches its points
    measure, and every offset's samples (A, U, M, 3)."""

    s: F64  # (M,) the samples along the wire, STRETCH_SAMPLES per stretch
    measured: npt.NDArray[np.bool_]  # (B,)
    points: F64  # (A, U, M, 3)


def _stretches(wire: FittedWire, pts_in_world: F64) -> _Stretches | None:
    """The wire's stretches between its attachments (ATTACHMENT_MARGIN_M inside), or None
    where none lies unmeasured next to a measured one. A stretch is measured where its
    points cover half of its tenths."""
    lo, hi = wire.s_range[0] + ATTACHMENT_MARGIN_M, wire.s_range[1] - ATTACHMENT_MARGIN_M
    n = int((hi - lo) // STRETCH_M)
    if n < 2 or len(wire.point_indices) == 0:
        return None
    step = STRETCH_M / STRETCH_SAMPLES
    s = lo + (np.arange(n * STRETCH_SAMPLES) + 0.5) * step
    own = wire.plane_coords(pts_in_world[wire.point_indices])[0]
    cell = np.floor((own - lo) / step).astype(np.int64)
    held = np.zeros(n * STRETCH_SAMPLES, bool)
    held[cell[(cell >= 0) & (cell < len(held))]] = True
    measured = held.reshape(n, STRETCH_SAMPLES).mean(axis=1) >= 0.5
    if measured.all() or not measured.any():
        return None
    normal = across_of(wire.plane_direction_xy)
    offsets = np.zeros((len(OFFSETS_ACROSS), len(OFFSETS_UP), 3))
    offsets[..., :2] = OFFSETS_ACROSS[:, None, None] * normal
    offsets[..., 2] = OFFSETS_UP[None, :]
    return _Stretches(s, measured, wire.points(s)[None, None] + offsets[:, :, None, :])


def _stretch_scores(
    image: SceneImage,
    grey: F32,
    wire: FittedWire,
    others: Sequence[FittedWire],
    st: _Stretches,
    detect: DetectOptions,
) -> tuple[F64, F64, F64] | None:
    """One view's sums over each stretch's samples at every offset, bright and dark
    (2, A, U, B), how many it sees unmasked (A, U, B), and whether it sees the curve's
    (B,): at least half of a stretch's samples; None where it sees too little of it."""
    a, u, m = st.points.shape[:3]
    n = len(st.measured)
    corners = st.points[[0, -1]][:, [0, -1]].reshape(-1, 3)
    ref = dataclasses.replace(wire, s_range=(float(st.s[0]), float(st.s[-1])))
    view = _view(image, ref, others, corners, detect, coarse=False, grey_image=grey)
    if view is None:
        return None
    uv, _, ok = image.project(st.points.reshape(-1, 3))
    h, w = view.maps[0].shape
    x = (uv[:, 0] - view.x0).astype(np.float32)
    y = (uv[:, 1] - view.y0).astype(np.float32)
    ok &= np.isfinite(x) & np.isfinite(y) & (x >= 0) & (y >= 0) & (x <= w - 1) & (y <= h - 1)
    x, y = np.where(ok, x, 0.0).astype(np.float32), np.where(ok, y, 0.0).astype(np.float32)
    sums = np.zeros((2, a, u, n))
    seen = np.zeros(0, bool)  # both maps are masked alike: counted from the first
    for p, image_map in enumerate(view.maps):
        v = _remap(image_map, x.reshape(-1, STRETCH_SAMPLES), y.reshape(-1, STRETCH_SAMPLES))
        v = np.where(ok.reshape(v.shape), v, np.nan).reshape(a, u, n, STRETCH_SAMPLES)
        if p == 0:
            seen = np.isfinite(v)
        sums[p] = np.where(seen, v, 0.0).sum(axis=-1)
    count = seen.sum(axis=-1).astype(np.float64)
    sees = count[a // 2, u // 2] >= STRETCH_SAMPLES // 2
    return sums, count, sees.astype(np.float64)


def _z_scores(mean: F64) -> tuple[F64, npt.NDArray[np.int64], F64]:
    """(B,) each stretch's evidence at the curve (:func:`_around` at offset 0); (B, 2)
    where in (A, U) its highest lies; and (B,) the evidence on the curve itself."""
    n = mean.shape[-1]
    z, on = np.zeros(n), np.zeros(n)
    at = np.zeros((n, 2), np.int64)
    for b in range(n):
        z[b], at[b], on[b] = _around(mean[:, :, b], (0.0, 0.0))
    return z, at, on


def _around(m: F64, centre: tuple[float, float]) -> tuple[float, npt.NDArray[np.int64], float]:
    """A stretch's evidence ``m`` (A, U) at the offset ``centre`` (across, up): the highest
    mean response within NEAR_M of it, less the median of the offsets FAR_M or more from it,
    in their robust standard deviations (0 where a higher one lies just outside, within
    FAR_M, by a robust sd: the wire runs beside it there, and what lies within NEAR_M is the
    flank of its peak); the cell (A, U) of that highest; and the evidence at the cell
    nearest ``centre`` itself, likewise."""
    da = np.abs(OFFSETS_ACROSS - centre[0])[:, None]
    du = np.abs(OFFSETS_UP - centre[1])[None, :]
    near = (da <= NEAR_M + 1e-9) & (du <= NEAR_M + 1e-9)
    around = (da <= FAR_M + 1e-9) & (du <= FAR_M + 1e-9)
    far = (da >= FAR_M - 1e-9) | (du >= FAR_M - 1e-9)
    bg = m[far]
    med = float(np.median(bg))
    mad = 1.4826 * float(np.median(np.abs(bg - med))) + 1e-9
    best = np.where(near, m, -np.inf)
    at = np.array(np.unravel_index(int(np.argmax(best)), m.shape), np.int64)
    on = (float(m[int(np.argmin(da[:, 0])), int(np.argmin(du[0]))]) - med) / mad
    if np.max(np.where(around & ~near, m, -np.inf)) > best[tuple(at)] + mad:
        return 0.0, at, on
    return (float(best[tuple(at)]) - med) / mad, at, on


def evidence_stretches(
    scene: Scene,
    wires: Sequence[FittedWire],
    pts_in_world: F64,
    detect: DetectOptions,
    min_z: float,
    min_views: int,
    num_threads: int,
    only: Collection[int] | None = None,
) -> tuple[list[F64], list[npt.NDArray[np.int32]], list[Path]]:
    """Per wire, the points (N, 3) the views' summed line evidence measures along its
    unmeasured stretches between its attachments, and how many views see each (N,); and
    the images read.

    Each stretch (STRETCH_M) of a span-wire is scored in every view that sees it, the other
    wires' images masked: the normalised line response summed over its samples at the wire's
    curve and at offsets around it (OFFSETS_ACROSS, OFFSETS_UP), over the views together
    (:func:`_around`, of the wire's polarity where it is measured), around the curve or,
    past its measured stretches at either end, around the curve continued as the evidence
    prefers (:func:`_continued`). An unmeasured stretch is taken where its evidence is
    ``min_z`` or more in ``min_views`` views or more, next to a measured stretch or a
    stretch so taken, or past stretches too few views see to judge (from its measured
    stretches on, one after another: a stretch on its own says little). Its
    points lie where it was judged, moved to the evidence's peak near it where that stands
    a robust sd higher (a parabola through the peak and its neighbours, within NEAR_M), as
    densely as the wire's own points. ``only``: the indices of the wires judged (all by
    default; the others' images are masked all the same)."""
    plans = [
        _stretches(w, pts_in_world) if only is None or k in only else None
        for k, w in enumerate(wires)
    ]
    todo = [k for k, p in enumerate(plans) if p is not None]
    pts_out: list[F64] = [np.zeros((0, 3)) for _ in wires]
    views_out: list[npt.NDArray[np.int32]] = [np.zeros(0, np.int32) for _ in wires]
    if not todo:
        return pts_out, views_out, []

    def one(image: SceneImage) -> dict[int, tuple[F64, F64, F64]]:
        grey: F32 | None = None
        out: dict[int, tuple[F64, F64, F64]] = {}
        for k in todo:
            st = plans[k]
            assert st is not None
            _, _, ok = image.project(st.points[st.points.shape[0] // 2, st.points.shape[1] // 2])
            if ok.sum() < MIN_VIEW_SAMPLES:
                continue
            if grey is None:
                grey = _to_gray(read_image(image.path, cv2.IMREAD_GRAYSCALE))
            others = [w for j, w in enumerate(wires) if j != k]
            res = _stretch_scores(image, grey, wires[k], others, st, detect)
            if res is not None:
                out[k] = res
        return out

    totals: dict[int, list[F64]] = {}
    decoded: list[Path] = []
    with ThreadPoolExecutor(max_workers=num_threads) as pool:
        for image, res in zip(scene.images, pool.map(one, scene.images), strict=True):
            if res:
                decoded.append(image.path)
            for k, parts in res.items():
                if k not in totals:
                    totals[k] = [np.zeros_like(x) for x in parts]
                for total, x in zip(totals[k], parts, strict=True):
                    total += x
    for k, (sums, count, views) in totals.items():
        st = plans[k]
        assert st is not None
        mean = sums / np.maximum(count, 1)[None]
        scored = [_z_scores(sign * mean[p]) for p, sign in ((0, 1.0), (1, -1.0))]
        # The wire's polarity: its evidence where it is measured.
        p = int(np.argmax([np.median(z[st.measured]) for z, _, _ in scored]))
        m = (1.0 if p == 0 else -1.0) * mean[p]
        # Past the measured stretches at either end, each stretch is judged around the
        # curve continued as the evidence there says (:func:`_continued`), elsewhere
        # around the curve itself.
        centre, reach = _continued(m, st.measured, views, min_views)
        z, at, on = (x.copy() for x in scored[p])
        # Around the curve continued where the evidence holds on it; around the curve the
        # evidence prefers only where it does not (on the package's `angle` layout, judged
        # around the preferred curve everywhere, a shield's stretches were taken up to
        # 13 cm higher, which pulled its sag from 12 to 28 cm off).
        family = (z < min_z) & centre.any(axis=1)
        for b in np.flatnonzero(family):
            z[b], at[b], on[b] = _around(m[:, :, b], (centre[b, 0], centre[b, 1]))
        centre[~family] = 0.0
        # Out of reach, a stretch counts as one that does not hold (two end the run).
        taken = _walked((z >= min_z) & reach, (views >= min_views) | ~reach, st.measured)
        if not taken.any():
            continue
        spacing = _spacing(wires[k], pts_in_world)
        new, seen = [], []
        for b in np.flatnonzero(taken):
            # Where it is judged, unless the peak beside it stands a robust sd higher
            # (views overhead hardly tell heights apart: their evidence is flat along "up").
            cb = (float(centre[b, 0]), float(centre[b, 1]))
            da, du = _peak(m[:, :, b], at[b], cb) if z[b] - on[b] >= 1.0 else cb
            s = np.arange(st.s[b * STRETCH_SAMPLES] - 0.5 * STRETCH_M / STRETCH_SAMPLES,
                          st.s[(b + 1) * STRETCH_SAMPLES - 1], spacing)  # fmt: skip
            q = wires[k].points(s)
            q[:, :2] += da * across_of(wires[k].plane_direction_xy)
            q[:, 2] += du
            new.append(q)
            seen.append(np.full(len(q), int(views[b]), np.int32))
        pts_out[k] = np.concatenate(new)
        views_out[k] = np.concatenate(seen)
        logger.info(
            "evidence: wire %d: %d of its %d unmeasured %.0f m stretches measured by the "
            "views' line evidence together (%.1f-%.1f sd, %d-%d views), judged up to %.2f "
            "across and %.2f up from its curve",
            wires[k].wire_id,
            int(taken.sum()),
            int((~st.measured).sum()),
            STRETCH_M,
            float(z[taken].min()),
            float(z[taken].max()),
            int(views[taken].min()),
            int(views[taken].max()),
            float(np.abs(centre[taken, 0]).max()),
            float(centre[taken, 1][np.argmax(np.abs(centre[taken, 1]))]),
        )
    return pts_out, views_out, decoded


# The curves past a wire's measured stretches that the evidence may prefer to the curve
# continued: offsets from it growing from nothing where its measured stretches end, up by
# a slope and a curvature, across by a slope (a catenary fitted to part of a span is off
# past it by its slope's and its sag's errors: on the shared twolines seed 12 a shield's,
# fitted to 40 m of 101, lay 0.3 m under the wire 16 m on and 1.2 m under it at the far
# tower).
CONTINUED_UP_SLOPES = np.linspace(-0.06, 0.06, 25)  # per model unit along
CONTINUED_UP_CURVATURES = np.linspace(-0.0012, 0.0012, 13)  # per unit squared
CONTINUED_ACROSS_SLOPES = np.linspace(-0.02, 0.02, 9)
CONTINUED_CLIP = (-3.0, 10.0)  # each stretch's evidence counted within these (robust sd)
CONTINUED_MIN_RUN = 3  # measured stretches in a row that pin the curve


def _continued(
    m: F64, measured: npt.NDArray[np.bool_], views: F64, min_views: int
) -> tuple[F64, npt.NDArray[np.bool_]]:
    """(B, 2) the offset (across, up) around which each stretch of a wire is judged, and
    (B,) whether it lies within reach of the measured ones. Past
    its measured stretches at either end, the curve of the family above (offsets from
    nothing where the last run of CONTINUED_MIN_RUN measured stretches ends: on the shared
    twolines seed 12 a shield measured along 38 m lay 0.25 m off its curve at a 2 m piece
    traced 13 m past them) whose offsets hold the most evidence over that
    end's stretches seen by ``min_views`` views or more (``m`` (A, U, B): the mean response
    at each offset, in robust sd of each stretch's offsets, clipped to CONTINUED_CLIP),
    where it holds a robust sd a stretch more than the curve continued; elsewhere (0, 0).
    Past the measured stretches, a stretch is within reach no farther from them than they
    reach along the wire (a curve fitted to a length of wire foretells it about as far
    again: shared cross seed 6's shield, measured along 20 m, continued 30-50 m past them
    lay 0.3-0.7 m off the wire, and stretches of chance evidence there were taken)."""
    n = m.shape[-1]
    centre = np.zeros((n, 2))
    reach = np.ones(n, bool)
    idx = np.flatnonzero(measured)
    if len(idx) == 0:
        return centre, reach
    slope, curv, across = np.meshgrid(
        CONTINUED_UP_SLOPES, CONTINUED_UP_CURVATURES, CONTINUED_ACROSS_SLOPES, indexing="ij"
    )
    slope, curv, across = slope.ravel(), curv.ravel(), across.ravel()
    # The curve is pinned where runs of CONTINUED_MIN_RUN measured stretches or more hold
    # it; a short measured piece past them (tracing's, a few metres on) may lie off it.
    run = np.convolve(measured.astype(int), np.ones(CONTINUED_MIN_RUN, int), "valid")
    held = np.flatnonzero(run == CONTINUED_MIN_RUN)
    first, last = (held[0], held[-1] + CONTINUED_MIN_RUN - 1) if len(held) else (idx[0], idx[-1])
    for end, side in (
        (first, np.arange(idx[0] - 1, -1, -1)),
        (last, np.arange(idx[-1] + 1, n)),
    ):
        # How far past the end of the measured stretches that pin the curve each one's
        # middle lies.
        t_side = (np.abs(side - end) - 0.5) * STRETCH_M
        # No farther past them than the measured stretches reach along the wire.
        reach[side] = t_side <= (idx[-1] - idx[0] + 1) * STRETCH_M
        seen = side[(views[side] >= min_views) & reach[side]]
        t = t_side[(views[side] >= min_views) & reach[side]]
        if len(seen) < 2:
            continue
        score = np.zeros(len(slope))
        on_curve = 0.0
        for b, tb in zip(seen, t, strict=True):
            grid = m[:, :, b]
            med = float(np.median(grid))
            mad = 1.4826 * float(np.median(np.abs(grid - med))) + 1e-9
            zmap = np.clip((grid - med) / mad, *CONTINUED_CLIP)
            look = RegularGridInterpolator(
                (OFFSETS_ACROSS, OFFSETS_UP), zmap, bounds_error=False, fill_value=np.nan
            )
            v = look(np.c_[across * tb, slope * tb + curv * tb * tb])
            score += np.where(np.isfinite(v), v, CONTINUED_CLIP[0])
            on_curve += float(look([[0.0, 0.0]])[0])
        # Only where it stands a robust sd a stretch above the curve continued, as a peak
        # beside the curve must (views overhead see a wire's evidence as a ridge along
        # "up", and over its flat top some curve of the family always scores higher).
        # The best of the family: the one nearest the curve at the farthest stretch among
        # those about as good chose curves climbing with the evidence and coming back down
        # onto the curve there (shared twolines seed 12, its span's ends moved 0.1 m).
        k = int(np.argmax(score))
        if score[k] < on_curve + len(seen):
            continue
        centre[side, 0] = across[k] * t_side
        centre[side, 1] = slope[k] * t_side + curv[k] * t_side * t_side
    return centre, reach


def _walked(
    holds: npt.NDArray[np.bool_], judged: npt.NDArray[np.bool_], measured: npt.NDArray[np.bool_]
) -> npt.NDArray[np.bool_]:
    """(B,) the stretches taken: from the measured stretches on, one after another while
    the evidence ``holds``. A stretch too few views see (not ``judged``) is passed over,
    neither taken nor ending the run, and so is one stretch that does not hold where the
    next judged one does (on the shared twolines seed 12, a shield's stretches seen by two
    views, and one at 3.9 sd, lay between its measured ones and 30 m of stretches at
    4.2-7.7 sd); two in a row end it."""
    taken = np.zeros(len(holds), bool)
    for b in np.flatnonzero(measured):
        for step in (-1, 1):
            c, missed = b + step, 0
            while 0 <= c < len(holds) and not measured[c] and not taken[c]:
                if judged[c]:
                    if not holds[c]:
                        missed += 1
                        if missed > 1:
                            break
                    else:
                        taken[c], missed = True, 0
                c += step
    return taken


def _spacing(wire: FittedWire, pts_in_world: F64) -> float:
    """The median spacing of the wire's own points along it (bounded to a few per tenth)."""
    d = np.diff(wire.own_positions(pts_in_world))
    d = d[d > 0]
    return float(np.clip(np.median(d) if len(d) else 0.05, 0.02, 0.1))


def _peak(m: F64, at: npt.NDArray[np.int64], centre: tuple[float, float]) -> tuple[float, float]:
    """The offset (across, up) of the evidence's peak at cell ``at`` of ``m`` (A, U),
    refined by a parabola through it and its neighbours in each direction, within NEAR_M of
    ``centre``."""

    def vertex(x: F64, y: tuple[float, float, float]) -> float:
        # The vertex of the parabola through (x_i, y_i), within half a cell of x[1].
        (x0, x1, x2), (y0, y1, y2) = x, y
        d0, d2 = x0 - x1, x2 - x1
        den = d0 * d2 * (d2 - d0)
        a = ((y2 - y1) * d0 - (y0 - y1) * d2) / den  # curvature / 2
        b = ((y0 - y1) * d2 * d2 - (y2 - y1) * d0 * d0) / den
        if a >= 0 or not np.isfinite(a):
            return float(x1)
        return float(np.clip(x1 - b / (2 * a), x1 + 0.5 * d0, x1 + 0.5 * d2))

    i, j = int(at[0]), int(at[1])
    A, U = OFFSETS_ACROSS, OFFSETS_UP
    da = (
        vertex(A[i - 1 : i + 2], (m[i - 1, j], m[i, j], m[i + 1, j]))
        if 0 < i < len(A) - 1
        else float(A[i])
    )
    du = (
        vertex(U[j - 1 : j + 2], (m[i, j - 1], m[i, j], m[i, j + 1]))
        if 0 < j < len(U) - 1
        else float(U[j])
    )
    return (
        float(np.clip(da, centre[0] - NEAR_M, centre[0] + NEAR_M)),
        float(np.clip(du, centre[1] - NEAR_M, centre[1] + NEAR_M)),
    )
