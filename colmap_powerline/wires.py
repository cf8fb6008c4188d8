"""Wires: split verified points into conductors and fit a catenary to each.

Points are expressed in line coordinates (s along the wires' azimuth, c across, z up) and
voxelised coarsely along s and finely across, so that one wire becomes a thin chain of
voxels; chains that touch are one wire candidate. This separates conductors that are only
0.5 m apart side by side as well as conductors stacked vertically. Each candidate gets a
vertical plane (robust line in plan) and a robust catenary in that plane; pieces of the
same wire (split by gaps, or found by several pairs) are merged when their curves agree;
candidates that are not wires (too short, too few points, poor fit) are dropped; finally
every point is given to the nearest wire within a tolerance and the wires are refitted.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import numpy.typing as npt
from scipy.ndimage import correlate
from scipy.optimize import least_squares
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from .geometry import across_of, azimuth_deg_of, offsets_across, plan_axes
from .options import check_limits

logger = logging.getLogger(__name__)

F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]
GroundFn = Callable[[F64], F64]


@dataclass(kw_only=True)
class WiresOptions:
    voxel_along: float = 0.5  # voxel size along the line (model units)
    voxel_across: float = 0.06  # voxel size across the line and in height
    link_cells: int = 2  # voxels this many cells apart across/in height are neighbours
    link_along_cells: int = 6  # and this many along the line (bridges small gaps)
    min_points: int = 30  # candidates with fewer points are not wires
    min_length: float = 5.0  # candidates shorter along the line are not wires
    max_rms: float = 0.10  # candidates whose robust fit is worse are not wires
    inlier_distance: float = 0.12  # points farther from the fitted curve are not support
    merge_distance: float = 0.15  # two curves closer than this (mean) are one wire
    max_gap: float = 25.0  # pieces at most this far apart along the line may be merged
    max_plane_angle_deg: float = 10.0  # wire planes deviate at most this from the azimuth
    sample_step: float = 0.1  # polyline spacing of the fitted wires

    LIMITS: ClassVar[dict[str, str]] = {
        "voxel_along": "> 0",
        "voxel_across": "> 0",
        "link_cells": ">= 1",
        "link_along_cells": ">= 1",
        "min_points": ">= 3",
        "min_length": ">= 0",
        "max_rms": "> 0",
        "inlier_distance": "> 0",
        "merge_distance": "> 0",
        "max_gap": ">= 0",
        "max_plane_angle_deg": "(0, 90]",
        "sample_step": "> 0",
    }

    def __post_init__(self) -> None:
        check_limits(self)


def _catenary(s: F64, k: float, s0: float, z0: float) -> F64:
    """z(s) = z0 + (cosh(k (s - s0)) - 1) / k, with k = 1 / a (stable as k → 0)."""
    u = k * (np.asarray(s) - s0)
    with np.errstate(over="ignore"):
        big = (np.cosh(u) - 1) / k
    small = k * (np.asarray(s) - s0) ** 2 / 2 * (1 + u**2 / 12)
    return z0 + np.where(np.abs(u) < 1e-3, small, big)


def catenary_mid(d: F64, k: float, a: float, z_m: float) -> F64:
    """The catenary by its height ``z_m`` and slope ``sinh(a)`` at ``d = 0`` and its
    curvature ``k`` at the lowest point: ``z_m + 2 sinh(a + k d / 2) sinh(k d / 2) / k``
    (any k, also 0 and below: a short or nearly straight piece stays well conditioned)."""
    x = k * np.asarray(d, np.float64) / 2
    with np.errstate(over="ignore", invalid="ignore"):  # sinh(0) / 0: the series is taken
        shc = np.where(np.abs(x) < 1e-4, 1 + x**2 / 6, np.sinh(x) / x)
    return z_m + d * np.sinh(a + x) * shc


# The most a catenary may curve (1 / a, per model unit; a >= 20 m at metre scale): a wire
# 60 m long would sag 22 m, which no overhead wire does. A fit that takes all of it wanted
# more: its points are no wire's (on the real road flight, a 7 m piece whose heights mixed
# a lower cable's with a conductor's, which tracing then carried up onto the conductor).
MAX_CURVATURE = 0.05


def fit_catenary(
    s: F64, z: F64, f_scale: float = 0.03, loss: str = "soft_l1"
) -> tuple[float, float, float, F64]:
    """Robust catenary ``z = z0 + a (cosh((s - s0) / a) - 1)`` through (s, z) samples.

    Returns:
        a, s0, z0 and the (N,) residuals. Near-straight wires get a large ``a`` (≤ 1e7).
    """
    s, z = np.asarray(s, np.float64), np.asarray(z, np.float64)
    if s.shape != z.shape or s.ndim != 1:
        raise ValueError(f"{s.shape=} and {z.shape=} must be equal (N,)")
    if len(s) < 3:
        raise ValueError(f"need at least 3 points to fit a catenary, got {len(s)}")
    # Fitted as the height z_m and the slope sinh(A) at the middle of the samples and the
    # curvature k = 1 / a at the lowest point: unlike (k, s0, z0), a short or nearly straight
    # piece is well conditioned (its lowest point, far away, is not pinned down).
    s_m = float(np.mean(s))
    d = s - s_m
    c2, c1, c0 = np.polyfit(d, z, 2)
    k_min, k_max, a_max = 1e-7, MAX_CURVATURE, 1.0

    def residual(x: F64) -> F64:
        return catenary_mid(d, x[0], x[1], x[2]) - z

    a0 = float(np.clip(np.arcsinh(c1), -a_max * 0.99, a_max * 0.99))
    k0 = float(np.clip(2 * c2 / np.cosh(a0), k_min * 1.01, k_max * 0.99))
    sol = least_squares(
        residual,
        np.array([k0, a0, c0]),
        bounds=([k_min, -a_max, -np.inf], [k_max, a_max, np.inf]),
        loss=loss,
        f_scale=f_scale,
        x_scale=[1e-3, 0.1, 1.0],
    )
    k, a, z_m = sol.x
    s0 = s_m - a / k
    z0 = z_m - (np.cosh(a) - 1) / k
    return float(1.0 / k), float(s0), float(z0), residual(sol.x)


@dataclass(frozen=True, eq=False)
class FittedWire:
    """One wire: a catenary in a vertical plane, between its observed ends."""

    wire_id: int
    plane_origin_xy: F64  # (2,) a point of the wire's vertical plane
    plane_direction_xy: F64  # (2,) unit horizontal direction of the plane
    catenary_a: float  # z(s) = z0 + a (cosh((s - s0) / a) - 1),
    s0: float  # with s = (xy - origin) · direction
    z0: float
    s_range: tuple[float, float]  # observed ends
    point_indices: I64  # (K,) indices of the supporting input points
    rms_residual: float  # RMS distance of the support to the curve (model units)

    def z_at(self, s: F64) -> F64:
        return _catenary(np.asarray(s, np.float64), 1.0 / self.catenary_a, self.s0, self.z0)

    def points(self, s: F64) -> F64:
        """(N,) positions along the plane → (N, 3) points on the wire."""
        s = np.asarray(s, np.float64).reshape(-1)
        xy = self.plane_origin_xy + s[:, None] * self.plane_direction_xy
        return np.c_[xy, self.z_at(s)]

    def polyline(self, step: float = 0.1) -> F64:
        """(M, 3) the wire sampled every ``step`` between its observed ends."""
        lo, hi = self.s_range
        n = max(int(np.ceil((hi - lo) / step)) + 1, 2)
        return self.points(np.linspace(lo, hi, n))

    def plane_coords(self, pts: F64) -> tuple[F64, F64, F64]:
        """(N, 3) points → s along the plane, signed offset across it, height above the curve."""
        rel = np.asarray(pts, np.float64)[:, :2] - self.plane_origin_xy
        d = self.plane_direction_xy
        s = rel @ d
        across = rel @ across_of(d)
        return s, across, np.asarray(pts)[:, 2] - self.z_at(s)

    def own_positions(self, pts_in_world: F64) -> F64:
        """Where its own points (``pts_in_world[point_indices]``) lie along it, sorted."""
        return np.sort(self.plane_coords(pts_in_world[self.point_indices])[0])

    def s_at_along(self, along: F64, bounds: tuple[float, float]) -> tuple[float, float]:
        """The ``s`` where the wire's plane reaches the plan positions ``bounds`` along the
        unit direction ``along`` (measured from the origin), in increasing order."""
        rate = float(self.plane_direction_xy @ along)
        offset = float(self.plane_origin_xy @ along)
        a, b = (bounds[0] - offset) / rate, (bounds[1] - offset) / rate
        return (min(a, b), max(a, b))

    def distance(self, pts: F64) -> F64:
        """(N,) distance of points to the curve (first order in the residuals)."""
        s, across, dz = self.plane_coords(pts)
        # The vertical residual, turned perpendicular to the curve in its plane.
        a = self.catenary_a
        t = np.sinh((s - self.s0) / a)
        return np.hypot(across, dz / np.sqrt(1 + t**2))

    def sag(self) -> float:
        """Largest vertical distance between the chord joining the observed ends and the wire."""
        lo, hi = self.s_range
        s = np.linspace(lo, hi, 2001)
        z = self.z_at(s)
        chord = z[0] + (z[-1] - z[0]) * (s - lo) / max(hi - lo, 1e-12)
        return float(np.max(chord - z))

    def lowest_point(self) -> F64:
        lo, hi = self.s_range
        s = float(np.clip(self.s0, lo, hi))
        return self.points(np.array([s]))[0]

    def length(self) -> float:
        """Arc length between the observed ends."""
        p = self.polyline(0.05)
        return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())

    def to_json(self, ground_height: GroundFn | None = None, step: float = 0.1) -> dict:
        poly = self.polyline(step)
        clearance = None
        if ground_height is not None:
            clearance = float(np.min(poly[:, 2] - ground_height(poly[:, :2])))
        return {
            "id": self.wire_id,
            "catenary": {"a": self.catenary_a, "s0": self.s0, "z0": self.z0},
            "plane": {
                "origin": self.plane_origin_xy.tolist(),
                "direction": self.plane_direction_xy.tolist(),
            },
            "ends": [poly[0].tolist(), poly[-1].tolist()],
            "s_range": list(self.s_range),
            "sag_m": self.sag(),
            "lowest_point": self.lowest_point().tolist(),
            "clearance_m": clearance,
            "num_points": int(len(self.point_indices)),
            "rms_m": self.rms_residual,
            "length_m": self.length(),
            "polyline": np.round(poly, 4).tolist(),
        }


def _fit(pts: F64, idx: I64, azimuth_xy: F64, options: WiresOptions) -> FittedWire | None:
    """Plane + catenary through the points ``pts[idx]``; None when it is not a wire."""
    p = pts[idx]
    normal = across_of(azimuth_xy)
    s, c = p[:, :2] @ azimuth_xy, p[:, :2] @ normal
    if len(idx) < options.min_points or np.ptp(s) < options.min_length:
        return None
    # Plane: c = c0 + slope * s, robustly.
    sol = least_squares(
        lambda x: x[0] + x[1] * s - c, [np.median(c), 0.0], loss="soft_l1", f_scale=0.03
    )
    c0, slope = sol.x
    if np.degrees(np.arctan(abs(slope))) > options.max_plane_angle_deg:
        return None
    direction = (azimuth_xy + slope * normal) / np.hypot(1.0, slope)
    origin = c0 * normal
    s_plane = (p[:, :2] - origin) @ direction
    try:
        a, s0, z0, res_z = fit_catenary(s_plane, p[:, 2])
    except ValueError:
        return None
    if a * MAX_CURVATURE < 1.001:
        return None  # curved as much as a catenary may: not a wire's points
    across = offsets_across(p[:, :2], origin, direction)
    dist = np.hypot(across, res_z)
    inl = dist < options.inlier_distance
    if inl.sum() < options.min_points:
        return None
    lo, hi = np.quantile(s_plane[inl], [0.0, 1.0])
    rms = float(np.sqrt(np.mean(dist[inl] ** 2)))
    return FittedWire(
        wire_id=-1,
        plane_origin_xy=origin,
        plane_direction_xy=direction,
        catenary_a=a,
        s0=s0,
        z0=z0,
        s_range=(float(lo), float(hi)),
        point_indices=idx[inl],
        rms_residual=rms,
    )


def nearest_wire(
    wires: list[FittedWire], pts: F64, reach: float, tolerance: F64
) -> npt.NDArray[np.int64]:
    """(N,) the index of the wire whose curve, continued ``reach`` past its ends, passes
    nearest each point within that wire's ``tolerance`` (-1: none)."""
    if not wires:
        return np.full(len(pts), -1, np.int64)
    dist = np.full((len(wires), len(pts)), np.inf)
    for k, w in enumerate(wires):
        s = w.plane_coords(pts)[0]
        inside = np.flatnonzero((s >= w.s_range[0] - reach) & (s <= w.s_range[1] + reach))
        d = w.distance(pts[inside])
        dist[k, inside] = np.where(d < tolerance[k], d, np.inf)
    best = np.argmin(dist, axis=0)
    return np.where(np.isfinite(dist[best, np.arange(len(pts))]), best, -1)


def absorb_points(
    wires: list[FittedWire],
    pts_in_world: F64,
    new_idx: I64,
    azimuth_deg: float,
    options: WiresOptions,
) -> tuple[list[FittedWire], I64, I64]:
    """Give the points ``pts_in_world[new_idx]`` to the wire whose curve (extended by
    ``max_gap`` past its ends) passes within ``inlier_distance``, and refit those wires.

    Returns:
        The wires (same ids), and the points taken with the id of the wire each went to.
    """
    if not wires or len(new_idx) == 0:
        return wires, np.zeros(0, np.int64), np.zeros(0, np.int64)
    best = nearest_wire(
        wires,
        pts_in_world[new_idx],
        options.max_gap,
        np.full(len(wires), options.inlier_distance),
    )
    close = best >= 0
    along, _ = plan_axes(azimuth_deg)
    out = []
    for k, w in enumerate(wires):
        mine = new_idx[close & (best == k)]
        fit = (
            _fit(pts_in_world, np.r_[w.point_indices, mine], along, options) if len(mine) else None
        )
        out.append(dataclasses.replace(fit, wire_id=w.wire_id) if fit is not None else w)
    taken = new_idx[close]
    return out, taken, np.array([wires[b].wire_id for b in best[close]], np.int64)


def refit(
    wire: FittedWire, pts_in_world: F64, idx: I64, azimuth_xy: F64, options: WiresOptions
) -> FittedWire:
    """The wire fitted again to the points ``pts_in_world[idx]`` (same id); the wire as it
    was when they fit no curve."""
    fit = _fit(pts_in_world, idx, azimuth_xy, options)
    return wire if fit is None else dataclasses.replace(fit, wire_id=wire.wire_id)


def trim_wire(
    wire: FittedWire,
    pts_in_world: F64,
    s_range: tuple[float, float],
    azimuth_deg: float,
    options: WiresOptions,
) -> FittedWire | None:
    """The wire refitted on its points within ``s_range`` along its plane (None: too few)."""
    s = wire.plane_coords(pts_in_world[wire.point_indices])[0]
    idx = wire.point_indices[(s >= s_range[0]) & (s <= s_range[1])]
    fit = _fit(pts_in_world, idx, plan_axes(azimuth_deg)[0], options)
    if fit is None or fit.rms_residual > options.max_rms:
        return None
    return dataclasses.replace(fit, wire_id=wire.wire_id)


def merge_pieces(
    wires: list[FittedWire], pts_in_world: F64, azimuth_deg: float, options: WiresOptions
) -> tuple[list[FittedWire], dict[int, int]]:
    """Join pieces of one wire across any gap: those in one vertical plane whose points one
    catenary fits (each piece's own curve, continued far, would not meet the other's).

    Returns:
        The wires (a joined wire keeps the id of its first piece) and, for every id that was
        joined into another, that wire's id.
    """
    along, _ = plan_axes(azimuth_deg)
    out = list(wires)
    joined: dict[int, int] = {}
    apart: set[tuple[int, int]] = set()  # pairs of ids already found to be two wires
    changed = True
    while changed:
        changed = False
        for i in range(len(out)):
            for j in range(i + 1, len(out)):
                a, b = out[i], out[j]
                if (a.wire_id, b.wire_id) in apart:
                    continue
                apart.add((a.wire_id, b.wire_id))
                # Only pieces near one vertical plane are worth a joint fit (a shortcut: the
                # joint fit decides).
                _, across, _ = a.plane_coords(b.points(np.array(b.s_range)))
                if np.abs(across).max() > MERGE_PLANE_REACH or _apart_where_both_are(
                    a, b, pts_in_world, options
                ):
                    continue
                fit = _joint_fit(a, b, pts_in_world, along, options)
                if fit is None:
                    continue
                # The joined wire is new: its pairs are tried again.
                apart = {p for p in apart if a.wire_id not in p}
                out[i] = dataclasses.replace(fit, wire_id=a.wire_id)
                joined[b.wire_id] = a.wire_id
                del out[j]
                changed = True
                break
            if changed:
                break
    # Chains (c joined into b, b into a) point at the surviving wire.
    for k in joined:
        while joined[k] in joined:
            joined[k] = joined[joined[k]]
    return out, joined


def _across_support(
    a: FittedWire, b: FittedWire, pts_in_world: F64, along: F64, options: WiresOptions
) -> bool:
    """Do two pieces, each a support window long or more (a span's wire, not a support's
    member or a few metres by an insulator), meet at a support (:func:`_support_places`
    of their points together: the next span's conductor of a straight line)?"""
    window = SUPPORT_WINDOW_LENGTHS * options.min_length
    if min(np.ptp(a.s_range), np.ptp(b.s_range)) < window:
        return False
    idx = np.r_[a.point_indices, b.point_indices]
    return bool(_support_places(pts_in_world, idx, along, options))


def _joint_fit(
    a: FittedWire, b: FittedWire, pts_in_world: F64, along: F64, options: WiresOptions
) -> FittedWire | None:
    """One curve through the points of two pieces, when it keeps ``MERGE_INLIER_SHARE`` of
    each piece's points (a short piece beside a long wire is a small share of their points,
    so the share of all of them would not tell), or of all but a shorter stretch at the end
    facing the other (:func:`_kept_but_near_end`), and they meet at no support
    (:func:`_across_support`); else None."""
    idx = np.r_[a.point_indices, b.point_indices]
    fit = _fit(pts_in_world, idx, along, options)
    if fit is None or fit.rms_residual > options.max_rms:
        return None
    if _across_support(a, b, pts_in_world, along, options):
        return None
    inlier = np.isin(idx, fit.point_indices)
    n_a = len(a.point_indices)
    if min(inlier[:n_a].mean(), inlier[n_a:].mean()) >= MERGE_INLIER_SHARE:
        return fit
    s = fit.plane_coords(pts_in_world[idx])[0]
    for own, other in ((slice(0, n_a), slice(n_a, None)), (slice(n_a, None), slice(0, n_a))):
        if not _kept_but_near_end(s[own], inlier[own], s[other]):
            return None
    return fit


def _kept_but_near_end(s: F64, kept: npt.NDArray[np.bool_], s_other: F64) -> bool:
    """Does one curve through two pieces keep ``MERGE_INLIER_SHARE`` of one piece's points
    (along-line places ``s``, ``kept`` by the curve), but for a stretch at the end facing the
    other piece (at ``s_other``, wholly beyond that end) shorter than the rest of it?

    Points matched last before a gap are matched worst; a piece whose far part lies on the
    other's curve continued is a stretch of that wire (wires in one vertical plane never
    cross), whatever its near end holds (the shared corridor seed 1: a shield wire's 30 m
    piece whose first 8 m lie 10-20 cm high, beside a 29 m piece of it 3 m away)."""
    if kept.mean() >= MERGE_INLIER_SHARE:
        return True
    lo, hi = float(s.min()), float(s.max())
    if s_other.min() < hi and s_other.max() > lo:
        return False  # side by side: no end faces the other
    from_end = hi - s if s_other.min() >= hi else s - lo
    order = np.argsort(from_end)
    lost = ~kept[order]
    # Past each place from the end: points lost, and points in all.
    lost_past = np.cumsum(lost[::-1])[::-1]
    ok = lost_past <= (1 - MERGE_INLIER_SHARE) * np.arange(len(s), 0, -1)
    return bool(ok.any() and from_end[order][np.argmax(ok)] < (hi - lo) / 2)


def parabola_split_rss(s: F64, z: F64) -> tuple[F64, F64]:
    """For every split k of the sorted samples: the residual sums of squares of the best
    parabolas through ``[:k]`` and ``[k:]`` (cumulative moments: all splits at once)."""
    m = np.stack([s**j for j in range(5)])  # (5, N)
    t = np.stack([z * s**j for j in range(3)])
    zz = z**2

    def sides(mom: F64, tz: F64, z2: F64) -> F64:
        a = np.stack([np.stack([mom[i + j] for j in range(3)], -1) for i in range(3)], -2)
        a = a + 1e-9 * np.eye(3)
        beta = np.linalg.solve(a, tz.T[..., None])[..., 0]
        return np.maximum(z2 - np.sum(beta * tz.T, axis=1), 0.0)

    cm = np.concatenate([np.zeros((5, 1)), np.cumsum(m, axis=1)], axis=1)
    ct = np.concatenate([np.zeros((3, 1)), np.cumsum(t, axis=1)], axis=1)
    cz = np.r_[0.0, np.cumsum(zz)]
    left = sides(cm, ct, cz)
    right = sides(cm[:, -1:] - cm, ct[:, -1:] - ct, cz[-1] - cz)
    return left, right


# A wire bends down where a support holds it by the sum of its two curves' slopes there
# (about 4 sag / span each side: 10 degrees for a 100 m span sagging 2.5 m); a chain is cut
# where two curves fit it far better than one and bend down by at least this.
SUPPORT_MIN_BEND_DEG = 2.0
# ... and the two curves' residual sum of squares is at most this share of one curve's
# (one curve through a support misses by decimetres, two fit to the noise).
SUPPORT_MAX_RSS_SHARE = 0.25
# The curves either side are fitted over this many ``min_length`` (20 m at the defaults:
# less than a span, so that one side holds no other support).
SUPPORT_WINDOW_LENGTHS = 4
MAX_SPLIT_SAMPLES = 4000


def _support_places(pts: F64, idx: I64, along: F64, options: WiresOptions) -> list[float]:
    """Where supports hold the chain ``idx`` (along ``along``): places where two parabolas
    in height, each over ``SUPPORT_WINDOW_LENGTHS`` × ``min_length`` of the chain on its
    side, fit far better than one on the points they hold (``SUPPORT_MAX_RSS_SHARE``:
    :func:`_held_parabola`) and meet bending down (``SUPPORT_MIN_BEND_DEG``); of such
    places within a window of one another, the best fit wins. The two curves must cross
    within ``min_length`` of the place tried, and the support lies where they cross (the
    place tried may lie a few metres off it: each side's curve leaves out the other span's
    few metres as it would false pairings).

    A straight line's conductors run on from span to span: the voxel chains join a span's
    wire to the next one's at their support, and one curve then holds none of them."""
    s = pts[idx, :2] @ along
    order = np.argsort(s, kind="stable")
    s_o, z_o = s[order], pts[idx[order], 2]
    if len(s_o) > MAX_SPLIT_SAMPLES:
        keep = np.linspace(0, len(s_o) - 1, MAX_SPLIT_SAMPLES).astype(np.int64)
        s_o, z_o = s_o[keep], z_o[keep]
    window = SUPPORT_WINDOW_LENGTHS * options.min_length
    if len(s_o) < 2 * options.min_points or s_o[-1] - s_o[0] < 2 * options.min_length:
        return []
    found: list[tuple[float, float]] = []  # (RSS share, place)
    for b in np.arange(s_o[0] + options.min_length, s_o[-1] - options.min_length, 1.0):
        lo, mid, hi = np.searchsorted(s_o, [b - window, b, b + window])
        if min(mid - lo, hi - mid) < options.min_points:
            continue
        x, z = s_o[lo:hi] - b, z_o[lo:hi]
        k = mid - lo
        if x[k - 1] - x[0] < options.min_length or x[-1] - x[k] < options.min_length:
            continue
        # Compared on the points the two curves hold: a chain also carries false pairings
        # decimetres off the wire (layers), whose squares would outweigh the wire's own.
        pl, rl, kl = _held_parabola(x[:k], z[:k], options.inlier_distance)
        pr, rr, kr = _held_parabola(x[k:], z[k:], options.inlier_distance)
        bend = np.degrees(np.arctan(pl[1]) - np.arctan(pr[1]))  # slopes at b (x = 0)
        # Each curve must be the wire of its side, and the spans' curves meet at their
        # support (a side may hold a false pairing's layer: its curve then runs beside
        # the other, not into it).
        if min(kl.mean(), kr.mean()) < 0.5 or bend < SUPPORT_MIN_BEND_DEG:
            continue
        meet = _where_curves_meet(pl, pr, options.min_length)
        if meet is None:
            continue
        xi, zi = np.r_[x[:k][kl], x[k:][kr]], np.r_[z[:k][kl], z[k:][kr]]
        one = float(np.sum((zi - np.polyval(np.polyfit(xi, zi, 2), xi)) ** 2))
        share = float(rl @ rl + rr @ rr) / one if one > 0 else 1.0
        if share <= SUPPORT_MAX_RSS_SHARE:
            found.append((share, float(b + meet)))
    cuts: list[float] = []
    for _, b in sorted(found):
        if all(abs(b - c) >= window for c in cuts):
            cuts.append(b)
    return sorted(cuts)


def _where_curves_meet(left: F64, right: F64, reach: float) -> float | None:
    """Where two parabolas in x cross: the crossing nearest x = 0 within ``reach``, or None
    when they do not cross there."""
    roots = np.roots(np.polysub(left, right))
    real = roots[np.isreal(roots)].real
    real = real[np.abs(real) <= reach]
    return float(real[np.argmin(np.abs(real))]) if len(real) else None


def _held_parabola(x: F64, z: F64, tol: float) -> tuple[F64, F64, npt.NDArray[np.bool_]]:
    """The parabola z(x) of the densest layer of points: least squares, then again on the
    points within max(``tol``, 2.5 × their median residual) of it, until that is ``tol``
    or the points kept stop changing. Returns (coefficients, residuals of the points kept,
    which points are kept)."""
    keep = np.ones(len(x), bool)
    p = np.polyfit(x, z, 2)
    for _ in range(HELD_PARABOLA_ROUNDS):
        res = np.abs(z - np.polyval(p, x))
        new = res < max(tol, 2.5 * float(np.median(res[keep])))
        if new.sum() < 3 or np.array_equal(new, keep):
            break
        keep = new
        p = np.polyfit(x[keep], z[keep], 2)
    return p, z[keep] - np.polyval(p, x[keep]), keep


HELD_PARABOLA_ROUNDS = 5


def _supports_of_line(places: list[float], options: WiresOptions) -> list[float]:
    """The line's supports from the places its chains bend at (:func:`_support_places`):
    one per cluster of two or more places within ``min_length`` of one another (a support
    holds all its conductors at one place along the line, and a line has two wires or more;
    one chain bending alone is as likely a row of ground texture or a false pairing)."""
    if not places:
        return []
    p = np.sort(np.asarray(places, np.float64))
    groups = np.split(p, np.flatnonzero(np.diff(p) > options.min_length) + 1)
    return [float(np.median(g)) for g in groups if len(g) >= 2]


def _held(pts: F64, idx: I64, along: F64, options: WiresOptions) -> FittedWire | None:
    """The one curve of a chain, when it holds most of the chain's points."""
    fit = _fit(pts, idx, along, options)
    if fit is None or fit.rms_residual > options.max_rms:
        return None
    return fit if 2 * len(fit.point_indices) >= len(idx) else None


def _past_supports(
    s: F64, own: F64, supports: list[float], options: WiresOptions
) -> npt.NDArray[np.bool_]:
    """Which of the places ``s`` (along the line) lie past a support at which a wire whose
    points lie at ``own`` ends (within ``min_length``), and past its own points: the next
    span's. A few stray points near its curve continued would otherwise carry its end tens
    of metres into that span."""
    past = np.zeros(len(s), bool)
    if len(own) == 0:
        return past
    lo, hi = float(own.min()), float(own.max())
    for b in supports:
        if lo + options.min_length < b < hi - options.min_length:
            continue  # it runs through this one (a chain one curve holds)
        # Never past its own points: the support's place is known to a metre or so.
        if b >= hi - options.min_length:
            past |= s > max(b, hi)
        if b <= lo + options.min_length:
            past |= s < min(b, lo)
    return past


def _chain_curves(
    pts: F64, idx: I64, along: F64, options: WiresOptions, supports: list[float]
) -> list[FittedWire]:
    """The curves of one voxel chain that one curve does not hold: where it runs through
    the line's ``supports`` (:func:`_supports_of_line`), the curves of each piece between
    them; each piece one curve holds gives it, any other its layers (:func:`_layers`)."""
    s = pts[idx, :2] @ along
    inside = [
        b for b in supports if s.min() + options.min_length < b < s.max() - options.min_length
    ]
    side = np.searchsorted(inside, s)
    out: list[FittedWire] = []
    for j in range(len(inside) + 1):
        piece = idx[side == j]
        if len(piece) < options.min_points:
            continue
        fit = _held(pts, piece, along, options) if inside else None
        # One curve does not hold most of it: it holds several (a wire and a false pairing
        # 1 m above it all along, joined by the points between).
        out += [fit] if fit is not None else _layers(pts, piece, along, options)
    return out


def _layers(pts: F64, idx: I64, along: F64, options: WiresOptions) -> list[FittedWire]:
    """The curves a chain of points holds, densest first: each grown from the densest layer
    of what the curves before it left (points within the inlier distance of one another
    across a smooth trend of all of them), until no layer of ``min_points`` is left."""
    out: list[FittedWire] = []
    rest = idx
    normal = across_of(along)
    while len(rest) >= options.min_points and len(out) < MAX_LAYERS:
        p = pts[rest]
        s, c = p[:, :2] @ along, p[:, :2] @ normal
        # The trend: a straight plane and a parabola in height (robust to the layers'
        # spread, which is what is looked for).
        c_res = c - np.polyval(np.polyfit(s, c, 1), s)
        z_res = p[:, 2] - np.polyval(np.polyfit(s, p[:, 2], 2), s)
        step = options.inlier_distance
        cells = np.floor(np.c_[c_res, z_res] / step).astype(np.int64)
        cells -= cells.min(axis=0)
        dense = np.zeros(cells.max(axis=0) + 3, np.int64)
        np.add.at(dense, (cells[:, 0] + 1, cells[:, 1] + 1), 1)
        # Points of a 3 x 3 block of cells (the layer and its spread).
        block = correlate(dense, np.ones((3, 3), np.int64), mode="constant")
        bi, bj = np.unravel_index(np.argmax(block), block.shape)
        seed = rest[(np.abs(cells[:, 0] + 1 - bi) <= 1) & (np.abs(cells[:, 1] + 1 - bj) <= 1)]
        fit = None
        for _ in range(MAX_LAYER_GROWTH):  # refit on what lies on it, until it stops growing
            f = _fit(pts, seed, along, options)
            if f is None:
                break
            fit = f
            grown = rest[fit.distance(pts[rest]) < options.inlier_distance]
            if len(grown) <= len(seed):
                break
            seed = grown
        if fit is None or fit.rms_residual > options.max_rms:
            break
        out.append(fit)
        rest = np.setdiff1d(rest, fit.point_indices)
    return out


# A chain holds at most this many curves (layers); a layer is regrown at most this often.
MAX_LAYERS = 6
MAX_LAYER_GROWTH = 5


def _apart_where_both_are(
    a: FittedWire, b: FittedWire, pts_in_world: F64, options: WiresOptions
) -> bool:
    """Do two pieces lie apart all along a stretch where both hold points (more than
    ``1 - MERGE_INLIER_SHARE`` of each)? One curve cannot then keep both: at each place it
    passes within the inlier distance of one piece's points or of the other's, not both."""
    lo, hi = max(a.s_range[0], b.s_range[0]), min(a.s_range[1], b.s_range[1])
    if hi <= lo:
        return False
    for w in (a, b):
        s = w.plane_coords(pts_in_world[w.point_indices])[0]
        if np.mean((s >= lo) & (s <= hi)) <= 1 - MERGE_INLIER_SHARE:
            return False
    gap = b.distance(a.points(np.linspace(lo, hi, 9)))
    return bool(gap.min() > 4 * options.inlier_distance)


# Pieces are one wire when one catenary keeps at least this share of the points of each.
MERGE_INLIER_SHARE = 0.95
# Pieces farther apart across the line than this (at the ends of one, in the plane of the
# other) are not tried.
MERGE_PLANE_REACH = 2.0


def _same_wire(a: FittedWire, b: FittedWire, options: WiresOptions) -> bool:
    """Do two fitted pieces describe one wire (over their overlap, or across a short gap)?"""
    lo = max(a.s_range[0], b.s_range[0])
    hi = min(a.s_range[1], b.s_range[1])
    if hi < lo:  # disjoint: compare across the gap
        if lo - hi > options.max_gap:
            return False
        s = np.linspace(hi, lo, 5)
    else:
        s = np.linspace(lo, hi, 9)
    pts = a.points(s)
    # Both wires' planes share nearly the same direction: evaluate b at the same places.
    s_b, across, dz = b.plane_coords(pts)
    return bool(np.mean(np.hypot(across, dz)) < options.merge_distance)


def estimate_azimuth(pts: F64) -> float:
    """The dominant horizontal direction of the points (degrees clockwise from +y)."""
    xy = pts[:, :2] - np.median(pts[:, :2], axis=0)
    _, _, vt = np.linalg.svd(xy[:: max(len(xy) // 20000, 1)], full_matrices=False)
    return azimuth_deg_of(vt[0])


def split_wires(
    pts_in_world: F64,
    azimuth_deg: float | None = None,
    options: WiresOptions | None = None,
    layers: bool = True,
) -> list[FittedWire]:
    """Split verified points into individual wires and fit each.

    A chain of points that one curve does not hold (it keeps less than half of them) is cut
    at the line's supports (:func:`_support_places`: a straight line's conductors run on
    from span to span), and otherwise gives its curves layer by layer (:func:`_layers`);
    without ``layers``, the one curve only when that fits.

    Args:
        pts_in_world: (N, 3) verified wire points.
        azimuth_deg: the line's horizontal direction (clockwise from +y); None: from the points.
        options: clustering, fitting and merging options.
        layers: split a chain one curve does not hold into its layers (the main split);
            False: keep that one curve when it fits (the corridor probe, which ranks
            directions by the length of wire their points make).

    Returns:
        The wires, numbered from 0, ordered across the line then by height.
    """
    options = options or WiresOptions()
    pts = np.asarray(pts_in_world, np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"{pts.shape=} but expected (N, 3)")
    if len(pts) < options.min_points:
        return []
    if azimuth_deg is None:
        azimuth_deg = estimate_azimuth(pts)
    along, normal = plan_axes(azimuth_deg)
    s, c, z = pts[:, :2] @ along, pts[:, :2] @ normal, pts[:, 2]

    # Voxel chains: coarse along the line, fine across and in height.
    cells = np.floor(
        np.c_[s / options.voxel_along, c / options.voxel_across, z / options.voxel_across]
    ).astype(np.int64)
    cells -= cells.min(axis=0)
    vox, inverse, counts = np.unique(cells, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    scaled = vox / np.array([options.link_along_cells, options.link_cells, options.link_cells])
    pairs = cKDTree(scaled).query_pairs(1.0 + 1e-9, p=np.inf, output_type="ndarray")
    graph = coo_matrix(
        (np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(vox), len(vox))
    )
    n_comp, comp_of_vox = connected_components(graph, directed=False)
    comp = comp_of_vox[inverse]
    order = np.argsort(comp, kind="stable")
    bounds = np.searchsorted(comp[order], np.arange(n_comp + 1))
    pieces: list[FittedWire] = []
    unheld: list[I64] = []
    for k in range(n_comp):
        idx = order[bounds[k] : bounds[k + 1]]
        if len(idx) < options.min_points:
            continue
        fit = _fit(pts, idx, along, options)
        fits = fit if fit is not None and fit.rms_residual <= options.max_rms else None
        if fits is not None and (not layers or 2 * len(fits.point_indices) >= len(idx)):
            pieces.append(fits)
        elif layers:
            unheld.append(idx)
    # A chain one curve does not hold runs through the line's supports (a straight line's
    # conductors run on from span to span: the chains join one span's wire to the next's),
    # or holds several curves. The supports are where the chains bend, all of them together:
    # a chain of several layers does not show its own bend.
    supports = _supports_of_line(
        [b for idx in unheld for b in _support_places(pts, idx, along, options)], options
    )
    for idx in unheld:
        pieces += _chain_curves(pts, idx, along, options, supports)

    # Merge pieces of the same wire (gaps, duplicates from several pairs), then refit.
    n = len(pieces)
    parent = list(range(n))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i in range(n):
        for j in range(i + 1, n):
            # Close where they meet, and not at a support: a span's conductor meets the
            # next span's at their support, where no curve continues.
            if (
                root(i) != root(j)
                and _same_wire(pieces[i], pieces[j], options)
                and not _across_support(pieces[i], pieces[j], pts, along, options)
            ):
                parent[root(j)] = root(i)
    groups: dict[int, list[int]] = {}
    for i in range(n):
        groups.setdefault(root(i), []).append(i)
    merged = []
    for members in groups.values():
        idx = np.concatenate([pieces[m].point_indices for m in members])
        fit = _fit(pts, idx, along, options) if len(members) > 1 else pieces[members[0]]
        if fit is not None:
            merged.append(fit)

    # Every point to its nearest wire within the tolerance, then a final fit.
    wires: list[FittedWire] = []
    if merged:
        dist = np.stack([w.distance(pts) for w in merged])  # (K, N)
        s_line = pts[:, :2] @ along
        for k, w in enumerate(merged):
            s_w = w.plane_coords(pts)[0]
            outside = (s_w < w.s_range[0] - 2 * options.max_gap) | (
                s_w > w.s_range[1] + 2 * options.max_gap
            )
            outside |= _past_supports(s_line, s_line[w.point_indices], supports, options)
            dist[k, outside] = np.inf
        best = np.argmin(dist, axis=0)
        close = dist[best, np.arange(len(pts))] < options.inlier_distance
        for k in range(len(merged)):
            fit = _fit(pts, np.flatnonzero(close & (best == k)), along, options)
            if fit is not None and fit.rms_residual <= options.max_rms:
                wires.append(fit)
    # Pieces of one wire that the voxel chains and the short-gap merge left apart.
    wires, _ = merge_pieces(
        [dataclasses.replace(w, wire_id=i) for i, w in enumerate(wires)], pts, azimuth_deg, options
    )
    # Deterministic numbering: across the line, then by height.
    wires.sort(key=lambda w: (round(float(w.plane_origin_xy @ normal), 1), w.z0))
    out = [dataclasses.replace(w, wire_id=i) for i, w in enumerate(wires)]
    logger.info(
        "wires: %d wires from %d points (%d candidates, %d after merging); %d points assigned",
        len(out),
        len(pts),
        len(pieces),
        len(merged),
        sum(len(w.point_indices) for w in out),
    )
    return out
