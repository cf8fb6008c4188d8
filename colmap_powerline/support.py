"""Whole-wire support: does each fitted wire lie on wires in the views, and can they tell?

Point-by-point verification weighs only the views offset across the wires from both
cameras of a point's pair; with the parallel wires of a line, a false pairing (image wire i
matched with image wire j) can still collect a few lucky hits and gather into a wire-shaped
curve. A false pairing is a false *wire*: projected as a whole into a view that can tell, it
falls between the wires over its whole length, while a true wire lies on them wherever the
view sees it. So every fitted wire is projected into every view that was searched for wires,
and its share of projected length on wire pixels is compared with the chance level there
(the same test on copies of it displaced across the wire, as the held-out image check does).

Each wire gets a confidence (the posterior probability that it is a real wire, from the
views that can tell) and a description of its geometry: how many views saw it, from how many
distinct positions across it ("strips"), and how many of them can tell it from a false
pairing. Wires that such views reject are dropped; wires that no such view sees are kept,
flagged as resting on weak geometry, with what to fly to make it strong.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any, ClassVar

import numpy as np
import numpy.typing as npt
from scipy.spatial import cKDTree

from .geometry import azimuth_deg_of, crossing_views, offsets_across
from .options import check_limits
from .scene import Scene
from .verify import CONTROL_OFFSETS_PX, ViewWirePixels
from .wires import FittedWire

logger = logging.getLogger(__name__)

F64 = npt.NDArray[np.float64]


@dataclass(kw_only=True)
class SupportOptions:
    min_confidence: float = 0.99  # wires that views able to tell make less likely than this
    # to be real are dropped
    correlation_length_px: float = 15.0  # hits along a wire are independent only this far
    # apart (the detector's template length)
    min_projected_px: float = 30.0  # a view counts for a wire when this much of it lies in
    # the region that view searched
    min_pair_share: float = 0.5  # views can tell a wire from a false pairing when, between
    # them, they can for the pairs that gave at least this share of its points; each view
    # counts when it can for at least this share of what the best one can
    min_hit_share: float = 0.8  # over all views, a wire must lie on wire pixels at least
    # this share as often as the views see true wires (a false pairing lands on wires only
    # in the views along one of its cameras, and not where the wires slope)

    LIMITS: ClassVar[dict[str, str]] = {
        "min_confidence": "[0.5, 1)",
        "correlation_length_px": ">= 1",
        "min_projected_px": ">= 1",
        "min_pair_share": "(0, 1]",
        "min_hit_share": "[0, 1]",
    }

    def __post_init__(self) -> None:
        check_limits(self)

    def accepts(self, confidence: float | None) -> bool:
        """Whether a wire with this confidence is kept."""
        return confidence is not None and confidence >= self.min_confidence


@dataclass(frozen=True)
class WireSupport:
    """How well the views support one wire."""

    wire_id: int
    views: int  # views in which the wire was looked for
    strips: int  # groups of those views at distinct positions across the wire
    crossing_views: int  # views offset across the wire from both cameras of the pairs
    # that measured it: the only ones that can tell it from a false pairing
    hit_rate: float  # share of its projected length on wire pixels, over all views
    crossing_hit_rate: float | None  # the same over the crossing views
    chance: float  # the share expected by accident (displaced copies of the wire)
    confidence: float | None  # probability that it is a real wire, from the stretches of it
    # that no better supported wire explains (None: there are none)
    geometry: str  # "strong": crossing views confirm it; "weak": no view can tell it from a
    # false pairing (the confidence then comes from the other views)
    height_above_ground: float  # median height of the wire above the ground surface
    advice: str | None = None  # what to fly to make weak geometry strong
    traced_share: float | None = None  # share of the places along it where the views would
    # fix the wire (three or more, offset across it enough) at which they found it
    # (:mod:`colmap_powerline.trace`; None: no such places)
    confirming_strips: int = 0  # strips whose views see a stretch of it that no other wire
    # explains (one strip alone confirms a plane through its cameras, not where in it the
    # wire lies)
    found_by: str = "pairs"  # "pairs": matched by image pairs and confirmed by the views;
    # "line evidence": too faint for the detector, found by the line evidence of all views
    # together and measured by tracing (:mod:`colmap_powerline.faint`)
    evidence_sd: float | None = None  # "line evidence": how many of the sweep's standard
    # deviations its evidence stands out
    supported_s: tuple[float, float] | None = None  # (not written) when the views reject
    # the wire as a whole but support one stretch of it: that stretch along its plane

    def to_json(self) -> dict[str, Any]:
        out = asdict(self)
        del out["supported_s"]
        return out


@dataclass(frozen=True, eq=False)
class _ViewMeasure:
    view_index: int
    uv: F64  # (n, 2) the wire's samples (half a pixel apart) in the view's crop
    normal: F64  # (n, 2) unit image normals of the wire there
    hit: npt.NDArray[np.bool_]  # (n,) on a wire pixel
    control: F64  # (n,) share of the displaced copies on a wire pixel (chance)
    s: F64  # (n,) where each sample lies along the wire's plane
    uv_extended: F64  # (m, 2) the curve continued past its observed ends (EXTEND_SHARE of
    # its length each side), where it explains other wires' stretches

    def share(self, own: npt.NDArray[np.bool_]) -> tuple[float, float, float]:
        """(length px, hit share, chance) over the samples ``own``."""
        n = int(own.sum())
        if n == 0:
            return 0.0, 0.0, 0.0
        return 0.5 * n, float(self.hit[own].mean()), float(self.control[own].mean())


# A wire the views reject as a whole is looked at in this many stretches along it, for
# one they support (a true wire whose end went astray, or one partly over ground where the
# views cannot see it).
TRIM_BINS = 20
MIN_TRIM_BINS = 3  # a supported stretch shorter than this many is not proposed

# A strip confirms a wire seen only from strips along it when other wires explain less than
# this share of what it sees of the wire (on the shared generator's area survey a false
# pairing is explained all along from one strip, true wires 0–35 %; on the package's
# corridor, top conductors stacked over lower ones are explained all along from the strip
# over the line).
MIN_OWN_SHARE = 0.5

# Views that can tell but see less than this share of what all views see of a wire (a
# glimpse: 0.5 % of a conductor on the shared corridor seed 2) leave it, when they neither
# confirm nor reject it, to the strips; short false pairings that they see well (a third of
# what all views see) stay theirs to decide.
GLIMPSE_SHARE = 0.1

# Acceptance is repeated on the accepted set until it no longer changes, at most this often.
MAX_SUPPORT_ROUNDS = 4

# A wire explains other wires' stretches along its catenary continued this share of its
# observed length past each end (a wire seen in part still hangs to its supports).
EXTEND_SHARE = 0.25

# Pairs of one kind (cameras in the same two strips) see a false pairing of parallel wires
# at the same place, pairs of another kind elsewhere: a wire whose points come from one kind
# while another kind's pairs see it too is a false pairing. A kind counts as missing the wire
# when at least MIN_KIND_PAIRS of its pairs see it (one pair can miss a true wire: its wire
# detection failed in one image) and they gave less than MISSING_SHARE of their share of its
# points, that share being at least MIN_KIND_POINTS (fewer can be missed by chance). On the
# shared generator's corridor seed 3 the kinds that see a true wire give 0.78-0.97 of their
# share, those that see a false pairing 0 of 17-26 points; over the shared cross, grid,
# corridor and mixed scenes and the package's demo, true wires' kinds give at least 0.22.
MIN_KIND_PAIRS = 2
MISSING_SHARE = 0.1
MIN_KIND_POINTS = 10.0
# A pair sees a wire when both its images hold at least half of it and its baseline crosses
# it at least this steeply (the pair selection's bound: flatter pairs hardly triangulate it).
# (Only what lies 5 % inside the borders counted at first: pairs of the other kinds then saw
# none of a 6 m false pairing by the images' edges on corridor seed 3.)
KIND_MIN_CROSSING_DEG = 45.0


def _measure_in_view(
    scene: Scene, wire: FittedWire, pixels: ViewWirePixels, near_wire: npt.NDArray[np.bool_]
) -> _ViewMeasure | None:
    """Project the wire into one view; its hit share and chance level in the searched crop."""
    view = scene.images[pixels.view_index]
    lo, hi = wire.s_range
    depth = float(np.median(view.to_cam(wire.points(np.array([lo, 0.5 * (lo + hi), hi])))[:, 2]))
    if depth <= 0:
        return None
    step = 0.5 * depth / view.focal_px  # half a pixel at the wire
    s_all = np.arange(lo, hi + 1e-9, step)
    uv, _, inside = view.project(wire.points(s_all))
    if inside.sum() < 3:
        return None
    uv, s_all = uv[inside] - [pixels.x0, pixels.y0], s_all[inside]
    h, w = pixels.shape
    in_crop = (uv[:, 0] >= 0) & (uv[:, 1] >= 0) & (uv[:, 0] < w) & (uv[:, 1] < h)
    if in_crop.sum() < 3:
        return None
    tangent = np.gradient(uv, axis=0)
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-9)
    normal = np.c_[-tangent[:, 1], tangent[:, 0]]
    uv, normal, s_all = uv[in_crop], normal[in_crop], s_all[in_crop]

    def on_wire(pts: F64) -> npt.NDArray[np.bool_]:
        x = np.clip(np.floor(pts[:, 0]).astype(np.int64), 0, w - 1)
        y = np.clip(np.floor(pts[:, 1]).astype(np.int64), 0, h - 1)
        return near_wire[y, x]

    control = np.mean([on_wire(uv + o * normal) for o in CONTROL_OFFSETS_PX], axis=0)
    ext = EXTEND_SHARE * (hi - lo)
    uv_ext, _, inside_ext = view.project(wire.points(np.arange(lo - ext, hi + ext, step)))
    uv_ext = uv_ext[inside_ext] - [pixels.x0, pixels.y0]
    return _ViewMeasure(pixels.view_index, uv, normal, on_wire(uv), control, s_all, uv_ext)


def _explained(
    measure: _ViewMeasure, others: list[_ViewMeasure], radius_px: float
) -> npt.NDArray[np.bool_]:
    """(n,) samples of a wire that lie on (within ``radius_px`` of) another wire in this view."""
    out = np.zeros(len(measure.uv), bool)
    for o in others:
        if len(o.uv_extended):
            d, _ = cKDTree(o.uv_extended).query(measure.uv, distance_upper_bound=radius_px)
            out |= np.isfinite(d)
    return out


def height_above_ground(scene: Scene, wire: FittedWire) -> float:
    """Median height of a fitted wire above the ground of the sparse points."""
    poly = wire.polyline(1.0)
    return float(np.median(poly[:, 2] - scene.ground_height(poly[:, :2])))


def _strips(offsets: F64, gap: float) -> list[F64]:
    """Group positions across the wire into strips: sorted runs closer than ``gap``."""
    order = np.sort(offsets)
    cuts = np.flatnonzero(np.diff(order) > gap) + 1
    return np.split(order, cuts)


def _strip_of(groups: list[F64], offsets: F64) -> npt.NDArray[np.int64]:
    """The strip (index into ``groups``) of each position across the wire that lies in one."""
    starts = np.array([float(g[0]) for g in groups[1:]])
    return np.searchsorted(starts, offsets, side="right").astype(np.int64)


def _advice(wire: FittedWire, groups: list[F64], need: float, hidden: bool = False) -> str:
    """What to fly so that a view can tell this wire from a false pairing (``hidden``: the
    views that could see it only where other wires lie on it)."""
    mid = wire.points(np.array([0.5 * sum(wire.s_range)]))[0]
    centres = [float(np.median(g)) for g in groups]
    # An offset at least ``need`` from every strip that sees it, as close to the wire as that.
    options = [0.0, *(c + need for c in centres), *(c - need for c in centres)]
    ok = [o for o in options if all(abs(o - c) >= need - 1e-9 for c in centres)]
    target = min(ok, key=abs) if ok else max(centres, key=abs) + need
    side = (
        "over the line"
        if abs(target) < 0.5 * need
        else f"{abs(target):.0f} m to the " + ("right" if target > 0 else "left")
    )
    where = ", ".join(f"{c:+.0f}" for c in centres)
    seen = (
        f"the views that could tell it from a false pairing see it only where other wires lie "
        f"on it (stacked wires; {len(groups)} strip(s) see it, at {where} m across the wire)"
        if hidden
        else f"only {len(groups)} strip(s) see it (at {where} m across the wire)"
    )
    return (
        f"{seen}: fly one more strip along the line {side} of it (at least "
        f"{need:.0f} m from the others), or a few images across the line near "
        f"({mid[0]:.1f}, {mid[1]:.1f})"
    )


def _pair_kinds_disagree(
    scene: Scene,
    wire: FittedWire,
    point_pair: npt.NDArray[np.int32],
    pair_views: npt.NDArray[np.int64],
    gap: float,
) -> bool:
    """Whether pairs of one kind (cameras in the same two strips across the wire: runs of
    offsets across it closer than ``gap``) that see the wire gave almost none of its points
    while pairs of another kind gave them: the signature of a false pairing, which each kind
    of pair puts somewhere else."""
    lo, hi = wire.s_range
    pts = wire.points(np.linspace(lo, hi, 50))
    inside = np.zeros((len(scene.images), len(pts)), bool)
    for v in np.unique(pair_views):
        inside[v] = scene.images[v].project(pts)[2]
    both = (inside[pair_views[:, 0]] & inside[pair_views[:, 1]]).mean(axis=1) >= 0.5
    centres = scene.centers_in_world
    base = centres[pair_views[:, 1], :2] - centres[pair_views[:, 0], :2]
    cos = np.abs(base @ wire.plane_direction_xy) / np.maximum(np.linalg.norm(base, axis=1), 1e-12)
    sees = both & (cos <= np.cos(np.deg2rad(KIND_MIN_CROSSING_DEG)))
    if not sees.any():
        return False
    lateral = offsets_across(centres[:, :2], wire.plane_origin_xy, wire.plane_direction_xy)
    groups = _strips(lateral[np.unique(pair_views)], gap)
    strips = np.sort(_strip_of(groups, lateral[pair_views]), axis=1)
    kinds = strips[:, 0] * len(groups) + strips[:, 1]
    counts = np.bincount(point_pair[wire.point_indices], minlength=len(pair_views))
    total = float(counts[sees].sum())
    for kind in np.unique(kinds[sees]):
        of_kind = sees & (kinds == kind)
        share = total * of_kind.sum() / sees.sum()
        if (
            of_kind.sum() >= MIN_KIND_PAIRS
            and share >= MIN_KIND_POINTS
            and counts[of_kind].sum() < MISSING_SHARE * share
        ):
            return True
    return False


def _evidence(length_px: F64, hit: F64, chance: F64, correlation_px: float) -> float:
    """Log likelihood ratio, summed over views: the wire hits more often than chance
    (its hit share itself the best estimate of how often a real wire hits) against it
    hitting at chance. Hits along a wire are independent only ``correlation_px`` apart."""
    c = np.clip(chance, 1e-3, 0.95)
    f = np.clip(hit, 1e-6, 1 - 1e-6)
    kl = f * np.log(f / c) + (1 - f) * np.log((1 - f) / (1 - c))
    return float(np.sum(np.where(f > c, kl, 0.0) * length_px / correlation_px))


def _hit_share(measures: Sequence[_ViewMeasure]) -> float:
    """How often a wire lands on wire pixels over the views ``measures`` (by length)."""
    if not measures:
        return 0.0
    return float(
        np.average([m.hit.mean() for m in measures], weights=[len(m.uv) for m in measures])
    )


def _short_of(observed: float, expected: float, n_eff: float, min_share: float) -> bool:
    """Is a hit share ``observed`` below ``min_share`` of ``expected``, beyond what chance
    along ``n_eff`` independent stretches explains?"""
    slack = 2.0 * np.sqrt(expected * (1 - expected) / n_eff)
    return observed < min_share * expected - slack


def wire_support(
    scene: Scene,
    wires: Sequence[FittedWire],
    wire_pixels: Sequence[ViewWirePixels],
    point_pair: npt.NDArray[np.int32],
    pair_centres: F64,
    view_hit_rates: F64,
    crossing_offset: float,
    tolerance_px: float,
    options: SupportOptions | None = None,
    pair_views: npt.NDArray[np.int64] | None = None,
) -> list[WireSupport]:
    """Measure every wire in every searched view and weigh the views that can tell.

    Wires are taken from the best supported down. In each view, the stretches of a wire
    that lie on a wire already accepted are explained by it and do not count: a false
    pairing of image wires i and j lies on wire i in the views along the wires from one
    camera and on wire j from the other, and nowhere else.

    Args:
        scene: the oriented scene.
        wires: the fitted wires.
        wire_pixels: what each searched view saw (from verification).
        point_pair: (N,) the pair that produced each verified point (``wire.point_indices``
            index it).
        pair_centres: (P, 2, 3) the camera centres of each pair.
        view_hit_rates: (V,) how often each view lands on true wire points (NaN: unknown).
        crossing_offset: a view can tell when it is offset across the wire from both cameras
            of a pair by this share of its height above the wire.
        tolerance_px: how close to a wire pixel a projection counts as on it.
        options: the thresholds.
        pair_views: (P, 2) the scene indices of each pair's two images (None: the pairs
            of different strips are not compared).

    Returns:
        One :class:`WireSupport` per wire, in the same order (``confidence`` None when no
        view sees a stretch of it that other wires do not explain, at most 0.5 when it is
        not accepted).
    """
    options = options or SupportOptions()
    # One view's mask unpacked at a time (a few images' worth of memory, not all views').
    per_wire: list[list[_ViewMeasure]] = [[] for _ in wires]
    density: dict[int, float] = {}
    for p in wire_pixels:
        mask = p.near_wire()
        density[p.view_index] = float(mask.mean())
        for k, wire in enumerate(wires):
            m = _measure_in_view(scene, wire, p, mask)
            if m is not None and 0.5 * len(m.uv) >= options.min_projected_px:
                per_wire[k].append(m)
    centres = scene.centers_in_world
    measured = []
    for wire, ms in zip(wires, per_wire, strict=True):
        pairs = point_pair[wire.point_indices]
        counts = np.bincount(pairs, minlength=len(pair_centres))
        produced = np.flatnonzero(counts > 0)
        mid = wire.points(np.array([0.5 * sum(wire.s_range)]))[0]
        height = float(np.median(centres[:, 2]) - mid[2])
        azimuth = azimuth_deg_of(wire.plane_direction_xy)
        view_idx = np.array([m.view_index for m in ms], np.int64)
        cross = np.zeros(len(ms), bool)
        if len(produced) and len(ms):
            # Views can tell when, between them, they can for the pairs that gave most of
            # the wire's points. Pairs from different strips (1-2, 2-3, 1-3) each have their
            # own such views: each view counts when it can for about as many of the points
            # as the best one (a false pairing comes from pairs of one kind, and the views
            # along their cameras never get there).
            can = crossing_views(
                centres[view_idx], pair_centres[produced], azimuth, height, crossing_offset
            )  # (P, V)
            total = max(counts.sum(), 1)
            share = counts[produced] @ can / total
            told = counts[produced] @ can.any(axis=1) / total
            if told >= options.min_pair_share:
                cross = share >= options.min_pair_share * share.max()
        lateral = offsets_across(
            centres[view_idx, :2], wire.plane_origin_xy, wire.plane_direction_xy
        )
        groups = _strips(lateral, crossing_offset * height) if len(lateral) else []
        # Each view's strip: the group its offset across the wire falls in.
        strip_of = _strip_of(groups, lateral)
        strength = sum(0.5 * len(m.uv) * (m.hit.mean() - m.control.mean()) for m in ms)
        disagree = False
        if pair_views is not None and len(pair_views):
            disagree = _pair_kinds_disagree(
                scene, wire, point_pair, pair_views, crossing_offset * height
            )
        measured.append((ms, cross, groups, height, strength, strip_of, disagree))

    finite = view_hit_rates[np.isfinite(view_hit_rates)]
    typical_rate = float(np.median(finite)) if len(finite) else 0.7
    radius = 2 * tolerance_px + 1
    # Which samples of wire k lie on wire o in each view, computed once per (k, o).
    overlap: dict[tuple[int, int], list[npt.NDArray[np.bool_]]] = {}

    def on_other(k: int, o: int) -> list[npt.NDArray[np.bool_]]:
        if (k, o) not in overlap:
            out_k = []
            for m in measured[k][0]:
                other = [x for x in measured[o][0] if x.view_index == m.view_index]
                out_k.append(_explained(m, other, radius))
            overlap[(k, o)] = out_k
        return overlap[(k, o)]

    sure = options.accepts

    def explained_by(k: int, others: set[int]) -> list[npt.NDArray[np.bool_]]:
        """Per view of wire k, its samples that lie on one of the wires ``others``."""
        explained = [np.zeros(len(m.uv), bool) for m in measured[k][0]]
        for o in others:
            explained = [e | x for e, x in zip(explained, on_other(k, o), strict=True)]
        return explained

    pixels_of = {p.view_index: p for p in wire_pixels}
    masks: dict[int, npt.NDArray[np.bool_]] = {}  # a few views' unpacked masks
    partner: dict[tuple[int, int, frozenset[int]], bool] = {}

    def other_partner(k: int, covered: int, others: set[int], own_length: F64) -> bool:
        """Does wire k, moved along the rays of the strip that confirms it most, meet an
        image wire in strip ``covered`` that none of the wires ``others`` explains, as often
        as a wire passes there?"""
        key = (k, covered, frozenset(others))
        if key not in partner:
            partner[key] = _other_partner(k, covered, others, own_length)
        return partner[key]

    def _other_partner(k: int, covered: int, others: set[int], own_length: F64) -> bool:
        ms, strip_of = measured[k][0], measured[k][5]
        rest = strip_of != covered
        if not rest.any():
            return False
        # The confirming strip: the one seeing most of the wire unexplained; its cameras lie
        # on a line along the wire (a strip of a flight along the line).
        by_strip = {int(g): own_length[strip_of == g].sum() for g in np.unique(strip_of[rest])}
        best = max(by_strip, key=lambda g: by_strip[g])
        cams = centres[[m.view_index for m, g in zip(ms, strip_of, strict=True) if g == best]]
        wire = wires[k]
        along = np.r_[wire.plane_direction_xy, 0.0]
        pts = wire.polyline(1.0)
        mean = cams.mean(axis=0)
        ray_from = mean + np.outer((pts - mean) @ along, along)  # (n, 3) the strip's line
        # Candidate depths: from 2 m above the ground to 5 m below the cameras.
        ground = scene.ground_height(pts[:, :2])
        views = [m for m, g in zip(ms, strip_of, strict=True) if g == covered]
        # Steps of the tolerance where the covered strip's views see it move fastest.
        probe = []
        for m in views:
            view = scene.images[m.view_index]
            a = view.project(ray_from + 1.0 * (pts - ray_from))[0]
            b = view.project(ray_from + 1.01 * (pts - ray_from))[0]
            probe.append(np.nanmedian(np.linalg.norm(b - a, axis=1)) / 0.01)
        px_per_unit = float(np.nanmax(probe)) if probe else 0.0
        if not np.isfinite(px_per_unit) or px_per_unit <= 0:
            return False
        lam = np.arange(0.2, 2.0, tolerance_px / px_per_unit)[:2000]
        cand = ray_from[None] + lam[:, None, None] * (pts - ray_from)[None]  # (L, n, 3)
        valid = (cand[..., 2] >= ground[None] + 2.0) & (cand[..., 2] <= mean[2] - 5.0)
        hits = np.zeros(len(lam))
        count = np.zeros(len(lam))
        for m in views:
            p = pixels_of[m.view_index]
            if m.view_index not in masks:
                if len(masks) >= 8:
                    masks.pop(next(iter(masks)))
                masks[m.view_index] = p.near_wire()
            near = masks[m.view_index]
            h, w = p.shape
            uv, _, inside = scene.images[m.view_index].project(cand.reshape(-1, 3))
            uv = uv - [p.x0, p.y0]
            inside &= valid.ravel()
            inside &= (uv[:, 0] >= 0) & (uv[:, 1] >= 0) & (uv[:, 0] < w) & (uv[:, 1] < h)
            idx = np.flatnonzero(inside)
            x = np.floor(uv[idx, 0]).astype(np.int64)
            y = np.floor(uv[idx, 1]).astype(np.int64)
            on = near[y, x]
            # Image wires the others explain, and the wire's own (where no other lies on it).
            other_uv = [m.uv_extended] + [
                o.uv_extended
                for j in others
                for o in measured[j][0]
                if o.view_index == m.view_index
            ]
            if on.any():
                d, _ = cKDTree(np.concatenate(other_uv)).query(
                    uv[idx[on]], distance_upper_bound=radius
                )
                on[np.flatnonzero(on)[np.isfinite(d)]] = False
            row = idx // len(pts)
            hits += np.bincount(row, on, len(lam))
            count += np.bincount(row, minlength=len(lam))
        enough = count >= 0.25 * len(pts) * len(views)  # seen along a quarter of it
        if not enough.any():
            return False
        rate = np.array([view_hit_rates[m.view_index] for m in views])
        expected = float(np.nanmean(rate)) if np.isfinite(rate).any() else typical_rate
        # As often as these views find the image wire k lies on there: the estimate from
        # single points is low where whole wires are found nearly everywhere (0.77 against
        # 0.96-1.0 at 12 MP on the package's corridor, where a shield that only the middle
        # strip sees met the top conductor's rays at 65 % of its length).
        expected = max(expected, _hit_share(views))
        share = np.where(enough, hits / np.maximum(count, 1), 0.0)
        return bool(share.max() >= options.min_hit_share * expected)

    def judge(
        k: int, others: set[int]
    ) -> tuple[float | None, F64, F64, npt.NDArray[np.bool_], str | None]:
        """(confidence, length, hit share, views used, why the views that can tell did not
        decide: None when they did, "glimpse", "hidden" or "none") of wire k, where the
        wires ``others`` explain what they cover.

        Views that can tell decide wherever they see enough of the wire to. When they see
        only a glimpse of it, too little to confirm it, and do not reject it either (70 px
        in one view of a wire 14 views see along 1500 px), or when all they see of it lies
        on other wires (a conductor hidden behind its neighbours from every view that can
        tell: on the shared generator's flight across, seed 2, the top conductor lies on
        the middle one from half of them and on the lowest from the others), the wire is
        judged as one that no view can tell: by every strip that sees it. A duplicate of a
        wire lies on it from every view and stays unconfirmed."""
        ms, cross = measured[k][0], measured[k][1]
        explained = explained_by(k, others)
        rows = np.array([m.share(~e) for m, e in zip(ms, explained, strict=True)]).reshape(-1, 3)
        length, hit, control = rows.T
        chance = np.maximum(control, [density[m.view_index] for m in ms])
        informative = length >= options.min_projected_px
        rate = np.array([view_hit_rates[m.view_index] for m in ms])
        rate = np.where(np.isfinite(rate), rate, typical_rate)
        seen = np.array([0.5 * len(m.uv) for m in ms])
        glimpse = seen[cross].sum() < GLIMPSE_SHARE * seen.sum()
        why = "none"
        if (cross & (seen >= options.min_projected_px)).any():
            confidence, rejected = decide(k, others, cross, seen, length, hit, chance, rate)
            # None: what they see of it other wires explain.
            if confidence is not None and (sure(confidence) or rejected or not glimpse):
                return confidence, length, hit, cross & informative, None
            why = "hidden" if confidence is None else "glimpse"
        confidence, _ = decide(k, others, np.zeros(len(ms), bool), seen, length, hit, chance, rate)
        return confidence, length, hit, informative, why

    def decide(
        k: int,
        others: set[int],
        cross: npt.NDArray[np.bool_],
        seen: F64,
        length: F64,
        hit: F64,
        chance: F64,
        rate: F64,
    ) -> tuple[float | None, bool]:
        """(confidence, whether the views' hits reject it) of wire k from the views that can
        tell (``cross``) or, without any, from every strip."""
        informative = length >= options.min_projected_px
        use = cross & informative if cross.any() else informative
        if not use.any():
            return None, False
        llr = _evidence(length[use], hit[use], chance[use], options.correlation_length_px)
        confidence = float(1 / (1 + np.exp(-min(llr, 50.0))))
        rejected = False
        if measured[k][6]:
            # Pairs of another kind see it and gave (almost) none of its points.
            confidence, rejected = min(confidence, 0.5), True
        # A real wire lands on wire pixels in every view about as often as that view sees
        # true wires; a false pairing does so only in the views along one of its cameras,
        # and not where the wires slope towards their supports.
        # Where no view can tell, it must do so from every strip that sees a stretch no
        # other wire explains (a false pairing lies on wire i from one and on j from the
        # other); elsewhere over the views that can tell together, and from every strip of
        # the other views (a line 6.7 m above the ground along the wires' shadows on the
        # shared mixed seed 2, which the views able to tell confirm, misses from one strip).

        def short(sel: npt.NDArray[np.bool_]) -> bool:
            """Do the views ``sel`` land on wire pixels less often than they see true wires,
            beyond what chance along a short stretch explains?"""
            expected = float(np.average(rate[sel], weights=length[sel]))
            observed = float(np.average(hit[sel], weights=length[sel]))
            n_eff = max(float(length[sel].sum()) / options.correlation_length_px, 1.0)
            return _short_of(observed, expected, n_eff, options.min_hit_share)

        strips = measured[k][5]
        groups = [use] if cross.any() else []
        along = informative & ~cross if cross.any() else informative
        groups += [along & (strips == g) for g in np.unique(strips[along])]
        if any(short(sel) for sel in groups):
            confidence, rejected = min(confidence, 0.5), True
        if not cross.any() and sure(confidence):
            # Seen only from strips along it, a wire is measured from two of them. Where
            # other wires lie on most of what one strip sees of it, that strip cannot confirm
            # it: it is either a wire hidden behind another from there (conductors or a
            # shield stacked above each other, seen from over them) or a false pairing of
            # image wires i and j lying on the true wire j all along from j's strip. In the
            # second case the true wire i is missing, and its image is free in that strip:
            # the wire goes when, moved along the rays of the strip that confirms it, it
            # meets an image wire there that no other wire explains, found there about as
            # often as those views find the image wire it lies on (a wire the other strip
            # cannot see, a shield over the stacked conductors, also leaves an image free;
            # along the rays of a true wire the views find it only where the two meet).
            for g in np.unique(strips):
                sel = strips == g
                if (
                    seen[sel].sum() >= options.min_projected_px
                    and length[sel].sum() < MIN_OWN_SHARE * seen[sel].sum()
                    and other_partner(k, int(g), others, length)
                ):
                    confidence = min(confidence, 0.5)
        return confidence, rejected

    def stretch(k: int, others: set[int]) -> tuple[float, float] | None:
        """The longest stretch of wire k that the views support, when that is not all of it:
        along the wire, bins where the views hit at least halfway from chance to their hit
        rate on true wires (bins they hardly see do not break it)."""
        ms, cross = measured[k][0], measured[k][1]
        if not ms:
            return None
        explained = explained_by(k, others)
        length = np.array([0.5 * (~e).sum() for e in explained])
        informative = length >= options.min_projected_px
        use = cross & informative if cross.any() else informative
        if not use.any():
            return None
        own = [(m, ~e) for m, e, u in zip(ms, explained, use, strict=True) if u]
        s_at = np.concatenate([m.s[o] for m, o in own])
        hit = np.concatenate([m.hit[o] for m, o in own]).astype(np.float64)
        control = np.concatenate([m.control[o] for m, o in own])
        rate = np.concatenate([np.full(int(o.sum()), view_hit_rates[m.view_index]) for m, o in own])
        rate = np.where(np.isfinite(rate), rate, typical_rate)
        lo, hi = wires[k].s_range
        n_bins = max(int(TRIM_BINS), 1)
        edges = np.linspace(lo, hi, n_bins + 1)
        b = np.clip(np.searchsorted(edges, s_at, side="right") - 1, 0, n_bins - 1)
        count = np.bincount(b, minlength=n_bins).astype(np.float64)
        seen = np.maximum(count, 1.0)
        observed = np.bincount(b, hit, n_bins) / seen
        expected = np.bincount(b, rate, n_bins) / seen
        chance = np.bincount(b, control, n_bins) / seen
        known = 0.5 * count >= options.min_projected_px
        good = known & (observed >= 0.5 * (chance + expected))
        ok = good | ~known
        best: tuple[int, int] | None = None
        start = None
        for i in range(n_bins + 1):
            if i < n_bins and ok[i]:
                start = i if start is None else start
                continue
            if start is not None and good[start:i].any():
                # Trim unknown bins at the ends of the run.
                g = np.flatnonzero(good[start:i]) + start
                run = (int(g[0]), int(g[-1]) + 1)
                if best is None or run[1] - run[0] > best[1] - best[0]:
                    best = run
            start = None
        if best is None or best == (0, n_bins) or best[1] - best[0] < MIN_TRIM_BINS:
            return None
        return float(edges[best[0]]), float(edges[best[1]])

    # How often each wire lands on wire pixels over every view that sees it, and along how
    # many independent stretches.
    fit = {
        k: (
            _hit_share(ms),
            max(0.5 * sum(len(m.uv) for m in ms) / options.correlation_length_px, 1.0),
        )
        for k, (ms, *_) in enumerate(measured)
    }

    def fits_worse(o: int, k: int) -> bool:
        """Does wire o land on wire pixels less often than ``min_hit_share`` of the rate at
        which wire k does, beyond chance along its length?"""
        return _short_of(fit[o][0], fit[k][0], fit[o][1], options.min_hit_share)

    # Best supported first: each wire is judged on what the wires accepted before it leave.
    order = sorted(range(len(wires)), key=lambda k: -measured[k][4])
    accepted: set[int] = set()
    for _ in range(MAX_SUPPORT_ROUNDS):
        before = set(accepted)
        for k in order:
            if k not in accepted and sure(judge(k, accepted)[0]):
                accepted.add(k)
        # Then each accepted wire against all the others: a false pairing accepted early is
        # explained once the true wires it borrows from are in; drop the least sure, repeat.
        while accepted:
            scores = {k: judge(k, accepted - {k})[0] for k in accepted}
            # Equal scores (two wires each explained by the other from one strip): the
            # weaker goes.
            worst = min(
                accepted,
                key=lambda k: (-1.0 if scores[k] is None else scores[k], measured[k][4]),
            )
            if sure(scores[worst]):
                break
            # Unless a wire that lands on wire pixels clearly less often is all that keeps it
            # unsure: the two lie on the same image wire from one strip, each explains the
            # other away there, and only one of them is what that image shows. The worse
            # fit goes (a false pairing leaves the image wire it borrows where the true
            # wires slope; package corridor at 12 MP: 77 % against the conductor's 98 %).
            loser = next(
                (
                    o
                    for o in sorted(accepted - {worst}, key=lambda o: fit[o][0])
                    if fits_worse(o, worst) and sure(judge(worst, accepted - {worst, o})[0])
                ),
                worst,
            )
            if loser != worst:
                logger.debug(
                    "support: wire %d, not wire %d, goes: it alone keeps %d unsure and lands "
                    "on wire pixels less often (%.2f against %.2f)",
                    loser,
                    worst,
                    worst,
                    fit[loser][0],
                    fit[worst][0],
                )
            accepted.discard(loser)
        # A wire rejected while the wires it lies beside were not yet in (an image wire of
        # theirs then looked free to pair with) is judged again on the final set.
        if accepted == before:
            break

    out = []
    for k, wire in enumerate(wires):
        ms, cross, groups, height = measured[k][:4]
        confidence, length, hit, use, why = judge(k, accepted - {k})
        confirming = _confirming_strips(
            measured[k][5],
            length,
            hit,
            np.array([view_hit_rates[m.view_index] for m in ms]),
            typical_rate,
            options,
        )
        strong = why is None  # views that can tell decided (not a glimpse in one of them)
        all_len = np.maximum(0.5 * np.array([len(m.uv) for m in ms]), 1e-9)
        all_chance = np.array([m.control.mean() for m in ms])
        out.append(
            WireSupport(
                wire_id=wire.wire_id,
                views=len(ms),
                strips=len(groups),
                crossing_views=int(cross.sum()),
                hit_rate=fit[k][0],
                crossing_hit_rate=float(np.average(hit[use], weights=length[use]))
                if strong and use.any()
                else None,
                chance=float(np.average(all_chance, weights=all_len)) if ms else 0.0,
                confidence=confidence if k in accepted else min(confidence or 0.0, 0.5),
                geometry="strong" if strong else "weak",
                height_above_ground=height_above_ground(scene, wire),
                advice=None
                if strong or not groups
                else _advice(wire, groups, crossing_offset * height, why == "hidden"),
                supported_s=None if k in accepted else stretch(k, accepted - {k}),
                confirming_strips=confirming,
            )
        )
    return out


def _confirming_strips(
    strip_of: npt.NDArray[np.int64],
    length: F64,
    hit: F64,
    rate: F64,
    typical_rate: float,
    options: SupportOptions,
) -> int:
    """How many strips confirm a wire on their own: their views see a stretch of it that no
    other wire explains (``length``, px) and land on wire pixels there at least
    ``min_hit_share`` as often as they see true wires."""
    own = length >= options.min_projected_px
    rate = np.where(np.isfinite(rate), rate, typical_rate)
    count = 0
    for g in np.unique(strip_of[own]):
        sel = own & (strip_of == g)
        observed = float(np.average(hit[sel], weights=length[sel]))
        count += observed >= options.min_hit_share * float(
            np.average(rate[sel], weights=length[sel])
        )
    return count


def _extent(wire: FittedWire) -> float:
    return float(wire.s_range[1] - wire.s_range[0])


# Ends of long wires this close together along the line mark one support.
SUPPORT_END_SPREAD = 5.0
# A short piece reaching at least this far into the span past a support and this far out
# past the outermost end of the long wires there is part of it (the ends of pieces are
# uncertain by a few tenths of a metre).
SUPPORT_OVERHANG = 1.0
SUPPORT_OVERHANG_OUT = 0.5


def support_members(
    wires: Sequence[FittedWire], along_xy: F64, long_length: float
) -> list[tuple[int, float]]:
    """Short pieces that are members of a support (tower bracing), not wires, and short
    pieces wholly past a support where no long wire hangs.

    Conductors end at their supports, so where two or more long wires (at least
    ``long_length``) end together along the line there is a support. A lattice tower's
    members along the line are straight, well seen and really there, so the views confirm
    them; but a piece shorter than ``long_length`` that runs through such a place, past it on
    both sides, is part of the structure: a conductor stops there.

    Returns:
        (index into ``wires``, position of the support along the line) of each member.
    """

    def ends(w: FittedWire) -> F64:
        return np.sort(w.points(np.array(w.s_range))[:, :2] @ along_xy)

    spans = [ends(w) for w in wires]
    long_wires = [(w, e) for w, e in zip(wires, spans, strict=True) if _extent(w) >= long_length]
    long_spans = [e for _, e in long_wires]

    def lowest_end_z(at: float) -> float:
        """The lowest of the long wires' ends within SUPPORT_END_SPREAD of ``at`` (inf: none)."""
        z = []
        for w, _ in long_wires:
            p = w.points(np.array(w.s_range))
            d = np.abs(p[:, :2] @ along_xy - at)
            if d.min() <= SUPPORT_END_SPREAD:
                z.append(float(p[np.argmin(d), 2]))
        return min(z, default=np.inf)

    # Wires seen only in part end short of their support, inside the span: the support is
    # where the outermost ends of a group of nearby ends meet (the lower ends from below,
    # the upper ends from above).
    supports = []
    for side in (0, 1):
        sign = 1.0 if side == 0 else -1.0  # outward is down for lower ends, up for upper
        pos = np.sort(sign * np.array([e[side] for e in long_spans]))
        if len(pos) < 2:
            continue
        breaks = np.flatnonzero(np.diff(pos) > SUPPORT_END_SPREAD) + 1
        for group in np.split(pos, breaks):
            outer = group[group <= group[0] + SUPPORT_END_SPREAD]
            if len(outer) >= 2:
                at = float(sign * np.median(outer))
                supports.append((sign, at, float(sign * outer[0]), lowest_end_z(at)))
    out = []
    for k, (w, (lo, hi)) in enumerate(zip(wires, spans, strict=True)):
        if _extent(w) >= long_length:
            continue
        # Wholly past a support, where no long wire hangs: not a wire of these spans (it
        # lies past where they all end; a span beyond has long wires of its own there).
        past = [
            (sign, at)
            for sign, at, outermost, _ in supports
            if (hi if sign > 0 else -lo) <= sign * outermost - SUPPORT_OVERHANG_OUT
        ]
        if past and not any(e[0] < hi and lo < e[1] for e in long_spans):
            out.append((k, past[0][1]))
            continue
        for sign, at, outermost, lowest_end in supports:
            # Along the outward direction: the piece's outer and inner ends.
            outer_end, inner_end = (lo, hi) if sign > 0 else (-hi, -lo)
            if (
                outer_end <= sign * outermost - SUPPORT_OVERHANG_OUT
                and inner_end >= sign * at + SUPPORT_OVERHANG
            ):
                out.append((k, at))
                break
            # At the support and far below every long wire's end there: no conductor of it
            # hangs that low (insulators are a few metres long); a member of the structure
            # (shared cross seed 6: a 5.6 m piece 9 m above the ground at the tower, the
            # wires' ends 25-35 m up, ending where the outermost wire ends).
            if (
                lo <= at + SUPPORT_END_SPREAD
                and hi >= at - SUPPORT_END_SPREAD
                and float(w.polyline(1.0)[:, 2].max()) < lowest_end - SUPPORT_END_SPREAD
            ):
                out.append((k, at))
                break
    return out


def keep_supported(
    wires: Sequence[FittedWire],
    supports: Sequence[WireSupport],
    options: SupportOptions,
    min_height: float,
) -> tuple[list[FittedWire], list[WireSupport]]:
    """Drop the wires that the views able to tell reject and the lines on the ground (median
    height above it below ``min_height``); warn about weak geometry."""
    kept, kept_support = [], []
    for w, s in zip(wires, supports, strict=True):
        if s.height_above_ground < min_height:
            logger.info(
                "support: wire %d dropped (%.0f m): %.1f above the ground — a line on the "
                "ground (road edge, shadow, field row), not a wire",
                w.wire_id,
                w.s_range[1] - w.s_range[0],
                s.height_above_ground,
            )
            continue
        if not options.accepts(s.confidence):
            logger.info(
                "support: wire %d dropped (%.0f m): confidence %s, on wires %.0f %% of its "
                "length in %d views (%d crossing), chance %.0f %% — a false pairing of image "
                "wires, or explained by other wires",
                w.wire_id,
                w.s_range[1] - w.s_range[0],
                "none" if s.confidence is None else f"{s.confidence:.3f}",
                100 * s.hit_rate,
                s.views,
                s.crossing_views,
                100 * s.chance,
            )
            continue
        kept.append(w)
        kept_support.append(s)
    for w, s in zip(kept, kept_support, strict=True):
        if s.geometry == "weak":
            logger.warning(
                "wire %d rests on weak geometry (%d views, no view can tell it from a false "
                "pairing of neighbouring wires): %s",
                w.wire_id,
                s.views,
                s.advice,
            )
    logger.info(
        "support: %d of %d wires kept (%d on strong geometry); confidence %s",
        len(kept),
        len(wires),
        sum(s.geometry == "strong" for s in kept_support),
        [None if s.confidence is None else round(s.confidence, 3) for s in kept_support],
    )
    return kept, kept_support
