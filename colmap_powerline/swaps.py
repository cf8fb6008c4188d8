"""Swapped pairings: where only two strips see a line, false wires that borrow a wire's image
lines.

Seen only from two strips along the line, every pairing of an image wire of one strip with
an image wire of the other triangulates to a smooth, catenary-shaped curve. Three wires T, g
and h, where g lies on T's image from one strip (A) and h on it from the other (B), pair
T's lines a (in A) and a' (in B) twice: g = (a, b') and h = (c, a'), with other lines b'
and c. Either T is real and g and h are false pairings (the shared generator's
soil seeds 11 and 13: a conductor beside two others that were not found), or g and h are
real and T is their swapped pairing; each passes every test a wire of two strips can get
(on a wire in every view all along; on another's image from one strip, which is what a wire
hidden behind another from there looks like). The two differ where the wires slope towards
their supports: there the views of one strip (one camera line along the wire) no longer
share one plane through the wire, and a false pairing cannot lie on its image lines in all
of them at once. Its fitted curve then runs beside the line, over whole stretches, in some
views, where a real wire's curve stays on it in all.

So for each such triple every view's line response is averaged across each wire over
stretches of its image (``STRETCH_PX``), the peak's offset taken per stretch, and a view's
disagreement is its median offset over the stretches (other wires' lines left out of the
search); a wire's is the largest of its views'. The side whose disagreement exceeds the
verification's tolerance and twice the other side's goes; when neither does, all three go
(on a flight of two strips a false wire costs more than a missing one).
"""

from __future__ import annotations

import logging
from itertools import permutations
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt
from scipy.spatial import cKDTree

from .detect import DetectOptions, line_response
from .scene import Scene, read_image
from .support import WireSupport
from .trace import image_normals
from .verify import image_wire_direction_deg, samples_across
from .wires import FittedWire

logger = logging.getLogger(__name__)

F64 = npt.NDArray[np.float64]

STRETCH_PX = 100.0  # the response is averaged along the wire's image over stretches this long
SAMPLES = 400  # along each wire (its image a few px apart; the wire on T's image: 5× as many)
MIN_STRETCHES = 3  # a view's disagreement needs this many stretches it sees
MIN_SHARE_ON = 0.5  # a wire lies on another's image in a view along this share of it
MIN_VIEWS = 2  # views that show each of g and h on T's image (one strip's worth)
MARGIN = 2.0  # the side that goes disagrees beyond the tolerance and this many times as much
# as the other. On the shared generator's two-strip flights true wires measure 0.4-1.8 px
# (faint ones over soil most) and the false pairings of triples 1.4-3.7 px: the two overlap,
# so one side is kept only when the other stands well apart


def _points(wire: FittedWire, n: int = SAMPLES) -> tuple[F64, F64]:
    """``n`` samples along the wire: (points, unit tangents)."""
    pts = wire.points(np.linspace(wire.s_range[0], wire.s_range[1], n))
    tangent = np.gradient(pts, axis=0)
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-12)
    return pts, tangent


class _Projected:
    """Each wire's samples (``SAMPLES``, or five times as many: ``dense``) projected into
    every view, once: the tests below look at the same wires in the same views many times."""

    def __init__(self, scene: Scene, wires: list[FittedWire]) -> None:
        self.scene, self.wires = scene, wires
        self._done: dict[tuple[int, bool], list[tuple[F64, npt.NDArray[np.bool_]]]] = {}

    def __call__(self, k: int, dense: bool = False) -> list[tuple[F64, npt.NDArray[np.bool_]]]:
        """Per view: (uv, inside) of wire k's samples."""
        if (k, dense) not in self._done:
            pts = _points(self.wires[k], 5 * SAMPLES if dense else SAMPLES)[0]
            self._done[(k, dense)] = [
                (uv, inside) for uv, _, inside in (v.project(pts) for v in self.scene.images)
            ]
        return self._done[(k, dense)]


def _on_image_of(projected: _Projected, g: int, t: int, tolerance_px: float) -> set[int]:
    """The views in which wire g lies on wire t's image (within ``tolerance_px`` along at
    least ``MIN_SHARE_ON`` of what the view sees of g)."""
    out = set()
    for k, ((ug, ig), (ut, it)) in enumerate(
        zip(projected(g), projected(t, dense=True), strict=True)
    ):
        if ig.sum() < 0.3 * len(ig) or it.sum() < 2:
            continue
        d, _ = cKDTree(ut[it]).query(ug[ig], distance_upper_bound=tolerance_px)
        if np.isfinite(d).mean() >= MIN_SHARE_ON:
            out.add(k)
    return out


def _peak(steps: F64, profile: F64) -> float:
    """Where a profile of the line response across a wire, signed so that the wire's is
    positive, peaks: the centroid of its strongest positive lobe above half its height (a
    line straddling two pixels gives a flat top)."""
    k = int(np.argmax(profile))
    if profile[k] <= 0:
        return float("nan")
    above = profile >= 0.5 * profile[k]
    lo, hi = k, k
    while lo > 0 and above[lo - 1]:
        lo -= 1
    while hi < len(profile) - 1 and above[hi + 1]:
        hi += 1
    w = profile[lo : hi + 1]
    return float((steps[lo : hi + 1] * w).sum() / w.sum())


def _disagreement(
    projected: _Projected,
    k_wire: int,
    responses: dict[int, npt.NDArray[np.float32]],  # the views' signed line responses
    azimuth_deg: float,
    detect: DetectOptions,
    reach_px: float,
    tolerance_px: float,
) -> float:
    """The largest over the views of their median offset (px) between the wire's projection
    and the peak of their signed line response averaged across it over each ``STRETCH_PX``
    of its image. The lines of the ``others`` are left out of the search (their response is
    no evidence about this wire's), except where one lies on this wire's own image."""
    scene = projected.scene
    pts, tangent = _points(projected.wires[k_wire])
    others = [j for j in range(len(projected.wires)) if j != k_wire]
    steps = np.arange(-reach_px, reach_px + 1e-9, 0.25)
    block = detect.side_offset_px + 2.0  # how far another line's response (its side taps, its
    # blur) reaches
    worst = 0.0
    for k, (view, (uv, inside)) in enumerate(zip(scene.images, projected(k_wire), strict=True)):
        if inside.sum() < 0.3 * len(pts):
            continue
        if k not in responses:
            image = read_image(view.path)
            gray = cv2.cvtColor(image, cv2.COLOR_RGB2GRAY).astype(np.float32)
            mid = pts[inside][inside.sum() // 2]
            direction = image_wire_direction_deg(view, mid, azimuth_deg)
            responses[k] = line_response(gray, direction, detect)
        uv, tan = uv[inside], tangent[inside]
        normal, _ = image_normals(view, pts[inside], tan)
        profile = samples_across(responses[k], uv, normal, steps)
        # Other wires' image lines within reach, at this place: their offsets across.
        views_of_others = [projected(j, dense=True)[k] for j in others]
        near = np.concatenate([o_uv[o_in] for o_uv, o_in in views_of_others] + [np.zeros((0, 2))])
        if len(near):
            tree = cKDTree(near)
            for i, nb in enumerate(tree.query_ball_point(uv, reach_px + 1.5)):
                if not nb:
                    continue
                rel = near[nb] - uv[i]
                at = np.abs(rel @ np.r_[normal[i, 1], -normal[i, 0]]) <= 1.0  # same place
                offset = rel[at] @ normal[i]
                offset = offset[np.abs(offset) > tolerance_px]
                if len(offset):
                    blocked = np.abs(steps[:, None] - offset[None]).min(axis=1) < block
                    profile[i, blocked] = 0.0
        along = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(uv, axis=0), axis=1))]
        bins = np.floor(along / STRETCH_PX).astype(np.int64)
        full = np.flatnonzero(
            np.bincount(bins) * along[-1] / max(len(along) - 1, 1) >= 0.5 * STRETCH_PX
        )
        if len(full) < MIN_STRETCHES:
            continue
        # The wire's polarity in this view: that of the strongest response across it over
        # the whole view (a line's centre responds twice as strongly as its side lobes,
        # which have the other sign).
        whole = profile.mean(axis=0)
        sign = np.sign(whole[np.argmax(np.abs(whole))]) or 1.0
        offsets = [abs(_peak(steps, sign * profile[bins == b].mean(axis=0))) for b in full]
        offsets = [o if np.isfinite(o) else reach_px for o in offsets]  # no line: far off
        worst = max(worst, float(np.median(offsets)))
    return worst


def swapped_pairings(
    scene: Scene,
    wires: list[FittedWire],
    supports: list[WireSupport],
    azimuth_deg: float,
    detect: DetectOptions,
    tolerance_px: float,
) -> tuple[set[int], list[Path]]:
    """Indices of the wires to drop as swapped pairings of another wire's image lines (see
    the module's description), and the images read; only wires on weak geometry (no view
    can tell them from a false pairing) are considered."""
    weak = [k for k, s in enumerate(supports) if s.geometry == "weak"]
    if len(weak) < 3:
        return set(), []
    projected = _Projected(scene, wires)
    on = {(g, t): _on_image_of(projected, g, t, tolerance_px) for g, t in permutations(weak, 2)}
    responses: dict[int, npt.NDArray[np.float32]] = {}
    score: dict[int, float] = {}
    reach = 4 * tolerance_px  # the image lines a false pairing runs beside lie this near

    def disagreement(k: int) -> float:
        if k not in score:
            score[k] = _disagreement(
                projected, k, responses, azimuth_deg, detect, reach, tolerance_px
            )
        return score[k]

    drop: set[int] = set()
    for t in weak:
        for g, h in permutations([k for k in weak if k != t], 2):
            if g > h or {g, h, t} & drop:
                continue
            only_g = on[(g, t)] - on[(h, t)]
            only_h = on[(h, t)] - on[(g, t)]
            if len(only_g) < MIN_VIEWS or len(only_h) < MIN_VIEWS:
                continue
            dt, dg, dh = disagreement(t), disagreement(g), disagreement(h)
            ig, ih, it = wires[g].wire_id, wires[h].wire_id, wires[t].wire_id
            if min(dg, dh) > max(tolerance_px, MARGIN * dt):
                gone = [g, h]
                why = f"the views agree on wire {it} and put wires {ig} and {ih} beside its lines"
            elif dt > max(tolerance_px, MARGIN * max(dg, dh)):
                gone = [t]
                why = f"the views agree on wires {ig} and {ih} and put wire {it} beside theirs"
            else:
                # Two strips cannot tell which pairing is real: none is written (on such a
                # flight a false wire costs more than a missing one).
                gone = [t, g, h]
                why = "the views do not tell which"
            drop.update(gone)
            logger.info(
                "support: wires %s dropped: wires %d and %d each lie on wire %d's image from "
                "one strip and on another line from the other (wire %d's lines, each paired "
                "twice); %s (%.1f, %.1f and %.1f px "
                "off where the wires slope, tolerance %.1f)",
                ", ".join(str(wires[k].wire_id) for k in sorted(gone)),
                ig,
                ih,
                it,
                it,
                why,
                dg,
                dh,
                dt,
                tolerance_px,
            )
    return drop, [scene.images[k].path for k in responses]
