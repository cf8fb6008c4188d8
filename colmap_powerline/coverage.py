"""Where each wire was measured, and why not elsewhere.

A wire's catenary runs between its observed ends; its measured points (the pairs' verified
matches and the points traced in every view) need not cover all of it. Where they do not,
the curve is an interpolation, and an inspector has to know where and why: a stretch that
the flight's images cannot measure needs more images; one they see clearly but where the
wire was not found is a contrast problem that more images of the same kind do not mend.

Along each wire, a place counts as measured where a measured point of it lies within
``radius`` along the wire (the fit's inlier distance: what counts as the wire across it counts
along it). Runs of unmeasured places at least ``MIN_REPORTED_GAP`` long are the gaps.
At each gap's middle, every image that sees it is asked whether another wire's image lies
within the reach of the line search there (trace's rule: the searched line and the other
line's template response can meet); those clear of it are grouped by their position across
the wire, as the support check groups strips. Tracing fixes a place from three views or
more (two fix it, the third checks it) at two or more positions across the wire, so a gap
with fewer is one the flight cannot measure; with enough, the views saw the place and did
not find the wire.

Where both kinds of measurement cover a wire, how far the pairs' points lie from the points
traced in every view near them (within ``AGREEMENT_WINDOW`` along it) is reported too: the
median offset across the wire and in height. Each pair's points inherit that pair's two
images: its baseline's pose error, and a blend where another wire's line lies on this one's
in one of them (a circuit on three levels seen from above stacks two of them in most images
of a flight across the line). The traced points are fixed by every view that sees the place
clearly (two lines fitted jointly where they are close). Scatter averages out of the median;
what is left is the two measurements' disagreement.

The traced points are the better measurement of the two where they disagree (every view
against two, and two lines fitted jointly where a pair's detector saw one blend): on the
shared generator's flight across the line, the middle phases' pairs' points lie 2-12 cm
off in height, pair by pair, and the traced points near them within 2 cm of the truth.
So each pair's points on a wire are moved by that pair's own median offset from the
traced points (:func:`pairs_onto_traced`), where it is compared with them at
``MIN_COMPARED_WINDOWS`` places or more, and the wire is fitted again: the pairs keep
their density and their scatter, the traced points give the datum. The offset is one
per pair and wire: what a pair's relative orientation or a blend in its images does to a
wire changes little along it (a line through each pair's offsets along the wire measured
no better on that flight). The disagreement reported is the one before the move.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.stats import binned_statistic

from .geometry import across_of, offsets_across, positions_across
from .scene import Scene, SceneImage
from .trace import MIN_VIEWS, _beside_others
from .verify import _roughly_in_view
from .wires import FittedWire, WiresOptions, _fit

logger = logging.getLogger(__name__)

F64 = npt.NDArray[np.float64]

# Unmeasured runs shorter than this (model units) are not listed: the catenary spans them
# within its fit accuracy, and a list of every missing decimetre would hide the stretches
# that matter. They still count against the measured share.
MIN_REPORTED_GAP = 1.0

# Pairs' points are compared with the traced points in bins this long along the wire (model
# units; traced places are a few pixels apart, so a bin holds several).
AGREEMENT_WINDOW = 0.5
# ... holding at least this many traced points.
MIN_TRACED_IN_WINDOW = 3
# A pair's offset from the traced points on a wire is taken (and its points moved by it)
# where it is compared at this many windows or more: a median of fewer places is no datum.
MIN_COMPARED_WINDOWS = 5

# How far along the other wires their images are sampled either side of a gap's middle
# (model units), and how finely: enough to find where each crosses the gap's image normal.
_OTHER_HALF_LENGTH = 3.0
_OTHER_STEP = 0.01

# The reasons, from the views' geometry at a gap's middle.
UNSEEN = "no image sees it"
FEW_VIEWS = "too few images see it clear of the other wires"
ONE_POSITION = "the images that see it clear of the other wires are all at one position across it"
NOT_FOUND = "the images see it, but the wire was not found in them there"


@dataclass(frozen=True)
class MeasurementGap:
    """A stretch of a wire with no measured point: its curve there is interpolated."""

    from_m: float  # horizontal distance from the wire's first end, like its measures
    to_m: float
    at: tuple[float, float, float]  # its middle, on the curve
    views: int  # images that see its middle
    clear_views: int  # of those, the images where no other wire's line is within reach
    clear_positions: int  # distinct positions across the wire of those clear images
    why: str  # one of UNSEEN, FEW_VIEWS, ONE_POSITION, NOT_FOUND

    @property
    def length_m(self) -> float:
        return self.to_m - self.from_m

    @property
    def flight_limited(self) -> bool:
        """The images cannot measure it: more images would."""
        return self.why != NOT_FOUND

    def describe(self) -> str:
        where = (
            f"{self.from_m:.1f}-{self.to_m:.1f} from its first end, "
            f"near ({self.at[0]:.1f}, {self.at[1]:.1f})"
        )
        if self.why == UNSEEN:
            detail = UNSEEN
        elif self.why == FEW_VIEWS:
            detail = (
                f"only {self.clear_views} image(s) see it"
                if self.clear_views == self.views
                else f"only {self.clear_views} of the {self.views} images that see it are "
                "clear of the other wires there"
            )
        elif self.why == ONE_POSITION:
            detail = (
                f"the {self.clear_views} images clear of the other wires there are all at "
                "one position across it"
            )
        else:
            detail = (
                f"{self.clear_views} images from {self.clear_positions} positions across it "
                "see it clear of the other wires, but no measurement of it there passed (the "
                "wire faint against the ground there, or the images disagreeing on where it is)"
            )
        return f"{self.length_m:.1f} unmeasured at {where}: {detail}"

    def to_json(self) -> dict[str, Any]:
        out = asdict(self)
        out["at"] = list(self.at)
        out["length_m"] = round(self.length_m, 3)
        return out


@dataclass(frozen=True)
class WireCoverage:
    measured_share: float  # of the wire between its ends, the share within ``radius`` of a
    # measured point of it (along the wire)
    gaps: tuple[MeasurementGap, ...]  # unmeasured runs at least MIN_REPORTED_GAP long
    # The median offset of the pairs' points from the traced points near them, across the
    # wire and in height (None: too few of either to compare), and the share of the pairs'
    # points compared.
    pairs_vs_traced: tuple[float, float] | None = None
    compared_share: float = 0.0
    # The pairs whose points on the wire were moved onto the traced points, and the
    # largest move (model units).
    pairs_moved: int = 0
    largest_move: float = 0.0

    @property
    def longest_gap_m(self) -> float:
        return max((g.length_m for g in self.gaps), default=0.0)

    def measured_at(self, x_m: float) -> bool:
        """Whether the wire was measured at ``x_m`` (horizontal distance from its first end,
        like its measures): not inside one of its gaps. Where it was not (the point of
        maximum sag of a shield measured along half its span), what is read there comes
        from its curve continued."""
        return not any(g.from_m <= x_m <= g.to_m for g in self.gaps)

    @property
    def disagreement_m(self) -> float | None:
        """How far apart the pairs' and the traced measurements put the wire (median)."""
        if self.pairs_vs_traced is None:
            return None
        return float(np.hypot(*self.pairs_vs_traced))

    def to_json(self) -> dict[str, Any]:
        return {
            "measured_share": round(self.measured_share, 4),
            "longest_gap_m": round(self.longest_gap_m, 3),
            "gaps": [g.to_json() for g in self.gaps],
            "pairs_vs_traced": None
            if self.pairs_vs_traced is None
            else {
                "across_m": round(self.pairs_vs_traced[0], 4),
                "height_m": round(self.pairs_vs_traced[1], 4),
                "distance_m": round(self.disagreement_m or 0.0, 4),
                "compared_share": round(self.compared_share, 3),
                "pairs_moved": self.pairs_moved,
                "largest_move_m": round(self.largest_move, 4),
            },
        }


def _offsets_from_traced(
    s: F64, across: F64, dz: F64, paired: npt.NDArray[np.bool_]
) -> tuple[F64, F64, npt.NDArray[np.int64]] | None:
    """Each pair point's (across, height) offset from the median of the traced points in its
    ``AGREEMENT_WINDOW`` along the wire (NaN where that window holds fewer than
    ``MIN_TRACED_IN_WINDOW``), and its window; None: too few points of either kind.
    ``s``, ``across``, ``dz``: the wire's points in its plane's coordinates."""
    traced = ~paired
    if not paired.any() or traced.sum() < MIN_TRACED_IN_WINDOW:
        return None
    n_bins = int((s.max() - s.min()) // AGREEMENT_WINDOW) + 1
    edges = s.min() + AGREEMENT_WINDOW * np.arange(n_bins + 1)
    ref = binned_statistic(s[traced], [across[traced], dz[traced]], "median", bins=edges)
    count = np.bincount(ref.binnumber - 1, minlength=n_bins)
    b = np.clip(np.searchsorted(edges, s, side="right") - 1, 0, n_bins - 1)
    ok = paired & (count[b] >= MIN_TRACED_IN_WINDOW)
    d_across = np.where(ok, across - ref.statistic[0][b], np.nan)
    d_height = np.where(ok, dz - ref.statistic[1][b], np.nan)
    return d_across, d_height, b


def _pairs_vs_traced(
    s: F64, across: F64, dz: F64, paired: npt.NDArray[np.bool_]
) -> tuple[tuple[float, float] | None, float]:
    """The median (across, height) offset of a wire's pairs' points (``paired``) from its
    traced points in the same ``AGREEMENT_WINDOW`` along it, and the share of its pairs'
    points compared; ``s``, ``across``, ``dz``: its points in its plane's coordinates."""
    found = _offsets_from_traced(s, across, dz, paired)
    if found is None:
        return None, 0.0
    d_across, d_height, _ = found
    ok = np.isfinite(d_across)
    if not ok.any():
        return None, 0.0
    return (
        (float(np.median(d_across[ok])), float(np.median(d_height[ok]))),
        float(ok.sum() / paired.sum()),
    )


def _curve_refitted(wire: FittedWire, pts_in_world: F64, options: WiresOptions) -> FittedWire:
    """The wire's curve fitted again to its points (moved), with the same points and ends:
    which points are the wire's and where it ends were decided before, a datum shift of
    centimetres does not change them."""
    fit = _fit(pts_in_world, wire.point_indices, wire.plane_direction_xy, options)
    if fit is None:
        return wire
    ends = wire.points(np.array(wire.s_range))[:, :2]
    s_ends = (ends - fit.plane_origin_xy) @ fit.plane_direction_xy
    return dataclasses.replace(
        fit,
        wire_id=wire.wire_id,
        s_range=(float(s_ends.min()), float(s_ends.max())),
        point_indices=wire.point_indices,
    )


def pairs_onto_traced(
    wires: Sequence[FittedWire],
    pts_in_world: F64,
    pair_index: npt.NDArray[np.int32],
    options: WiresOptions,
) -> tuple[F64, list[FittedWire], list[tuple[int, float]]]:
    """Each pair's points on each wire moved by that pair's median offset (across the wire
    and in height) from the wire's traced points near them, where compared at
    ``MIN_COMPARED_WINDOWS`` windows or more (module docstring); the wires fitted again to
    the moved points. ``pair_index`` (N,): each point's pair (< 0: traced).

    Returns the moved points (a copy), the wires, and per wire the number of pairs moved
    and the largest move."""
    pts = np.array(pts_in_world, np.float64, copy=True)
    moved = np.zeros(len(pts), bool)  # a point two wires share is moved once
    out_wires: list[FittedWire] = []
    summary: list[tuple[int, float]] = []
    for wire in wires:
        idx = wire.point_indices
        s, across, dz = wire.plane_coords(pts_in_world[idx])
        pairs = pair_index[idx]
        found = _offsets_from_traced(s, across, dz, pairs >= 0)
        n_moved, largest = 0, 0.0
        if found is not None:
            d_across, d_height, window = found
            side = np.r_[across_of(wire.plane_direction_xy), 0.0]
            for p in np.unique(pairs[pairs >= 0]):
                mine = (pairs == p) & ~moved[idx]
                compared = mine & np.isfinite(d_across)
                if len(np.unique(window[compared])) < MIN_COMPARED_WINDOWS:
                    continue
                shift = float(np.median(d_across[compared])) * side
                shift[2] = float(np.median(d_height[compared]))
                pts[idx[mine]] -= shift
                moved[idx[mine]] = True
                n_moved += 1
                largest = max(largest, float(np.linalg.norm(shift)))
        if n_moved:
            wire = _curve_refitted(wire, pts, options)
            logger.info(
                "coverage: wire %d: the points of %d pair(s) moved onto the traced points "
                "(each by its own offset from them; at most %.3f)",
                wire.wire_id,
                n_moved,
                largest,
            )
        out_wires.append(wire)
        summary.append((n_moved, largest))
    return pts, out_wires, summary


def _unmeasured_runs(
    wire: FittedWire, s_pts: F64, radius: float, step: float
) -> tuple[float, list[tuple[float, float]]]:
    """The measured share of the wire between its ends and its unmeasured runs (s, from the
    first end), each at least MIN_REPORTED_GAP long."""
    lo, hi = wire.s_range
    n = max(int(np.ceil((hi - lo) / step)) + 1, 2)
    grid = np.linspace(lo, hi, n)
    s_pts = np.sort(s_pts)
    if len(s_pts) == 0:
        return 0.0, [(0.0, hi - lo)] if hi - lo >= MIN_REPORTED_GAP else []
    # Distance along the wire to the nearest measured point, from the two either side.
    j = np.searchsorted(s_pts, grid)
    before = s_pts[np.clip(j - 1, 0, len(s_pts) - 1)]
    after = s_pts[np.clip(j, 0, len(s_pts) - 1)]
    covered = np.minimum(np.abs(grid - before), np.abs(grid - after)) <= radius
    runs = []
    change = np.diff(np.r_[0, (~covered).astype(np.int8), 0])
    starts, stops = np.flatnonzero(change == 1), np.flatnonzero(change == -1)
    for a, b in zip(starts, stops, strict=True):
        # From the last measured place before it to the first after it (the curve's ends
        # where it reaches them).
        s_a = grid[a - 1] if a > 0 else grid[0]
        s_b = grid[b] if b < len(grid) else grid[-1]
        if s_b - s_a >= MIN_REPORTED_GAP:
            runs.append((float(s_a - lo), float(s_b - lo)))
    return float(covered.mean()), runs


def _passes_through(wire: FittedWire, at: F64, distance: float) -> bool:
    """Whether ``wire``, between its ends, passes within ``distance`` of ``at``."""
    s = float(wire.plane_coords(at[None])[0][0])
    return wire.s_range[0] <= s <= wire.s_range[1] and float(wire.distance(at[None])[0]) <= distance


def _clear_of_others(
    view: SceneImage,
    wire: FittedWire,
    at: F64,
    others: Sequence[FittedWire],
    reach_px: float,
    side_offset_px: int,
) -> bool:
    """Whether, in ``view``, no other wire's image lies within reach of this wire's line
    search at ``at``: trace's own test (:func:`trace._beside_others`) on the place and the
    other wires' curves sampled either side of it."""
    s = float(wire.plane_coords(at[None])[0][0])
    uv, _, _ = view.project(np.r_[at[None], wire.points(np.array([s - 0.5, s + 0.5]))])
    if not np.isfinite(uv).all():
        return True
    tangent = uv[2] - uv[1]
    tangent /= max(float(np.linalg.norm(tangent)), 1e-12)
    samples = []
    for other in others:
        s_o = float(other.plane_coords(at[None])[0][0])
        lo = max(s_o - _OTHER_HALF_LENGTH, other.s_range[0])
        hi = min(s_o + _OTHER_HALF_LENGTH, other.s_range[1])
        if hi > lo:
            samples.append(other.points(np.arange(lo, hi + _OTHER_STEP, _OTHER_STEP)))
    if not samples:
        return True
    uv_o, _, _ = view.project(np.concatenate(samples))
    owner = np.concatenate([np.full(len(p), k + 1) for k, p in enumerate(samples)])
    ok = np.isfinite(uv_o).all(axis=1)
    places = np.r_[uv[:1], uv_o[ok]]
    # The other lines run nearly parallel where they come near: this line's normal serves.
    normal = np.tile([-tangent[1], tangent[0]], (len(places), 1))
    _, near = _beside_others(places, normal, np.r_[0, owner[ok]], reach_px, side_offset_px)
    return bool(np.isnan(near[0]))


def _diagnose(
    scene: Scene,
    wire: FittedWire,
    others: Sequence[FittedWire],
    at: F64,
    reach_px: float,
    side_offset_px: int,
    crossing_offset: float,
) -> tuple[int, int, int, str]:
    """(views, clear views, their positions across the wire, why) at a gap's middle."""
    seeing = [
        v
        for v in scene.images
        if _roughly_in_view(v, at[None], 0.0)[0] and v.project(at[None])[2][0]
    ]
    if not seeing:
        return 0, 0, 0, UNSEEN
    clear = [v for v in seeing if _clear_of_others(v, wire, at, others, reach_px, side_offset_px)]
    centres = np.array([v.center_in_world for v in clear]).reshape(-1, 3)
    lateral = offsets_across(centres[:, :2], wire.plane_origin_xy, wire.plane_direction_xy)
    height = float(np.median(scene.centers_in_world[:, 2]) - at[2])
    positions = positions_across(lateral, crossing_offset * height)
    if len(clear) < MIN_VIEWS:
        why = FEW_VIEWS
    elif positions < 2:
        why = ONE_POSITION
    else:
        why = NOT_FOUND
    return len(seeing), len(clear), positions, why


def measured_coverage(
    scene: Scene,
    wires: Sequence[FittedWire],
    pts_in_world: F64,
    radius: float,
    reach_px: float,
    side_offset_px: int,
    crossing_offset: float,
    from_pairs: npt.NDArray[np.bool_] | None = None,
    step: float = 0.1,
) -> list[WireCoverage]:
    """Each wire's measured share and its gaps, with what the views could do there (module
    docstring). ``pts_in_world``: the points the wires index; ``radius``: how far along the
    wire a measured point covers it; ``reach_px``, ``side_offset_px``: trace's line search
    and the detector's template (how near another wire's line spoils the search);
    ``crossing_offset``: views closer across the wire than this times their height above
    it are at one position; ``from_pairs`` (N,): the points the pairs measured (the others
    traced in every view; None: no comparison)."""
    out = []
    for k, wire in enumerate(wires):
        s_pts, across, dz = wire.plane_coords(pts_in_world[wire.point_indices])
        share, runs = _unmeasured_runs(wire, s_pts, radius, step)
        gaps = []
        for a, b in runs:
            at = wire.points(np.array([wire.s_range[0] + 0.5 * (a + b)]))[0]
            # Another wire through the same place is a piece of this one (the next span's,
            # overlapping it at a support): its line on this one's is no other wire's.
            others = [
                w for j, w in enumerate(wires) if j != k and not _passes_through(w, at, 2 * radius)
            ]
            views, clear, positions, why = _diagnose(
                scene, wire, others, at, reach_px, side_offset_px, crossing_offset
            )
            gaps.append(
                MeasurementGap(
                    from_m=round(a, 3),
                    to_m=round(b, 3),
                    at=(float(at[0]), float(at[1]), float(at[2])),
                    views=views,
                    clear_views=clear,
                    clear_positions=positions,
                    why=why,
                )
            )
        offset, compared = (
            _pairs_vs_traced(s_pts, across, dz, from_pairs[wire.point_indices])
            if from_pairs is not None
            else (None, 0.0)
        )
        out.append(WireCoverage(share, tuple(gaps), offset, compared))
    return out


def log_coverage(
    wires: Sequence[FittedWire], coverage: Sequence[WireCoverage], radius: float
) -> None:
    """One line per wire with gaps: its measured share and its longest gap, why; a warning
    where the flight cannot measure a stretch (what to fly). Per wire, how far its pairs'
    points lie from its traced ones: a warning beyond the bound tracing holds its own
    points to (``radius`` / 2.33: within the inlier distance at 98 %, one-sided)."""
    for wire, cov in zip(wires, coverage, strict=True):
        if cov.pairs_vs_traced is not None:
            beyond = (cov.disagreement_m or 0.0) > radius / 2.33
            (logger.warning if beyond and not cov.pairs_moved else logger.info)(
                "coverage: wire %d: the pairs' points lie %.3f from the traced points near "
                "them (median; %+.3f across, %+.3f in height; %.0f %% of them compared)%s",
                wire.wire_id,
                cov.disagreement_m,
                *cov.pairs_vs_traced,
                100 * cov.compared_share,
                (
                    ": each pair's points moved onto the traced points"
                    if cov.pairs_moved
                    else ": its position is uncertain by about that much (two wires' lines "
                    "on each other in the pairs' images, or the model's pose error)"
                )
                if beyond
                else "",
            )
        if not cov.gaps:
            continue
        longest = max(cov.gaps, key=lambda g: g.length_m)
        flight = [g for g in cov.gaps if g.flight_limited]
        log = logger.warning if flight else logger.info
        log(
            "coverage: wire %d measured along %.0f %% of its length, %d gap(s) of %.1f or "
            "more; the longest: %s%s",
            wire.wire_id,
            100 * cov.measured_share,
            len(cov.gaps),
            MIN_REPORTED_GAP,
            longest.describe(),
            (
                f". {sum(g.length_m for g in flight):.1f} of it the images cannot measure: "
                f"a few images offset across the line near "
                + ", ".join(f"({g.at[0]:.0f}, {g.at[1]:.0f})" for g in flight[:3])
                + " would"
            )
            if flight
            else "",
        )
