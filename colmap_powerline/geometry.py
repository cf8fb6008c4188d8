"""The plan geometry the stages share: a line's axes from its azimuth, azimuth ↔ image
direction, and the offset of views across the wires.

Conventions: an azimuth is in degrees clockwise from +y (north); the unit vector along
azimuth ``az`` is (sin az, cos az), the one across it (cos az, −sin az): the along vector
turned 90° clockwise, to the right of a line looked along. A line's azimuth is axial (10°
and 190° are one direction). Image directions are degrees in [0, 180), 0 = +x (column),
90 = +y (row, down).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt
from scipy.spatial import cKDTree

F64 = npt.NDArray[np.float64]


def across_of(direction_xy: F64) -> F64:
    """(2,) the plan direction turned 90° clockwise: the positive side across a line
    running along ``direction_xy``."""
    return np.array([direction_xy[1], -direction_xy[0]])


def plan_axes(azimuth_deg: float) -> tuple[F64, F64]:
    """(2,) unit vectors along azimuth ``azimuth_deg`` and across it (:func:`across_of`)."""
    az = np.deg2rad(azimuth_deg)
    along = np.array([np.sin(az), np.cos(az)])
    return along, across_of(along)


def azimuth_deg_of(direction_xy: npt.ArrayLike, axial: bool = True) -> float:
    """Azimuth of a plan direction (degrees clockwise from +y): in [0, 180) when ``axial``
    (a line's direction), else in (−180, 180] (the vector's own, e.g. for an axial mean,
    which needs no folding)."""
    d = np.asarray(direction_xy)
    azimuth = np.rad2deg(np.arctan2(d[0], d[1]))
    return float(azimuth % 180.0) if axial else float(azimuth)


def axial_diff_deg(a: npt.ArrayLike, b: npt.ArrayLike) -> F64:
    """Angles between axial directions in degrees (0-90): 10° and 190° are one direction."""
    return np.abs((np.asarray(a, np.float64) - np.asarray(b, np.float64) + 90.0) % 180.0 - 90.0)


def axial_mean_deg(angles_deg: F64, weights: F64) -> float:
    """Weighted mean of directions defined modulo 180° (degrees, in [0, 180))."""
    doubled = np.deg2rad(2 * np.asarray(angles_deg, np.float64))
    w = np.asarray(weights, np.float64)
    mean = np.arctan2((w * np.sin(doubled)).sum(), (w * np.cos(doubled)).sum())
    return float(np.rad2deg(mean) / 2 % 180.0)


def image_direction_deg(uv: F64) -> float:
    """Direction of the image segment ``uv[0]`` → ``uv[1]`` ((2, 2) pixels) in degrees in
    [0, 180) (0 = +x, 90 = down): what the wire detector is given."""
    du = uv[1] - uv[0]
    return float(np.rad2deg(np.arctan2(du[1], du[0])) % 180.0)


def image_axes(direction_deg: float) -> tuple[F64, F64]:
    """(2,) unit pixel vectors along image direction ``direction_deg`` (0 = +x, 90 = down)
    and across it: (cos, sin) and (−sin, cos)."""
    along = np.array([np.cos(np.deg2rad(direction_deg)), np.sin(np.deg2rad(direction_deg))])
    return along, np.array([-along[1], along[0]])


def image_direction_of_azimuth(
    project: Callable[[F64], F64], pt_in_world: F64, azimuth_deg: float
) -> float:
    """Image direction (:func:`image_direction_deg`) of the horizontal line of azimuth
    ``azimuth_deg`` through ``pt_in_world``, as ``project`` ((N, 3) world points → (N, 2)
    pixels) shows it: perspective turns the line across the image, so the direction holds
    near that point (one unit either side of it is projected)."""
    d = np.r_[plan_axes(azimuth_deg)[0], 0.0]
    return image_direction_deg(project(np.stack([pt_in_world - d, pt_in_world + d])))


def offsets_across(xy: F64, origin_xy: F64, direction_xy: F64) -> F64:
    """Signed offsets of plan positions ``xy`` (..., 2) across the line through ``origin_xy``
    along ``direction_xy`` (positive on its :func:`across_of` side); both broadcast."""
    return (xy - origin_xy) @ across_of(direction_xy)


def crossing_views(
    view_centres: F64, pair_centres: F64, azimuth_deg: float, height: float, offset: float
) -> npt.NDArray[np.bool_]:
    """Which views can reject a pair's false matches.

    A camera that moved along the wires from a pair camera sees the same plane through each
    wire, so it confirms that camera's false matches. Only views offset across the wires from
    both pair cameras by more than ``offset × height`` can reject them.

    Args:
        view_centres: (V, 3) camera centres of the views.
        pair_centres: (P, 2, 3) the two camera centres of each pair.
        azimuth_deg: the wires' direction.
        height: camera height above the wires (model units).
        offset: the lateral offset needed, as a share of ``height``.

    Returns:
        (P, V) True where view v is offset across the wires from both cameras of pair p.
    """
    along, _ = plan_axes(azimuth_deg)
    lateral = offsets_across(
        view_centres[None, None, :, :2], pair_centres[:, :, None, :2], along
    )  # (P, 2, V)
    return np.abs(lateral).min(axis=1) > offset * height


def positions_across(offsets: F64, need: float) -> int:
    """How many positions across the wire, each at least ``need`` from the one before, the
    views at ``offsets`` hold. Strips with gaps between them are positions, but so are the
    ends of an area survey's views spread evenly across a wire at an angle to its strips
    (shared twolines seed 7: 12 views over 70 m across the pole line, no gap over 9 m:
    one strip, five positions 9 m apart)."""
    count, last = 0, -np.inf
    for x in np.sort(offsets):
        if x - last >= need:
            count, last = count + 1, x
    return count


def distance_to_polyline(pts: F64, polyline: F64) -> F64:
    """(N, D) points → (N,) exact distance to the (M, D) polyline's segments (D: 2 or 3)."""
    pts = np.asarray(pts, np.float64).reshape(-1, polyline.shape[1])
    a, b = polyline[:-1], polyline[1:]
    seg = b - a
    mid = 0.5 * (a + b)
    tree = cKDTree(mid)
    # Candidate segments: the k nearest midpoints (segments are short and evenly spaced).
    k = min(8, len(mid))
    _, cand = tree.query(pts, k=k)
    cand = cand.reshape(len(pts), k)
    sa, sv = a[cand], seg[cand]  # (N, k, D)
    t = np.einsum("nkj,nkj->nk", pts[:, None] - sa, sv) / np.maximum(
        np.einsum("nkj,nkj->nk", sv, sv), 1e-300
    )
    proj = sa + np.clip(t, 0, 1)[..., None] * sv
    return np.linalg.norm(pts[:, None] - proj, axis=2).min(axis=1)
