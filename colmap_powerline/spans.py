"""Lines, spans and supports: the towers and poles the conductors hang from, from the wires.

A conductor hangs in spans, each a catenary between two supports. Where it passes a
support it kinks: the support holds it up, so its slope drops there by the two spans' end
slopes together (a 90 m span with 3 m of sag ends at 7-8°: the kink is about 15°). A
single catenary through both spans misses the points on either side by decimetres, two
catenaries meeting at the support fit them to the measurement noise. Supports are found
where the wires say so, in three ways:

- **a kink inside a wire** (one wire measured across the support): the place where two
  curves, fitted to the points on either side, fit far better than one, meeting in a
  downward bend;
- **two pieces meeting**: one conductor's pieces in neighbouring spans, ending on either
  side of a support, whose curves (extended) cross there in a downward bend;
- **wires ending together** where the images see beyond them: the end of a line (a
  terminal tower, placed at the pole the images show there if they show one). Wires that
  end where the images end have left the survey, and no support is made up for them.

Before that, two wires of one line that touch in one vertical plane are put right: two
wires never cross, so along each stretch between their crossings one of them is not there.
Past a support the conductor runs on in plan, and views from above match it at another
height there, so one span's wire is often carried far into the next span's plane. The
views that see the two curves apart (beside the plane) show which one is the wire; the
other gives up that stretch.

Kinks and meetings within ``support_radius`` along the line are one support; supports of
two corridors (the legs of a line on either side of an angle tower) within twice that in
plan are one angle support, and the legs are one line. Each wire is then cut at every
support it runs across, numbered by span along its line, extended to its attachments (the
supports it hangs between: the tips of the insulators, where the curves meet) and linked
to the same conductor in the next span (attachments within ``same_conductor_m``).

Everything here works on fitted wires and their points; images are read only to tell two
wires in one plane apart, to see whether wires go on past where they end, and to find the
pole a line ends at.
"""

from __future__ import annotations

import dataclasses
import itertools
import logging
import warnings
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import cv2
import numpy as np
import numpy.typing as npt
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from .geometry import (
    across_of,
    axial_diff_deg,
    azimuth_deg_of,
    distance_to_polyline,
    positions_across,
)
from .options import check_limits
from .pairs import WireCorridor
from .scene import read_image
from .wires import FittedWire, WiresOptions, parabola_split_rss, refit

logger = logging.getLogger(__name__)

F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]

# Images that must see a place past the wires' ends for the end to be the line's (as
# tracing needs to measure a place: two fix it, a third checks it).
MIN_VIEWS_BEYOND = 3
# How far past the ends that place is looked at (model units): past the insulators.
BEYOND_M = (5.0, 10.0)
# A wire whose plane turns this far from its leg's direction is not along the leg (an
# angle tower's other leg, a line that leaves a junction): the wires' own planes give a
# line's direction within a degree or two.
MAX_TURN_DEG = 5.0


@dataclass(kw_only=True)
class SpanOptions:
    min_kink_deg: float = 2.0  # a wire bending down by at least this where its two curves
    # meet hangs from a support there (spans end at 5-10°: a kink is 10-20°; a catenary's
    # slope changes smoothly and no piece of one bends)
    min_improvement: float = 2.0  # and its two curves fit its points at least this many
    # times better (RMS) than one (one curve through a support misses by decimetres, two
    # fit to the noise of a few centimetres)
    min_piece_m: float = 5.0  # each side of a kink holds at least this much wire
    support_radius: float = 4.0  # kinks, meetings and ends this close along the line are
    # one support (a tower's cross-arms are 4-7 m from its axis)
    max_meeting_gap: float = 40.0  # pieces of one conductor at most this far apart along
    # the line may meet at a support between them
    same_conductor_m: float = 1.0  # attachments of two spans' wires this close at a
    # support are one conductor (conductors hang 1-7 m apart)

    LIMITS: ClassVar[dict[str, str]] = {
        "min_kink_deg": "(0, 90)",
        "min_improvement": ">= 1",
        "min_piece_m": "> 0",
        "support_radius": "> 0",
        "max_meeting_gap": "> 0",
        "same_conductor_m": "> 0",
    }

    def __post_init__(self) -> None:
        check_limits(self)


@dataclass(frozen=True)
class LineSupport:
    """A tower or pole found from the wires.

    Attributes:
        support_id: 0, 1, … in the order of the lines and along each line.
        line: the line it carries (1, 2, …).
        kind: ``suspension`` (the line runs straight through), ``angle`` (it turns there
            by ``turn_deg``), ``end`` (the line ends there) or ``junction`` (the line runs
            through and another line leaves it, at ``turn_deg`` to it: ``lines``).
        position: (3,) its centre: in plan, midway across its wires on the line's axis; z
            the ground under it.
        top_z: the height of its highest attachment (model frame); see ``top_from``.
        turn_deg: the line's change of direction there.
        wire_ids: the wires attached to it.
        found_by: ``kink``, ``pieces meeting``, ``wires ending`` or (an angle support)
            ``spans crossing``: where each conductor's two spans' vertical planes cross.
    """

    support_id: int
    line: int
    kind: str
    position: F64
    top_z: float
    turn_deg: float
    wire_ids: tuple[int, ...]
    found_by: str
    reach_m: float = 0.0  # plan distance from its centre to its farthest attachment
    top_wire: int | None = None  # the wire of its highest attachment
    top_from: str = ""  # that wire's kind (``shield``/``conductor``, set once the kinds are
    # known), or ``line``: the line's shields were not found here but at its other supports,
    # and ``top_z`` is raised by the height they stand above the conductors there
    lines: tuple[int, ...] = ()  # every line it carries (a junction's: the line running
    # through first, then those that leave it; given empty: ``(line,)``)

    def __post_init__(self) -> None:
        if not self.lines:
            object.__setattr__(self, "lines", (self.line,))

    def to_json(self, convert: Callable[[F64], F64] | None = None) -> dict:
        pos = self.position if convert is None else convert(self.position[None])[0]
        return {
            "id": self.support_id,
            "line": self.line,
            "kind": self.kind,
            "position": [float(v) for v in pos],
            "top_z": self.top_z + float(pos[2] - self.position[2]),
            "height_m": self.top_z - float(self.position[2]),
            "turn_deg": self.turn_deg,
            "wires": list(self.wire_ids),
            "found_by": self.found_by,
            "reach_m": self.reach_m,
            "top_from": self.top_from or None,
            "lines": list(self.lines),
        }


@dataclass(frozen=True)
class WireSpan:
    """Where a wire hangs: its line, span (both numbered from 1 along the line), the
    supports at its first and last end (None: not found, e.g. outside the survey) and the
    conductor it belongs to (the same number in every span)."""

    line: int
    span: int
    supports: tuple[int | None, int | None]
    conductor: int

    def to_json(self) -> dict:
        return {
            "line": self.line,
            "span": self.span,
            "support_ids": list(self.supports),
            "conductor": self.conductor,
        }


@dataclass
class Spans:
    """:func:`find_spans`: the wires cut at their supports, where each hangs, the supports,
    and for each wire the index of the input wire it came from."""

    wires: list[FittedWire]
    placement: list[WireSpan]
    supports: list[LineSupport]
    source: list[int]
    legs: list[int] = field(default_factory=list)
    # Lines beside a leg's: (leg, across, side) — the leg's wires across from its axis
    # beyond ``across`` on ``side`` (+1: more, -1: less) are a line of their own
    # (:func:`_cut_at_supports`); none where every leg holds one line.
    beside: list[tuple[int, float, int]] = field(default_factory=list)


@dataclass
class _Candidate:
    leg: int
    u: float  # along the leg's axis
    found_by: str
    wire_ids: set[int]


class _Leg:
    """One corridor's plan axes: u along its direction from its centre, c across."""

    def __init__(self, corridor: WireCorridor) -> None:
        self.origin = np.asarray(corridor.centre_xy, np.float64)
        self.direction = corridor.direction_xy
        self.normal = corridor.normal_xy
        self.azimuth_deg = corridor.azimuth_deg
        self.extent = corridor.s_range  # the corridor's ends along u

    def u(self, xy: F64) -> F64:
        return (np.asarray(xy, np.float64).reshape(-1, 2) - self.origin) @ self.direction

    def c(self, xy: F64) -> F64:
        return (np.asarray(xy, np.float64).reshape(-1, 2) - self.origin) @ self.normal

    def xy(self, u: float, c: float) -> F64:
        return self.origin + u * self.direction + c * self.normal

    def s_along(self, wire: FittedWire, u: F64) -> F64:
        """(N,) positions along ``wire``'s plane that lie at ``u`` (N,) along this leg."""
        d = float(wire.plane_direction_xy @ self.direction)
        u0 = float(self.u(wire.plane_origin_xy)[0])
        u = np.asarray(u, np.float64)
        return (u - u0) / d if abs(d) > 1e-6 else np.full(u.shape, np.nan)

    def s_of(self, wire: FittedWire, u: float) -> float:
        return float(self.s_along(wire, np.array([u]))[0])

    def curve(self, wire: FittedWire, u: F64) -> tuple[F64, F64]:
        """``wire`` at ``u`` (N,) along this leg: its offset across the leg and height."""
        p = wire.points(self.s_along(wire, u))
        return self.c(p[:, :2]), p[:, 2]

    def bisector(self, others: Sequence[_Leg]) -> tuple[F64, F64]:
        """The mean direction of this leg and ``others`` (axial: each turned towards this
        one), and across it: a support's cross-arm where the legs meet."""
        d = self.direction + sum((e if e @ self.direction > 0 else -e) for e in
                                 (o.direction for o in others))  # fmt: skip
        d = d / np.linalg.norm(d)
        return d, across_of(d)

    def ends_u(self, wire: FittedWire) -> tuple[float, float]:
        u = self.u(wire.points(np.array(wire.s_range))[:, :2])
        return float(u.min()), float(u.max())


def _kink_between(left: F64, right: F64, lo: float, hi: float) -> tuple[float, float] | None:
    """Where two parabolas (left and right of a support) cross between ``lo`` and ``hi``,
    and the bend there in degrees (positive: downward, as a support makes)."""
    roots = np.roots(left - right) if np.any(left != right) else np.array([])
    roots = np.real(roots[np.abs(np.imag(roots)) < 1e-9])
    roots = roots[(roots >= lo) & (roots <= hi)]
    if not len(roots):
        return None
    mid = 0.5 * (lo + hi)
    t = float(roots[np.argmin(np.abs(roots - mid))])
    bend = np.degrees(
        np.arctan(np.polyval(np.polyder(left), t)) - np.arctan(np.polyval(np.polyder(right), t))
    )
    return t, float(bend)


def find_kink(wire: FittedWire, pts_in_world: F64, options: SpanOptions) -> float | None:
    """The position along ``wire``'s plane of a support it was measured across (see the
    module docstring), or None."""
    s, _, _ = wire.plane_coords(pts_in_world[wire.point_indices])
    z = pts_in_world[wire.point_indices, 2]
    order = np.argsort(s)
    s, z = s[order], z[order]
    if len(s) > 4000:  # evenly thinned: the fit needs the shape, not every point
        keep = np.linspace(0, len(s) - 1, 4000).astype(np.int64)
        s, z = s[keep], z[keep]
    return _kink_in(s, z, options, 10)


# A wire that one curve holds over two short spans: that curve holds their outer parts and
# lets go of the points by the support between, where both spans rise to it (the package's
# `parallel` layout: a pole line's 45 m spans kinked by 6-7°, its points 0.8 m above the one
# curve at the pole, 2-6 % of them held within 10 m of it). The points in its plane near
# the curve tell (:func:`band_kink`): within this height of the curve (a curve over two
# spans kinked by 10° misses the points by the support by about a hundredth of the spans'
# length)...
BAND_HEIGHT_M = 1.0
# ... their median height every this far along it (a false pairing's layer beside the wire,
# a fifth of the points, moves no median) ...
BAND_STEP_M = 1.0
# ... where it holds at least this many of them.
BAND_MIN_POINTS = 5


def band_kink(
    wire: FittedWire, pts_in_world: F64, options: SpanOptions, max_across: float
) -> tuple[float, I64] | None:
    """The position along ``wire``'s plane of a support it runs across where its curve lets
    go of the points (see ``BAND_HEIGHT_M``): the kink test of :func:`find_kink` on the
    median heights of all the points within ``max_across`` of its plane and
    ``BAND_HEIGHT_M`` of its curve, held by it or not; with those points' indices. None
    where there is no such kink."""
    lo, hi = wire.s_range
    s, c, dz = wire.plane_coords(pts_in_world)
    near = np.flatnonzero(
        (np.abs(c) <= max_across) & (s >= lo) & (s <= hi) & (np.abs(dz) <= BAND_HEIGHT_M)
    )
    s, dz = s[near], dz[near]
    if not len(s):
        return None
    edges = np.arange(lo, hi + BAND_STEP_M, BAND_STEP_M)
    bins = np.clip(np.digitize(s, edges) - 1, 0, len(edges) - 2)
    counts = np.bincount(bins, minlength=len(edges) - 1)
    filled = np.flatnonzero(counts >= BAND_MIN_POINTS)
    if not len(filled):
        return None
    centres = 0.5 * (edges[filled] + edges[filled + 1])
    medians = np.array([np.median(dz[bins == b]) for b in filled])
    t = _kink_in(centres, wire.z_at(centres) + medians, options, BAND_MIN_POINTS)
    return None if t is None else (t, near)


def _kink_in(s: F64, z: F64, options: SpanOptions, min_side: int) -> float | None:
    """:func:`find_kink` on sorted samples (``s`` along the plane, ``z``): each side of the
    kink holds ``min_side`` of them and ``min_piece_m`` of wire."""
    if len(s) < 2 * min_side or s[-1] - s[0] < 2 * options.min_piece_m:
        return None
    centre, scale = 0.5 * (s[0] + s[-1]), 0.5 * (s[-1] - s[0])
    x = (s - centre) / scale
    left, right = parabola_split_rss(x, z)
    n = len(s)
    k = np.arange(n + 1)
    ok = (k >= min_side) & (k <= n - min_side)
    ok[min_side : n - min_side + 1] &= (
        s[min_side - 1 : n - min_side] - s[0] >= options.min_piece_m
    ) & (s[-1] - s[min_side : n - min_side + 1] >= options.min_piece_m)
    if not ok.any():
        return None
    split = np.where(ok, left + right, np.inf)
    best = int(np.argmin(split))
    one = left[-1]
    if not np.isfinite(split[best]) or one <= options.min_improvement**2 * split[best]:
        return None
    pl, pr = np.polyfit(x[:best], z[:best], 2), np.polyfit(x[best:], z[best:], 2)
    # The support lies between the two sides' points, or a little beyond either.
    margin = options.support_radius / scale
    kink = _kink_between(pl, pr, x[best - 1] - margin, x[best] + margin)
    if kink is None:
        return None
    t, _ = kink
    # The bend in degrees needs the real slopes: parabolas in s, not in x.
    bend = np.degrees(
        np.arctan(np.polyval(np.polyder(pl), t) / scale)
        - np.arctan(np.polyval(np.polyder(pr), t) / scale)
    )
    if bend < options.min_kink_deg:
        return None
    return float(centre + t * scale)


def _cut_at_kinks(
    wire: FittedWire,
    pts_in_world: F64,
    direction_xy: F64,
    options: SpanOptions,
    wires_options: WiresOptions,
    next_id: int,
) -> tuple[list[FittedWire], list[F64], int]:
    """``wire`` cut at every kink (:func:`find_kink`; its pieces looked at again: a wire may
    run across two supports): the pieces (new ones numbered from ``next_id``), where the
    kinks are in plan, and the next free id."""
    out, kinks, todo = [], [], [wire]
    while todo:
        piece = todo.pop()
        t = find_kink(piece, pts_in_world, options)
        if t is not None:
            s, _, _ = piece.plane_coords(pts_in_world[piece.point_indices])
            left, right = piece.point_indices[s < t], piece.point_indices[s >= t]
            if min(len(left), len(right)) >= wires_options.min_points:
                a = refit(piece, pts_in_world, left, direction_xy, wires_options)
                b = refit(piece, pts_in_world, right, direction_xy, wires_options)
                if a is not piece and b is not piece:
                    b = dataclasses.replace(b, wire_id=next_id)
                    next_id += 1
                    kinks.append(piece.points(np.array([t]))[0, :2])
                    logger.info(
                        "spans: wire %d bends at %.1f along it (a support): cut into %d and %d",
                        piece.wire_id,
                        t - piece.s_range[0],
                        a.wire_id,
                        b.wire_id,
                    )
                    todo += [a, b]
                    continue
        out.append(piece)
    return out, kinks, next_id


def _pieces_meet(
    a: FittedWire, b: FittedWire, leg: _Leg, options: SpanOptions, max_across: float
) -> float | None:
    """Where two wires of one leg, ``a`` before ``b`` along it, meet at a support: their
    curves cross between ``a``'s end and ``b``'s start with a downward bend, in one
    vertical plane. Each may be carried a little past the support (its curve took some of
    the next span's points there): they may overlap by up to half ``max_meeting_gap``. The
    position along the leg, or None."""
    a_lo, a_hi = leg.ends_u(a)
    b_lo, b_hi = leg.ends_u(b)
    gap = b_lo - a_hi
    if not (-options.max_meeting_gap / 2 <= gap <= options.max_meeting_gap) or a_lo >= b_lo:
        return None
    if a_hi >= b_hi:
        return None
    r = options.support_radius
    lo, hi = min(a_hi, b_lo) - r, max(a_hi, b_lo) + r
    u = np.linspace(lo, hi, max(int((hi - lo) / 0.25), 2))
    ca, za = leg.curve(a, u)
    cb, zb = leg.curve(b, u)
    # Fitted in the leg's u (parabolas: within a millimetre of the catenaries here).
    fa = np.polyfit(u, za, 2)
    fb = np.polyfit(u, zb, 2)
    kink = _kink_between(fa, fb, lo, hi)
    if kink is None or kink[1] < options.min_kink_deg:
        return None
    t = kink[0]
    k = int(np.argmin(np.abs(u - t)))
    if abs(ca[k] - cb[k]) > max_across:
        return None
    # Neither curve carried farther than half the gap allowed: a curve continued far from
    # its points is a guess (a cable under a conductor, continued 25 m, met it).
    if max(t - a_hi, b_lo - t) > options.max_meeting_gap / 2:
        return None
    return t


def _plane_crossings(
    wires: list[FittedWire],
    legs: list[int],
    support: tuple[list[int], F64, str, set[int]],
    axes: list[_Leg],
    options: SpanOptions,
    max_across: float,
) -> F64:
    """(K, 2) where the vertical planes of wires of two legs ending at an angle support
    cross near it, at one height (one conductor's two spans): its attachments in plan."""
    near = [
        k
        for k in range(len(wires))
        if legs[k] in support[0]
        and min(
            np.linalg.norm(wires[k].points(np.array(wires[k].s_range))[:, :2] - support[1], axis=1)
        )
        <= options.max_meeting_gap / 2
    ]
    found = []
    for i in near:
        for j in near:
            if legs[i] >= legs[j]:
                continue
            a, b = wires[i], wires[j]
            m = np.c_[a.plane_direction_xy, -b.plane_direction_xy]
            if abs(np.linalg.det(m)) < 1e-3:
                continue
            sa, sb = np.linalg.solve(m, b.plane_origin_xy - a.plane_origin_xy)
            pa, pb = a.points(np.array([sa]))[0], b.points(np.array([sb]))[0]
            near_support = np.linalg.norm(pa[:2] - support[1]) <= 2 * options.support_radius
            if near_support and abs(pa[2] - pb[2]) <= max_across:
                found.append(pa[:2])
    return np.array(found).reshape(-1, 2)


def _met_again(
    wires: list[FittedWire],
    legs: list[int],
    leg: _Leg,
    li: int,
    u: float,
    options: SpanOptions,
    max_across: float,
) -> float:
    """Where the leg's wires ending on either side of the support at ``u`` meet (median),
    or ``u`` when none do."""
    r = 2 * options.support_radius
    before = [
        w for w, g in zip(wires, legs, strict=True) if g == li and abs(leg.ends_u(w)[1] - u) <= r
    ]
    after = [
        w for w, g in zip(wires, legs, strict=True) if g == li and abs(leg.ends_u(w)[0] - u) <= r
    ]
    met = [
        t
        for a in before
        for b in after
        if a is not b and (t := _pieces_meet(a, b, leg, options, max_across)) is not None
    ]
    return float(np.median(met)) if met else u


def _meeting(
    a: FittedWire, b: FittedWire, leg: _Leg, u: float, options: SpanOptions, max_across: float
) -> float | None:
    """The bend (degrees, downward positive) where two pieces of a wire cut at ``u`` along
    the leg meet within ``support_radius`` of it, or None when they do not meet there."""
    if np.mean(leg.ends_u(a)) > np.mean(leg.ends_u(b)):
        a, b = b, a
    r = options.support_radius
    grid = np.linspace(u - r, u + r, 33)
    ca, za = leg.curve(a, grid)
    cb, zb = leg.curve(b, grid)
    kink = _kink_between(np.polyfit(grid, za, 2), np.polyfit(grid, zb, 2), u - r, u + r)
    if kink is None:
        return None
    i = int(np.argmin(np.abs(grid - kink[0])))
    if abs(ca[i] - cb[i]) > max_across:
        return None
    return kink[1]


# The continuation test: the wire's curve extended this far past its end (model units: past
# the insulators' hardware and short of a next support), read across at these offsets (px).
CONTINUATION_M = (2.0, 8.0)
RIDGE_OFFSETS_PX = np.arange(-8.0, 8.01, 0.5)
RIDGE_SIGMAS = 2.5  # a ridge this many robust σ of the background's response is a line
MAX_CONTINUATION_VIEWS = 6


def _grey(view, greys: dict[Path, np.ndarray]) -> np.ndarray:
    """The view's grey image, read once into ``greys`` (the images read so far, the oldest
    let go past twice MAX_CONTINUATION_VIEWS: a few images in memory, at most)."""
    if view.path not in greys:
        if len(greys) >= 2 * MAX_CONTINUATION_VIEWS:
            del greys[next(iter(greys))]
        greys[view.path] = read_image(view.path, cv2.IMREAD_GRAYSCALE).astype(np.float32)
    return greys[view.path]


def _ridge(grey: np.ndarray, uv: F64) -> tuple[float, float]:
    """The thin line along the image curve ``uv`` (M, 2): its signed ridge response
    (brighter or darker than beside it: the grey levels across the curve averaged along
    it, less their mean 2.5-3 px either side) at its strongest within 1.5 px of the curve,
    and the robust σ of that response 5 px or more from it (the background's)."""
    peak, sigma, _ = _ridge_levels(grey, uv)
    return peak, sigma


def _ridge_levels(grey: np.ndarray, uv: F64) -> tuple[float, float, float]:
    """:func:`_ridge`, and the grey beside the curve where the ridge is read (the
    background's level there)."""
    t = np.gradient(uv, axis=0)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    normal = np.c_[-t[:, 1], t[:, 0]]
    pts = uv[:, None, :] + RIDGE_OFFSETS_PX[None, :, None] * normal[:, None, :] - 0.5
    samples = cv2.remap(
        grey,
        pts[..., 0].astype(np.float32),
        pts[..., 1].astype(np.float32),
        cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_REFLECT,
    )
    g = samples.mean(axis=0)
    o = RIDGE_OFFSETS_PX
    r = g - np.array([np.interp(o + d, o, g) for d in (-3.0, -2.5, 2.5, 3.0)]).mean(axis=0)
    inner = np.flatnonzero(np.abs(o) <= 1.5)
    at = inner[np.argmax(np.abs(r[inner]))]
    peak = float(r[at])
    sigma = 1.4826 * float(np.median(np.abs(r[np.abs(o) >= 5.0]))) + 1e-6
    return peak, sigma, float(g[at] - peak)


def _plain_before(
    views: Sequence,
    before: F64,
    curves: Sequence[F64],
    near: F64,
    greys: dict[Path, np.ndarray],
) -> Iterator[tuple[Any, np.ndarray, tuple[float, float], list[F64]]]:
    """The views, nearest ``near`` first and at most MAX_CONTINUATION_VIEWS of them, that
    show a wire plainly along ``before`` (a stretch of it before its end: its ridge at
    least RIDGE_SIGMAS σ of the background's) and see each of ``curves`` whole: each
    view, its grey image, that ridge and the grey beside it, and the curves in its
    pixels."""
    shown = 0
    for v in sorted(views, key=lambda v: np.linalg.norm(v.center_in_world[:2] - near[:2])):
        if shown >= MAX_CONTINUATION_VIEWS:
            return
        projected = [v.project(p) for p in (before, *curves)]
        if not all(ok.all() for _, _, ok in projected):
            continue
        uv = [q for q, _, _ in projected]
        if min(np.ptp(q[:, 0]) + np.ptp(q[:, 1]) for q in uv) < 10:  # too short to read
            continue
        grey = _grey(v, greys)
        ref, sigma, ground = _ridge_levels(grey, uv[0])
        if abs(ref) < RIDGE_SIGMAS * sigma:
            continue  # the measured wire itself is not plain here
        shown += 1
        yield v, grey, (ref, ground), uv[1:]


def _holds(grey: np.ndarray, uv: F64, ref: tuple[float, float], either: bool = True) -> bool:
    """Whether the image curve ``uv`` holds a line like the measured wire's (``ref``: its
    ridge and the grey beside it where it was measured): of its polarity and at least half
    its contrast (and RIDGE_SIGMAS σ of the background's). A thin wire covers part of a
    pixel: its ridge is that part of its grey less the ground's. Where the ground here has
    come nearer the wire's grey than where it was measured by as much as the ridge, the
    wire may show either way (a bright wire over a concrete drive: the full road flight's
    south-east end, its wires 60-77 grey levels bright over the soil, 5-16 over the drive,
    91-96 levels brighter), and a line of either polarity RIDGE_SIGMAS σ strong holds it.
    (Asking less where the ground came nearer by less took a lattice tower's members for a
    line turned past its end on the shared `soil` seed 25.) Not with ``either`` False:
    where a line's end is placed, its evidence would run on along a tower's members over
    the bright ground under it (0.1-0.45 m further on the shared and the package's
    towers)."""
    return _like(_ridge_levels(grey, uv), ref, either)


def _like(levels: tuple[float, float, float], ref: tuple[float, float], either: bool) -> bool:
    """:func:`_holds` on a curve's ridge read (:func:`_ridge_levels`)."""
    ridge, ground_before = ref
    peak, sigma, ground = levels
    if either and (ground - ground_before) * np.sign(ridge) >= abs(ridge):
        return bool(abs(peak) >= RIDGE_SIGMAS * sigma)
    return bool(
        np.sign(peak) == np.sign(ridge) and abs(peak) >= max(0.5 * abs(ridge), RIDGE_SIGMAS * sigma)
    )


def _continues(
    views: Sequence, wire: FittedWire, at_end: int, greys: dict[Path, np.ndarray]
) -> tuple[int, int]:
    """How many views show ``wire`` going on past its end ``at_end`` (0: first, 1: last),
    of how many could tell. Its curve is read CONTINUATION_M past the end, in two halves,
    in the views that show it plainly along the same length before the end (those that can
    tell): it goes on in a view where both halves hold a line of the same polarity and at
    least half the contrast of the measured wire's (a tower's members cross there at all
    angles and contrasts, a wire carries on as it was). ``greys``: the grey images read so
    far (the wires ending at one place share their views: each is read once)."""
    lo, hi = wire.s_range
    sign = -1.0 if at_end == 0 else 1.0
    end = lo if at_end == 0 else hi
    near, far = CONTINUATION_M
    mid = 0.5 * (near + far)
    halves = [
        wire.points(end + sign * np.linspace(near, mid, 15)),
        wire.points(end + sign * np.linspace(mid, far, 15)),
    ]
    before = wire.points(end - sign * np.linspace(near, far, 25))
    shown = going = 0
    for _, grey, ref, uv in _plain_before(views, before, halves, halves[0][0], greys):
        shown += 1
        going += all(_holds(grey, q, ref) for q in uv)
    return going, shown


# A line may turn at the pole where its measured wires end (an angle pole whose next leg no
# pair measured: the 40-image road flight's field line turns by about 9° at its last pole
# and runs on across the images). Each view that shows a wire plainly before its end reads
# the wire continued past the pole turned in plan about it, up to MAX_TURN_DEG either way,
# in steps that move its far end by two pixels at most (the ridge read holds a line within
# 1.5 px of the curve), in three pieces out to TURN_PIECES_M[-1] (a tower's members, at
# all angles, end within a few metres of its wires' ends; a line turned at a pole runs
# on); the view's turn is the angle where all three hold a line like the wire's, most
# strongly. The views' turns (of the three longest wires, pooled) must agree within
# TURN_AGREE_DEG, half of those that could tell or more. A view's turn is off by a few
# degrees where the next span hangs other than this one mirrored (the field line: 9.1,
# 10.4 and 13.5° in three of the five views that could tell; none going on straight).
MAX_TURN_DEG = 35.0
TURN_PIECES_M = (2.0, 5.0, 8.0, 14.0)
TURN_AGREE_DEG = 5.0
# Turned less than this, the line goes on straight past the pole (a suspension).
MIN_TURN_DEG = 1.5


def _turned(points: F64, at: F64, deg: float) -> F64:
    """``points`` turned in plan about the vertical through ``at`` by ``deg`` (clockwise
    seen from above, as azimuths grow)."""
    t = np.radians(deg)
    c, s = np.cos(t), np.sin(t)
    rel = points[:, :2] - at[:2]
    # An azimuth grows clockwise from +y: (x, y) -> (x cos t + y sin t, -x sin t + y cos t).
    xy = np.c_[rel[:, 0] * c + rel[:, 1] * s, -rel[:, 0] * s + rel[:, 1] * c] + at[:2]
    return np.c_[xy, points[:, 2]]


def _continues_turned(
    views: Sequence, wire: FittedWire, at_end: int, greys: dict[Path, np.ndarray], pivot: float
) -> tuple[list[float], int]:
    """The turns (degrees, clockwise from above) at which views show ``wire`` going on past
    the pole at ``pivot`` (s along its plane) beyond its end ``at_end``, one per view that
    shows one, and how many views could tell (those that show the wire plainly before its
    end and see the turned pieces whole at half the angles or more). The wire is continued
    from the pole along its plane, in height as it hangs before the pole, mirrored (the
    next span's wire leaves the pole as this one reaches it), and turned about it (see
    MAX_TURN_DEG's note)."""
    lo, hi = wire.s_range
    sign = -1.0 if at_end == 0 else 1.0
    pieces = []
    for a, b in zip(TURN_PIECES_M[:-1], TURN_PIECES_M[1:], strict=True):
        d = np.linspace(a, b, 15)
        p = wire.points(pivot + sign * d)
        p[:, 2] = wire.points(pivot - sign * d)[:, 2]
        pieces.append(p)
    tip = wire.points(np.array([pivot]))[0]
    edge = lo if at_end == 0 else hi
    before = wire.points(edge - sign * np.linspace(*CONTINUATION_M, 25))
    turns: list[float] = []
    shown = 0
    for v, grey, ref, _ in _plain_before(views, before, pieces[:1], pieces[0][0], greys):
        depth = float(v.project(tip[None])[1][0])
        step = np.degrees(2.0 * float(v.gsd_at_depth(depth)) / TURN_PIECES_M[-1])
        k = np.arange(1, int(MAX_TURN_DEG / step) + 1) * step
        angles = np.r_[-k[::-1], k]
        best, best_deg, seen = 0.0, None, 0
        for deg in angles:
            projected = [v.project(_turned(h, tip, float(deg))) for h in pieces]
            if not all(ok.all() for _, _, ok in projected):
                continue
            seen += 1
            strength = 0.0
            for q, _, _ in projected:
                levels = _ridge_levels(grey, q)
                if not _like(levels, ref, True):
                    break
                strength += abs(levels[0])
            else:
                if strength > best:
                    best, best_deg = strength, float(deg)
        # A view that sees the pieces whole at fewer than half the angles cannot tell.
        shown += seen >= len(angles) / 2
        if best_deg is not None:
            turns.append(best_deg)
    return turns, shown


# Where a wire's line evidence stops: its curve read in pieces of EVIDENCE_PIECE_M every
# EVIDENCE_STEP_M from EVIDENCE_SCAN_M before its measured end to as far past it, and
# further in by as far as a round of tracing goes past an end (``traced_past``: that
# round's points may all lie past the support, on ground texture near the curve).
EVIDENCE_SCAN_M = 5.0
EVIDENCE_STEP_M = 0.25
EVIDENCE_PIECE_M = 1.0
# A view's pieces must agree this well with one split into held and not held.
MIN_EVIDENCE_AGREEMENT = 0.75
# Views lose a wire short of its end (the tower's lattice behind it, its insulator's
# hardware, a change of ground), but no view shows it past its end: the line ends where
# the views that see it farthest say, their upper quartile (not their extreme: a tower
# member along a wire's curve carries one view on).
EVIDENCE_QUANTILE = 0.75


def _evidence_stops(
    views: Sequence,
    wire: FittedWire,
    at_end: int,
    greys: dict[Path, np.ndarray],
    traced_past: float,
) -> list[float]:
    """Where ``wire``'s line evidence stops near its end ``at_end`` (0: first, 1: last), in
    each view that shows it plainly before its end (:func:`_plain_before`): the distance
    along its plane past the measured end (negative: short of it). Its catenary is read
    piece by piece from EVIDENCE_SCAN_M + ``traced_past`` before the end outwards (tracing
    may have carried the wire that far past its support); a piece holds the wire as
    :func:`_holds` says. The wire ends within the first piece of the split of the pieces
    into held (before) and not held (after) that most of them agree with, in its first half
    (where it covers less than half of that piece). A view whose pieces agree with no split
    (MIN_EVIDENCE_AGREEMENT), or whose evidence stops within the first metre read, is not
    counted."""
    lo, hi = wire.s_range
    sign = -1.0 if at_end == 0 else 1.0
    end = lo if at_end == 0 else hi
    near, far = CONTINUATION_M
    before = wire.points(end - sign * np.linspace(near, far, 25))
    scan_in = EVIDENCE_SCAN_M + traced_past
    starts = np.arange(-scan_in, EVIDENCE_SCAN_M + 1e-9, EVIDENCE_STEP_M)
    pieces = [wire.points(end + sign * np.linspace(d, d + EVIDENCE_PIECE_M, 12)) for d in starts]
    stops: list[float] = []
    for v, grey, ref, _ in _plain_before(views, before, (), before[0], greys):
        held = []
        for piece in pieces:  # read outwards until a piece leaves the image
            q, _, ok = v.project(piece)
            if not ok.all():
                break
            held.append(_holds(grey, q, ref, either=False))
        if len(held) < 8:
            continue
        # The split of the pieces into held before and not held after that most of them
        # agree with (a stray miss before the end or a stray hit past it does not move it).
        signed = np.where(held, 1, -1)
        agree = np.cumsum(signed)[:-1] - (np.cumsum(signed[::-1])[::-1][1:])
        best = np.flatnonzero(agree == agree.max())
        k = 1 + int(best[len(best) // 2])
        if (agree.max() + len(held)) / (2 * len(held)) < MIN_EVIDENCE_AGREEMENT:
            continue
        if starts[k] < -scan_in + 1.0:
            continue
        stops.append(float(starts[k] + 0.5 * (EVIDENCE_PIECE_M - EVIDENCE_STEP_M)))
    return stops


# Where a line ends at a pole, the wires' line evidence runs on past their attachments along
# the pole or its arm (the package's `parallel` layout: its end poles placed 0.4-0.6 m out,
# each view's stop 0.4-0.7 m past the wires' ends). The pole itself is a vertical bar from
# the ground to the wires, one place in every view that sees it: a place is looked for
# within POLE_SEARCH_M of where the evidence ends, every POLE_STEP_M along and across the
# line, and the end moves there when the bar stands out there alone (a lattice tower's
# members give several bars about as strong, the ground's texture none).
POLE_SEARCH_M = 1.5
POLE_STEP_M = 0.1
POLE_HALF_WIDTH_M = 0.12  # a pole's half-width (poles are 0.2-0.4 m across)
POLE_FLANK_PX = 2.5  # the grey beside it read this far past its half-width, on both sides
POLE_READ_M = (1.5, 1.0)  # read from this far above the ground to this far under the wires
POLE_MIN_PX = 20.0  # a view reads the pole where its image is this long or more
POLE_VIEWS = (3, 10)  # at least, at most (the longest images)
POLE_CLEAR_M = 0.5  # the bar's rivals: every place this far from it or farther
# The bar must stand this many times as high above the places around (their median) as its
# strongest rival: 19-85 at the poles of the package's `parallel` and `branch` layouts,
# 1.1-1.3 at their towers, where it was chosen; measured after, on the shared generator,
# 3.8-4.4 at three of its four poles and 1.0-1.75 at its towers, on the road flight 33 at
# its end pole (README).
POLE_MIN_RATIO = 3.0


def _grey_along(grey: np.ndarray, lines: F64) -> F64:
    """(..., ) the mean grey along each image line of ``lines`` (..., M, 2) points."""
    q = lines.astype(np.float32).reshape(-1, lines.shape[-2], 2)
    g = cv2.remap(grey, np.ascontiguousarray(q[..., 0]), np.ascontiguousarray(q[..., 1]),
                  cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)  # fmt: skip
    return g.mean(axis=1).reshape(lines.shape[:-2])


def _bar(crop: np.ndarray, lines: F64, beside: F64) -> F64:
    """(...,) for each image line of ``lines`` (..., M, 2): the grey along it less the grey
    along it moved by ``beside`` (px) to each side — a bar, not an edge: the smaller of the
    two where both have one sign, else none — in robust σ of those differences."""
    mid = _grey_along(crop, lines)
    a = mid - _grey_along(crop, lines + beside)
    b = mid - _grey_along(crop, lines - beside)
    ab = np.r_[a.ravel(), b.ravel()]
    sigma = 1.4826 * float(np.median(np.abs(ab - np.median(ab)))) + 1e-6
    return np.where(a * b > 0, np.sign(a) * np.minimum(np.abs(a), np.abs(b)), 0.0) / sigma


def _pole(
    views: Sequence,
    leg: _Leg,
    u: float,
    c: float,
    ground_height: Callable[[F64], F64],
    top_z: float,
    greys: dict[Path, np.ndarray],
) -> float | None:
    """Where along ``leg``, within POLE_SEARCH_M of (``u``, ``c``), the images show a pole
    standing from the ground to the wires (``top_z``: their height there), or None.

    In each view whose image of the pole is POLE_MIN_PX long or more (the POLE_VIEWS[1]
    longest), each place's vertical is read along its image from POLE_READ_M[0] above the
    ground to POLE_READ_M[1] under ``top_z``: the grey along it less the grey beside it,
    on each side (a bar, not an edge: the smaller of the two where both have one sign,
    else none), in robust σ of those differences over the places. The views' median (a
    view alone reads the pole all along the line through it from its nadir; two views'
    lines cross only at the pole), of either polarity, must stand POLE_MIN_RATIO times as
    high above the places' median as the best place POLE_CLEAR_M or more from it."""
    off = np.arange(-POLE_SEARCH_M, POLE_SEARCH_M + 1e-9, POLE_STEP_M)
    n = len(off)
    du, dc = np.meshgrid(off, off, indexing="ij")
    xy = leg.xy(u, c) + du[..., None] * leg.direction + dc[..., None] * leg.normal
    lo = float(ground_height(leg.xy(u, c)[None])[0]) + POLE_READ_M[0]
    hi = top_z - POLE_READ_M[1]
    if hi - lo < 2.0 * POLE_READ_M[0]:
        return None
    hs = np.linspace(lo, hi, 24)
    plan = np.repeat(xy[:, :, None, :], len(hs), axis=2)
    pts = np.concatenate([plan, np.broadcast_to(hs, (n, n, len(hs)))[..., None]], axis=-1)
    pts = pts.reshape(-1, 3)
    seen = []
    for v in views:
        uv, depth, ok = v.project(pts)
        if not ok.all():
            continue
        uv = uv.reshape(n, n, len(hs), 2) - 0.5
        along = uv[n // 2, n // 2, -1] - uv[n // 2, n // 2, 0]
        length = float(np.linalg.norm(along))
        if length >= POLE_MIN_PX:
            seen.append((length, v, uv, along / length, float(np.median(depth))))
    seen = sorted(seen, key=lambda t: -t[0])[: POLE_VIEWS[1]]
    if len(seen) < POLE_VIEWS[0]:
        return None
    zs = []
    for _, v, uv, along, depth in seen:
        normal = np.array([-along[1], along[0]])
        half = max(1.0, POLE_HALF_WIDTH_M / float(v.gsd_at_depth(depth)))
        grey = _grey(v, greys)
        flat = uv.reshape(-1, 2)
        pad = half + POLE_FLANK_PX + 8.0
        x0, y0 = np.maximum(np.floor(flat.min(axis=0) - pad), 0).astype(int)
        x1, y1 = np.ceil(flat.max(axis=0) + pad).astype(int) + 1
        crop = cv2.GaussianBlur(grey[y0:y1, x0:x1], (0, 0), 0.8)
        lines = uv - [x0, y0]  # each place's vertical in the crop's pixels
        zs.append(_bar(crop, lines, (half + POLE_FLANK_PX) * normal))
    middle = np.median(zs, axis=0)
    for sign in (1.0, -1.0):
        score = sign * middle
        k = np.unravel_index(int(np.argmax(score)), score.shape)
        rivals = np.hypot(du - du[k], dc - dc[k]) >= POLE_CLEAR_M
        base = float(np.median(score[rivals]))
        rival = float(score[rivals].max()) - base
        if rival > 0 and score[k] - base >= POLE_MIN_RATIO * rival:
            return u + float(du[k])
    return None


# A distribution pole holds its conductors on a cross-arm a little under them (pin
# insulators), a bar across the line that the images show plainly from above, where the
# wires bend too little at the pole for a kink (the road flight: spans of 45-59 m that sag
# about 0.2 m, a bend of about 2°; one curve misses their points by ±7 cm). Along each leg,
# every ARM_STEP_M, the segment across the line from ARM_PAST_M outside its outermost wires
# is read ARM_DEPTHS_M under their median height, in each view that sees it ARM_MIN_PX long
# or more: the grey along its image less the grey beside it, shifted along the line by a
# bar's half-width and POLE_FLANK_PX on each side (a bar, not an edge), in robust σ over
# the places read. The views' median (ground texture under the line lies elsewhere in
# each view; the arm only at its place) at the best depth must stand ARM_MIN_RATIO times
# as high above the median within ARM_WINDOW_M as the best place POLE_CLEAR_M or more away.
ARM_STEP_M = 0.05
ARM_DEPTHS_M = np.arange(-0.3, 1.2001, 0.05)
ARM_PAST_M = 0.6
ARM_HALF_WIDTH_M = 0.05  # a cross-arm is 9-12 cm wide
ARM_MIN_PX = 30.0
ARM_SAMPLES = 24  # along each segment
ARM_WINDOW_M = 2.0
ARM_BLOCK_M = 25.0  # the leg is read a block of places at a time (memory)
ARM_PROBE_M = 1.0  # a view's footprint is tens of metres: probed this often for it
ARM_OTHERS_STEP_M = 0.02  # other wires sampled about a pixel apart in the images
# Another leg's wire lies along a segment where its image passes within the bar's reach
# of this share of the segment's samples (one crossing it passes near one or two of 24).
ARM_CROSSED_SHARE = 0.25
# Chosen on the full road flight: with a prototype of this read, 6.7-12.2 at six poles and
# 1.0-2.7 at 27 other places along its 370 m (among them five where the pole read,
# scanned along the line, stood at 3.3-6.2 with no pole); the runs find the three poles
# the kinks missed at 10.1-19.5, and with the pole read's threshold (3) a place with no
# arm at 3.0. The middle of that gap (on a log scale). Confirmed on the 40-image flight
# (its arm at 18.1), the shared `multispan` seed 3 and `twolines` seed 12 and the
# package's `crossing` layout (none; README).
ARM_MIN_RATIO = 4.5


def _arm_geometry(work: _Work, leg: _Leg, li: int, u: F64) -> tuple[F64, F64, F64, F64]:
    """At each place ``u`` along the leg: the outermost wires across it (c), their median
    height, and how many of the leg's wires are there."""
    cs, zs = [], []
    for k in work.on_leg(li):
        w = work.wires[k]
        s = leg.s_along(w, u)
        inside = (s >= w.s_range[0]) & (s <= w.s_range[1])
        p = w.points(s)
        c = np.where(inside, leg.c(p[:, :2]), np.nan)
        cs.append(c)
        zs.append(np.where(inside, p[:, 2], np.nan))
    if not cs:
        nan = np.full(len(u), np.nan)
        return nan, nan, nan, np.zeros(len(u))
    c, z = np.array(cs), np.array(zs)
    n = np.isfinite(c).sum(axis=0)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmin(c, axis=0), np.nanmax(c, axis=0), np.nanmedian(z, axis=0), n


def _arm_reads(
    views: Sequence,
    leg: _Leg,
    u: F64,
    c0: F64,
    c1: F64,
    z: F64,
    others: F64,
    greys: dict[Path, np.ndarray],
    trees: dict[Path, cKDTree | None],
) -> F64:
    """(U, D) the views' median bar score (see ARM_MIN_RATIO's note) of the cross-arm
    segments at ``u`` across from ``c0`` to ``c1``, ARM_DEPTHS_M under ``z``; NaN where
    fewer than POLE_VIEWS[0] views read it. ``others``: (K, 3) points along the wires of
    the other legs; a view does not read a segment that their image lies along (the wires
    of a line crossing above: the shared generator's `twolines`). ``greys``: the grey images
    read so far (:func:`_grey`); ``trees``: per view, the image of ``others`` (None: it
    sees none), kept from block to block of the leg."""
    t = np.linspace(0.0, 1.0, ARM_SAMPLES)
    cc = (c0 - ARM_PAST_M)[:, None] + (c1 - c0 + 2 * ARM_PAST_M)[:, None] * t[None]
    xy = leg.origin + u[:, None, None] * leg.direction + cc[..., None] * leg.normal
    n_u, n_d = len(u), len(ARM_DEPTHS_M)
    pts = np.empty((n_u, n_d, ARM_SAMPLES, 3))
    pts[..., :2] = xy[:, None]
    pts[..., 2] = (z[:, None] - ARM_DEPTHS_M[None])[..., None]
    flat = pts.reshape(-1, 3)
    # The views that see an end of a segment (every ARM_PROBE_M along the block, at the
    # middle depth) read it: the others are not projected whole.
    probe = np.unique(np.linspace(0, n_u - 1, int(np.ptp(u) / ARM_PROBE_M) + 2).astype(int))
    corners = pts[probe][:, n_d // 2][:, [0, -1]].reshape(-1, 3)
    scores = []
    for v in views:
        if not v.project(corners)[2].any():
            continue
        uv, depth, ok = v.project(flat)
        ok = ok.reshape(n_u, n_d, ARM_SAMPLES).all(axis=(1, 2))
        if not ok.any():
            continue
        uv = uv.reshape(n_u, n_d, ARM_SAMPLES, 2)
        length = np.linalg.norm(uv[:, :, -1] - uv[:, :, 0], axis=-1).min(axis=1)
        use = ok & (length >= ARM_MIN_PX)
        if use.sum() < 2:
            continue
        k = int(np.flatnonzero(use)[0])
        ahead = v.project((pts[k, 0, 0] + ARM_STEP_M * np.r_[leg.direction, 0.0])[None])[0][0]
        along = ahead - uv[k, 0, 0]
        if not np.all(np.isfinite(along)) or not np.any(along):
            continue
        along /= np.linalg.norm(along)
        half = max(1.0, ARM_HALF_WIDTH_M / float(v.gsd_at_depth(float(np.median(depth)))))
        shift = (half + POLE_FLANK_PX) * along
        q = uv[use]
        lo = np.floor(np.nanmin(q.reshape(-1, 2), axis=0) - abs(shift) - 4).astype(int)
        hi = np.ceil(np.nanmax(q.reshape(-1, 2), axis=0) + abs(shift) + 4).astype(int)
        lo = np.maximum(lo, 0)
        grey = _grey(v, greys)[lo[1] : hi[1] + 1, lo[0] : hi[0] + 1]
        crop = cv2.GaussianBlur(grey, (0, 0), 0.8)
        bar = _bar(crop, q - lo - 0.5, shift)
        if len(others) and v.path not in trees:
            ouv, _, ook = v.project(others)
            trees[v.path] = cKDTree(ouv[ook]) if ook.any() else None
        tree = trees.get(v.path)
        if tree is not None:
            near, _ = tree.query(q.reshape(-1, 2), distance_upper_bound=(
                float(np.linalg.norm(shift)) + half + 1.0))  # fmt: skip
            crossed = np.isfinite(near).reshape(q.shape[:-1]).mean(axis=-1)
            bar = np.where(crossed >= ARM_CROSSED_SHARE, np.nan, bar)
        score = np.full((n_u, n_d), np.nan)
        score[use] = bar
        scores.append(score)
    if len(scores) < POLE_VIEWS[0]:
        return np.full((n_u, n_d), np.nan)
    stack = np.array(scores)
    enough = np.isfinite(stack).sum(axis=0) >= POLE_VIEWS[0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.where(enough, np.nanmedian(stack, axis=0), np.nan)


def _cross_arms(
    views: Sequence, work: _Work, axes: list[_Leg], found: list[_Found], options: SpanOptions
) -> tuple[list[_Found], dict[int, float]]:
    """Cross-arms the images show along each leg, away from the supports found (see
    ARM_MIN_RATIO's note): a support at each, its wires those of the leg there. Also, per
    support found by wires ending (index into ``found``), the strongest arm within two
    ``support_radius`` of it and of no other support: the pole the wires end by (they end
    where the measured stretch does, which may be past it)."""
    out: list[_Found] = []
    at_end: dict[int, tuple[float, float]] = {}  # found index → (ratio, u)
    greys: dict[Path, np.ndarray] = {}  # the views' grey images, each read once while kept
    for li, leg in enumerate(axes):
        idx = work.on_leg(li)
        if len(idx) < 2:
            continue
        ends = np.array([leg.ends_u(work.wires[k]) for k in idx])
        u_all = np.arange(ends[:, 0].min(), ends[:, 1].max() + 1e-9, ARM_STEP_M)
        c0, c1, z, n = _arm_geometry(work, leg, li, u_all)
        # The other legs' wires, a point every ARM_OTHERS_STEP_M along them.
        rest = [w for k, w in enumerate(work.wires) if work.legs[k] != li]
        others = (
            np.concatenate([w.polyline(ARM_OTHERS_STEP_M) for w in rest])
            if rest
            else np.zeros((0, 3))
        )
        trees: dict[Path, cKDTree | None] = {}  # per view, the other legs' wires' image
        best = np.full(len(u_all), np.nan)
        block = max(1, int(round(ARM_BLOCK_M / ARM_STEP_M)))
        for start in range(0, len(u_all), block):
            sl = slice(start, min(start + block, len(u_all)))
            ok = n[sl] >= 2
            if not ok.any():
                continue
            reads = _arm_reads(views, leg, u_all[sl][ok], c0[sl][ok], c1[sl][ok], z[sl][ok],
                               others, greys, trees)  # fmt: skip
            part = np.full(sl.stop - sl.start, np.nan)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                part[ok] = np.nanmax(reads, axis=1)
            best[sl] = part
        w = int(round(ARM_WINDOW_M / ARM_STEP_M))
        clear = int(round(POLE_CLEAR_M / ARM_STEP_M))
        for k in np.flatnonzero(np.isfinite(best)):
            lo, hi = max(0, k - w), min(len(best), k + w + 1)
            win = best[lo:hi]
            if best[k] < np.nanmax(win):
                continue
            far = np.abs(np.arange(lo, hi) - k) >= clear
            rivals = win[far & np.isfinite(win)]
            if len(rivals) < w:
                continue
            base = float(np.median(rivals))
            rival = float(rivals.max()) - base
            if rival <= 0 or best[k] - base < ARM_MIN_RATIO * rival:
                continue
            u = float(u_all[k])
            ratio = (best[k] - base) / rival
            near = [
                i
                for i, (s_li, s_u, _, _) in enumerate(found)
                if s_li == li and abs(s_u - u) <= 2 * options.support_radius
            ]
            if near or any(s_li == li and abs(s_u - u) <= 2 * options.support_radius
                           for s_li, s_u, _, _ in out):  # fmt: skip
                if (
                    len(near) == 1
                    and found[near[0]][2] in ENDING
                    and ratio > at_end.get(near[0], (-np.inf, 0.0))[0]
                ):
                    at_end[near[0]] = (ratio, u)
                continue
            ids = {
                work.wires[i].wire_id
                for i in idx
                if leg.ends_u(work.wires[i])[0] <= u <= leg.ends_u(work.wires[i])[1]
            }
            logger.info(
                "spans: a cross-arm the images show at %.1f along the line (%.1f times its "
                "rivals within %.0f m): a support",
                u,
                ratio,
                ARM_WINDOW_M,
            )
            out.append((li, u, "cross-arm", ids))
    return out, {i: u for i, (_, u) in at_end.items()}


def _ends_at_arms(
    work: _Work, axes: list[_Leg], found: list[_Found], arms: dict[int, float], r: float
) -> list[_Found]:
    """Supports found by wires ending, moved to the cross-arm the images show by them
    (:func:`_cross_arms`). Where the wires go on past the arm by more than ``r`` (the
    measured stretch ends past the pole: the full road flight's north-west end, 4.7 m),
    the line does not end there: a support the wires hang from, both pieces kept."""
    out = list(found)
    for i, u_arm in arms.items():
        li, u_end, how, ids = found[i]
        leg = axes[li]
        beyond = u_end - u_arm
        if abs(beyond) > r:
            how = "cross-arm"
            ids = {
                work.wires[k].wire_id
                for k in work.on_leg(li)
                if leg.ends_u(work.wires[k])[0] <= u_arm <= leg.ends_u(work.wires[k])[1]
            } or ids
        logger.info(
            "spans: the wires ending at %.1f along the line hang from the cross-arm the "
            "images show at %.1f: the support %s",
            u_end,
            u_arm,
            "placed there" if how in ENDING else "placed there, the wires going on past it",
        )
        out[i] = (li, u_arm, how, ids)
    return out


# Two wires' image curves at least this far apart (px) are told apart by their ridges (each
# ridge is read within 1.5 px of its curve, and the grey beside it 2.5-3 px out).
MIN_APART_PX = 6.0
# A stretch of two wires in one plane shorter than this (model units) is left to both.
MIN_CONFLICT_M = 1.0


def _told_apart(views: Sequence, a: F64, b: F64, greys: dict[Path, np.ndarray]) -> tuple[int, int]:
    """How many views show a line along the 3D curve ``a`` (M, 3) and none along ``b``, and
    how many the reverse: read where a view sees both (at least 10 px of them) at least
    MIN_APART_PX apart across (views from above a wire's plane see two curves in it on one
    line; oblique ones part them), the farthest apart first, at most
    MAX_CONTINUATION_VIEWS. A view that shows both, or neither, does not say (where
    neither curve is the wire, neither shows)."""
    ranked = []
    for v in views:
        (ua, _, oka), (ub, _, okb) = v.project(a), v.project(b)
        both = oka & okb
        if both.sum() < 2:
            continue
        ua, ub = ua[both], ub[both]
        if np.ptp(ua[:, 0]) + np.ptp(ua[:, 1]) < 10:
            continue
        apart = float(np.median(distance_to_polyline(ub, ua)))  # across, not along
        if apart >= MIN_APART_PX:
            ranked.append((apart, v, ua, ub))
    ranked.sort(key=lambda r: -r[0])
    votes = [0, 0]
    for _, v, ua, ub in ranked[:MAX_CONTINUATION_VIEWS]:
        grey = _grey(v, greys)
        (pa, sa), (pb, sb) = _ridge(grey, ua), _ridge(grey, ub)
        shows_a, shows_b = abs(pa) >= RIDGE_SIGMAS * sa, abs(pb) >= RIDGE_SIGMAS * sb
        if shows_a != shows_b:
            votes[int(shows_b)] += 1
    return votes[0], votes[1]


def _one_per_plane(
    work: _Work,
    axes: list[_Leg],
    views: Sequence,
    pts_in_world: F64,
    options: SpanOptions,
    wires_options: WiresOptions,
    max_across: float,
) -> None:
    """Two wires of one leg whose curves touch in one vertical plane (within ``max_across``
    across and in height somewhere along the stretch both measure) cannot both hang there:
    two wires never cross, and a cable below a conductor stays metres below it. It happens
    where a wire is carried past a support: beyond it the conductor runs on in plan, and
    where the views see the line from above it matches at another height, on the next
    span's wire in plan. Each stretch between the curves' crossings, where they lie apart,
    goes to the wire the views that part them show (:func:`_told_apart`); the other loses
    its points there and is refitted to the rest (left out when too little is left). Where
    the views disagree (a third or more show the other), both lose them.
    Overlaps shorter than ``support_radius`` are left alone: a support's two spans meet in
    a bend, each carried a little past it."""
    greys: dict[Path, np.ndarray] = {}
    out = work.wires
    changed = True
    while changed:
        changed = False
        for i, j in itertools.combinations(range(len(out)), 2):
            if work.legs[i] != work.legs[j]:
                continue
            leg = axes[work.legs[i]]
            touching = _touching(out[i], out[j], leg, options.support_radius, max_across)
            if touching is None:
                continue
            loser = _stretches_lost(out[i], out[j], leg, *touching, max_across, views, greys)
            if loser is not None:
                which, lost = loser
                # Both (j first: deleting it leaves i where it is) where the views disagree.
                for k in (j, i) if which == 2 else ((i, j)[which],):
                    changed |= _give_up(
                        work, k, lost, leg, pts_in_world, options, wires_options, which == 2
                    )
                if changed:
                    break


def _touching(
    a: FittedWire, b: FittedWire, leg: _Leg, min_overlap: float, max_across: float
) -> tuple[F64, F64] | None:
    """Where along the leg two wires both measure (``u``, every 0.25) and their heights'
    difference there, when that stretch is ``min_overlap`` or longer and their curves lie
    in one vertical plane (within ``max_across``) and touch in it; else None."""
    (a_lo, a_hi), (b_lo, b_hi) = leg.ends_u(a), leg.ends_u(b)
    lo, hi = max(a_lo, b_lo), min(a_hi, b_hi)
    if hi - lo < min_overlap:
        return None
    u = np.linspace(lo, hi, int((hi - lo) / 0.25) + 2)
    ca, za = leg.curve(a, u)
    cb, zb = leg.curve(b, u)
    dz = za - zb
    if np.max(np.abs(ca - cb)) > max_across or np.min(np.abs(dz)) > max_across:
        return None
    return u, dz


def _stretches_lost(
    a: FittedWire,
    b: FittedWire,
    leg: _Leg,
    u: F64,
    dz: F64,
    max_apart: float,
    views: Sequence,
    greys: dict[Path, np.ndarray],
) -> tuple[int, tuple[float, float]] | None:
    """The first of two wires in one plane (0: ``a``, 1: ``b``, 2: both, where the views
    disagree; ``dz``: their heights' difference at ``u`` along the leg) that the views do
    not show between two of their crossings, and that stretch (along the leg); None when no
    view tells them apart. Each stretch is read where they lie more than ``max_apart`` apart
    (nearer the crossing the views cannot tell them) and goes to one of them up to the
    crossings."""
    sign = np.sign(dz)
    cuts = np.flatnonzero(sign[1:] != sign[:-1]) + 1
    for s, e in zip(np.r_[0, cuts], np.r_[cuts, len(u)], strict=True):
        part = np.arange(s, e)[np.abs(dz[s:e]) > max_apart]
        if len(part) < 2 or u[part[-1]] - u[part[0]] < MIN_CONFLICT_M:
            continue
        uu = u[part]
        va, vb = _told_apart(
            views, a.points(leg.s_along(a, uu)), b.points(leg.s_along(b, uu)), greys
        )
        if va == vb == 0:
            continue
        # Where a third or more of the views that part them show the other curve, the
        # views disagree: the stretch is neither's (on the road flight, 2 views against 1,
        # turned by a hair's change in the points, over a stretch that ran across a pole:
        # one side of it each wire's, and both curves off there). Tracing measures it
        # again on each span's own curve once the supports are found.
        which = 2 if max(va, vb) <= 2 * min(va, vb) else int(va > vb)
        return which, (float(u[s]), float(u[e - 1]))
    return None


def _give_up(
    work: _Work,
    k: int,
    lost: tuple[float, float],
    leg: _Leg,
    pts_in_world: F64,
    options: SpanOptions,
    wires_options: WiresOptions,
    disputed: bool = False,
) -> bool:
    """Wire ``k`` of ``work`` without its points in the ``lost`` stretch (along the leg):
    refitted to the longer side of the rest, or left out when that is no wire. False when
    it has no points to give up there. ``disputed``: the views disagree there (both wires
    give it up)."""
    w = work.wires[k]
    idx = w.point_indices
    u = leg.u(pts_in_world[idx, :2])
    rest = max(idx[u < lost[0]], idx[u > lost[1]], key=len)
    if len(rest) == len(idx):
        return False
    kept = None
    if len(rest) >= wires_options.min_points:
        kept = refit(w, pts_in_world, rest, leg.direction, wires_options)
        if kept is w or np.ptp(leg.ends_u(kept)) < options.min_piece_m:
            kept = None
    logger.info(
        "spans: wire %d lies in one plane with another wire and the views show %s along "
        "%.1f-%.1f: %s",
        w.wire_id,
        "either, or neither," if disputed else "the other",
        *lost,
        "left out" if kept is None else "those points left out",
    )
    if kept is None:
        del work.wires[k], work.source[k], work.legs[k]
    else:
        work.wires[k] = kept
    work.cut_ids.add(w.wire_id)
    return True


def _seeing(views: Sequence, at: F64) -> list:
    """The views that see the place ``at``."""
    return [v for v in views if v.project(at[None])[2][0]]


def _measurable(seeing: Sequence, at: F64, leg: _Leg, crossing_offset: float) -> bool:
    """Whether the views ``seeing`` the place ``at`` along the leg could measure a wire
    there: three of them, from two positions across it (tracing's rule, and the coverage
    report's)."""
    if len(seeing) < MIN_VIEWS_BEYOND:
        return False
    centres = np.array([v.center_in_world for v in seeing])
    height = float(np.median(centres[:, 2]) - at[2])
    return positions_across(leg.c(centres[:, :2]), crossing_offset * height) >= 2


def _cluster(values: F64, radius: float) -> list[I64]:
    """Indices of ``values`` grouped where consecutive sorted values lie within ``radius``."""
    if not len(values):
        return []
    order = np.argsort(values)
    breaks = np.flatnonzero(np.diff(values[order]) > radius) + 1
    return [g for g in np.split(order, breaks)]


_Found = tuple[int, float, str, set[int]]  # (leg, u along it, found by, wire ids)
# Found where a leg's wires end (:func:`_line_ends`): the line's end, or where it turns on.
ENDING = ("wires ending", "wires turning")
_Located = tuple[list[int], F64, str, set[int]]  # (legs, plan position, found by, wire ids)


@dataclass
class _Work:
    """The wires as :func:`find_spans` cuts them: each with the input wire it came from and
    the leg (corridor) that measured it; ``cut_ids``: the wires made by a cut; ``let_go``:
    for a wire whose curve lets go of the points by a support (:func:`band_kink`), the
    points in its plane near its curve, which its pieces are fitted to when it is cut
    there."""

    wires: list[FittedWire]
    source: list[int]
    legs: list[int]
    cut_ids: set[int]
    next_id: int
    let_go: dict[int, I64] = field(default_factory=dict)
    beside: list[tuple[int, float, int]] = field(default_factory=list)
    # A line's last support where its wires go on turned (:func:`_line_ends`): the turn
    # (degrees) by the wire ids found there.
    turns: dict[frozenset[int], float] = field(default_factory=dict)

    def on_leg(self, li: int) -> list[int]:
        return [k for k in range(len(self.wires)) if self.legs[k] == li]


def find_spans(
    views: Sequence,
    ground_height: Callable[[F64], F64],
    wires: Sequence[FittedWire],
    legs: Sequence[int],
    corridors: Sequence[WireCorridor],
    pts_in_world: F64,
    options: SpanOptions | None = None,
    wires_options: WiresOptions | None = None,
    crossing_offset: float = 0.15,
    traced_past: float = 5.0,
) -> Spans:
    """Find the supports, cut the wires at them, and say where each wire hangs.

    Args:
        views: the registered images (``project``, ``center_in_world``), to tell a line's
            end from the survey's.
        ground_height: (N, 2) plan points → (N,) ground heights.
        wires: the fitted wires; ``legs[k]`` the corridor (index into ``corridors``) that
            measured wire k.
        pts_in_world: (N, 3) the points the wires' ``point_indices`` refer to.
        crossing_offset: views this far apart across a wire, per unit of their height
            above it, are at two positions (:class:`VerifyOptions`).
        traced_past: how far a round of tracing goes past a wire's end
            (:class:`TraceOptions` ``extend``): where a line ends, its wires' evidence
            is looked for that far inside their measured ends too.
    """
    options = options or SpanOptions()
    wires_options = wires_options or WiresOptions()
    axes = [_Leg(c) for c in corridors]
    max_across = 2.5 * wires_options.inlier_distance
    work = _Work([], [], [], set(), max((w.wire_id for w in wires), default=-1) + 1)

    # 1-2. Kinks in a wire and pieces meeting across a gap; one support per cluster of them
    # along a leg.
    cands = _kinks(work, wires, legs, axes, pts_in_world, options, wires_options)
    _one_per_plane(work, axes, views, pts_in_world, options, wires_options, max_across)
    cands += _meetings(work, axes, options, max_across)
    found = _clustered(cands, len(axes), options)
    found = _not_run_through(found, work, axes, pts_in_world, options, wires_options)
    # 3. Wires ending together where the images see past them: the line ends there.
    found += _line_ends(
        views, work, axes, found, options, crossing_offset, traced_past, ground_height
    )
    # 3b. Cross-arms the images show where the wires bend too little to tell a support.
    arms, at_ends = _cross_arms(views, work, axes, found, options)
    found = _ends_at_arms(work, axes, found, at_ends, options.support_radius) + arms
    # 4. Every wire cut at each support of its leg that it runs across.
    _cut_at_supports(work, found, axes, pts_in_world, options, wires_options, max_across)
    # A piece cut off at a support may lie on the next span's wire of the same conductor
    # (one curve took the points of both near the support, where they run close): it is
    # that wire's, not a wire of its own.
    work.wires, work.source, work.legs = _absorb_cut_pieces(
        work.wires, work.source, work.legs, work.cut_ids, pts_in_world, axes, wires_options
    )
    # The cut pieces end at their supports now: where they meet places each support again
    # (a wire carried past one had bent the curve that placed it).
    found = [
        (li, _met_again(work.wires, work.legs, axes[li], li, u, options, max_across), how, ids)
        if how not in (*ENDING, "cross-arm")
        else (li, u, how, ids)
        for li, u, how, ids in found
    ]
    found = _one_per_place(found, options)
    # 5. Supports of two legs at one place: an angle support, and the legs one line; or a
    # junction, where one leg runs on through and the other leaves it, a line of its own.
    located, junction = _located(work, axes, found, options, max_across)
    line_of_leg, line_ids = _lines(work, len(axes), located, junction)
    # 6. Chainage along each line, spans between its supports, attachments, conductors.
    return _placed(
        work,
        axes,
        located,
        junction,
        line_of_leg,
        line_ids,
        ground_height,
        options,
        pts_in_world,
        wires_options,
        max_across,
    )


def _kinks(
    work: _Work,
    wires: Sequence[FittedWire],
    legs: Sequence[int],
    axes: list[_Leg],
    pts_in_world: F64,
    options: SpanOptions,
    wires_options: WiresOptions,
) -> list[_Candidate]:
    """A wire measured across a support is cut at its kink there (and its pieces looked at
    again: a wire may run across two); the pieces go into ``work``. A wire not cut whose
    curve lets go of the points in its plane by a place (:func:`band_kink`) gives a
    support there where another wire of its leg does so too."""
    cands: list[_Candidate] = []
    band: list[_Candidate] = []
    let_go: dict[int, I64] = {}
    for k, w in enumerate(wires):
        leg = axes[legs[k]]
        pieces, kinks, work.next_id = _cut_at_kinks(
            w, pts_in_world, leg.direction, options, wires_options, work.next_id
        )
        work.wires += pieces
        work.source += [k] * len(pieces)
        work.legs += [legs[k]] * len(pieces)
        if kinks:
            work.cut_ids.update(p.wire_id for p in pieces)
        for xy in kinks:
            cands.append(_Candidate(legs[k], float(leg.u(xy)[0]), "kink", set()))
        if not kinks:
            found = band_kink(w, pts_in_world, options, 2.5 * wires_options.inlier_distance)
            if found is not None:
                u = float(leg.u(w.points(np.array([found[0]]))[:, :2])[0])
                band.append(_Candidate(legs[k], u, "kink", {w.wire_id}))
                let_go[w.wire_id] = np.union1d(w.point_indices, found[1])
    # A wire's curve letting go of the points by a place is a support where another wire of
    # the leg does so too (a support holds all its conductors; one wire alone is as likely
    # a stretch it holds poorly: on the road flight one conductor's curve at 13 m from a
    # pole).
    for c in band:
        if any(
            o.leg == c.leg and o.wire_ids != c.wire_ids and abs(o.u - c.u) <= options.support_radius
            for o in band
        ):
            logger.info(
                "spans: wire %d's curve lets go of the points in its plane at %.1f along its "
                "line, as another wire's does there: a support",
                *c.wire_ids,
                c.u,
            )
            cands.append(c)
            work.let_go.update((wid, let_go[wid]) for wid in c.wire_ids)
    return cands


def _meetings(
    work: _Work, axes: list[_Leg], options: SpanOptions, max_across: float
) -> list[_Candidate]:
    """Pieces of one conductor meeting across a gap at a support."""
    out, cands = work.wires, []
    for li, leg in enumerate(axes):
        idx = work.on_leg(li)
        for i in idx:
            for j in idx:
                if i == j:
                    continue
                t = _pieces_meet(out[i], out[j], leg, options, max_across)
                if t is not None:
                    cands.append(
                        _Candidate(li, t, "pieces meeting", {out[i].wire_id, out[j].wire_id})
                    )
    return cands


def _clustered(cands: list[_Candidate], n_legs: int, options: SpanOptions) -> list[_Found]:
    """One support per cluster of kinks and meetings along a leg."""
    found: list[_Found] = []
    for li in range(n_legs):
        mine = [c for c in cands if c.leg == li]
        for g in _cluster(np.array([c.u for c in mine]), options.support_radius):
            members = [mine[i] for i in g]
            kinds = {c.found_by for c in members}
            found.append(
                (
                    li,
                    float(np.median([c.u for c in members])),
                    "kink" if "kink" in kinds else "pieces meeting",
                    set().union(*(c.wire_ids for c in members)),
                )
            )
    return found


def _one_per_place(found: list[_Found], options: SpanOptions) -> list[_Found]:
    """Supports of one leg placed again within ``support_radius`` of each other (two
    places where pieces met, each moved to where the pieces cut there meet) are one, as
    :func:`_clustered` makes them; a line's end stays as it is."""
    out = [f for f in found if f[2] in ENDING]
    for li in sorted({f[0] for f in found}):
        mine = [f for f in found if f[0] == li and f[2] not in ENDING]
        for g in _cluster(np.array([f[1] for f in mine]), options.support_radius):
            members = [mine[i] for i in g]
            kinds = {f[2] for f in members}
            out.append(
                (
                    li,
                    float(np.median([f[1] for f in members])),
                    "kink" if "kink" in kinds else members[0][2],
                    set().union(*(f[3] for f in members)),
                )
            )
    return sorted(out, key=lambda f: (f[0], f[1]))


def _not_run_through(
    found: list[_Found],
    work: _Work,
    axes: list[_Leg],
    pts_in_world: F64,
    options: SpanOptions,
    wires_options: WiresOptions,
) -> list[_Found]:
    """The supports found, but those only pieces meeting placed (their curves continued
    across a gap) where more wires of the leg run through without a kink than conductors
    meet there. A wire runs through where it holds ``min_points`` on either side between
    one and three ``support_radius`` away (nearer, the next span's conductor converges on
    the same attachment). On a straight line the next span's wires are measured through
    such a place, and two pieces' curves, each carried past its own support by a few stray
    points, met between them."""
    r = options.support_radius
    out = []
    for li, u, how, ids in found:
        if how == "pieces meeting":
            leg = axes[li]
            through = []
            for k in work.on_leg(li):
                w = work.wires[k]
                if w.wire_id in ids:
                    continue
                d = leg.u(pts_in_world[w.point_indices, :2]) - u
                before = np.count_nonzero((d > -3 * r) & (d < -r))
                after = np.count_nonzero((d > r) & (d < 3 * r))
                if min(before, after) >= wires_options.min_points:
                    through.append(w.wire_id)
            if len(through) > len(ids) // 2:
                logger.info(
                    "spans: no support at %.1f along its line: %d pieces' curves meet there, "
                    "but wires %s are measured through it without a bend",
                    u,
                    len(ids),
                    sorted(through),
                )
                continue
        out.append((li, u, how, ids))
    return out


def _line_ends(
    views: Sequence,
    work: _Work,
    axes: list[_Leg],
    found: list[_Found],
    options: SpanOptions,
    crossing_offset: float,
    traced_past: float,
    ground_height: Callable[[F64], F64],
) -> list[_Found]:
    """Two or more wires ending together where the images see past them (and do not show
    them going on), away from the corridor's end and from the supports found: the line
    ends there (at the pole the images show there, if they show one: :func:`_pole`)."""
    out, ends_found = work.wires, []
    for li, leg in enumerate(axes):
        idx = work.on_leg(li)
        if not idx:
            continue
        ends = np.array([leg.ends_u(out[k]) for k in idx])
        for side, sign in ((0, -1.0), (1, 1.0)):
            for g in _cluster(ends[:, side], options.support_radius):
                if len(g) < 2:
                    continue
                u_end = float(ends[g, side].max() if sign > 0 else ends[g, side].min())
                # A wire carrying on past it: not where the line ends.
                further = ends[:, side] * sign > u_end * sign + options.support_radius
                if further.any():
                    continue
                if any(s_li == li and abs(u - u_end) <= 2 * options.support_radius
                       for s_li, u, _, _ in found):  # fmt: skip
                    continue
                z = float(
                    np.median(
                        [out[idx[i]].points(np.array(out[idx[i]].s_range))[:, 2].mean() for i in g]
                    )
                )
                c_mid = float(np.median([leg.c(out[idx[i]].plane_origin_xy)[0] for i in g]))
                past = np.array([np.r_[leg.xy(u_end + sign * d, c_mid), z] for d in BEYOND_M])
                # Where the corridor ends, its wires end with it: the survey's edge.
                edge = min(abs(u_end - e) for e in axes[li].extent)
                if edge <= options.support_radius:
                    continue
                # Past the ends the views could measure a wire, or at least two see there
                # (fewer than tracing needs: the wires may end for want of views)...
                seeing = [_seeing(views, p) for p in past]
                measurable = all(
                    _measurable(by, p, leg, crossing_offset)
                    for by, p in zip(seeing, past, strict=True)
                )
                if not measurable and min(len(by) for by in seeing) < 2:
                    continue
                # ...and the images do not show the wires going on (where the measurements
                # stopped short of a support, they do). Where the views could not measure
                # there, two or more must show the wires plainly before their ends and none
                # going on.
                # Which end (0: first, 1: last) of each wire lies at the place.
                at_end = {
                    i: 0
                    if (float(np.mean(leg.ends_u(out[idx[i]]))) > u_end)
                    == _s_grows_along(out[idx[i]], leg)
                    else 1
                    for i in g
                }
                longest = sorted(g, key=lambda i: -np.ptp(ends[i]))[:3]
                greys: dict[Path, np.ndarray] = {}
                reads = [_continues(views, out[idx[i]], at_end[i], greys) for i in longest]
                going, shown = np.sum(reads, axis=0)
                if not measurable and (shown < 2 or going > 0):
                    continue
                # The line goes on, or it ends: all its wires alike (the views' reads of
                # them pooled; one view of one wire does not decide).
                if shown and going >= shown / 2:
                    logger.info(
                        "spans: %d wires end together at %.1f along the line, but the "
                        "images show them going on: not the line's end",
                        len(g),
                        u_end,
                    )
                    continue
                # Placed where the wires' line evidence ends in the views (the measurements
                # stop short at the insulators' hardware, or are carried on along the
                # tower's members or on ground texture near the curve): the upper quartile
                # of its stops outwards (EVIDENCE_QUANTILE); without three, where the
                # measurements end (their median).
                at_u = []
                for i in g:
                    w, which = out[idx[i]], at_end[i]
                    s_past = w.s_range[which] + (-1.0 if which == 0 else 1.0) * np.array(
                        _evidence_stops(views, w, which, greys, traced_past)
                    )
                    at_u += leg.u(w.points(s_past)[:, :2]).tolist()
                if len(at_u) >= MIN_VIEWS_BEYOND:
                    far_q = EVIDENCE_QUANTILE if sign > 0 else 1.0 - EVIDENCE_QUANTILE
                    u_at = float(np.quantile(at_u, far_q))
                else:
                    u_at = float(np.median(ends[g, side]))
                # The wires' height at their ends here: the top of the pole's read.
                top = max(
                    float(out[idx[i]].points(np.array([out[idx[i]].s_range[at_end[i]]]))[0, 2])
                    for i in g
                )
                pole = _pole(views, leg, u_at, c_mid, ground_height, top, greys)
                if pole is not None:
                    logger.info(
                        "spans: the line ends at a pole the images show %.2f m from where "
                        "its wires' evidence ends (%.1f along it)",
                        abs(pole - u_at),
                        u_at,
                    )
                    u_at = pole
                # Not going on straight, but turned about the pole (the same angle for all
                # its wires): the line turns there, its next leg not measured.
                turn = None
                if shown >= MIN_VIEWS_BEYOND - 1:
                    turned = [
                        _continues_turned(views, out[idx[i]], at_end[i], greys,
                                          float(leg.s_of(out[idx[i]], u_at)))
                        for i in longest
                    ]  # fmt: skip
                    angles = np.array([a for t in turned for a in t[0]])
                    t_shown = sum(t[1] for t in turned)
                    if len(angles):
                        agree = np.abs(angles[:, None] - angles[None]) <= TURN_AGREE_DEG
                        best = int(np.argmax(agree.sum(axis=1)))
                        n_agree = int(agree[best].sum())
                        if n_agree >= max(2, t_shown / 2):
                            turn = float(np.median(angles[agree[best]]))
                            logger.info(
                                "spans: %d wires end together at %.1f along the line, and "
                                "the images show them going on turned by %.1f° (%d of %d "
                                "reads): the line goes on there, its next leg not measured",
                                len(g),
                                u_at,
                                turn,
                                n_agree,
                                t_shown,
                            )
                ids = {out[idx[i]].wire_id for i in g}
                if turn is None:
                    ends_found.append((li, u_at, "wires ending", ids))
                else:
                    work.turns[frozenset(ids)] = abs(turn)
                    ends_found.append((li, u_at, "wires turning", ids))
    return ends_found


def _cut_at_supports(
    work: _Work,
    found: list[_Found],
    axes: list[_Leg],
    pts_in_world: F64,
    options: SpanOptions,
    wires_options: WiresOptions,
    max_across: float,
) -> None:
    """Cut every wire of ``work`` at each support of its leg that it runs across. A
    conductor hangs from the support: its two pieces meet there in a bend. Running smoothly
    through it, the wire is no conductor of this line: of a line beside, where it lies
    across beyond the wires hanging from the support (:func:`_beside`: left whole, and the
    line noted in ``work.beside``), else a false pairing (dropped). A piece that does not
    meet the other there is a tail the curve took past the support. At a cross-arm the
    images show (:func:`_cross_arms`), both pieces are kept: such a pole is found because
    its wires bend too little there."""
    out = work.wires
    passed: set[tuple[int, float]] = set()  # (wire, support) a line beside passes by
    changed = True
    while changed:
        changed = False
        for k in range(len(out)):
            li = work.legs[k]
            leg = axes[li]
            lo, hi = leg.ends_u(out[k])
            for s_li, u, how, ids in found:
                r = options.support_radius
                if s_li != li or not (lo + r < u < hi - r) or (out[k].wire_id, u) in passed:
                    continue
                # A wire whose curve let go of the points by a support: its pieces fitted
                # to those points too.
                let_go = work.let_go.get(out[k].wire_id)
                tries = [out[k]] if let_go is None else [
                    dataclasses.replace(out[k], point_indices=let_go), out[k]
                ]  # fmt: skip
                cut = None
                for w in tries:
                    cut = _cut(w, leg.s_of(w, u), pts_in_world, leg, wires_options, work.next_id)
                    if cut is not None:
                        break
                if cut is None:
                    # One side holds too few points for a wire of its own: a tail the curve
                    # took past the support (a few stray points on it continued).
                    kept = _trimmed(out[k], leg.s_of(out[k], u), pts_in_world, leg, wires_options)
                    if kept is None:
                        continue
                    logger.info(
                        "spans: wire %d has a tail past the support at %.1f along its line: "
                        "the tail left out",
                        out[k].wire_id,
                        u,
                    )
                    out[k] = kept
                    changed = True
                    break
                work.next_id += 1
                meet = _meeting(cut[0], cut[1], leg, u, options, max_across)
                keep = list(cut)
                short = [w for w in cut if np.ptp(leg.ends_u(w)) < options.max_meeting_gap / 2]
                if how == "cross-arm":
                    # The images show the arm the wire hangs from: both pieces are spans'
                    # wires, however little it bends there (ARM_MIN_RATIO's note).
                    pass
                elif meet is None or (meet < options.min_kink_deg and short):
                    # The shorter piece is a tail (a curve carried past the support by a
                    # few metres of points; on its own its bend is not measured).
                    keep = [max(cut, key=lambda w: np.ptp(leg.ends_u(w)))]
                elif meet < options.min_kink_deg:
                    keep = []
                    # Across beyond the wires that hang from the support: a line beside
                    # this one, which passes the support by (not a false pairing).
                    side = _beside(work, leg, u, ids, out[k])
                    if side is not None:
                        logger.info(
                            "spans: wire %d runs straight through the support at %.1f along "
                            "its line, %.1f across beyond the wires that hang from it: a "
                            "line beside",
                            out[k].wire_id,
                            u,
                            side[1],
                        )
                        work.beside.append((li, side[0], side[2]))
                        passed.add((out[k].wire_id, u))
                        continue
                if len(keep) < 2:
                    logger.info(
                        "spans: wire %d %s the support at %.1f along its line: %s",
                        out[k].wire_id,
                        "runs straight through" if not keep else "has a tail past",
                        u,
                        "left out (a false pairing)" if not keep else "the tail left out",
                    )
                work.cut_ids.update(w.wire_id for w in keep)
                out[k : k + 1] = keep
                work.source[k : k + 1] = [work.source[k]] * len(keep)
                work.legs[k : k + 1] = [li] * len(keep)
                changed = True
                break
            if changed:
                break


# A wire running smoothly through a support, this far across beyond every wire that hangs
# from it, is of a line beside (a cross-arm holds its conductors within a few metres of
# the outermost: the package's `parallel` layout 12 m apart, the pole line's outer
# conductor 5.3 m from the tower line's).
LINE_BESIDE_M = 3.0


def _beside(
    work: _Work, leg: _Leg, u: float, ids: set[int], wire: FittedWire
) -> tuple[float, float, int] | None:
    """Where ``wire``, which runs through the support at ``u`` along ``leg`` without a bend,
    lies across beyond every other wire of ``ids`` (those that found the support) by
    LINE_BESIDE_M or more: (the across halfway between it and the nearest of them, how far
    beyond it lies, the side: +1 more across, -1 less), else None."""
    c = float(leg.curve(wire, np.array([u]))[0][0])
    hung = [
        float(leg.curve(w, np.array([u]))[0][0])
        for w in work.wires
        if w.wire_id in ids and w.wire_id != wire.wire_id
    ]
    hung = [x for x in hung if np.isfinite(x)]
    if not hung or not np.isfinite(c):
        return None
    lo, hi = min(hung), max(hung)
    if c > hi + LINE_BESIDE_M:
        return 0.5 * (c + hi), c - hi, 1
    if c < lo - LINE_BESIDE_M:
        return 0.5 * (c + lo), lo - c, -1
    return None


def _one_each(beside: list[tuple[int, float, int]]) -> list[tuple[int, float, int]]:
    """One line beside per leg and side: the across nearest the leg's own wires (the
    smallest on the side of more across, the largest on the other)."""
    out: dict[tuple[int, int], float] = {}
    for li, c, side in beside:
        key = (li, side)
        out[key] = c if key not in out else (min(out[key], c) if side > 0 else max(out[key], c))
    return [(li, c, side) for (li, side), c in sorted(out.items())]


def _located(
    work: _Work, axes: list[_Leg], found: list[_Found], options: SpanOptions, max_across: float
) -> tuple[list[_Located], list[bool]]:
    """Each support in plan (midway across the wires that touch it); supports of two legs
    at one place are one angle support, placed where each conductor's two spans' vertical
    planes cross, or a junction (flagged) where one of the legs runs on through it: that
    leg first, placed as it found it."""
    out = work.wires
    located = []
    for li, u, how, ids in found:
        leg = axes[li]
        near = [k for k in work.on_leg(li) if _touches(out[k], leg, u, options)]
        cs = [float(leg.c(out[k].points(np.array([leg.s_of(out[k], u)]))[:, :2])[0]) for k in near]
        c_mid = 0.5 * (min(cs) + max(cs)) if cs else 0.0
        located.append(([li], leg.xy(u, c_mid), how, set(ids) | {out[k].wire_id for k in near}))
    merged: list[_Located] = []
    own: list[dict[int, F64]] = []  # each merged support's place as each of its legs found it
    for item in located:
        for m, places in zip(merged, own, strict=True):
            if np.linalg.norm(m[1] - item[1]) <= 2 * options.support_radius and set(m[0]) != set(
                item[0]
            ):
                m[0].extend(item[0])
                m[3].update(item[3])
                m[1][:] = 0.5 * (m[1] + item[1])
                places.setdefault(item[0][0], item[1].copy())
                break
        else:
            merged.append((list(item[0]), item[1].copy(), item[2], set(item[3])))
            own.append({item[0][0]: item[1].copy()})
    junction = [False] * len(merged)
    for i, m in enumerate(merged):
        if len(set(m[0])) < 2:
            continue
        # A leg whose wires hang on both sides of the place runs on through it: the other
        # legs leave it, lines of their own (a branch line from a junction pole: the road
        # flight's line across the field leaves the road line's pole at 78°). A line that
        # turns ends each leg there.
        through = [li for li in dict.fromkeys(m[0]) if _runs_through(work, axes, li, m[1], options)]
        if through:
            junction[i] = True
            first = through[0]
            legs_m = [first] + [li for li in m[0] if li != first]
            merged[i] = (legs_m, own[i].get(first, m[1]).copy(), m[2], m[3])
    # At an angle support each conductor's two spans hang in vertical planes that cross
    # at its attachment: the support lies midway between the outermost of those crossings.
    for i, m in enumerate(merged):
        if len(set(m[0])) > 1 and not junction[i]:
            at = _plane_crossings(out, work.legs, m, axes, options, max_across)
            if len(at) >= 2:
                d, arm = _arm(axes, m[0])
                c = at @ arm
                m[1][:] = np.mean(at @ d) * d + 0.5 * (c.min() + c.max()) * arm
                merged[i] = (m[0], m[1], "spans crossing", m[3])
    return merged, junction


def _runs_through(work: _Work, axes: list[_Leg], li: int, xy: F64, options: SpanOptions) -> bool:
    """Whether wires of leg ``li`` hang on both sides of a support at plan ``xy``: on each
    side a wire along the leg (its plane within ``MAX_TURN_DEG`` of the leg's direction)
    covers the place half ``max_meeting_gap`` from it (a span, however little of it was
    measured near the support, not a stretch one curve carried past its support; nor
    another leg's wires a corridor measured near an angle tower)."""
    leg = axes[li]
    u = float(leg.u(xy)[0])
    reach = options.max_meeting_gap / 2
    before = after = False
    for k in work.on_leg(li):
        w = work.wires[k]
        if axial_diff_deg(azimuth_deg_of(w.plane_direction_xy), leg.azimuth_deg) > MAX_TURN_DEG:
            continue
        lo, hi = leg.ends_u(w)
        before |= lo <= u - reach <= hi
        after |= lo <= u + reach <= hi
    return before and after


def _lines(
    work: _Work, n_legs: int, located: list[_Located], junction: list[bool]
) -> tuple[I64, dict[int, int]]:
    """Legs joined at an angle support they share are one line (not at a junction): each
    leg's line label, and the lines numbered from 1 in the order of their first leg (the
    main line first)."""
    rows, cols = list(range(n_legs)), list(range(n_legs))
    for m, j in zip(located, junction, strict=True):
        if j:
            continue
        rows += [m[0][0]] * len(m[0])
        cols += m[0]
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n_legs, n_legs))
    _, line_of_leg = connected_components(graph, directed=False)
    with_wires = [int(line_of_leg[li]) for li in work.legs]
    line_ids = {lab: n + 1 for n, lab in enumerate(dict.fromkeys(with_wires))}
    return line_of_leg, line_ids


def _placed(
    work: _Work,
    axes: list[_Leg],
    merged: list[_Located],
    junction: list[bool],
    line_of_leg: I64,
    line_ids: dict[int, int],
    ground_height: Callable[[F64], F64],
    options: SpanOptions,
    pts_in_world: F64,
    wires_options: WiresOptions,
    past: float,
) -> Spans:
    """Chainage along each line, the supports numbered along it, each wire's span between
    them, its attachments (its fitted curve extended or cut back to them; its points more
    than ``past`` beyond one are the next span's, and it is refitted without them), the
    supports' heights and wires, and the conductors."""
    out, out_legs = work.wires, work.legs
    chainage = _chainages(
        axes,
        [m for m, j in zip(merged, junction, strict=True) if not j],
        line_of_leg,
        out,
        out_legs,
    )
    sup_ch = [chainage[m[0][0]](m[1]) for m in merged]
    order = sorted(
        range(len(merged)), key=lambda i: (line_ids[int(line_of_leg[merged[i][0][0]])], sup_ch[i])
    )
    supports_out: list[LineSupport] = []
    for new_id, mi in enumerate(order):
        legs_m, xy, how, _ = merged[mi]
        turn = max(
            (
                float(axial_diff_deg(axes[a].azimuth_deg, axes[b].azimuth_deg))
                for a in legs_m
                for b in legs_m
            ),
            default=0.0,
        )
        if junction[mi]:
            kind = "junction"
            turn = min(
                float(axial_diff_deg(axes[legs_m[0]].azimuth_deg, axes[b].azimuth_deg))
                for b in legs_m[1:]
            )
        else:
            if how == "wires turning" and len(set(legs_m)) == 1:
                turn = work.turns.get(frozenset(merged[mi][3]), turn)
            kind = (
                "angle"
                if len(set(legs_m)) > 1 or (how == "wires turning" and turn >= MIN_TURN_DEG)
                else ("end" if how == "wires ending" else "suspension")
            )
        supports_out.append(
            LineSupport(
                support_id=new_id,
                line=line_ids[int(line_of_leg[legs_m[0]])],
                kind=kind,
                position=np.r_[xy, float(ground_height(xy[None])[0])],
                top_z=float("nan"),
                turn_deg=float(turn),
                wire_ids=(),
                found_by=how,
                lines=tuple(dict.fromkeys(line_ids[int(line_of_leg[li])] for li in legs_m)),
            )
        )
    # Each support's cross-arm in plan: across its leg, or along the bisector of the turn
    # at an angle support (each conductor keeps its offset from the line on both legs).
    # At a junction, each line's wires across its own leg.
    arms = [_arm(axes, merged[mi][0][:1] if junction[mi] else merged[mi][0])[1] for mi in order]
    leg_arms = {
        (new_id, li): _arm(axes, [li])[1]
        for new_id, mi in enumerate(order)
        if junction[mi]
        for li in merged[mi][0]
    }
    # Each wire's span (its line, and how many of the line's supports lie before its
    # middle), the supports on either side of it, and those its measured ends reach (within
    # ``max_meeting_gap``). A wire that reaches one of its span's supports hangs from the
    # other too where the span's other wires reach it (the package's `angle` layout: its
    # 20 mm shields measured along half their spans from the angle tower).
    spans_key: list[tuple[int, int]] = []
    sides: list[tuple[int | None, int | None]] = []
    own: list[list[int]] = []
    reached: dict[tuple[int, int], set[int]] = {}
    for k, w in enumerate(out):
        li = out_legs[k]
        line = line_ids[int(line_of_leg[li])]
        ends_xy = w.points(np.array(w.s_range))[:, :2]
        ch = sorted(chainage[li](xy) for xy in ends_xy)
        on_line = [
            (chainage[li](merged[mi][1]), new_id)
            for new_id, mi in enumerate(order)
            if line in supports_out[new_id].lines
        ]
        mid = 0.5 * (ch[0] + ch[1])
        before = [(c, i) for c, i in on_line if c <= mid]
        after = [(c, i) for c, i in on_line if c > mid]
        key = (line, len(before))
        spans_key.append(key)
        sides.append((max(before)[1] if before else None, min(after)[1] if after else None))
        own.append([])
        if before and ch[0] - max(before)[0] <= options.max_meeting_gap:
            own[-1].append(max(before)[1])
        if after and min(after)[0] - ch[1] <= options.max_meeting_gap:
            own[-1].append(min(after)[1])
        reached.setdefault(key, set()).update(own[-1])
    placement: list[WireSpan] = []
    attached: dict[int, list[tuple[int, F64]]] = {}
    for k, w in enumerate(out):
        li = out_legs[k]
        line = line_ids[int(line_of_leg[li])]
        bounds = own[k]
        if len(bounds) == 1:  # the span's other support, where its other wires reach it
            bounds = [sid for sid in sides[k] if sid in reached[spans_key[k]]]
        # Extended to each support, or cut back to it: past its attachment (by less than
        # ``support_radius``, else the wire was cut there) a curve is the next span's, and
        # so are its points there (on the road flight, span 3's road-side conductor held
        # 3.7 m of span 2's points past their pole, and span 2's wires up to 7 m of span 3's).
        held_by = [
            (sid, supports_out[sid].position[:2], leg_arms.get((sid, li), arms[sid]))
            for sid in bounds
        ]
        ends = _attachments(w, held_by)
        if ends:
            s_pts = w.plane_coords(pts_in_world[w.point_indices])[0]
            inside = np.ones(len(s_pts), bool)
            for _, side, s_att in ends:
                inside &= s_pts >= s_att - past if side == 0 else s_pts <= s_att + past
            if not inside.all() and inside.sum() >= wires_options.min_points:
                fit = refit(
                    w, pts_in_world, w.point_indices[inside], axes[li].direction, wires_options
                )
                if fit is not w:
                    logger.info(
                        "spans: wire %d: %d points past its supports' attachments left out",
                        w.wire_id,
                        int((~inside).sum()),
                    )
                    w = fit
                    ends = _attachments(w, held_by)
        s_lo, s_hi = w.s_range
        at_end: list[int | None] = [None, None]
        for sid, side, s_att in ends:
            s_lo, s_hi = (s_att, s_hi) if side == 0 else (s_lo, s_att)
            at_end[side] = sid
            attached.setdefault(sid, []).append((k, w.points(np.array([s_att]))[0]))
        out[k] = dataclasses.replace(w, s_range=(float(s_lo), float(s_hi)))
        placement.append(WireSpan(line=line, span=0, supports=(at_end[0], at_end[1]), conductor=-1))
    # Spans numbered from 1 along each line, without holes.
    numbers = {
        key: n + 1
        for line in sorted(line_ids.values())
        for n, key in enumerate(sorted({sk for sk in spans_key if sk[0] == line}))
    }
    supports_out = attached_again(supports_out, out, placement)
    placement = [
        dataclasses.replace(p, span=numbers[sk]) for p, sk in zip(placement, spans_key, strict=True)
    ]
    conductor = _conductors(out, placement, attached, options.same_conductor_m)
    placement = [
        dataclasses.replace(p, conductor=c) for p, c in zip(placement, conductor, strict=True)
    ]
    if supports_out:
        logger.info(
            "spans: %d line(s), %d support(s) (%s), %d wires in %d spans",
            len(line_ids),
            len(supports_out),
            ", ".join(f"{s.kind} by {s.found_by}" for s in supports_out),
            len(out),
            len(numbers),
        )
    return Spans(out, placement, supports_out, work.source, out_legs, _one_each(work.beside))


def attached_again(
    supports: list[LineSupport], wires: Sequence[FittedWire], placement: Sequence[WireSpan]
) -> list[LineSupport]:
    """``supports`` with their tops, top wires, wires and reach read from the wires as they
    are drawn (each wire's ends at its supports are its attachments): when the supports are
    placed, and again at the end of the run. The wires found
    with the supports are traced on and refitted afterwards; a top read from a shield's
    curve then, fitted to a short piece and continued to the support, may lie metres off
    its attachment now (the package's `angle` layout: the angle tower's top 8.1 m high,
    and the end towers', raised by it, 8.1 m)."""
    attached: dict[int, list[tuple[int, F64]]] = {}
    for k, (w, p) in enumerate(zip(wires, placement, strict=True)):
        for side, sid in enumerate(p.supports):
            if sid is not None:
                attached.setdefault(sid, []).append((k, w.points(np.array([w.s_range[side]]))[0]))
    out = list(supports)
    for sid, att in attached.items():
        out[sid] = dataclasses.replace(
            out[sid],
            top_z=float(max(p[2] for _, p in att)),
            top_wire=wires[max(att, key=lambda a: float(a[1][2]))[0]].wire_id,
            wire_ids=tuple(sorted(wires[k].wire_id for k, _ in att)),
            reach_m=float(max(np.hypot(*(p[:2] - out[sid].position[:2])) for _, p in att)),
        )
    return out


def _attachments(
    w: FittedWire, supports: list[tuple[int, F64, F64]]
) -> list[tuple[int, int, float]]:
    """(support id, end: 0 low s, 1 high s, s) where ``w``'s plane meets each support's
    cross-arm (``supports``: id, plan position, arm direction), but for arms it runs
    parallel to."""
    out = []
    for sid, xy, arm in supports:
        s_att = _s_on_arm(w, xy, arm)
        if s_att is not None:
            out.append((sid, 0 if s_att < 0.5 * (w.s_range[0] + w.s_range[1]) else 1, s_att))
    return out


def _chainages(
    axes: list[_Leg],
    merged: list[tuple[list[int], F64, str, set[int]]],
    line_of_leg: I64,
    wires: list[FittedWire],
    legs: list[int],
) -> list[Callable[[F64], float]]:
    """Per leg, plan point → distance along its line: legs chained through the supports
    they share, each walked away from the one before (a line's first leg along its u)."""
    shared: dict[int, dict[int, F64]] = {li: {} for li in range(len(axes))}
    for m in merged:
        for a in m[0]:
            for b in m[0]:
                if a != b:
                    shared[a][b] = m[1]
    funcs: list[Callable[[F64], float] | None] = [None] * len(axes)

    def make(leg: _Leg, base: float, u_ref: float, sign: float) -> Callable[[F64], float]:
        return lambda xy: base + sign * (float(leg.u(xy)[0]) - u_ref)

    def wires_u(li: int) -> list[float]:
        return [
            float(np.mean(axes[li].ends_u(w))) for w, g in zip(wires, legs, strict=True) if g == li
        ]

    for start in range(len(axes)):
        if funcs[start] is not None:
            continue
        # Start the line at a leg with one neighbour (its end), else at this one, walking
        # towards that neighbour (each next leg is walked away from the support it shares
        # with the one before: a first leg walked away from it too folds the line back on
        # itself, and its spans take the next leg's numbers).
        line = [li for li in range(len(axes)) if line_of_leg[li] == line_of_leg[start]]
        first = next((li for li in line if len(shared[li]) <= 1), start)
        sign = 1.0
        if len(shared[first]) == 1:
            (xy,) = shared[first].values()
            us = wires_u(first)
            sign = 1.0 if not us or float(axes[first].u(xy)[0]) >= np.median(us) else -1.0
        funcs[first] = make(axes[first], 0.0, 0.0, sign)
        todo = [first]
        while todo:
            li = todo.pop()
            here = funcs[li]
            assert here is not None
            for nb, xy in shared[li].items():
                if funcs[nb] is not None:
                    continue
                leg = axes[nb]
                u_at = float(leg.u(xy)[0])
                us = wires_u(nb)
                sign = 1.0 if not us or np.median(us) >= u_at else -1.0
                funcs[nb] = make(leg, here(xy), u_at, sign)
                todo.append(nb)
    return [f if f is not None else make(axes[i], 0.0, 0.0, 1.0) for i, f in enumerate(funcs)]


SUPPORT_COLUMNS = (
    "support_id", "line", "kind", "x", "y", "ground_z", "top_z", "height_m", "top_from",
    "turn_deg", "found_by", "wires", "lines",
)  # fmt: skip
SPAN_COLUMNS = ("line", "span", "first_support", "last_support", "conductor")


def supports_csv(
    supports: Sequence[LineSupport], convert: Callable[[F64], F64] | None = None
) -> str:
    """One row per support (:data:`SUPPORT_COLUMNS`), millimetre precision."""
    rows = [",".join(SUPPORT_COLUMNS)]
    for sup in supports:
        d = sup.to_json(convert)
        x, y, z = d["position"]
        rows.append(
            ",".join(
                [str(d["id"]), str(d["line"]), d["kind"]]
                + [f"{v:.3f}" for v in (x, y, z, d["top_z"], d["height_m"])]
                + [d["top_from"] or "", f"{d['turn_deg']:.3f}", d["found_by"]]
                + [" ".join(str(w) for w in d["wires"])]
                + [" ".join(str(n) for n in d["lines"])]
            )
        )
    return "\n".join(rows) + "\n"


def _absorb_cut_pieces(
    wires: list[FittedWire],
    source: list[int],
    legs: list[int],
    cut_ids: set[int],
    pts_in_world: F64,
    axes: list[_Leg],
    options: WiresOptions,
) -> tuple[list[FittedWire], list[int], list[int]]:
    """Pieces (``cut_ids``) whose points mostly lie on another wire of their leg, between
    its ends and within twice the inlier distance of it, given to that wire (refitted)."""
    gone: set[int] = set()
    for k, piece in enumerate(wires):
        if piece.wire_id not in cut_ids:
            continue
        p = pts_in_world[piece.point_indices]
        best, share = -1, 0.5
        for j, other in enumerate(wires):
            if j == k or j in gone or legs[j] != legs[k]:
                continue
            if len(other.point_indices) <= len(piece.point_indices):
                continue
            s_other = other.plane_coords(p)[0]
            lo, hi = other.s_range[0] - 1.0, other.s_range[1] + 1.0
            within = (s_other >= lo) & (s_other <= hi)
            on = float(np.mean(within & (other.distance(p) <= 2 * options.inlier_distance)))
            if on >= share:
                best, share = j, on
        if best < 0:
            continue
        both = np.union1d(wires[best].point_indices, piece.point_indices)
        grown = refit(wires[best], pts_in_world, both, axes[legs[best]].direction, options)
        if grown is wires[best]:
            continue
        logger.info(
            "spans: piece %d (%d points) lies on wire %d: joined to it",
            piece.wire_id,
            len(piece.point_indices),
            wires[best].wire_id,
        )
        wires[best] = grown
        gone.add(k)
    keep = [k for k in range(len(wires)) if k not in gone]
    return [wires[k] for k in keep], [source[k] for k in keep], [legs[k] for k in keep]


def _arm(axes: list[_Leg], legs: list[int]) -> tuple[F64, F64]:
    """Along and across the cross-arm of a support of ``legs``: across its leg, or along
    the bisector of the turn where two legs meet."""
    first, *others = dict.fromkeys(legs)
    return axes[first].bisector([axes[o] for o in others])


def _s_grows_along(w: FittedWire, leg: _Leg) -> bool:
    """Whether the wire's own s grows along the leg's u."""
    return bool(w.plane_direction_xy @ leg.direction > 0)


def _s_on_arm(w: FittedWire, xy: F64, arm: F64) -> float | None:
    """Where ``w``'s plane crosses the cross-arm line through ``xy`` (position along the
    plane), or None when they run parallel."""
    a = np.c_[w.plane_direction_xy, -arm]
    if abs(np.linalg.det(a)) < 1e-6:
        return None
    s, _ = np.linalg.solve(a, xy - w.plane_origin_xy)
    return float(s)


def _touches(w: FittedWire, leg: _Leg, u: float, options: SpanOptions) -> bool:
    lo, hi = leg.ends_u(w)
    return lo - options.max_meeting_gap / 2 <= u <= hi + options.max_meeting_gap / 2 and (
        abs(u - lo) <= options.max_meeting_gap / 2 or abs(u - hi) <= options.max_meeting_gap / 2
    )


def _cut(
    wire: FittedWire,
    s_cut: float,
    pts_in_world: F64,
    leg: _Leg,
    options: WiresOptions,
    new_id: int,
) -> tuple[FittedWire, FittedWire] | None:
    """``wire`` cut at ``s_cut`` along its plane: two wires refitted to the points on
    either side (the second with ``new_id``), or None when a side holds no wire."""
    s, _, _ = wire.plane_coords(pts_in_world[wire.point_indices])
    left, right = wire.point_indices[s < s_cut], wire.point_indices[s >= s_cut]
    if len(left) < options.min_points or len(right) < options.min_points:
        return None
    a = refit(wire, pts_in_world, left, leg.direction, options)
    b = refit(wire, pts_in_world, right, leg.direction, options)
    if a is wire or b is wire:
        return None
    return a, dataclasses.replace(b, wire_id=new_id)


def _trimmed(
    wire: FittedWire, s_cut: float, pts_in_world: F64, leg: _Leg, options: WiresOptions
) -> FittedWire | None:
    """``wire`` refitted to its points on the side of ``s_cut`` that holds most of them, when
    that side holds a wire and the other does not (fewer than ``min_points``, or no curve
    fits them); else None."""
    s, _, _ = wire.plane_coords(pts_in_world[wire.point_indices])
    left, right = wire.point_indices[s < s_cut], wire.point_indices[s >= s_cut]
    main, rest = (left, right) if len(left) >= len(right) else (right, left)
    if len(main) < options.min_points:
        return None
    if (
        len(rest) >= options.min_points
        and refit(wire, pts_in_world, rest, leg.direction, options) is not wire
    ):
        return None
    kept = refit(wire, pts_in_world, main, leg.direction, options)
    return None if kept is wire else kept


def _conductors(
    wires: list[FittedWire],
    placement: list[WireSpan],
    attached: dict[int, list[tuple[int, F64]]],
    same_m: float,
) -> list[int]:
    """One number per conductor: wires of neighbouring spans whose attachments at a shared
    support lie within ``same_m`` of each other (mutual nearest) are one conductor."""
    n = len(wires)
    rows, cols = list(range(n)), list(range(n))
    for att in attached.values():
        if len(att) < 2:
            continue
        ks = [k for k, _ in att]
        p = np.array([q for _, q in att])
        d = np.linalg.norm(p[:, None] - p[None], axis=2)
        spans = np.array([placement[k].span for k in ks])
        d[spans[:, None] == spans[None]] = np.inf
        for i in range(len(ks)):
            j = int(np.argmin(d[i]))
            if d[i, j] <= same_m and int(np.argmin(d[j])) == i:
                rows.append(ks[i])
                cols.append(ks[j])
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))
    _, lab = connected_components(graph, directed=False)
    first = {int(v): i for i, v in enumerate(dict.fromkeys(lab.tolist()))}
    return [first[int(v)] for v in lab]
