"""The whole method, composed from its stages: model + images → wires.

``reconstruct`` only chains the stage functions; each stage can be called on its own.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt
from scipy.cluster.hierarchy import fcluster, linkage
from scipy.spatial import cKDTree
from scipy.stats import norm

from .clearance import WireMeasures, assign_kinds, measure_wire
from .coverage import log_coverage, measured_coverage, pairs_onto_traced
from .dense import dense_ground, fill, open_ply
from .detect import DetectOptions, WireMask, detect_wires
from .errors import InputError, PairGeometryError
from .export import export_results
from .faint import evidence_stretches, faint_hypotheses
from .files import wire_colors
from .geometry import (
    across_of,
    axial_diff_deg,
    axial_mean_deg,
    azimuth_deg_of,
    image_direction_of_azimuth,
    plan_axes,
)
from .georef import Georeference, crs_converter, crs_wkt, read_georeference
from .las import CONDUCTOR, WIRE_CLASS, write_las
from .options import validate
from .pairs import (
    WIDE_CANDIDATES,
    DirectionCandidates,
    ImagePair,
    WireCorridor,
    anchored_corridor,
    corridor_from_points,
    direction_candidates,
    directions_near,
    footprint_along,
    provisional_corridors,
    select_pairs,
)
from .rectify import RectifiedPair, rectify_pair
from .report import write_report
from .results import (
    CorridorResult,
    OutputOptions,
    ReconstructionOptions,
    ReconstructionResult,
)
from .scene import Scene, SceneImage, load_scene, read_image, resolve_inputs
from .sfm import run_sfm
from .spans import LineSupport, Spans, WireSpan, attached_again, find_spans
from .support import (
    SupportOptions,
    WireSupport,
    height_above_ground,
    keep_supported,
    support_members,
    wire_support,
)
from .swaps import swapped_pairings
from .tasks import ExecutionOptions, Store, Tasks, digest, run_key, tasks_for
from .trace import MIN_REDUNDANCY, MIN_TRACED_SHARE, MIN_VIEWS, TraceOptions, trace_wires
from .triangulate import Primitives, triangulate_pair, wire_centres
from .verify import VerifiedPoints, WireMaskFn, verify_primitives
from .wires import (
    FittedWire,
    WiresOptions,
    absorb_points,
    merge_pieces,
    nearest_wire,
    refit,
    split_wires,
    trim_wire,
)

logger = logging.getLogger(__name__)

F64 = npt.NDArray[np.float64]

# A confirmed piece whose points lie this close (median) to another wire's curve is a stretch
# of that wire (a third of a metre: a catenary continued 20-30 m past its points).
CONTINUATION_DISTANCE = 0.3

# A primitive within this many times a confirmed wire's RMS residual of its curve is a
# measured point of it (1.5: on the shared generator's cross and grid flights the points
# then reach 3-13 % more of each wire with the median distance to the truth at 2.7-3.3 cm;
# twice the residual adds 1-2 % more at 3.1-3.5 cm).
CONSENSUS_SIGMAS = 1.5

# A wire the views' hit rates rejected is kept when the views that would fix it find it at
# this share of its places or more (:func:`_second_look`). On the shared generator's flights
# across the line the true wires so rejected are found at 94 %, the false pairings at 0-8 %.
MIN_SECOND_LOOK_SHARE = 0.5

# The conductors of a line run side by side at its crossarm's spacing: where two confirmed
# wires run parallel along at least this share of the shorter one, the offset between them
# (across and in height) is one of the line's, and a conductor that offset beside any
# confirmed wire is looked for (:func:`_siblings`).
MIN_SIBLING_OVERLAP = 0.5
# Where the views find such a hypothesis at all, it is looked for again at these heights
# about its offset's, in units of ``CONTINUATION_DISTANCE`` (:func:`_siblings`).
SIBLING_LIFTS = (-0.5, 0.5, -1.0, 1.0)

# Confirmed wires take the points the views favour in steps of ``WiresOptions.max_gap`` past
# their ends; this many steps reach past any span.
MAX_ABSORB_STEPS = 40


def _add_time(timings: dict[str, float], stage: str, t0: float) -> None:
    timings[stage] = timings.get(stage, 0.0) + time.perf_counter() - t0


def _merged(
    parts: Sequence[CorridorResult], inlier_distance: float, long_length: float = np.inf
) -> CorridorResult:
    """The corridors' results as one: their points, pairs and wires side by side, wire ids
    and point indices kept apart. A wire of a later corridor whose points mostly lie on a
    wire of an earlier one (where two legs of a line overlap at an angle tower, one leg's
    pairs see the other's wires too) is that wire seen again, and is left out. So is a
    piece of a later corridor that holds no wire ``long_length`` long where it is a member
    of an earlier line's support (:func:`support_members` along that line): a tower's
    bracing, straight and really there, probed as a line of its own."""
    first = parts[0]
    if len(parts) == 1:
        return dataclasses.replace(first, legs=[0] * len(first.wires), corridors=[first.corridor])
    wires, supports = list(first.wires), list(first.supports)
    legs = [0] * len(wires)
    n_pts, n_pairs = len(first.verified), len(first.pairs)
    n_prims = int(sum(len(p) for p in first.primitives))
    next_id = max((w.wire_id for w in wires), default=-1) + 1
    verified = first.verified
    for leg, part in enumerate(parts[1:], 1):
        v = part.verified
        before = [w.polyline(0.1) for w in wires]
        tree = cKDTree(np.concatenate(before)) if before else None
        pieces_only = all(w.s_range[1] - w.s_range[0] < long_length for w in part.wires)
        bracing = _support_members_of(part.wires, parts[:leg], long_length) if pieces_only else {}
        for k, (w, sup) in enumerate(zip(part.wires, part.supports, strict=True)):
            line = bracing.get(k)
            if line is not None:
                logger.info(
                    "line at %.1f°: wire %d (%.0f m) is a member of a support of the line at "
                    "%.1f°; left out",
                    part.corridor.azimuth_deg,
                    w.wire_id,
                    w.s_range[1] - w.s_range[0],
                    line.corridor.azimuth_deg,
                )
                continue
            if tree is not None:
                d, _ = tree.query(v.pts_in_world[w.point_indices])
                if np.mean(d <= 2 * inlier_distance) >= 0.5:
                    logger.info(
                        "line at %.1f°: wire %d lies on a wire of an earlier line; left out",
                        part.corridor.azimuth_deg,
                        w.wire_id,
                    )
                    continue
            wires.append(
                dataclasses.replace(w, wire_id=next_id, point_indices=w.point_indices + n_pts)
            )
            supports.append(sup)
            legs.append(leg)
            next_id += 1
        verified = verified.concatenated(v, n_pairs, n_prims)
        n_pts += len(v)
        n_pairs += len(part.pairs)
        n_prims += int(sum(len(p) for p in part.primitives))
    return _side_by_side(
        first.corridor, parts, verified, wires, supports, legs, [p.corridor for p in parts]
    )


# Wires of one line hang from its supports' cross-arms: each lies within this distance
# (across the line and in height, at its middle) of another of the line's wires. The
# widest phase spacings, of 765 kV lines on flat towers, are about 14 m; lines side by side
# keep more between them.
LINE_LINK_M = 15.0


def _middles(part: CorridorResult, idx: Sequence[int]) -> F64:
    """(len(idx), 3) the middle of each of ``part``'s wires ``idx``."""
    return np.array(
        [part.wires[k].points(np.array([np.mean(part.wires[k].s_range)]))[0] for k in idx]
    )


def _own_corridor(
    legs: list[int], corridors: list[WireCorridor], c: WireCorridor, wires: Sequence[int],
    across: F64,
) -> float:  # fmt: skip
    """Give ``wires`` (their ``across`` ``c`` at their middles) a copy of corridor ``c`` (its
    direction and extent) centred on them, in ``legs`` and ``corridors``; how far across."""
    shift = float(np.mean(across))
    corridors.append(dataclasses.replace(c, centre_xy=c.centre_xy + shift * c.normal_xy))
    for k in wires:
        legs[k] = len(corridors) - 1
    return shift


def _lines_apart(part: CorridorResult) -> CorridorResult:
    """``part`` with the wires of each corridor that hang in groups apart (no wire of a group
    within ``LINE_LINK_M`` of one of another, across the line and in height) as lines of their
    own: the group with the most wires keeps the corridor, each other one gets a copy of it
    (its direction and extent) centred on the group. A pole line along a tower line in the
    same band of an area survey is otherwise taken for the tower line's outer wires: the
    line's ends are placed between the towers' and the poles' (the package's `parallel`
    layout: 11.9 m off), and the pole line has no support of its own."""
    legs, corridors = list(part.legs), list(part.corridors)
    for li, c in enumerate(part.corridors):
        idx = np.array([k for k, leg in enumerate(part.legs) if leg == li])
        if len(idx) < 2:
            continue
        mids = _middles(part, idx)
        across = (mids[:, :2] - c.centre_xy) @ c.normal_xy
        groups = fcluster(linkage(np.c_[across, mids[:, 2]], "single"), LINE_LINK_M, "distance")
        if groups.max() == 1:
            continue
        by_size = sorted(set(groups.tolist()), key=lambda g: (-int((groups == g).sum()), g))
        for g in by_size[1:]:
            mine = groups == g
            shift = _own_corridor(legs, corridors, c, idx[mine], across[mine])
            logger.info(
                "lines: %d wires %.1f across the line at %.1f° from its other %d, in a group of "
                "their own: a line beside it",
                int(mine.sum()),
                shift,
                c.azimuth_deg,
                int((~mine).sum()),
            )
    if len(corridors) == len(part.corridors):
        return part
    return dataclasses.replace(part, legs=legs, corridors=corridors)


def _side_by_side(
    corridor: WireCorridor,
    parts: Sequence[CorridorResult],
    verified: VerifiedPoints,
    wires: list[FittedWire],
    supports: list[WireSupport],
    legs: list[int] | None = None,
    corridors: list[WireCorridor] | None = None,
) -> CorridorResult:
    """Parts' results as one, given their points and wires put together: their pairs,
    primitives and decoded images one after the other, their counts summed."""
    return CorridorResult(
        corridor,
        [p for part in parts for p in part.pairs],
        [p for part in parts for p in part.primitives],
        verified,
        wires,
        supports,
        [p for part in parts for p in part.decoded],
        sum(p.n_candidates for p in parts),
        sum(p.on_ground for p in parts),
        legs or [],
        corridors or [],
    )


def _detect_rectified(
    pair: RectifiedPair,
    side: int,
    image: np.ndarray,
    corridor: WireCorridor,
    options: DetectOptions,
):
    """Wire centres of one side of a rectified pair."""
    rect, valid = pair.rectify_image(side, image)
    centre = np.r_[corridor.centre_xy, corridor.height]
    direction = image_direction_of_azimuth(
        lambda p: pair.project(side, p)[0], centre, corridor.azimuth_deg
    )
    wm = detect_wires(rect, direction, options)
    # The template sees the edge of the resampled footprint as a line: drop it.
    border = options.template_length_px + 4
    valid = cv2.erode(valid.astype(np.uint8), np.ones((border, border), np.uint8)).astype(bool)
    return wire_centres(wm.mask & valid, wm.response), int(wm.mask.sum())


def crop_wire_mask(options: DetectOptions, template_length_px: int = 0) -> WireMaskFn:
    """The detector verification calls on each view: only the crop where primitives land is
    searched; the length filter stays scaled to the whole image; ``template_length_px``
    (0: the detector's own) is the line template's length there."""
    if template_length_px:
        options = dataclasses.replace(options, template_length_px=template_length_px)

    def wire_mask(
        view: SceneImage, image: np.ndarray, direction: float, crop: tuple[int, int, int, int]
    ) -> WireMask:
        x0, y0, x1, y1 = crop
        crop_options = dataclasses.replace(
            options, min_component_length_px=options.min_length_px(view.width)
        )
        return detect_wires(image[y0:y1, x0:x1], direction, crop_options)

    return wire_mask


# A power line carries at least two wires (a circuit and its return; a single-wire earth
# return line is the exception): a best direction whose probe found fewer makes the direction
# search look wider, and the wider look's directions compete with it by wire length.
MIN_LINE_WIRES = 2


@dataclass(frozen=True, eq=False)
class _Probe:
    """What the pairs of one probed band measured: its wires' length and number, the band,
    their points, and the direction of their planes."""

    length: float
    num_wires: int
    corridor: WireCorridor
    pts_in_world: F64
    azimuth_deg: float


def _probe(
    prov: WireCorridor, scene: Scene, options: ReconstructionOptions
) -> tuple[_Probe | None, list[Path]]:
    """Triangulate and verify a few pairs crossing one provisional band; the wires above the
    ground their points make (None: none), and the images decoded. One task of its own."""
    quiet = dataclasses.replace(options, show_progress=False)
    probe_options = dataclasses.replace(options.pairs, max_pairs=options.pairs.probe_pairs)
    azimuth = prov.azimuth_deg
    try:
        pairs = select_pairs(scene, prov, probe_options, options.verify.crossing_offset)
    except InputError as e:
        logger.info("probe %.1f°: %s", azimuth, e)
        return None, []
    prims, decoded = primitives_for_pairs(scene, pairs, prov, quiet)
    if sum(len(p) for p in prims) == 0:
        return None, decoded
    # The views around the pairs are enough to tell wires from other lines.
    mid = np.mean([[p.left.center_in_world, p.right.center_in_world] for p in pairs], (0, 1))
    near = np.argsort(np.linalg.norm(scene.centers_in_world[:, :2] - mid[:2], axis=1))
    keep = set(near[: options.pairs.probe_views].tolist())
    keep |= {scene.images.index(v) for p in pairs for v in (p.left, p.right)}
    views = tuple(scene.images[i] for i in sorted(keep))
    verified = verify_primitives(
        scene.with_images(views),
        prims,
        [(p.left.name, p.right.name) for p in pairs],
        crop_wire_mask(options.detect, options.verify.template_length_px),
        azimuth,
        options.verify,
        show_progress=False,
        min_height_above_ground=options.triangulate.min_wire_height,
    )
    decoded += verified.decoded
    # Lines on the ground (roads, rows, shadows) triangulate too: they are not wires. The
    # probe ranks directions by the length of wire their points make: it splits chains
    # into layers of curves only in the main split (a wrong direction's scattered false
    # matches give many: shared cross seed 1, probe at 0.2°: 6 → 17 wires, 124 → 377 m,
    # over the wires' 89.7°, 328 m).
    wires = [
        w
        for w in split_wires(verified.pts_in_world, azimuth, options.wires, layers=False)
        if height_above_ground(scene, w) >= options.triangulate.min_wire_height
    ]
    length = float(sum(w.s_range[1] - w.s_range[0] for w in wires))
    logger.info(
        "probe %.1f°: %d pairs, %d verified points, %d wires, %.0f m of wire",
        azimuth,
        len(pairs),
        len(verified),
        len(wires),
        length,
    )
    if not wires:
        return None, decoded
    idx = np.concatenate([w.point_indices for w in wires])
    # The direction of the wires' own planes, weighted by their length (the points' spread
    # is not: parallel wires widen it across the line).
    measured = axial_mean_deg(
        np.array([azimuth_deg_of(w.plane_direction_xy, axial=False) for w in wires]),
        np.array([w.s_range[1] - w.s_range[0] for w in wires]),
    )
    return _Probe(length, len(wires), prov, verified.pts_in_world[idx], measured), decoded


def _same_band(a: WireCorridor, b: WireCorridor, tolerance_deg: float) -> bool:
    """Whether two provisional bands are one: directions within ``tolerance_deg``, each
    band's middle within the other, and neither more than twice as wide as the other (a
    band across the whole survey probed with a few pairs has not probed a narrow one in
    it)."""
    if axial_diff_deg(a.azimuth_deg, b.azimuth_deg) >= tolerance_deg:
        return False
    normal = plan_axes(a.azimuth_deg)[1]
    apart = abs(float((a.centre_xy - b.centre_xy) @ normal))
    wa, wb = a.wires_half_width, b.wires_half_width
    return apart <= min(wa, wb) and max(wa, wb) <= 2.0 * min(wa, wb)


def _has_line(probe: _Probe | None) -> bool:
    """Did a probe measure a line's wires (a line carries at least ``MIN_LINE_WIRES``)?"""
    return probe is not None and probe.num_wires >= MIN_LINE_WIRES


def probe_corridor(scene: Scene, options: ReconstructionOptions) -> WireCorridor:
    """The main line's corridor: the first of :func:`probe_corridors`."""
    return probe_corridors(scene, options)[0]


def _another_line(
    probe: _Probe, found: Sequence[_Probe | WireCorridor], tolerance_deg: float
) -> bool:
    """Whether a probe measured a line other than those found: wires enough for a line, in
    a direction of their own (a probe across the found line's wires at another angle
    measures that line's direction again)."""
    return probe.num_wires >= MIN_LINE_WIRES and all(
        axial_diff_deg(probe.azimuth_deg, f.azimuth_deg) >= tolerance_deg for f in found
    )


def probe_corridors(
    scene: Scene, options: ReconstructionOptions, tasks: Tasks | None = None
) -> list[WireCorridor]:
    """Find where the wires are by measuring them: a few pairs per candidate direction.

    Long image lines run along the wires, but also along roads, field rows and shadows. For
    each of the strongest candidate directions, a few pairs crossing it are triangulated and
    verified in the views around them; the direction whose points form the most wire length
    is the main line, and its points give the corridor's band and heights (so that pairs are
    then chosen where the wires really are, at the heights they really hang).

    A survey may hold more lines, or a line that turns at an angle tower: every other
    direction whose probe measures a line's wires (two or more) running in a direction of
    their own is a corridor too, longest first.
    """
    cands = direction_candidates(scene, options.pairs)
    decoded = list(cands.decoded)
    heights = (options.triangulate.min_wire_height, options.triangulate.max_wire_height)
    probes: list[_Probe] = []

    def best() -> _Probe | None:
        return max(probes, key=lambda p: p.length) if probes else None

    tried: list[WireCorridor] = []

    def probe_all(
        found: DirectionCandidates, ks: Sequence[int], bands: int = 2, slices: bool = False
    ) -> None:
        # Each probe is a task of its own (its pairs run one after the other in it). A band
        # probed already (in about the same direction, place and width) is not probed again.
        provs = []
        for k in ks:
            for prov in provisional_corridors(
                scene, found, found.azimuths_deg[k], options.pairs, heights, slices=slices
            )[: None if slices else bands]:
                if not any(_same_band(prov, t, tol) for t in tried):
                    provs.append(prov)
                    tried.append(prov)
        for probe, n in (tasks or Tasks()).map(_probe, provs, scene, options):
            decoded.extend(n)
            if probe is not None:
                probes.append(probe)

    tol = options.pairs.candidate_tolerance_deg
    order = list(np.argsort(cands.weights)[::-1][: options.pairs.probe_candidates])
    probe_all(cands, order)
    first = best()
    if options.pairs.wire_azimuth_deg is None:
        # A few images show the main line; another line may cross a corner of the survey
        # that they miss (shared twolines seed 3: the pole line, seen by none of the six).
        # Read more images, rank their directions alike at every angle, and probe those not
        # probed yet. When no direction of the first look has a line's wires (or only one
        # wire, where a line carries at least two: an area survey whose line a few of its
        # images see, at an angle to its strips; shared grid seed 3: 0 of 6 probes), this
        # is the run's last chance to find it: up to twice as many.
        lost = not _has_line(first)
        wide = direction_candidates(scene, options.pairs, wide=True, read=cands.analysed)
        decoded += list(wide.decoded)  # at full resolution: the first look's images again
        if lost or first is None:
            # Still looking for the line: every direction again, with the bands the wider
            # look's images give it. The first look's few images may all miss the line in a
            # large survey: its bands of a direction are where those images lie (on the
            # full road flight, 162 images over 400 m, none of its six sees the road line,
            # and its direction was probed far from it and over the whole survey at once;
            # a footprint-wide slice of it holds the line, below). A band probed already
            # is not probed again (``tried``).
            ranked = [int(k) for k in np.argsort(wide.weights)[::-1]]
        else:
            # Another line runs in a direction of its own: one near the found line's can
            # only measure that line again.
            wide_tol = max(tol, options.pairs.line_tolerance_deg)
            probed = [cands.azimuths_deg[k] for k in order] + [first.azimuth_deg]
            ranked = [
                int(k)
                for k in np.argsort(wide.weights)[::-1]
                if all(axial_diff_deg(wide.azimuths_deg[k], a) >= wide_tol for a in probed)
            ]
        fresh = ranked[: (WIDE_CANDIDATES if lost else 1) * options.pairs.probe_candidates]
        logger.info(
            "probe: %s; %d more from %d images ranked alike at every angle: %s",
            "no direction gave wires"
            if first is None
            else ("the best direction gave one wire" if lost else "looking for more lines"),
            len(fresh),
            len(wide.analysed),
            [round(wide.azimuths_deg[k], 1) for k in fresh],
        )
        # Looking for more lines, the densest band of each direction is enough: a line's
        # wires pile up there (the wider band is for a main line a road outdoes). Still
        # looking for the line, the strongest directions are probed across the whole survey,
        # slice by slice (a few pairs over it all see a few places of it).
        if lost:
            top = fresh[: options.pairs.probe_candidates]
            for k in top:  # one direction at a time: the first with a line ends it
                probe_all(wide, [k], slices=True)
                if _has_line(best()):
                    break
            else:
                probe_all(wide, fresh[len(top) :], options.pairs.probe_bands)
        else:
            probe_all(wide, fresh, 1)
        # Still no line: on down the list, a few at a time, until one has a line's wires.
        step = options.pairs.probe_candidates
        for at in range(len(fresh), len(ranked) if lost else 0, step):
            if _has_line(best()):
                break
            batch = ranked[at : at + step]
            logger.info(
                "probe: still no line; %d more of the wider look's directions: %s",
                len(batch),
                [round(wide.azimuths_deg[k], 1) for k in batch],
            )
            probe_all(wide, batch, options.pairs.probe_bands)
    first = best()
    if first is None:
        azimuth = cands.azimuths_deg[int(np.argmax(cands.weights))]
        logger.warning(
            "no candidate direction gave wires in a probe; using the strongest line direction "
            "%.1f° with an unmeasured corridor (give --pairs.wire_azimuth_deg if it is not "
            "the wires)",
            azimuth,
        )
        prov = provisional_corridors(scene, cands, azimuth, options.pairs, heights)[0]
        return [dataclasses.replace(prov, decoded=tuple(decoded))]
    lines = [first]
    if options.pairs.wire_azimuth_deg is None:
        for probe in sorted(probes, key=lambda p: -p.length):
            if _another_line(probe, lines, options.pairs.line_tolerance_deg):
                lines.append(probe)
    corridors = [
        corridor_from_points(
            scene,
            p.pts_in_world,
            p.azimuth_deg if options.pairs.wire_azimuth_deg is None else p.corridor.azimuth_deg,
            options.pairs,
            p.corridor,
            tuple(decoded) if k == 0 else (),
        )
        for k, p in enumerate(lines)
    ]
    if len(corridors) > 1:
        logger.info(
            "%d lines (or legs of a line) in the survey, at %s°",
            len(corridors),
            ", ".join(f"{c.azimuth_deg:.1f}" for c in corridors),
        )
    return corridors


# Of the directions around a support not along a line found, the strongest this many are
# probed for a line leaving it.
BRANCH_CANDIDATES = 2


def branch_corridors(
    scene: Scene,
    supports: Sequence[LineSupport],
    corridors: Sequence[WireCorridor],
    options: ReconstructionOptions,
    tasks: Tasks | None = None,
) -> tuple[list[WireCorridor], list[Path]]:
    """Lines that leave a support of a line found (a branch line from a junction pole), and
    the images read to look for them.

    Over the whole survey a thin line that a few of its images cross is outvoted by roads,
    field rows and the main line (the road flight's line across the field: two wires of
    ~10 mm, 20-somethingth of the wider look's directions). Lines end and branch at
    supports, and around one the lines that leave it are a large share of what the images
    show (:func:`directions_near`). The strongest ``BRANCH_CANDIDATES`` directions there
    that no corridor runs along are probed in a band through the support (its radius,
    ``SpanOptions.support_radius``, either side), as the first look probes a direction;
    a probe that measures a line's wires in a direction of their own, reaching past the
    support, gives a corridor."""
    if options.pairs.wire_azimuth_deg is not None or not supports:
        return [], []
    tol = options.pairs.line_tolerance_deg
    known = [c.azimuth_deg for c in corridors]
    radius = options.spans.support_radius
    provs, at = [], []
    decoded: list[Path] = []
    for sup in supports:
        if not np.isfinite(sup.top_z):
            continue
        top = np.r_[sup.position[:2], sup.top_z]
        ground = float(sup.position[2])
        near, read = directions_near(scene, top, ground, options.pairs)
        decoded += read
        fresh = [a for a, _ in near if all(axial_diff_deg(a, k) >= tol for k in known)]
        for azimuth in fresh[:BRANCH_CANDIDATES]:
            provs.append(
                anchored_corridor(
                    scene, azimuth, sup.position[:2], radius, float(sup.top_z),
                    (ground + options.triangulate.min_wire_height, float(sup.top_z) + radius),
                    options.pairs,
                )
            )  # fmt: skip
            at.append(sup)
        logger.info(
            "branches: support %d: directions around it %s; probing %s",
            sup.support_id,
            [round(a, 1) for a, _ in near[:6]],
            [round(a, 1) for a in fresh[:BRANCH_CANDIDATES]],
        )
    found: list[WireCorridor] = []
    for (probe, read), sup in zip(
        (tasks or Tasks()).map(_probe, provs, scene, options), at, strict=True
    ):
        decoded += read
        if probe is None or not _another_line(probe, [*corridors, *found], tol):
            continue
        # A line leaving the support runs on past it (tower members and cross-arms do not).
        past = np.hypot(*(probe.pts_in_world[:, :2] - sup.position[:2]).T) > 2 * radius
        if past.sum() < options.wires.min_points:
            continue
        logger.info(
            "branches: a line leaves support %d at %.1f° (%d wires, %.0f m of wire)",
            sup.support_id,
            probe.azimuth_deg,
            probe.num_wires,
            probe.length,
        )
        found.append(
            corridor_from_points(
                scene, probe.pts_in_world, probe.azimuth_deg, options.pairs, probe.corridor
            )
        )
    return found, decoded


def _pair_primitives(
    job: tuple[int, ImagePair], scene: Scene, corridor: WireCorridor, options: ReconstructionOptions
) -> tuple[Primitives, list[Path]]:
    """Rectify, detect and triangulate pair ``k`` of ``job`` (one task: it reads only its
    two images). Returns its primitives and the images decoded."""
    k, p = job
    try:
        geom = rectify_pair(
            scene, p.left, p.right, options.rectify, options.triangulate.max_wire_height
        )
    except PairGeometryError as exc:
        # One pair the selection's estimate let through (an oblique pair in a probe of a
        # direction that is not the line's on Seneca) does not stop the run.
        logger.warning("pair %d skipped: %s", k, exc)
        return Primitives(np.zeros((0, 3)), np.zeros(0), np.zeros(0), np.zeros(0), k), []
    centres = []
    decoded = []
    for side, view in enumerate(geom.sides):
        image = read_image(view.path)
        decoded.append(view.path)
        c, n_px = _detect_rectified(geom, side, image, corridor, options.detect)
        centres.append(c)
    prims = triangulate_pair(geom, scene, centres[0], centres[1], k, options.triangulate)
    left = centres[0]
    u_src, v_src = geom._source_pixels(0, np.c_[left.u, left.rows + 0.5])
    seen = u_src > -1e4
    prims = dataclasses.replace(prims, left_wire_px=np.c_[u_src[seen], v_src[seen]])
    logger.info(
        "pair %d %s|%s: %dx%d px rectified, %d + %d wire centres → %d primitives",
        k,
        p.left.name,
        p.right.name,
        geom.widths_px[0],
        geom.height_px,
        len(centres[0]),
        len(centres[1]),
        len(prims),
    )
    return prims, decoded


def primitives_for_pairs(
    scene: Scene,
    pairs: list[ImagePair],
    corridor: WireCorridor,
    options: ReconstructionOptions,
    tasks: Tasks | None = None,
) -> tuple[list[Primitives], list[Path]]:
    """Rectify, detect and triangulate every pair, each pair one task of ``tasks`` (None:
    in this process). Returns the primitives, in the pairs' order, and the images decoded."""
    results = (tasks or Tasks()).map(
        _pair_primitives,
        list(enumerate(pairs)),
        scene,
        corridor,
        options,
        desc="pairs",
        unit="pair",
        show_progress=options.show_progress,
    )
    out: list[Primitives] = []
    decoded: list[Path] = []
    for prims, paths in results:
        out.append(prims)
        decoded += paths
    return out, decoded


def _settled_by_the_views(
    verified: VerifiedPoints, min_posterior: float, near: float
) -> VerifiedPoints:
    """Pending points that views offset across the wires see, most of them on a wire, and
    that every view seeing them makes sure to lie on a wire (a posterior ≥
    ``min_posterior`` with the prior 1/2 of a settled match), join the points from which
    wires are hypothesised, where they add to the verified points (farther than ``near``).

    Their match is not settled point by point (one wire centre, K candidates on its row,
    few views: the top conductors and shields of a flight across the line are seen by 3-6
    images, 2 of them the pair's), but a wire of them is judged as a whole by the views
    that can tell (:func:`colmap_powerline.support.wire_support`). Points that no view
    offset across the wires sees stay pending: there the prior 1/K is all that keeps false
    pairings out of the hypotheses, and only confirmed wires take them."""
    pending = verified.pending
    if pending is None:
        return verified
    logit = np.log(min_posterior / (1 - min_posterior))
    # Seen by views that can tell, and most of them land on a wire (a false pairing of a
    # flight along the line that every view along the wires favours misses them).
    take = np.flatnonzero(
        (pending.evidence >= logit)
        & (pending.crossing_views > 0)
        & (2 * pending.crossing_hits >= pending.crossing_views)
    )
    if len(take) and len(verified):
        # Only where they add to what the verified points cover: within ``near`` of one they
        # lie on the same wire and only slow the split (a confirmed wire takes them later).
        d, _ = cKDTree(verified.pts_in_world).query(pending.pts_in_world[take])
        take = take[d > near]
    if len(take):
        logger.info(
            "verify: %d more points that every view seeing them favours, seen by views that "
            "can tell (%d pending); wires of them are judged as a whole",
            len(take),
            len(pending) - len(take),
        )
    return verified.with_pending(take, min_posterior)


def reconstruct(
    image_path: Path | str | None,
    input_path: Path | str | None,
    output_path: Path | str | None = None,
    options: ReconstructionOptions | None = None,
    outputs: OutputOptions | None = None,
    execution: ExecutionOptions | None = None,
) -> ReconstructionResult:
    """Reconstruct every wire of every line seen by a COLMAP model's images, then (with
    ``output_path``) write them: :func:`write_outputs`.

    Args:
        image_path: the image folder the model's image names are relative to (None: the
            ``images/`` of an undistorted workspace given as ``input_path``).
        input_path: the COLMAP sparse model (binary or text), or an undistorted COLMAP
            workspace; None runs SfM first and writes its model to ``output_path/sparse``.
        output_path: where to write the outputs (None: nothing is written).
        options: the options of every stage (not changed).
        outputs: what is written besides the output contract's files; its dense cloud
            also gives the ground for the clearance.
        execution: where the pairs run (here, or on Dask workers); the outputs are the
            same wherever they run.
    """
    options = options or ReconstructionOptions()
    outputs = outputs or OutputOptions()
    execution = execution or ExecutionOptions()
    validate(options)
    validate(outputs)
    validate(execution)
    if outputs.dense_path is not None:
        open_ply(outputs.dense_path)  # a missing or unreadable cloud stops the run now
    timings: dict[str, float] = {}
    if input_path is None:
        if output_path is None or image_path is None:
            raise InputError("running SfM needs an image folder and an output folder")
        sfm_options = dataclasses.replace(options.sfm, show_progress=options.show_progress)
        sfm = run_sfm(
            image_path, Path(output_path) / "sparse", sfm_options, options.skip_bad_images
        )
        timings.update({f"sfm_{k}": v for k, v in sfm.timings_s.items()})
        input_path = sfm.model_path
    input_path, image_path = resolve_inputs(image_path, input_path)
    georef = read_georeference(input_path)
    if outputs.output_crs:
        if georef is None or georef.origin_wgs84 is None:
            raise InputError(
                f"{input_path}: --output_crs needs a model georeferenced from GPS (georef.json)"
            )
        _crs_function(georef, outputs.output_crs)  # an unknown CRS stops the run now
    t0 = time.perf_counter()
    scene = load_scene(input_path, image_path, skip_bad_images=options.skip_bad_images)
    timings["scene"] = time.perf_counter() - t0

    # What a run writing its outputs finishes is kept in OUTPUT/.pieces/, by what it
    # depends on (the model's bytes, the images, the options), until its outputs are
    # written: a run cut short and started again does not redo it (--redo does).
    store = None
    if output_path is not None:
        quiet = json.dumps(
            dataclasses.asdict(dataclasses.replace(options, show_progress=False)), default=str
        )
        key = run_key(input_path, [v.path for v in scene.images], quiet)
        store = Store(Path(output_path) / ".pieces" / key, redo=execution.redo)
    with tasks_for(execution) as tasks:
        t0 = time.perf_counter()
        corridors = (
            store.get("corridors", lambda: probe_corridors(scene, options, tasks))
            if store is not None
            else probe_corridors(scene, options, tasks)
        )
        timings["pairs"] = time.perf_counter() - t0
        decoded = [p for c in corridors for p in c.decoded]
        parts = _reconstruct_corridors(scene, corridors, options, timings, tasks, store)
        part = _lines_apart(_merged(parts, options.wires.inlier_distance, options.wires.max_gap))
        t0 = time.perf_counter()
        part, spans = _spans_apart(scene, part, options)
        timings["spans"] = time.perf_counter() - t0
        # Lines that leave a support of those found (a branch line from a junction pole).
        t0 = time.perf_counter()
        branches, read = branch_corridors(scene, spans.supports, part.corridors, options, tasks)
        decoded += read
        more = (
            _reconstruct_corridors(scene, branches, options, timings, tasks, store, required=False)
            if branches
            else []
        )
        timings["branches"] = time.perf_counter() - t0
        if more:
            parts += more
            part = _lines_apart(
                _merged(parts, options.wires.inlier_distance, options.wires.max_gap)
            )
            t0 = time.perf_counter()
            part, spans = _spans_apart(scene, part, options)
            timings["spans"] += time.perf_counter() - t0
    corridor, pairs, primitives, verified = (
        part.corridor,
        part.pairs,
        part.primitives,
        part.verified,
    )
    wires, supports, on_ground, n_candidates = (
        part.wires,
        part.supports,
        part.on_ground,
        part.n_candidates,
    )
    decoded += part.decoded
    supports = [supports[k] for k in spans.source]
    t0 = time.perf_counter()
    wires, verified, dec = _traced_to_supports(spans, part.corridors, verified, scene, options)
    decoded += dec
    wires, verified, dec = _measured_by_evidence(
        wires, part.corridors, spans, verified, scene, options
    )
    decoded += dec
    wires, spans = _hung_where_reached(wires, spans, verified.pts_in_world, options)
    # Tracing on to the supports may carry a structure that reaches the ground down to the
    # floor of the heights searched: the floor rule again (shared cross seed 22: a 50 m
    # "line" across the span 5.09-6.2 above a road, 26 m at 5.3 before; 7 of its kind were
    # left out before tracing on).
    wires, spans, supports = _spans_above_the_floor(wires, spans, supports, scene, options)
    timings["trace_to_supports"] = time.perf_counter() - t0
    labels = np.full(len(verified), -1, np.int64)
    for w in wires:
        labels[w.point_indices] = w.wire_id
    logger.info(
        "wires: %d wires from %d verified points (%d assigned)",
        len(wires),
        len(verified),
        int((labels >= 0).sum()),
    )
    if not wires:
        why = []
        if on_ground:
            why.append(f"{on_ground} lay on the ground (road edges, field rows, shadows)")
        if n_candidates > on_ground:
            why.append(f"the views confirmed none of the other {n_candidates - on_ground}")
        logger.warning(
            "no wire found: %d wires were hypothesised from %d verified points%s. If the "
            "images show wires, they are too faint against this ground for the line detector "
            "(a wire of the ground's colour), or too few images see them from positions "
            "across them; the outputs hold no wire",
            n_candidates,
            len(verified),
            "; " + " and ".join(why) if why else "",
        )

    t0 = time.perf_counter()
    coverage = measured_coverage(
        scene,
        wires,
        verified.pts_in_world,
        options.wires.inlier_distance,
        options.trace.reach_px,
        options.detect.side_offset_px,
        options.verify.crossing_offset,
        verified.pair_index >= 0,
    )
    moved_pts, wires, moves = pairs_onto_traced(
        wires, verified.pts_in_world, verified.pair_index, options.wires
    )
    verified = dataclasses.replace(verified, pts_in_world=moved_pts)
    coverage = [
        dataclasses.replace(c, pairs_moved=n, largest_move=m)
        for c, (n, m) in zip(coverage, moves, strict=True)
    ]
    log_coverage(wires, coverage, options.wires.inlier_distance)
    timings["coverage"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    ground, source = scene.ground, "sparse points"
    if outputs.dense_path is not None:
        ground, source = dense_ground(open_ply(outputs.dense_path)), "dense cloud"
    measures = [measure_wire(w, ground, source, options.min_clearance_m) for w in wires]
    assign_kinds(measures, spans=[(p.line, p.span) for p in spans.placement])
    line_supports = _tops_from(
        attached_again(spans.supports, wires, spans.placement), wires, measures, spans.placement
    )
    timings["clearance"] = time.perf_counter() - t0
    result = ReconstructionResult(
        scene,
        corridor,
        pairs,
        primitives,
        verified,
        wires,
        labels,
        timings,
        decoded,
        measures,
        supports,
        georef,
        coverage=coverage,
        placement=spans.placement,
        line_supports=line_supports,
        corridors=part.corridors,
        ground=ground,
        ground_from=outputs.dense_path,
        options=options,
        image_path=Path(image_path),
        input_path=Path(input_path),
    )
    if options.min_clearance_m is not None:
        flagged = [m for m in measures if m.flagged]
        log = logger.warning if flagged else logger.info
        log(
            "clearance: %d of %d wires come closer than %.2f to the ground (%d stretches)",
            len(flagged),
            len(measures),
            options.min_clearance_m,
            sum(len(m.flagged) for m in flagged),
        )
    if output_path is not None:
        write_outputs(result, Path(output_path), outputs)
    if store is not None:
        # The outputs hold the run now: its pieces (tens to hundreds of MB) go.
        store.clear()
    return result


def write_outputs(
    result: ReconstructionResult, output_path: Path | str, outputs: OutputOptions | None = None
) -> dict[str, Path]:
    """Write a reconstruction: the output contract's files (wires.json, wires.csv,
    supports.csv, wires.ply, wire_points.ply) and what ``outputs`` asks for besides (LAS,
    the report, the wires merged into a dense cloud, primitives.ply). Returns the files
    written (also kept in ``result.outputs``)."""
    outputs = outputs or OutputOptions()
    validate(outputs)
    options = result.options or ReconstructionOptions()
    out, georef, timings = Path(output_path), result.georeference, result.timings_s
    if outputs.output_crs and (georef is None or georef.origin_wgs84 is None):
        raise InputError("--output_crs needs a model georeferenced from GPS (georef.json)")
    t0 = time.perf_counter()
    crs = _crs_function(georef, outputs.output_crs)
    result.outputs = export_results(
        out,
        wires=result.wires,
        points=result.verified.pts_in_world,
        labels=result.labels,
        primitives=np.concatenate([p.pts_in_world for p in result.primitives])
        if outputs.debug and result.primitives
        else None,
        metadata=_metadata(result, options, outputs),
        ground_height=result.scene.ground_height,
        sample_step=options.wires.sample_step,
        to_crs=crs,
        measures=result.measures,
        supports=result.supports,
        coverage=result.coverage,
        placement=result.placement,
        line_supports=result.line_supports,
    )
    wkt = crs_wkt(georef, outputs.output_crs)
    if outputs.las:
        result.outputs["wires.las"] = _write_wires_las(out, result, crs[0] if crs else None, wkt)
    ground = result.ground
    if outputs.dense_path is not None:
        same = result.ground_from is not None and Path(result.ground_from) == Path(
            outputs.dense_path
        )
        merged = fill(
            outputs.dense_path,
            result.outputs["wires.json"],
            out / "merged.ply",
            las=outputs.las,
            crs_wkt=wkt,
            ground=ground if same else None,
        )
        result.outputs["merged.ply"] = merged.output_path
        if merged.las_path:
            result.outputs["merged.las"] = merged.las_path
    timings["export"] = time.perf_counter() - t0
    if outputs.report:
        t0 = time.perf_counter()
        result.outputs["report"] = write_report(result, out, options, georef is not None, ground)
        timings["report"] = time.perf_counter() - t0
    return result.outputs


@dataclass(frozen=True)
class _Tile:
    """A stretch of one line, reconstructed as one task.

    ``corridor`` is the line's corridor cut to the stretch the task works on: the tile's own
    stretch (``core``, along the line's corridor from its centre) and half an image footprint
    on each side, so that pairs and views cover the core's ends as they cover its middle;
    a wire keeps its points in the core only. ``views`` are the images that see the
    stretch (None: all of them, a line in one tile).
    """

    line: int
    index: int
    of: int  # tiles of the line
    corridor: WireCorridor
    core: tuple[float, float]
    views: tuple[str, ...] | None

    @property
    def name(self) -> str:
        return (
            f"line_{self.line}_tile_{self.index}_{digest((self.corridor, self.core, self.views))}"
        )


def line_tiles(
    scene: Scene, corridor: WireCorridor, line: int, options: ReconstructionOptions
) -> list[_Tile]:
    """The tiles of one line: the whole line when it is shorter than 1.5 tiles, else equal
    stretches of about ``options.tile_footprints`` footprints (whatever the number of
    workers: the outputs do not depend on it)."""
    lo, hi = corridor.s_range
    footprint = footprint_along(scene, corridor)
    n = round((hi - lo) / (options.tile_footprints * footprint)) if np.isfinite(footprint) else 1
    if n <= 1:
        return [_Tile(line, 0, 1, corridor, (-np.inf, np.inf), None)]
    edges = np.linspace(lo, hi, n + 1)
    # Half a footprint past each end: the pairs and views that see the core's ends.
    margin = 0.5 * footprint
    tiles = []
    for t in range(n):
        stretch = (max(lo, edges[t] - margin), min(hi, edges[t + 1] + margin))
        cut = dataclasses.replace(corridor, s_range=(float(stretch[0]), float(stretch[1])))
        seen = scene.visibility(cut.sample_points(step=footprint / 20).reshape(-1, 3)).any(1)
        core = (
            -np.inf if t == 0 else float(edges[t]),
            np.inf if t == n - 1 else float(edges[t + 1]),
        )
        views = tuple(v.name for v, s in zip(scene.images, seen, strict=True) if s)
        tiles.append(_Tile(line, t, n, cut, core, views))
    logger.info(
        "line at %.1f°: %.0f long, %d tiles of %.0f (%.1f footprints of %.0f), %d–%d images each",
        corridor.azimuth_deg,
        hi - lo,
        n,
        (hi - lo) / n,
        (hi - lo) / n / footprint,
        footprint,
        min(len(t.views or ()) for t in tiles),
        max(len(t.views or ()) for t in tiles),
    )
    return tiles


def _tile_task(
    tile: _Tile, scene: Scene, options: ReconstructionOptions, tasks: Tasks | None
) -> tuple[CorridorResult | None, dict[str, float], str | None]:
    """:func:`reconstruct_corridor` on one tile (its pairs as ``tasks``), with the images that
    see it: its result, its wires cut to the tile's own stretch (None when it has no pair or
    no wire: the message says why), and its stage times."""
    timings: dict[str, float] = {}
    here = (
        scene
        if tile.views is None
        else scene.with_images([scene.image(name) for name in tile.views])
    )
    try:
        part = reconstruct_corridor(here, tile.corridor, options, timings, tasks)
    except InputError as e:
        return None, timings, str(e)
    if tile.views is None:
        return part, timings, None
    part = _cut_to_core(part, tile, scene, here, options)
    logger.info(
        "line at %.1f°, tile %d of %d: %d wires in its stretch, from %d images in %.0f s",
        tile.corridor.azimuth_deg,
        tile.index + 1,
        tile.of,
        len(part.wires),
        len(here.images),
        sum(timings.values()),
    )
    return part, timings, None


def _cut_to_core(
    part: CorridorResult, tile: _Tile, scene: Scene, here: Scene, options: ReconstructionOptions
) -> CorridorResult:
    """A tile's result with its wires' points in its core (a wire left with too few goes), in
    the whole scene's view numbers. What only judging the tile's wires needed (each view's
    wire pixels, the points still pending) is dropped: it does not leave the task."""
    v = part.verified
    along = (v.pts_in_world[:, :2] - tile.corridor.centre_xy) @ tile.corridor.direction_xy
    inside = (along >= tile.core[0]) & (along < tile.core[1])
    wires, supports = [], []
    for w, sup in zip(part.wires, part.supports, strict=True):
        idx = w.point_indices[inside[w.point_indices]]
        if len(idx) == len(w.point_indices):
            wires.append(w)
        elif len(idx) >= options.wires.min_points:
            s = w.plane_coords(v.pts_in_world[idx])[0]
            wires.append(
                dataclasses.replace(w, point_indices=idx, s_range=(float(s.min()), float(s.max())))
            )
        else:
            continue
        supports.append(sup)
    index_of = {im.name: k for k, im in enumerate(scene.images)}
    rates = np.full(len(scene.images), np.nan)
    rates[[index_of[im.name] for im in here.images]] = v.view_hit_rates
    verified = dataclasses.replace(v, view_hit_rates=rates, wire_pixels=[], pending=None)
    return dataclasses.replace(part, verified=verified, wires=wires, supports=supports)


def _joined_tiles(
    corridor: WireCorridor, parts: Sequence[CorridorResult], options: ReconstructionOptions
) -> CorridorResult:
    """The tiles of one line as the line's result: their points and pairs side by side, and
    the pieces of a wire that a tile's end cut joined again (one catenary fits them)."""
    if len(parts) == 1:
        return dataclasses.replace(parts[0], corridor=corridor)
    verified = parts[0].verified
    wires: list[FittedWire] = []
    supports: list[WireSupport] = []
    n_pairs = n_prims = 0
    for k, part in enumerate(parts):
        if k > 0:
            verified = verified.concatenated(part.verified, n_pairs, n_prims)
        n_pts = len(verified) - len(part.verified)
        for w, sup in zip(part.wires, part.supports, strict=True):
            wire_id = len(wires)
            wires.append(
                dataclasses.replace(w, wire_id=wire_id, point_indices=w.point_indices + n_pts)
            )
            supports.append(dataclasses.replace(sup, wire_id=wire_id))
        n_pairs += len(part.pairs)
        n_prims += int(sum(len(p) for p in part.primitives))
    wires, supports = _join_pieces(
        wires, supports, verified.pts_in_world, corridor.azimuth_deg, options.wires
    )
    return _side_by_side(corridor, parts, verified, wires, supports)


def _support_members_of(
    pieces: Sequence[FittedWire], lines: Sequence[CorridorResult], long_length: float
) -> dict[int, CorridorResult]:
    """Index into ``pieces`` → the first of ``lines`` whose support that piece is a member of
    (:func:`support_members` along that line, with its wires)."""
    out: dict[int, CorridorResult] = {}
    for line in lines:
        n = len(line.wires)
        for k, _ in support_members(
            list(line.wires) + list(pieces), line.corridor.direction_xy, long_length
        ):
            if k >= n:
                out.setdefault(k - n, line)
    return out


def _spans_apart(
    scene: Scene, part: CorridorResult, options: ReconstructionOptions
) -> tuple[CorridorResult, Spans]:
    """The supports and spans of the corridors' wires (:func:`_spans_of`), each line beside
    another's that the spans stage tells apart (its wires pass a support of the other's
    without a bend, across beyond the wires hanging from it) given a corridor of its own
    first (:func:`_beside_apart`): a pole line 12 m beside a tower line is within
    LINE_LINK_M of it, and the tower line's conductors, cut at the poles, were dropped as
    false pairings (the package's `parallel` layout with the lines 12 m apart)."""
    spans = _spans_of(scene, part, options)
    for _ in range(2):
        if not spans.beside:
            break
        part = _beside_apart(part, spans.beside)
        spans = _spans_of(scene, part, options)
    return part, spans


def _beside_apart(part: CorridorResult, beside: Sequence[tuple[int, float, int]]) -> CorridorResult:
    """``part`` with each leg's wires across beyond ``beside``'s (leg, across, side) as a
    line of their own: a copy of the leg's corridor centred on them (as
    :func:`_lines_apart`)."""
    legs, corridors = list(part.legs), list(part.corridors)
    for li, cut, side in beside:
        c = part.corridors[li]
        idx = np.array([k for k, leg in enumerate(part.legs) if leg == li])
        across = (_middles(part, idx)[:, :2] - c.centre_xy) @ c.normal_xy
        mine = side * (across - cut) > 0
        if not mine.any() or mine.all():
            continue
        shift = _own_corridor(legs, corridors, c, idx[mine], across[mine])
        logger.info(
            "lines: %d wires %.1f across the line at %.1f° pass its supports by: a line beside it",
            int(mine.sum()),
            shift,
            c.azimuth_deg,
        )
    if len(corridors) == len(part.corridors):
        return part
    return dataclasses.replace(part, legs=legs, corridors=corridors)


def _spans_of(scene: Scene, part: CorridorResult, options: ReconstructionOptions) -> Spans:
    """The supports and spans of the corridors' wires (:func:`find_spans`)."""
    return find_spans(
        scene.images,
        scene.ground_height,
        part.wires,
        part.legs,
        part.corridors,
        part.verified.pts_in_world,
        options.spans,
        options.wires,
        options.verify.crossing_offset,
        options.trace.extend,
    )


def _reconstruct_corridors(
    scene: Scene,
    corridors: Sequence[WireCorridor],
    options: ReconstructionOptions,
    timings: dict[str, float],
    tasks: Tasks | None,
    store: Store | None = None,
    required: bool = True,
) -> list[CorridorResult]:
    """Every corridor's result, in order. A long line is cut into tiles
    (:func:`line_tiles`). On Dask workers each tile is a task when there are several (each
    runs its pairs one after the other); one tile runs here, its pairs as tasks. With a
    ``store``, each tile is kept when done and taken from it when a run with the same
    inputs and options did it before. A line other than the first (or, not ``required``,
    any) without pairs or wires is left out, with a warning."""
    tasks = tasks or Tasks()
    tiles = [t for k, c in enumerate(corridors) for t in line_tiles(scene, c, k, options)]
    # Several tiles on workers: one task each, its pairs in it, no progress bars from the
    # workers (the bar over the tiles is the run's). Otherwise the tiles run here, their
    # pairs as ``tasks``.
    side_by_side = tasks.distributed and len(tiles) > 1
    results = (tasks if side_by_side else Tasks()).map(
        _tile_task,
        tiles,
        scene,
        dataclasses.replace(options, show_progress=False) if side_by_side else options,
        None if side_by_side else tasks,
        desc="tiles",
        unit="tile",
        show_progress=side_by_side and options.show_progress,
        store=store,
        names=[t.name for t in tiles],
    )
    # Pairs that came back from a worker or from the store hold copies of the scene's
    # images: the scene's own again.
    by_name = {v.name: v for v in scene.images}

    def own(p: ImagePair) -> ImagePair:
        return dataclasses.replace(p, left=by_name[p.left.name], right=by_name[p.right.name])

    parts = []
    for k, c in enumerate(corridors):
        done, why = [], []
        for tile, (part, t, reason) in zip(tiles, results, strict=True):
            if tile.line != k:
                continue
            for stage, seconds in t.items():
                timings[stage] = timings.get(stage, 0.0) + seconds
            if part is None:
                why.append(reason)
                if tile.views is not None:
                    logger.warning("line at %.1f°, tile %d: %s", c.azimuth_deg, tile.index, reason)
            else:
                done.append(dataclasses.replace(part, pairs=[own(p) for p in part.pairs]))
        if done:
            parts.append(_joined_tiles(c, done, options))
        elif k == 0 and required:
            raise InputError(why[0])
        else:
            logger.warning("line at %.1f°: %s", c.azimuth_deg, why[0])
    return parts


def reconstruct_corridor(
    scene: Scene,
    corridor: WireCorridor,
    options: ReconstructionOptions,
    timings: dict[str, float] | None = None,
    tasks: Tasks | None = None,
) -> CorridorResult:
    """Every wire of one corridor (a line, or a straight leg of one): pairs crossing it,
    their primitives verified in the other views, wires split, fitted, judged, traced.

    ``timings`` (stage → seconds) is added to. Raises :class:`InputError` when no pair
    gives a primitive.
    """
    timings = {} if timings is None else timings
    t0 = time.perf_counter()
    pairs = select_pairs(scene, corridor, options.pairs, options.verify.crossing_offset)
    _add_time(timings, "pairs", t0)
    decoded: list[Path] = []

    t0 = time.perf_counter()
    primitives, n = primitives_for_pairs(scene, pairs, corridor, options, tasks)
    decoded += n
    _add_time(timings, "rectify_detect_triangulate", t0)
    if sum(len(p) for p in primitives) == 0:
        raise InputError(f"{scene.image_path}: no wire was found in the chosen pairs")

    t0 = time.perf_counter()

    verified = verify_primitives(
        scene,
        primitives,
        [(p.left.name, p.right.name) for p in pairs],
        crop_wire_mask(options.detect, options.verify.template_length_px),
        corridor.azimuth_deg,
        options.verify,
        options.show_progress,
        options.triangulate.min_wire_height,
    )
    decoded += verified.decoded
    _add_time(timings, "verify", t0)
    verified = _settled_by_the_views(
        verified, options.verify.min_posterior, options.wires.inlier_distance
    )

    t0 = time.perf_counter()
    candidates = split_wires(verified.pts_in_world, corridor.azimuth_deg, options.wires)
    _add_time(timings, "wires", t0)
    t0 = time.perf_counter()
    index_of = {view.name: k for k, view in enumerate(scene.images)}
    pair_views = np.array(
        [[index_of[p.left.name], index_of[p.right.name]] for p in pairs], np.int64
    ).reshape(-1, 2)
    pair_centres = scene.centers_in_world[pair_views]

    def judge(wires: list[FittedWire]) -> list[WireSupport]:
        return wire_support(
            scene,
            wires,
            verified.wire_pixels,
            verified.pair_index,
            pair_centres,
            verified.view_hit_rates,
            options.verify.crossing_offset,
            options.verify.tolerance_px,
            options.support,
            pair_views,
        )

    supports = judge(candidates)
    # A wire the views reject as a whole may be right along one stretch (its end went
    # astray): that stretch, refitted, is judged again with the others.
    trimmed = {
        k: trim_wire(w, verified.pts_in_world, s.supported_s, corridor.azimuth_deg, options.wires)
        for k, (w, s) in enumerate(zip(candidates, supports, strict=True))
        if s.supported_s is not None
        and s.height_above_ground >= options.triangulate.min_wire_height
    }
    if any(t is not None for t in trimmed.values()):
        logger.info(
            "support: %d rejected wires have a supported stretch; judging them again",
            sum(t is not None for t in trimmed.values()),
        )
        candidates = [trimmed[k] or w if k in trimmed else w for k, w in enumerate(candidates)]
        supports = judge(candidates)
    rejected = _for_a_second_look(candidates, supports, options)
    on_ground = sum(s.height_above_ground < options.triangulate.min_wire_height for s in supports)
    n_candidates = len(candidates)
    kept, supports = keep_supported(
        candidates, supports, options.support, options.triangulate.min_wire_height
    )
    wires, supports = _without_members(kept, supports, corridor, options)
    wires, supports = _join_pieces(
        wires, supports, verified.pts_in_world, corridor.azimuth_deg, options.wires
    )
    # On a confirmed wire, a primitive the views favour is the right match with prior 1/2
    # (not 1/K): take those that then reach the posterior, and refit.
    pending = verified.pending
    confirmed = list(zip(wires, supports, strict=True))
    if wires:
        logit = np.log(options.verify.min_posterior / (1 - options.verify.min_posterior))
        sure = (
            np.flatnonzero(pending.evidence >= logit)
            if pending is not None
            else np.zeros(0, np.int64)
        )
        n_before = len(verified)
        both = (
            np.r_[verified.pts_in_world, pending.pts_in_world[sure]]
            if pending is not None
            else verified.pts_in_world
        )
        # A wire grows by at most ``max_gap`` past its ends per step: repeat while it takes
        # points (its refit curve then reaches the next stretch). Sure points that no
        # confirmed wire holds (those of a dropped duplicate of it) are offered too.
        held = np.zeros(n_before, bool)
        for w in wires:
            held[w.point_indices] = True
        left = np.r_[np.flatnonzero(~held), n_before + np.arange(len(sure))]
        taken = np.zeros(0, np.int64)
        for _ in range(MAX_ABSORB_STEPS):
            wires, new, _ = absorb_points(wires, both, left, corridor.azimuth_deg, options.wires)
            if len(new) == 0:
                # Pieces that grew towards each other may now be one wire, which grows on.
                n_wires = len(wires)
                wires, supports = _join_pieces(
                    wires, supports, both, corridor.azimuth_deg, options.wires
                )
                if len(wires) == n_wires:
                    break
                continue
            taken = np.r_[taken, new]
            left = np.setdiff1d(left, new)
        taken = np.sort(taken)
        new_pending = taken[taken >= n_before]
        # Keep only the points some wire took, in the order of ``both``.
        keep = np.r_[np.arange(n_before), new_pending]
        remap = np.full(len(both), -1, np.int64)
        remap[keep] = np.arange(len(keep))
        verified = verified.with_pending(sure[new_pending - n_before], options.verify.min_posterior)
        wires = [dataclasses.replace(w, point_indices=remap[w.point_indices]) for w in wires]
        logger.info(
            "wires: %d more points on the confirmed wires (%d sure ones of dropped duplicates, "
            "%d of the %d the views favour)",
            len(taken),
            len(taken) - len(new_pending),
            len(new_pending),
            len(pending) if pending is not None else 0,
        )
    if wires:
        # What the wires grew into is judged again, and the support reported is that of the
        # wire as written: a wire that took points past where it is real (a short piece by a
        # tower grown along a false pairing) keeps the stretch the views support, or goes.
        wires, supports = _confirm_grown(
            wires, confirmed, judge, verified.pts_in_world, corridor.azimuth_deg, options
        )
        # A piece by a support that grew may now run through it (the package's corridor at
        # quarter scale: a 5 m tower member at 9 m height, inside the conductors' ends when
        # confirmed, grew past them).
        wires, supports = _without_members(wires, supports, corridor, options)
    if wires:
        matches = np.concatenate([p.pts_in_world for p in primitives])
        wires, verified = _consensus(wires, verified, primitives, matches)
        t1 = time.perf_counter()
        # Before tracing too: such a wire holds, in one strip, the line of a wire it paired
        # wrongly, which tracing would then find fixed nowhere apart from it (mixed seed 3).
        wires, supports = _without_unconfirmed(wires, supports, options.support)
        wires, supports, verified, dec = _traced(
            wires, supports, verified, scene, corridor, options, primitives=matches
        )
        decoded += dec
        wires, supports = _without_untraced(wires, supports)
        wires, supports, verified, dec = _second_look(
            wires, supports, rejected, verified, scene, corridor, options
        )
        decoded += dec
        wires, supports, verified, dec = _siblings(
            wires, supports, verified, scene, corridor, options, judge
        )
        decoded += dec
        wires, supports, verified, dec = _faint_wires(
            wires, supports, verified, scene, corridor, options, judge
        )
        decoded += dec
        # Two confirmed pieces that tracing grew along the same wire are one (shared soil
        # seed 13: two pieces of a conductor, 14 and 8 m apart, traced into two 93 m copies
        # 1.6 cm apart).
        wires, supports = _join_pieces(
            wires, supports, verified.pts_in_world, corridor.azimuth_deg, options.wires
        )
        # Where two strips alone see the wires, two swapped pairings of a wire's image lines
        # with those of a wire not found can pass every test above (shared soil seed 11).
        swapped, dec = swapped_pairings(
            scene,
            wires,
            supports,
            corridor.azimuth_deg,
            options.detect,
            options.verify.tolerance_px,
        )
        decoded += dec
        if swapped:
            keep = [k for k in range(len(wires)) if k not in swapped]
            wires, supports = _kept(wires, supports, keep)
        wires, supports = _without_unconfirmed(wires, supports, options.support)
        _add_time(timings, "trace", t1)
        wires, supports = _above_the_floor(
            wires,
            supports,
            scene,
            options.triangulate.min_wire_height,
            options.wires.inlier_distance,
        )
    _add_time(timings, "support", t0)
    return CorridorResult(
        corridor, pairs, primitives, verified, wires, supports, decoded, n_candidates, on_ground
    )


def _without_members(
    wires: list[FittedWire],
    supports: list[WireSupport],
    corridor: WireCorridor,
    options: ReconstructionOptions,
) -> tuple[list[FittedWire], list[WireSupport]]:
    """The wires without the short pieces that are members of a support or lie outside the
    span (:func:`colmap_powerline.support.support_members`), renumbered from 0."""
    members = dict(support_members(wires, corridor.direction_xy, options.wires.max_gap))
    for k, at in members.items():
        logger.info(
            "support: wire %d dropped (%.0f m): it runs through or lies wholly past the place "
            "%.1f along the line where the longer wires end — a member of the support or "
            "outside the span, not a wire of it",
            wires[k].wire_id,
            wires[k].s_range[1] - wires[k].s_range[0],
            at,
        )
    kept = [w for k, w in enumerate(wires) if k not in members]
    sup = [s for k, s in enumerate(supports) if k not in members]
    return (
        [dataclasses.replace(w, wire_id=i) for i, w in enumerate(kept)],
        [dataclasses.replace(s, wire_id=i) for i, s in enumerate(sup)],
    )


def _traced_to_supports(
    spans: Spans,
    corridors: Sequence[WireCorridor],
    verified: VerifiedPoints,
    scene: Scene,
    options: ReconstructionOptions,
) -> tuple[list[FittedWire], VerifiedPoints, list[Path]]:
    """The span wires traced on toward their supports, where they stop short of them.

    Tracing runs before the supports are known, on wires that may run across a support in
    one curve; past the support the next span's wire sags again and leaves that curve, and
    the rounds past the end stop where it does (the real road flight's middle conductor of
    its third span stopped 9 m short of the pole the images show it reaching). Once each
    wire is cut at its supports its curve is the span's own: it is traced again past its
    ends (:func:`trace_wires`, the same tests), up to its span's supports, or where it has
    none, as far along the line as the line's other wires reach. So is a wire whose gaps
    leave as much of it unmeasured (:func:`_unmeasured_inside`): there too the search
    followed a curve the wire's own now corrects (the shared generator's area survey, seed
    5: a conductor's 4 m gap that two views see). Points are added only where
    it had none (:func:`_where_unmeasured`: past its old ends, and in its gaps); the rest of
    the wire stays as measured, and it stays drawn to the supports it was drawn to.

    Returns the wires (refitted where they grew), the points with those added, and the
    images read."""
    wires = list(spans.wires)
    if not options.trace.enabled or options.trace.extend == 0 or not wires:
        return wires, verified, []
    by_id = {s.support_id: s for s in spans.supports}
    legs = spans.legs or [0] * len(wires)
    decoded: list[Path] = []
    for leg in sorted(set(legs)):
        azimuth = corridors[leg].azimuth_deg
        along, _ = plan_axes(azimuth)
        on_leg = [k for k in range(len(wires)) if legs[k] == leg]
        # Where each wire's points reach along the line (its curve may have been drawn on
        # to a support already).
        ends = {}
        for k in on_leg:
            own = verified.pts_in_world[wires[k].point_indices][:, :2] @ along
            drawn = wires[k].points(np.array(wires[k].s_range))[:, :2] @ along
            ends[k] = np.array([own.min(), own.max()]) if len(own) else np.sort(drawn)
        short: list[int] = []
        limits: list[tuple[float, float]] = []
        supported: list[tuple[bool, bool]] = []  # whether a support sets each limit
        # How far each line's wires reach on this leg: the limit at an end with no support.
        reach: dict[int, tuple[float, float]] = {}
        for k in on_leg:
            line = spans.placement[k].line
            lo_k, hi_k = float(ends[k][0]), float(ends[k][1])
            old = reach.get(line, (lo_k, hi_k))
            reach[line] = (min(old[0], lo_k), max(old[1], hi_k))
        for k in on_leg:
            place = spans.placement[k]
            line_lo, line_hi = reach[place.line]
            mid = float(np.mean(ends[k]))
            at = [
                float(np.asarray(by_id[i].position)[:2] @ along)
                for i in place.supports
                if i is not None and i in by_id
            ]
            lo = max([u for u in at if u < mid], default=line_lo)
            hi = min([u for u in at if u > mid], default=line_hi)
            gap = max(ends[k][0] - lo, hi - ends[k][1])
            if max(gap, _unmeasured_inside(wires[k], verified.pts_in_world)) > (
                options.trace.extend / 2
            ):
                short.append(k)
                limits.append((lo, hi))
                supported.append((any(u < mid for u in at), any(u > mid for u in at)))
        if not short:
            continue
        pts = verified.pts_in_world
        n0 = len(pts)
        grown, traced = trace_wires(
            scene,
            [_measured_part(wires[k], pts, options.spans.max_meeting_gap) for k in short],
            pts,
            crop_wire_mask(options.detect, options.verify.template_length_px),
            azimuth,
            options.trace,
            options.wires,
            options.verify.tolerance_px,
            options.verify.num_threads,
            options.verify.margin_px,
            options.detect,
            [wires[k] for k in on_leg if k not in short],
            template_length_px=options.verify.template_length_px,
            limits=limits,
        )
        decoded += traced.decoded
        all_pts = np.r_[pts, traced.pts_in_world]
        keep = np.zeros(len(traced), bool)
        for k, g in zip(short, grown, strict=True):
            new = g.point_indices[g.point_indices >= n0]
            keep[new[_where_unmeasured(wires[k], pts, all_pts[new])] - n0] = True
        remap = np.full(len(all_pts), -1, np.int64)
        remap[:n0] = np.arange(n0)
        remap[n0 + np.flatnonzero(keep)] = n0 + np.arange(int(keep.sum()))
        verified = verified.with_traced(traced.pts_in_world[keep], traced.views[keep])
        for j, (k, g) in enumerate(zip(short, grown, strict=True)):
            new = remap[g.point_indices[g.point_indices >= n0]]
            new = new[new >= 0]
            if len(new) == 0:
                continue
            idx = np.r_[wires[k].point_indices, new]
            before = wires[k].s_range
            fit = refit(wires[k], verified.pts_in_world, idx, along, options.wires)
            # Still drawn to its supports' attachments, as it was; elsewhere as far as its
            # points reach, within its limits (its points may run on past a support).
            drawn = np.sort(fit.plane_coords(wires[k].points(np.array(before)))[0])
            lim = fit.s_at_along(along, limits[j])
            sup = supported[j] if fit.plane_direction_xy @ along > 0 else supported[j][::-1]
            s_lo = drawn[0] if sup[0] else max(min(fit.s_range[0], drawn[0]), lim[0])
            s_hi = drawn[1] if sup[1] else min(max(fit.s_range[1], drawn[1]), lim[1])
            wires[k] = dataclasses.replace(fit, s_range=(float(s_lo), float(s_hi)))
            logger.info(
                "trace: wire %d traced on toward its span's ends %.1f..%.1f along the line: "
                "s %.1f..%.1f -> %.1f..%.1f (%d points added)",
                wires[k].wire_id,
                *limits[j],
                *before,
                *wires[k].s_range,
                len(new),
            )
    return wires, verified, decoded


def _measured_part(wire: FittedWire, pts_in_world: F64, max_gap: float) -> FittedWire:
    """The wire as tracing takes it on: where it is drawn farther than ``max_gap`` past its
    points' ends (``--spans.max_meeting_gap``: farther than two pieces of one conductor
    meet, so farther than its curve is trusted to carry it anywhere else), it ends there.
    Tracing looks along the whole curve it is given at once, and past its ends round by
    round with its tests. A wire drawn on to its span's far support because the span's
    other wires reach it (a shield measured along half its span) is a prediction there,
    not a place to look along at once: on the package's `angle` layout a shield so took
    40 m of points 0.4-1.9 m off it. Nearer, the look along the curve finds the wire
    (the same layout: a shield measured along 5 m, drawn 37 m on to the angle tower,
    found along 16 m of that at once, and 0.15-0.7 m off it when taken round by round)."""
    own = wire.own_positions(pts_in_world)
    if len(own) == 0:
        return wire
    lo, hi = wire.s_range
    lo = float(own[0]) if own[0] - lo > max_gap else lo
    hi = float(own[-1]) if hi - own[-1] > max_gap else hi
    return dataclasses.replace(wire, s_range=(lo, hi))


def _hung_where_reached(
    wires: list[FittedWire], spans: Spans, pts_in_world: F64, options: ReconstructionOptions
) -> tuple[list[FittedWire], Spans]:
    """The wires and spans with each wire hanging only from the supports its points reach
    (within ``--spans.max_meeting_gap``, as :func:`find_spans` attaches them), now that
    tracing and the views' evidence have measured what they can. A wire found reaching one
    of its span's supports was drawn to the other too, so that both could measure it on
    toward it; where its points still end farther from that support, its curve there is a
    prediction from too little (the shared cross seed 6: two shields measured along 35 m
    of 100 m from one tower, a straight line continued 65 m, which put the far tower's top
    1.75 m low and made them conductors): it ends at its points there, and hangs from no
    support at that end (``coverage`` says how far it was measured)."""
    placement = list(spans.placement)
    out = list(wires)
    gap = options.spans.max_meeting_gap
    for k, (w, p) in enumerate(zip(wires, spans.placement, strict=True)):
        cut = _measured_part(w, pts_in_world, gap).s_range
        ends = [None if sid is not None and cut[j] != w.s_range[j] else sid
                for j, sid in enumerate(p.supports)]  # fmt: skip
        lo, hi = (cut[j] if ends[j] is None and p.supports[j] is not None else w.s_range[j]
                  for j in (0, 1))  # fmt: skip
        if (ends[0], ends[1]) != p.supports:
            logger.info(
                "spans: wire %d: its points end farther than %.0f from its span's support "
                "%s: it hangs from no support there",
                w.wire_id,
                gap,
                " and ".join(str(i) for i, j in zip(p.supports, ends, strict=True) if j is None),
            )
            out[k] = dataclasses.replace(w, s_range=(lo, hi))
            placement[k] = dataclasses.replace(p, supports=(ends[0], ends[1]))
    return out, dataclasses.replace(spans, wires=out, placement=placement)


# At most this many rounds of judging span-wires' unmeasured stretches by the views' line
# evidence together, each on the curves refitted to what the round before measured.
EVIDENCE_ROUNDS = 4


def _measured_by_evidence(
    wires: list[FittedWire],
    corridors: Sequence[WireCorridor],
    spans: Spans,
    verified: VerifiedPoints,
    scene: Scene,
    options: ReconstructionOptions,
) -> tuple[list[FittedWire], VerifiedPoints, list[Path]]:
    """The span wires with their unmeasured stretches next to measured ones measured where
    the views' line evidence together shows them (:func:`evidence_stretches`: a wire too
    faint for tracing's views one by one, the package's `angle` layout's shields), each
    refitted to its points and still drawn to its attachments. In rounds (at most
    EVIDENCE_ROUNDS): a wire that gained stretches is judged again on its refitted curve,
    which lies closer to the wire past what it was fitted to before.

    Returns the wires, the points with those added (as traced points: the views that see
    each stretch), and the images read."""
    if not options.trace.enabled or not options.trace.faint or not wires:
        return wires, verified, []
    legs = spans.legs or [0] * len(wires)
    out = list(wires)
    decoded: list[Path] = []
    todo: set[int] = set(range(len(wires)))
    gained: list[npt.NDArray[np.int64]] = [np.zeros(0, np.int64) for _ in wires]
    for _ in range(EVIDENCE_ROUNDS):
        # A stretch taken in an earlier round stays taken (measured), wherever the refitted
        # curve left its points: each round judges the rest, on the refitted curve.
        judged = [
            dataclasses.replace(w, point_indices=np.union1d(w.point_indices, g))
            for w, g in zip(out, gained, strict=True)
        ]
        new, views, dec = evidence_stretches(
            scene,
            judged,
            verified.pts_in_world,
            options.detect,
            options.trace.stretch_min_z,
            MIN_VIEWS,
            options.verify.num_threads,
            only=todo,
        )
        decoded += dec
        # Judged again: every wire that gained (its refitted curve lies closer to the wire
        # past what it was fitted to before, and what it now reaches reaches farther: the
        # release before judged again only wires whose curves took all they gained, and
        # shared twolines seed 12's shield stopped where its first round's reach ended).
        todo = {k for k, p in enumerate(new) if len(p)}
        if not todo:
            break
        start = len(verified)
        verified = verified.with_traced(np.concatenate(new), np.concatenate(views))
        for k, p in enumerate(new):
            if len(p) == 0:
                continue
            added = np.arange(start, start + len(p))
            start += len(p)
            gained[k] = np.r_[gained[k], added]
            along, _ = plan_axes(corridors[legs[k]].azimuth_deg)
            fit = refit(
                out[k], verified.pts_in_world, np.r_[out[k].point_indices, added], along,
                options.wires,
            )  # fmt: skip
            drawn = np.sort(fit.plane_coords(out[k].points(np.array(out[k].s_range)))[0])
            out[k] = dataclasses.replace(fit, s_range=(float(drawn[0]), float(drawn[1])))
    return out, verified, decoded


def _own_spacing(wire: FittedWire, pts_in_world: F64) -> tuple[F64, float]:
    """The wire's points' positions along it (sorted) and their median spacing (NaN: fewer
    than two points)."""
    own = wire.own_positions(pts_in_world)
    return own, float(np.median(np.diff(own))) if len(own) >= 2 else float("nan")


def _unmeasured_inside(wire: FittedWire, pts_in_world: F64) -> float:
    """How much of the wire between its points' ends lies in their gaps (wider than twice
    their median spacing, as :func:`_where_unmeasured` counts them)."""
    own, spacing = _own_spacing(wire, pts_in_world)
    if len(own) < 3:
        return 0.0
    d = np.diff(own)
    return float(d[d > 2 * spacing].sum())


def _where_unmeasured(wire: FittedWire, pts_in_world: F64, new: F64) -> npt.NDArray[np.bool_]:
    """(len(new),) the points ``new`` on ``wire`` that lie where its own points do not: more
    than twice their median spacing along it from the nearest of them (past its ends, or in
    its gaps; elsewhere they would measure the wire a second time)."""
    own, spacing = _own_spacing(wire, pts_in_world)
    s = wire.plane_coords(new)[0]
    if len(own) < 2:
        return np.ones(len(s), bool)
    i = np.clip(np.searchsorted(own, s), 1, len(own) - 1)
    nearest = np.minimum(np.abs(s - own[i - 1]), np.abs(s - own[i]))
    return nearest > 2 * spacing


def _traced(
    wires: list[FittedWire],
    supports: list[WireSupport],
    verified: VerifiedPoints,
    scene: Scene,
    corridor: WireCorridor,
    options: ReconstructionOptions,
    trace_options: TraceOptions | None = None,
    context: list[FittedWire] | None = None,
    min_redundancy: float = 0.0,
    primitives: npt.NDArray[np.float64] | None = None,
    groups: list[int] | None = None,
    evident: list[bool] | None = None,
) -> tuple[list[FittedWire], list[WireSupport], VerifiedPoints, list[Path]]:
    """The wires traced in every view (:func:`trace_wires`): refitted, their traced points
    added to the measured ones, their ``traced_share`` in the support (``primitives``: the
    pairs' matches, which may take tracing farther along the line than the measured wires
    reach; ``groups``: each wire's look, ``evident``: the wires the line evidence shows, see
    :func:`trace_wires`)."""
    wires, traced = trace_wires(
        scene,
        wires,
        verified.pts_in_world,
        crop_wire_mask(options.detect, options.verify.template_length_px),
        corridor.azimuth_deg,
        trace_options or options.trace,
        options.wires,
        options.verify.tolerance_px,
        options.verify.num_threads,
        options.verify.margin_px,
        options.detect,
        context,
        min_redundancy,
        options.verify.template_length_px,
        primitives,
        groups,
        evident,
    )
    supports = [
        dataclasses.replace(s, traced_share=None if np.isnan(f) else round(float(f), 3))
        for s, f in zip(supports, traced.share, strict=True)
    ]
    return (
        wires,
        supports,
        verified.with_traced(traced.pts_in_world, traced.views),
        traced.decoded,
    )


def _for_a_second_look(
    candidates: list[FittedWire], supports: list[WireSupport], options: ReconstructionOptions
) -> list[tuple[FittedWire, WireSupport]]:
    """The wires the views' hit rates reject that tracing looks at again
    (:func:`_second_look`): above the ground, and at least twice the shortest wire long (a
    support's member found so goes with the members after tracing). On the real road flight
    the span past the last pole was all in such pieces, 10-14 m, which one strip's hit
    rates reject; 25 m was asked before, and the span was lost."""
    return [
        (w, s)
        for w, s in zip(candidates, supports, strict=True)
        if not options.support.accepts(s.confidence)
        and s.height_above_ground >= options.triangulate.min_wire_height
        and w.s_range[1] - w.s_range[0] >= 2 * options.wires.min_length
    ]


def _looked_again(
    cand: list[FittedWire],
    looked: list[WireSupport],
    verified: VerifiedPoints,
    wires: list[FittedWire],
    scene: Scene,
    corridor: WireCorridor,
    options: ReconstructionOptions,
    look: TraceOptions,
) -> tuple[list[FittedWire], list[WireSupport], list[Path]]:
    """The hypotheses the views found at ``MIN_TRACED_SHARE`` of their places or more but
    fewer than ``MIN_SECOND_LOOK_SHARE``, looked for again along the curve of the places
    where they were found (fitted to those places alone, not to the hypothesis's own
    points): the better of the two looks, for each.

    A rejected wire's curve is fitted to its pairs' points, off where the matches were few
    or poor; the views then find it only where the curve passes within their search's reach
    of the wire. On the real road flight a conductor of the line across the field, plain
    in the images, was so found at 41 % of its places (69 % in a run whose pairs differed
    by one), and at 71 % looked for again. False pairings are found at 0-8 % (shared
    generator), under this look's bar; one found at 34 % on cross seed 8 was found at 0 %
    along the curve of its places."""
    again = [
        k
        for k, s in enumerate(looked)
        if MIN_TRACED_SHARE <= (s.traced_share or 0.0) < MIN_SECOND_LOOK_SHARE
    ]
    if not again:
        return cand, looked, []
    none = np.zeros(0, np.int64)
    bare = [
        dataclasses.replace(cand[k], wire_id=j, point_indices=none) for j, k in enumerate(again)
    ]
    sup = [dataclasses.replace(looked[k], wire_id=j) for j, k in enumerate(again)]
    seen, _, _, decoded = _traced(
        bare, sup, verified, scene, corridor, options, look, wires, MIN_REDUNDANCY
    )
    refits: list[FittedWire] = []
    which: list[int] = []
    for j, k in enumerate(again):
        if len(seen[j].point_indices) < options.wires.min_points:
            continue
        # Over the hypothesis's whole length (the places found may be fewer), with those
        # of its points that lie on the new curve.
        s_ends = seen[j].plane_coords(cand[k].points(np.array(cand[k].s_range)))[0]
        own = cand[k].point_indices
        on = seen[j].distance(verified.pts_in_world[own]) < options.wires.inlier_distance
        refits.append(
            dataclasses.replace(
                seen[j],
                wire_id=len(refits),
                point_indices=own[on],
                s_range=(float(s_ends.min()), float(s_ends.max())),
            )
        )
        which.append(k)
    if not refits:
        return cand, looked, decoded
    _, again_looked, _, dec = _traced(
        refits,
        [dataclasses.replace(looked[k], wire_id=j) for j, k in enumerate(which)],
        verified,
        scene,
        corridor,
        options,
        look,
        wires,
        MIN_REDUNDANCY,
    )
    cand, looked = list(cand), list(looked)
    for j, k in enumerate(which):
        share = again_looked[j].traced_share or 0.0
        logger.info(
            "trace: a rejected wire (%.0f m) found at %.0f %% of its places, looked for again "
            "along the curve of those places: %.0f %%",
            cand[k].s_range[1] - cand[k].s_range[0],
            100 * (looked[k].traced_share or 0.0),
            100 * share,
        )
        if share > (looked[k].traced_share or 0.0):
            cand[k] = dataclasses.replace(refits[j], wire_id=cand[k].wire_id)
            looked[k] = dataclasses.replace(again_looked[j], wire_id=looked[k].wire_id)
    return cand, looked, decoded + dec


def _second_look(
    wires: list[FittedWire],
    supports: list[WireSupport],
    rejected: list[tuple[FittedWire, WireSupport]],
    verified: VerifiedPoints,
    scene: Scene,
    corridor: WireCorridor,
    options: ReconstructionOptions,
) -> tuple[list[FittedWire], list[WireSupport], VerifiedPoints, list[Path]]:
    """The wires the views' hit rates rejected, traced: those that the views able to fix
    them find at ``MIN_SECOND_LOOK_SHARE`` of their places or more join the wires (traced
    in full), unless they are stretches of a wire already there.

    The hit rates judge a wire by whether it lands on wire pixels; in views where another
    wire lies close beside it (the top conductor above its neighbour in a flight across the
    line) or at the image edge that says little. Tracing asks for sub-pixel agreement of
    three or more views, which a false pairing does not have (shared generator: true wires
    59-100 % of their places, false pairings 0-8 %)."""
    if not rejected:
        return wires, supports, verified, []

    def near(w: FittedWire, others: list[FittedWire]) -> bool:
        p = w.polyline(0.5)
        return any(float(np.median(o.distance(p))) < CONTINUATION_DISTANCE for o in others)

    fresh = [(w, s) for w, s in rejected if not near(w, wires)]
    if not fresh:
        return wires, supports, verified, []
    look = dataclasses.replace(options.trace, max_rounds=0)
    cand = [dataclasses.replace(w, wire_id=k) for k, (w, _) in enumerate(fresh)]
    sup = [s for _, s in fresh]
    _, looked, _, decoded = _traced(
        cand, sup, verified, scene, corridor, options, look, wires, MIN_REDUNDANCY
    )
    cand, looked, dec = _looked_again(cand, looked, verified, wires, scene, corridor, options, look)
    decoded += dec
    # Longest first; one of two candidates for the same wire.
    order = sorted(range(len(cand)), key=lambda k: cand[k].s_range[0] - cand[k].s_range[1])
    taken: list[int] = []
    for k in order:
        share = looked[k].traced_share
        if share is None or share < MIN_SECOND_LOOK_SHARE:
            continue
        if near(cand[k], [cand[j] for j in taken]):
            continue
        taken.append(k)
        logger.info(
            "trace: a rejected wire (%.0f m, %.1f above the ground, confidence %s) is found "
            "by the views that fix it at %.0f %% of its places: kept",
            cand[k].s_range[1] - cand[k].s_range[0],
            looked[k].height_above_ground,
            "none" if looked[k].confidence is None else f"{looked[k].confidence:.3f}",
            100 * share,
        )
    if not taken:
        return wires, supports, verified, decoded
    n = len(wires)
    new = [dataclasses.replace(cand[k], wire_id=n + i) for i, k in enumerate(taken)]
    new_sup = [dataclasses.replace(looked[k], wire_id=n + i) for i, k in enumerate(taken)]
    new, new_sup, verified, dec = _traced(
        new,
        new_sup,
        verified,
        scene,
        corridor,
        options,
        context=wires,
        min_redundancy=MIN_REDUNDANCY,
    )
    wires, supports = _without_members(wires + new, supports + new_sup, corridor, options)
    return wires, supports, verified, decoded + dec


def _line_offsets(wires: list[FittedWire]) -> list[tuple[float, float]]:
    """The offsets (across, height; model units) between confirmed wires that run side by
    side: parallel within ``CONTINUATION_DISTANCE`` along at least ``MIN_SIBLING_OVERLAP`` of
    the shorter one, and apart by more than that. Both signs; offsets within
    ``CONTINUATION_DISTANCE`` of one another counted once."""
    found: list[tuple[float, float]] = []
    for i, a in enumerate(wires):
        for b in wires[i + 1 :]:
            pts = b.polyline(0.5)
            s, across, dz = a.plane_coords(pts)
            inside = (s >= a.s_range[0]) & (s <= a.s_range[1])
            shorter = min(np.ptp(a.s_range), np.ptp(b.s_range))
            if inside.sum() * 0.5 < MIN_SIBLING_OVERLAP * shorter:
                continue
            across, dz = across[inside], dz[inside]
            if max(np.ptp(np.percentile(across, [10, 90])), np.ptp(np.percentile(dz, [10, 90]))) > (
                CONTINUATION_DISTANCE
            ):
                continue  # not side by side all along
            offset = (float(np.median(across)), float(np.median(dz)))
            if np.hypot(*offset) <= CONTINUATION_DISTANCE:
                continue
            for o in (offset, (-offset[0], -offset[1])):
                if all(np.hypot(o[0] - f[0], o[1] - f[1]) > CONTINUATION_DISTANCE for f in found):
                    found.append(o)
    return found


def _shifted(wire: FittedWire, across: float, dz: float, wire_id: int) -> FittedWire:
    """The wire moved across its plane by ``across`` and up by ``dz``, without points."""
    return dataclasses.replace(
        wire,
        wire_id=wire_id,
        plane_origin_xy=wire.plane_origin_xy + across * across_of(wire.plane_direction_xy),
        z0=wire.z0 + dz,
        point_indices=np.zeros(0, np.int64),
    )


def _covered(w: FittedWire, others: list[FittedWire], in_plan: bool = False) -> bool:
    """Most of ``w`` lies on another wire between that wire's ends (not on its curve
    continued: past a pole the next span's conductor lies near that); ``in_plan``: above or
    below it."""
    p = w.polyline(0.5)
    on = np.zeros(len(p), bool)
    for o in others:
        s, across, _ = o.plane_coords(p)
        off = np.abs(across) if in_plan else o.distance(p)
        on |= (s >= o.s_range[0]) & (s <= o.s_range[1]) & (off < CONTINUATION_DISTANCE)
    return bool(on.mean() >= MIN_SIBLING_OVERLAP)


def _best_apart(cand: list[FittedWire], shares: list[float | None], bar: float) -> list[int]:
    """The hypotheses found at ``bar`` of their places or more, best first, of two at one
    place in plan the better."""
    taken: list[int] = []
    for i in sorted(range(len(cand)), key=lambda i: -(shares[i] or 0.0)):
        if (shares[i] or 0.0) < bar:
            break
        if not _covered(cand[i], [cand[j] for j in taken], in_plan=True):
            taken.append(i)
    return taken


def _traced_in_full(
    cand: list[FittedWire],
    looked: list[WireSupport],
    taken: list[int],
    wires: list[FittedWire],
    verified: VerifiedPoints,
    scene: Scene,
    corridor: WireCorridor,
    options: ReconstructionOptions,
    evident: bool = False,
) -> tuple[list[FittedWire], list[WireSupport], VerifiedPoints, list[Path]]:
    """The hypotheses ``taken`` (with their looks' supports), numbered after ``wires`` and
    traced in full beside them (every view checked by the others; ``evident``: line evidence
    shows them, :func:`trace_wires`)."""
    n = len(wires)
    new = [dataclasses.replace(cand[i], wire_id=n + j) for j, i in enumerate(taken)]
    new_sup = [dataclasses.replace(looked[i], wire_id=n + j) for j, i in enumerate(taken)]
    return _traced(
        new, new_sup, verified, scene, corridor, options, context=wires,
        min_redundancy=MIN_REDUNDANCY, evident=[True] * len(new) if evident else None,
    )  # fmt: skip


def _support_as_seen(
    wire: FittedWire,
    neighbour: FittedWire,
    traced_share: float | None,
    verified: VerifiedPoints,
    judge: Callable[[list[FittedWire]], list[WireSupport]],
) -> WireSupport:
    """``wire``'s support as the pairs that measured ``neighbour`` would see it (the camera
    geometry of a wire a few metres away is the same), with its traced share."""
    own = neighbour.point_indices
    as_seen = dataclasses.replace(wire, point_indices=own[verified.pair_index[own] >= 0])
    return dataclasses.replace(judge([as_seen])[0], wire_id=wire.wire_id, traced_share=traced_share)


def _siblings(
    wires: list[FittedWire],
    supports: list[WireSupport],
    verified: VerifiedPoints,
    scene: Scene,
    corridor: WireCorridor,
    options: ReconstructionOptions,
    judge: Callable[[list[FittedWire]], list[WireSupport]],
) -> tuple[list[FittedWire], list[WireSupport], VerifiedPoints, list[Path]]:
    """The conductors the line's own spacing predicts beside the confirmed wires, where the
    views find them: each confirmed wire moved by each offset between confirmed wires that
    run side by side (:func:`_line_offsets`), where no confirmed wire lies along most of it
    (between that wire's ends: the next span's conductor lies on a wire's curve continued),
    traced as a hypothesis (every view checked by the others) and kept where the views that
    would fix it find it at ``MIN_TRACED_SHARE`` of its places or more, then traced in full.

    A conductor no pair of images matched along a span (its image lines paired with no
    other, or its matches lost among a field's rows) is never a candidate; its neighbours
    are. On the real road flight the road-side conductor of one span, plain in the images,
    is found so at 45 % of its places, and the same hypothesis 0.5-1 m beside it at none.
    Its support is measured as the pairs that measured its neighbour would see it (the
    camera geometry of a wire a metre away is the same)."""
    offsets = _line_offsets(wires)
    if not offsets:
        return wires, supports, verified, []

    cand: list[FittedWire] = []
    source: list[int] = []
    for k, w in enumerate(wires):
        for across, dz in offsets:
            h = _shifted(w, across, dz, len(cand))
            if not _covered(h, wires + cand):
                cand.append(h)
                source.append(k)
    if not cand:
        return wires, supports, verified, []
    look = dataclasses.replace(options.trace, max_rounds=0)

    def looks(items: list[tuple[int, float]]) -> tuple[list[WireSupport], list[Path]]:
        # Each hypothesis (candidate, lift) is looked for as if alone: one that one view sees
        # within a search's reach of another would otherwise take the other's image for a
        # neighbour's (one above another shows so in every nadir view), but all are looked
        # for from one read of each image.
        hs = [
            dataclasses.replace(base[i], wire_id=g, z0=base[i].z0 + lift * CONTINUATION_DISTANCE)
            for g, (i, lift) in enumerate(items)
        ]
        sup = [
            dataclasses.replace(supports[source[i]], wire_id=g) for g, (i, _) in enumerate(items)
        ]
        _, out, _, dec = _traced(
            hs,
            sup,
            verified,
            scene,
            corridor,
            options,
            look,
            wires,
            MIN_REDUNDANCY,
            groups=list(range(len(items))),
        )
        return out, dec

    base = list(cand)
    looked, decoded = looks([(i, 0.0) for i in range(len(cand))])
    # One conductor's height beside another changes from span to span by up to what a curve
    # continued is off: where the views find a hypothesis at all, it is looked for again a
    # little higher and lower, and taken at its best height (on the road flight the
    # road-side conductor of one span is found at 16 % of its places at its offset's
    # height, at 77 % 14 cm higher).
    lifted = [
        (i, lift) for i in range(len(cand)) if looked[i].traced_share for lift in SIBLING_LIFTS
    ]
    if lifted:
        out, dec = looks(lifted)
        decoded += dec
        for (i, lift), o in zip(lifted, out, strict=True):
            if (o.traced_share or 0.0) > (looked[i].traced_share or 0.0):
                looked[i] = o
                cand[i] = dataclasses.replace(base[i], z0=base[i].z0 + lift * CONTINUATION_DISTANCE)
    shares = [s.traced_share for s in looked]
    # Best found first; of two at one place in plan, the better.
    taken = _best_apart(cand, shares, MIN_TRACED_SHARE)
    logger.info(
        "siblings: %d hypotheses at the line's %d offsets beside %d wires; found by the views "
        "at %s of their places%s",
        len(cand),
        len(offsets),
        len(wires),
        sorted((round(f, 2) for f in shares if f is not None), reverse=True),
        f"; {len(taken)} kept" if taken else "",
    )
    if not taken:
        return wires, supports, verified, decoded
    new, new_sup, verified, dec = _traced_in_full(
        cand, looked, taken, wires, verified, scene, corridor, options
    )
    for j, i in enumerate(taken):
        new_sup[j] = _support_as_seen(
            new[j], wires[source[i]], new_sup[j].traced_share, verified, judge
        )
        logger.info(
            "siblings: a %.0f m wire %.2f across and %.2f above wire %d, found by the views "
            "that fix it at %.0f %% of its places: kept",
            new[j].s_range[1] - new[j].s_range[0],
            *[float(v) for v in _offset_of(new[j], wires[source[i]])],
            wires[source[i]].wire_id,
            100 * (new_sup[j].traced_share or 0.0),
        )
    wires, supports = _without_untraced(wires + new, supports + new_sup)
    wires, supports = _without_members(wires, supports, corridor, options)
    return wires, supports, verified, decoded + dec


# A faint wire's hypothesis must be found this many times as often as its copies moved
# across (the chance level of the peak test there).
FAINT_CHANCE_RATIO = 3.0


def _faint_wires(
    wires: list[FittedWire],
    supports: list[WireSupport],
    verified: VerifiedPoints,
    scene: Scene,
    corridor: WireCorridor,
    options: ReconstructionOptions,
    judge: Callable[[list[FittedWire]], list[WireSupport]],
) -> tuple[list[FittedWire], list[WireSupport], VerifiedPoints, list[Path]]:
    """The wires too faint for the detector that the views' line evidence, integrated along
    hypothesised curves, shows in the line's cross-section (:mod:`colmap_powerline.faint`):
    each hypothesis traced as such (a response peak that stands out counts on it, every view
    checked by the others, looked for again refitted to what the views found) and kept
    where the views that would fix it find it at ``MIN_SECOND_LOOK_SHARE`` of its places or
    more (like a wire the hit rates rejected, nothing but tracing speaks for it: on the
    shared multispan seed 3 a hypothesis 1.3 m off span 1's unmeasurable shields was found
    at 21 %, the soil seed 11 shield at 55 %), ``FAINT_CHANCE_RATIO`` times as often as its
    copies moved across, and no confirmed wire lies along most of it, then traced in full.
    Its support is measured as the pairs that measured the wire whose stretch its sweep
    covered would see it, as a sibling's is."""
    if not options.trace.faint or not options.trace.enabled or not wires:
        return wires, supports, verified, []
    hyps, decoded = faint_hypotheses(
        scene, wires, options.detect, options.trace.faint_min_z, options.verify.num_threads
    )
    source = [i for i, h in enumerate(hyps) if not _covered(h.wire, wires)]
    cand = [dataclasses.replace(hyps[i].wire, wire_id=g) for g, i in enumerate(source)]
    if not cand:
        return wires, supports, verified, decoded
    # Each look is judged by tracing alone: the support it starts with is a placeholder.
    longest = max(range(len(wires)), key=lambda k: wires[k].s_range[1] - wires[k].s_range[0])
    look = dataclasses.replace(options.trace, max_rounds=0)
    sup = [dataclasses.replace(supports[longest], wire_id=g) for g in range(4 * len(cand))]

    def looks(hs: list[FittedWire]) -> tuple[list[FittedWire], list[WireSupport]]:
        fitted, out, _, dec = _traced(
            hs, sup[: len(hs)], verified, scene, corridor, options, look, wires, MIN_REDUNDANCY,
            groups=list(range(len(hs))), evident=[True] * len(hs),
        )  # fmt: skip
        decoded.extend(dec)
        return fitted, out

    fitted, looked = looks(cand)
    # The sweep places a hypothesis to a step (10-20 cm), tracing searches a few pixels
    # (3 px: 7 cm at the half-scale GSD): where the views found it at some places, it is
    # refitted to what they found and looked for again, and taken at its better look.
    again = [
        i
        for i, (f, s) in enumerate(zip(fitted, looked, strict=True))
        if (s.traced_share or 0.0) > 0.0 and len(f.point_indices) >= options.wires.min_points
    ]
    if again:
        moved = [
            dataclasses.replace(fitted[i], wire_id=g, point_indices=np.zeros(0, np.int64))
            for g, i in enumerate(again)
        ]
        _, second = looks(moved)
        for g, i in enumerate(again):
            if (second[g].traced_share or 0.0) > (looked[i].traced_share or 0.0):
                cand[i] = dataclasses.replace(moved[g], wire_id=i)
                looked[i] = dataclasses.replace(second[g], wire_id=i)
    shares = [s.traced_share for s in looked]
    # Against chance: the same hypothesis moved across by 4 and 8 search reaches each way
    # (off the wire in every view), where the peaks that stand out are found only by
    # accident; it must be found FAINT_CHANCE_RATIO times as often (among the other
    # conductors' images, a hypothesis between them is found at up to 16 % of its places on
    # the shared grid seed 8, and so are its moved copies).
    passing = [i for i in range(len(cand)) if (shares[i] or 0.0) >= MIN_SECOND_LOOK_SHARE]
    if passing:
        centres = scene.centers_in_world
        controls: list[FittedWire] = []
        for i in passing:
            mid = cand[i].points(np.array([np.mean(cand[i].s_range)]))[0]
            gsd = float(np.min(np.linalg.norm(centres - mid, axis=1))) / scene.images[0].focal_px
            step = 4.0 * options.trace.reach_px * gsd
            controls += [
                _shifted(cand[i], m * step, 0.0, len(controls) + q)
                for q, m in enumerate((-2.0, -1.0, 1.0, 2.0))
            ]
        _, chance = looks(controls)
        for n, i in enumerate(passing):
            level = float(np.mean([c.traced_share or 0.0 for c in chance[4 * n : 4 * n + 4]]))
            if (shares[i] or 0.0) < FAINT_CHANCE_RATIO * level:
                logger.info(
                    "faint: a hypothesis found at %.0f %% of its places, its copies moved across "
                    "at %.0f %%: chance, dropped",
                    100 * (shares[i] or 0.0),
                    100 * level,
                )
                shares[i] = 0.0
    taken = _best_apart(cand, shares, MIN_SECOND_LOOK_SHARE)
    logger.info(
        "faint: %d hypotheses from the line evidence; found by the views at %s of their places%s",
        len(cand),
        [None if f is None else round(f, 2) for f in shares],
        f"; {len(taken)} kept" if taken else "",
    )
    if not taken:
        return wires, supports, verified, decoded
    kept_from = [source[i] for i in taken]
    new, new_sup, verified, dec = _traced_in_full(
        cand, looked, taken, wires, verified, scene, corridor, options, evident=True
    )
    decoded += dec
    for j in range(len(new)):
        # Its confidence: that no cell of the sweep reached its evidence by chance
        # (Bonferroni over the cells), the detector's hit rates being blind to it.
        hyp = hyps[kept_from[j]]
        ref = next(k for k, w in enumerate(wires) if w.wire_id == hyp.ref_id)
        new_sup[j] = dataclasses.replace(
            _support_as_seen(new[j], wires[ref], new_sup[j].traced_share, verified, judge),
            found_by="line evidence",
            evidence_sd=round(hyp.z_score, 1),
            confidence=round(1.0 - min(1.0, hyp.cells * float(norm.sf(hyp.z_score))), 6),
        )
        logger.info(
            "faint: a %.0f m wire %.2f across and %.2f above wire %d, found by the views "
            "that fix it at %.0f %% of its places: kept",
            new[j].s_range[1] - new[j].s_range[0],
            *[float(v) for v in _offset_of(new[j], wires[ref])],
            wires[ref].wire_id,
            100 * (new_sup[j].traced_share or 0.0),
        )
    wires, supports = _without_untraced(wires + new, supports + new_sup)
    wires, supports = _without_members(wires, supports, corridor, options)
    return wires, supports, verified, decoded


def _offset_of(wire: FittedWire, other: FittedWire) -> tuple[float, float]:
    """The median offset (across, height) of ``wire`` from ``other``."""
    _, across, dz = other.plane_coords(wire.polyline(0.5))
    return float(np.median(across)), float(np.median(dz))


def _kept(
    wires: list[FittedWire], supports: list[WireSupport], keep: Sequence[int]
) -> tuple[list[FittedWire], list[WireSupport]]:
    """The wires (and their supports) at indices ``keep``, renumbered from 0."""
    return (
        [dataclasses.replace(wires[k], wire_id=i) for i, k in enumerate(keep)],
        [dataclasses.replace(supports[k], wire_id=i) for i, k in enumerate(keep)],
    )


def _without_unconfirmed(
    wires: list[FittedWire], supports: list[WireSupport], support: SupportOptions
) -> tuple[list[FittedWire], list[WireSupport]]:
    """The wires without those that no strip confirms on its own (``confirming_strips`` 0:
    every strip's views see them only where other wires lie, or miss them) and that nothing
    else tells from a false pairing: on weak geometry (no view can), or rejected by the
    views' hit rates (``support.accepts``: the views able to tell do not find it) and kept
    only by tracing's second look. Renumbered from 0. Nothing speaks for such a wire but the
    pairing it came from: on the shared two-strip flights the two of them written in fifteen
    scenes were a 98 m pairing of one conductor's image in one strip with another's in the
    other (mixed seed 3) and a 14 m piece a third of which lay 0.3-0.6 m off (soil seed 11);
    every other wire written had a strip confirming it. Tracing does not speak for it
    either: where a wire runs along the strips, every view of a strip sees the plane
    through the strip and the image wire it borrowed, so the views of the two strips a
    pairing came from agree on it (shared multispan seed 12: a 105 m copy of a conductor
    8.9 m from it, rejected by its hit rates, 36 % of them in the views able to tell, was
    kept when tracing found it at 55 % of its places). Run before tracing as well as after:
    the pairing holds, in one strip, the line of the wire whose image it borrowed, and
    tracing, which sees that wire only beside it there, would fix it nowhere and drop it
    (mixed seed 3's R2: 0 % with the rule run only after tracing, 99.7 % with it run
    before). A wire the line evidence found is no pairing, and no strip's detector confirms
    it (it is too faint for the detector): it stays."""
    keep = []
    for k, (w, s) in enumerate(zip(wires, supports, strict=True)):
        unconfirmed = s.confirming_strips == 0 and s.found_by == "pairs"
        if unconfirmed and s.geometry == "weak":
            why = "no view can tell it from a false pairing"
        elif unconfirmed and s.confidence is not None and not support.accepts(s.confidence):
            why = (
                "the views that can tell it from a false pairing reject it (confidence "
                f"{s.confidence:.3f})"
            )
        else:
            keep.append(k)
            continue
        logger.info(
            "support: wire %d dropped (%.0f m): %s and no strip confirms it on its own (each "
            "sees it only where other wires lie, or misses it)",
            w.wire_id,
            w.s_range[1] - w.s_range[0],
            why,
        )
    return _kept(wires, supports, keep)


def _above_the_floor(
    wires: list[FittedWire],
    supports: list[WireSupport],
    scene: Scene,
    min_height: float,
    inlier_distance: float,
) -> tuple[list[FittedWire], list[WireSupport]]:
    """The wires without those whose lowest point lies at the floor of the heights
    searched (``min_height`` above the ground, within ``inlier_distance``): a structure
    that reaches down to the ground (a hedge's or a tree row's edge, matched by views
    across it) is cut there by the search, a wire hanging free rarely just touches it
    (shared cross seed 2: three such 'wires' at 4.7-5.0 above the ground along a tree-lined
    road, read as a second line)."""
    kept = [
        k for k, w in enumerate(wires) if not _at_the_floor(w, scene, min_height, inlier_distance)
    ]
    return _kept(wires, supports, kept)


def _at_the_floor(w: FittedWire, scene: Scene, min_height: float, inlier_distance: float) -> bool:
    """Whether ``w``'s lowest point lies at the floor of the heights searched (logged)."""
    poly = w.polyline(0.5)
    low = float(np.min(poly[:, 2] - scene.ground_height(poly[:, :2])))
    if low > min_height + inlier_distance:
        return False
    logger.info(
        "wires: wire %d (%.0f m) comes down to %.2f above the ground, the floor of "
        "the heights searched: a structure reaching the ground, not a wire; left out",
        w.wire_id,
        w.s_range[1] - w.s_range[0],
        low,
    )
    return True


def _spans_above_the_floor(
    wires: list[FittedWire],
    spans: Spans,
    supports: list[WireSupport],
    scene: Scene,
    options: ReconstructionOptions,
) -> tuple[list[FittedWire], Spans, list[WireSupport]]:
    """:func:`_above_the_floor` on the span-wires: those left out leave their places in
    ``spans`` too; a line left with no wire goes, with its supports, and the lines are
    numbered again from 1 in their order."""
    floor, inlier = options.triangulate.min_wire_height, options.wires.inlier_distance
    keep = [k for k, w in enumerate(wires) if not _at_the_floor(w, scene, floor, inlier)]
    if len(keep) == len(wires):
        return wires, spans, supports
    lines = sorted({spans.placement[k].line for k in keep})
    number = {line: i + 1 for i, line in enumerate(lines)}
    placement = [dataclasses.replace(spans.placement[k], line=number[spans.placement[k].line])
                 for k in keep]  # fmt: skip
    line_supports = [
        dataclasses.replace(
            t,
            line=number[t.line],
            lines=tuple(number[x] for x in t.lines if x in number),
        )
        for t in spans.supports
        if t.line in number
    ]
    # Support ids stay as the placements give them: 0, 1, ... again where a line went.
    sid = {t.support_id: i for i, t in enumerate(line_supports)}
    placement = [
        dataclasses.replace(
            p, supports=tuple(None if x is None else sid.get(x) for x in p.supports)
        )
        for p in placement
    ]
    line_supports = [dataclasses.replace(t, support_id=i) for i, t in enumerate(line_supports)]
    out = [wires[k] for k in keep]
    spans = dataclasses.replace(
        spans,
        wires=out,
        placement=placement,
        supports=line_supports,
        source=[spans.source[k] for k in keep],
        legs=[spans.legs[k] for k in keep] if spans.legs else spans.legs,
    )
    return out, spans, [supports[k] for k in keep]


def _without_untraced(
    wires: list[FittedWire], supports: list[WireSupport]
) -> tuple[list[FittedWire], list[WireSupport]]:
    """The wires without those the views would fix but do not find (traced share below
    ``MIN_TRACED_SHARE``), and without those that no view can tell from a false pairing (no
    crossing view), or that one strip alone confirms, and that the views can fix nowhere
    apart from the other wires (no traced share) or find at fewer than half the places they
    would fix (``MIN_SECOND_LOOK_SHARE``), and without those tracing measured at no place (a
    line the views find, but fix nowhere): renumbered from 0."""

    def unfixed(s: WireSupport) -> bool:
        # Where only two strips see the wires, a pairing of two lines that other wires or
        # their shadows draw lies, in one strip or the other, on those lines all along: no
        # place of it is seen by views that tell it from them. On the shared generator's
        # two-strip flights (mixed seed 2; vegetation seeds 2-3 with a trial split) every
        # false wire but two was such a one and every conductor was fixed at 87-100 % of
        # its places.
        # The same where the views that can tell confirm it from one strip only (the rest
        # see it where other wires lie): one strip confirms the plane through its cameras,
        # not where in it the wire lies. On the shared corridor seed 3 a 16 m pairing of
        # two conductors from two strips lay on a wire's shadow from the third.
        return s.traced_share is None and untold(s)

    def untold(s: WireSupport) -> bool:
        # No view can tell it from a false pairing, or one strip alone confirms it.
        return s.crossing_views == 0 or s.confirming_strips < 2

    def untold_why(s: WireSupport) -> str:
        return (
            "no view can tell it from a false pairing"
            if s.crossing_views == 0
            else f"{s.confirming_strips} strip(s) of the views confirm it apart from other wires"
        )

    def bar(s: WireSupport) -> float:
        # Where nothing else tells it from a false pairing, the views that would fix it are
        # all the evidence left, and it must meet the bar of a wire that no check confirmed
        # (`MIN_SECOND_LOOK_SHARE`): a pairing of two wires' lines lies on one of them or
        # the other in many views, and these views found the false wires of the package's
        # layouts at 23-34 % of their places (angle: a pairing of the two shields between
        # the circuits; branch: two lines' hypotheses between the branch line's wires),
        # and true wires so confirmed at 69-100 % (50-69 % on the shared generator's
        # two-strip flight over soil and the real road flight, where the bar was not
        # chosen).
        return MIN_SECOND_LOOK_SHARE if untold(s) else MIN_TRACED_SHARE

    kept = [
        k
        for k, s in enumerate(supports)
        if (s.traced_share is None or s.traced_share >= bar(s))
        and not unfixed(s)
        and len(wires[k].point_indices) > 0
    ]
    for k in sorted(set(range(len(wires))) - set(kept)):
        w, s = wires[k], supports[k]
        if len(w.point_indices) == 0:
            why = "the views find it but measure it at no place (no point of it)"
        elif unfixed(s):
            why = (
                untold_why(s)
                + (" (one confirms a plane, not a line)" if s.crossing_views else "")
                + " and the views fix it nowhere apart from the other wires (a pairing of "
                "lines other wires or their shadows draw)"
            )
        elif untold(s) and (s.traced_share or 0.0) >= MIN_TRACED_SHARE:
            why = (
                "the views that would fix it find a wire at "
                f"{100 * (s.traced_share or 0.0):.0f} % of its places, under half, and "
                + untold_why(s)
            )
        else:
            why = (
                "the views that would fix it find a wire at "
                f"{100 * (s.traced_share or 0.0):.0f} % of its places (a false pairing)"
            )
        logger.info(
            "trace: wire %d dropped (%.0f m at %.1f above the ground): %s",
            w.wire_id,
            w.s_range[1] - w.s_range[0],
            s.height_above_ground,
            why,
        )
    return _kept(wires, supports, kept)


def _consensus(
    wires: list[FittedWire],
    verified: VerifiedPoints,
    primitives: list[Primitives],
    pts: npt.NDArray[np.float64] | None = None,
) -> tuple[list[FittedWire], VerifiedPoints]:
    """Every primitive lying on a confirmed wire's curve between its ends, within
    ``CONSENSUS_SIGMAS`` times the wire's own RMS residual, joins it as a measured point
    (the consensus set of the confirmed curve; the curve is not refit).

    Where few views see a wire (the top conductors and shields of a flight across the line,
    a stretch at an image edge) a true primitive often cannot reach the posterior on its
    own, and the points of a wire have gaps that its curve spans. A wrong match lands on a
    confirmed curve, within a few centimetres, only by accident, and is then a measurement
    of that wire all the same. ``pts``: the primitives' points, concatenated (when the
    caller has them)."""
    if pts is None:
        pts = np.concatenate([p.pts_in_world for p in primitives])
    pair = np.concatenate([np.full(len(p), p.pair_index, np.int32) for p in primitives])
    free = np.ones(len(pts), bool)
    free[verified.primitive_index] = False
    idx = np.flatnonzero(free)
    if len(idx) == 0:
        return wires, verified
    cand = pts[idx]
    best = nearest_wire(
        wires, cand, 0.0, CONSENSUS_SIGMAS * np.array([w.rms_residual for w in wires])
    )
    take = np.flatnonzero(best >= 0)
    if len(take) == 0:
        return wires, verified
    n_before = len(verified)
    verified = verified.with_consensus(cand[take], idx[take], pair[idx[take]])
    new = n_before + np.arange(len(take))
    wires = [
        dataclasses.replace(w, point_indices=np.r_[w.point_indices, new[best[take] == k]])
        for k, w in enumerate(wires)
    ]
    logger.info(
        "wires: %d primitives lie on the confirmed wires (within %.1f× each wire's RMS "
        "residual, between its ends) and join their points",
        len(take),
        CONSENSUS_SIGMAS,
    )
    return wires, verified


def _confirm_grown(
    wires: list[FittedWire],
    confirmed: list[tuple[FittedWire, WireSupport]],
    judge: Callable[[list[FittedWire]], list[WireSupport]],
    pts_in_world: F64,
    azimuth_deg: float,
    options: ReconstructionOptions,
) -> tuple[list[FittedWire], list[WireSupport]]:
    """Wires that grew or were joined since they were confirmed, judged again as they are
    now, with all the others. One the views reject is cut back to the stretch they support;
    if they support none, it goes with the pieces it grew from; if the cut is rejected too,
    it goes back to those pieces, each judged again (a piece that a better wire now explains
    goes; its points join a wire they lie on). A wire that did not
    change keeps its support. Renumbered from 0."""
    held = [set(w.point_indices.tolist()) for w in wires]
    parts: list[list[int]] = [[] for _ in wires]  # confirmed pieces in each wire
    for j, (c, _) in enumerate(confirmed):
        pts = set(c.point_indices.tolist())
        for k, h in enumerate(held):
            if len(pts & h) > 0.5 * len(pts):
                parts[k].append(j)
                break
    unchanged = [
        len(p) == 1 and len(held[k]) == len(confirmed[p[0]][0].point_indices)
        for k, p in enumerate(parts)
    ]
    if all(unchanged):
        return wires, [
            dataclasses.replace(confirmed[p[0]][1], wire_id=w.wire_id)
            for w, p in zip(wires, parts, strict=True)
        ]

    def length(w: FittedWire) -> str:
        return f"{w.s_range[1] - w.s_range[0]:.0f} m"

    # Per final wire: the wires standing for it, their supports once settled, and what was
    # tried (0: as grown, 1: cut back, 2: its confirmed pieces).
    entries: list[tuple[list[FittedWire], list[WireSupport] | None, int, int]] = [
        ([w], [confirmed[parts[k][0]][1]] if unchanged[k] else None, 0, k)
        for k, w in enumerate(wires)
    ]
    gone: list[npt.NDArray[np.int64]] = []
    for _ in range(3):
        if all(settled is not None for _, settled, _, _ in entries):
            break
        all_wires = [w for ws, _, _, _ in entries for w in ws]
        judged = iter(judge(all_wires))
        step: list[tuple[list[FittedWire], list[WireSupport] | None, int, int]] = []
        for ws, settled, stage, k in entries:
            got = [next(judged) for _ in ws]
            if settled is not None:
                step.append((ws, settled, stage, k))
                continue
            accepts = options.support.accepts
            good = [(w, g) for w, g in zip(ws, got, strict=True) if accepts(g.confidence)]
            if stage == 2:
                # A confirmed piece that another wire explains all along because it is a
                # stretch of that wire (its points lie on that wire's curve continued: the
                # two were not joined) stays, with the support it was confirmed with; one
                # that lies on no wire (a false pairing explained from each strip by another
                # wire) goes.
                others = [x for x in all_wires if all(x is not w for w in ws)]
                for w, g, j in zip(ws, got, parts[k], strict=True):
                    if g.confidence is None and any(
                        np.median(x.distance(pts_in_world[w.point_indices])) < CONTINUATION_DISTANCE
                        for x in others
                    ):
                        good.append((w, confirmed[j][1]))
            if stage == 2 or len(good) == len(ws):
                if len(good) < len(ws):
                    logger.info(
                        "support: wire %d: %d of the %d pieces it grew from are explained by "
                        "better wires now and go (their points to a wire they lie on)",
                        wires[k].wire_id,
                        len(ws) - len(good),
                        len(ws),
                    )
                    gone += [w.point_indices for w in ws if all(w is not x for x, _ in good)]
                step.append(([w for w, _ in good], [g for _, g in good], stage, k))
                continue
            cut = None
            supported = got[0].supported_s
            if stage == 0 and supported is not None:
                cut = trim_wire(ws[0], pts_in_world, supported, azimuth_deg, options.wires)
            if cut is not None:
                logger.info(
                    "support: wire %d (%s) grew past where the views support it: cut back to %s",
                    wires[k].wire_id,
                    length(ws[0]),
                    length(cut),
                )
                step.append(([cut], None, 1, k))
            elif stage == 0:
                # No stretch of it supported: what it grew along shows the piece it grew from
                # was a false pairing too (true pieces keep a supported stretch).
                logger.info(
                    "support: wire %d (%s) grew from a piece of %s and the views support no "
                    "stretch of it: dropped",
                    wires[k].wire_id,
                    length(ws[0]),
                    ", ".join(length(confirmed[j][0]) for j in parts[k]),
                )
                step.append(([], [], 2, k))
            else:
                pieces = [confirmed[j][0] for j in parts[k]]
                logger.info(
                    "support: wire %d (%s) grew past where the views support it: back to the "
                    "confirmed pieces it grew from (%s)",
                    wires[k].wire_id,
                    length(wires[k]),
                    ", ".join(length(p) for p in pieces),
                )
                step.append((pieces, None, 2, k))
        entries = step
    out = [
        (w, s)
        for ws, settled, _, _ in entries
        if settled is not None
        for w, s in zip(ws, settled, strict=True)
    ]
    kept = [dataclasses.replace(w, wire_id=i) for i, (w, _) in enumerate(out)]
    if gone:
        # A piece explained by one wire all along is a stretch of it that was not joined:
        # its points go to the wire whose curve they lie on (a false pairing's lie on none).
        owned = [w.point_indices for w in kept]
        free = np.setdiff1d(
            np.concatenate(gone), np.concatenate(owned) if owned else np.zeros(0, np.int64)
        ).astype(np.int64)
        kept, _, _ = absorb_points(kept, pts_in_world, free, azimuth_deg, options.wires)
    return kept, [dataclasses.replace(s, wire_id=i) for i, (_, s) in enumerate(out)]


def _tops_from(
    supports: Sequence[LineSupport],
    wires: Sequence[FittedWire],
    measures: Sequence[WireMeasures],
    placement: Sequence[WireSpan],
) -> list[LineSupport]:
    """Each support with the kind of the wire its top is the attachment of. Where a line's
    shield wires were found at some of its supports but a support's top is a conductor's,
    the shields were not found there and the structure stands higher: its top is taken as
    its highest conductor attachment plus the median height the line's shields stand above
    the highest conductors at the supports where both were found (the towers of a line are
    built alike), ``top_from`` ``line`` and said in the log (shared multispan seed 3: the
    first tower 6.4 m lower than the truth from its conductors alone)."""
    kind = {w.wire_id: m.kind for w, m in zip(wires, measures, strict=True)}
    out = [dataclasses.replace(s, top_from=kind.get(s.top_wire, "")) for s in supports]
    conductor_z: dict[int, float] = {}  # each support's highest conductor attachment
    for w, m, p in zip(wires, measures, placement, strict=True):
        if m.kind != "conductor":
            continue
        for side, sid in enumerate(p.supports):
            if sid is not None:
                z = float(w.points(np.array([w.s_range[side]]))[0, 2])
                conductor_z[sid] = max(conductor_z.get(sid, -np.inf), z)
    above: dict[int, list[float]] = {}  # per line: its shields' height above its conductors
    for s in out:
        if s.top_from == "shield" and s.support_id in conductor_z:
            above.setdefault(s.line, []).append(s.top_z - conductor_z[s.support_id])
    for i, s in enumerate(out):
        if s.top_from != "conductor" or s.line not in above:
            continue
        rise = float(np.median(above[s.line]))
        top = conductor_z.get(s.support_id, s.top_z) + rise
        out[i] = dataclasses.replace(s, top_z=top, top_from="line")
        logger.warning(
            "support %d (line %d): the line's shield wires were not found at it; its top "
            "is put %.2f above its highest conductor, as the shields stand at the line's "
            "%d other supports where both were found",
            s.support_id,
            s.line,
            rise,
            len(above[s.line]),
        )
    return out


def _join_pieces(
    wires: list[FittedWire],
    supports: list[WireSupport],
    pts_in_world: F64,
    azimuth_deg: float,
    options: WiresOptions,
) -> tuple[list[FittedWire], list[WireSupport]]:
    """Confirmed pieces of one wire joined (:func:`merge_pieces`), renumbered from 0. A joined
    wire reports the support of its piece seen in the most views."""
    wires, joined = merge_pieces(wires, pts_in_world, azimuth_deg, options)
    if not joined:
        return wires, supports
    best: dict[int, WireSupport] = {}
    for s in supports:
        into = joined.get(s.wire_id, s.wire_id)
        if into not in best or s.views > best[into].views:
            best[into] = s
    for b, a in sorted(joined.items()):
        logger.info("wires: wires %d and %d are one wire (one catenary fits both)", a, b)
    out_w = [dataclasses.replace(w, wire_id=i) for i, w in enumerate(wires)]
    out_s = [dataclasses.replace(best[w.wire_id], wire_id=i) for i, w in enumerate(wires)]
    return out_w, out_s


def _write_wires_las(
    out: Path,
    result: ReconstructionResult,
    convert: Callable[[npt.NDArray[np.float64]], npt.NDArray[np.float64]] | None,
    wkt: str | None,
) -> Path:
    """Measured (assigned) and fitted wire points as LAS, classed 14 / 13 by wire kind."""
    kind = {
        w.wire_id: WIRE_CLASS[m.kind] for w, m in zip(result.wires, result.measures, strict=True)
    }
    on = result.labels >= 0
    measured, mid = result.verified.pts_in_world[on], result.labels[on]
    fitted = [w.polyline(0.1) for w in result.wires]
    fid = [np.full(len(p), w.wire_id) for p, w in zip(fitted, result.wires, strict=True)]
    pts = np.concatenate([measured, *fitted]) if fitted else measured
    ids = np.concatenate([mid, *fid]).astype(np.int32) if fitted else mid.astype(np.int32)
    if convert is not None and len(pts):
        pts = convert(pts)
    cls = np.array([kind.get(int(i), CONDUCTOR) for i in ids], np.uint8)
    colors = wire_colors(ids)
    offset = pts.min(axis=0) if len(pts) else np.zeros(3)
    return write_las(out / "wires.las", [(pts, cls, ids, colors)], offset, wkt)


def _crs_function(
    georef: Georeference | None, crs: str | None
) -> tuple[Callable[[npt.NDArray[np.float64]], npt.NDArray[np.float64]], str] | None:
    """(model frame → ``crs`` function, CRS name), or None to keep the model frame."""
    if not crs or georef is None or georef.origin_wgs84 is None:
        return None
    return crs_converter(georef.origin_wgs84, crs)


def _metadata(
    result: ReconstructionResult, options: ReconstructionOptions, outputs: OutputOptions
) -> dict[str, Any]:
    georef = result.georeference

    def plain(obj: Any) -> Any:
        return json.loads(json.dumps(dataclasses.asdict(obj), default=str))

    return {
        "input_model": str(result.input_path),
        "image_path": str(result.image_path),
        "units": "metres" if georef is not None else "model units (not georeferenced)",
        "georeference": georef.to_json() if georef is not None else None,
        "wire_azimuth_deg": result.corridor.azimuth_deg,
        "pairs": [
            {
                "left": p.left.name,
                "right": p.right.name,
                "crossing_deg": p.crossing_deg,
                "base_height": p.base_height,
                "score": p.score,
            }
            for p in result.pairs
        ],
        "num_primitives": int(sum(len(p) for p in result.primitives)),
        "num_verified_points": len(result.verified),
        # Every read of an image (the work done), and the images read (each counted once).
        "image_reads": len(result.decoded),
        "images_read": len(set(result.decoded)),
        "timings_s": result.timings_s,
        "options": plain(options),
        "outputs": plain(outputs),
    }
