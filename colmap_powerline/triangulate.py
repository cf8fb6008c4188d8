"""Primitives: every wire pixel matched with every wire pixel on the same rectified row.

On each row of a rectified pair, each left wire centre is matched with every right wire
centre whose disparity the scene allows — between the ground (from the sparse points) and
a maximum wire height above it — and triangulated. Most of these candidates
("primitives") are wrong; multi-view verification removes them.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import numpy.typing as npt

from .options import OptionError, check_limits
from .rectify import RectifiedPair
from .scene import Scene

logger = logging.getLogger(__name__)

F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]
F32 = npt.NDArray[np.float32]


# Matching searches down to this far below the ground interpolated from the sparse points.
GROUND_SEARCH_BELOW = 2.0


@dataclass(kw_only=True)
class TriangulateOptions:
    min_wire_height: float = 5.0  # lowest wire above the ground (model units; overhead
    # lines keep at least 5–6 m over ground by regulation, tower bracing is lower); the search
    # starts from the ground itself, so that lines on it (road edges, shadows, field rows)
    # triangulate where they are and are then recognised as ground, not wires
    max_wire_height: float = 60.0  # highest wire above the ground (model units)
    same_polarity: bool = True  # match bright with bright and dark with dark only
    max_primitives: int = 20_000_000  # a pair with more candidates than this is skipped

    LIMITS: ClassVar[dict[str, str]] = {
        "min_wire_height": ">= 0",
        "max_wire_height": "> 0",
        "max_primitives": ">= 1",
    }

    def __post_init__(self) -> None:
        check_limits(self)
        if not self.max_wire_height > self.min_wire_height:
            raise OptionError(
                "max_wire_height",
                self.max_wire_height,
                f"> min_wire_height ({self.min_wire_height})",
            )


@dataclass(frozen=True, eq=False)
class WireCentres:
    """Sub-pixel wire centres on the rows of one rectified image (one per run of wire pixels)."""

    rows: I64  # (N,) row index
    u: F64  # (N,) column in COLMAP pixel coordinates (pixel centre at +0.5)
    polarity: npt.NDArray[np.int8]  # (N,) +1 brighter than the sides, -1 darker

    def __len__(self) -> int:
        return len(self.rows)


@dataclass(frozen=True, eq=False)
class Primitives:
    """Candidate wire points of one pair."""

    pts_in_world: F64  # (N, 3)
    u_left: F64  # (N,) rectified columns
    u_right: F64  # (N,)
    v: F64  # (N,) rectified row coordinate (pixel centre)
    pair_index: int
    left_wire_px: F32 | None = None  # (M, 2) the wire centres found in the left image, in
    # its own pixels (OpenCV convention): what the report draws, without detecting again

    def __len__(self) -> int:
        return len(self.pts_in_world)


def wire_centres(mask: npt.NDArray[np.bool_], response: npt.NDArray[np.float32]) -> WireCentres:
    """Collapse each horizontal run of wire pixels to its response-weighted centre.

    Args:
        mask: (H, W) wire pixels of a rectified image (wires roughly vertical).
        response: (H, W) signed line-template response.
    """
    if mask.shape != response.shape:
        raise ValueError(f"{mask.shape=} but {response.shape=}")
    rows, cols = np.nonzero(mask)  # row-major: sorted by row, then column
    if len(rows) == 0:
        return WireCentres(np.zeros(0, np.int64), np.zeros(0), np.zeros(0, np.int8))
    resp = response[rows, cols].astype(np.float64)
    sign = np.sign(resp)
    new_run = np.r_[
        True, (rows[1:] != rows[:-1]) | (cols[1:] != cols[:-1] + 1) | (sign[1:] != sign[:-1])
    ]
    starts = np.flatnonzero(new_run)
    weight = np.abs(resp) + 1e-6
    wsum = np.add.reduceat(weight, starts)
    u = np.add.reduceat(weight * (cols + 0.5), starts) / wsum
    return WireCentres(rows[starts].astype(np.int64), u, sign[starts].astype(np.int8))


def _ground_depth(pair: RectifiedPair, scene: Scene, uv: F64, height_above: float) -> F64:
    """Depth along the left rectified rays at which they are ``height_above`` the ground."""
    c = pair.left.center_in_world
    rays = pair.rays_in_world(0, uv)  # rectified depth = ray parameter (z component is 1)
    depth = np.full(len(uv), 0.5 * sum(pair.depth_range))
    down = rays[:, 2] < -1e-9
    for _ in range(6):  # fixed point: the ray meets the (smooth) ground + offset
        xy = c[:2] + depth[:, None] * rays[:, :2]
        target = scene.ground_height(xy) + height_above
        depth = np.where(down, (target - c[2]) / np.where(down, rays[:, 2], -1.0), depth)
    return np.clip(depth, *pair.depth_range)


def triangulate_pair(
    pair: RectifiedPair,
    scene: Scene,
    left: WireCentres,
    right: WireCentres,
    pair_index: int = 0,
    options: TriangulateOptions | None = None,
) -> Primitives:
    """Match every left wire centre with every right one on its row within the disparity range.

    Args:
        pair: the rectified pair geometry.
        scene: for the ground height under each left ray (from the sparse points).
        left: wire centres of the left rectified image.
        right: wire centres of the right rectified image.

    Returns:
        All candidate points (the primitives) of this pair.
    """
    options = options or TriangulateOptions()
    empty = Primitives(np.zeros((0, 3)), np.zeros(0), np.zeros(0), np.zeros(0), pair_index)
    if len(left) == 0 or len(right) == 0:
        return empty
    uv_left = np.c_[left.u, left.rows + 0.5]
    # Depth bounds per left centre: far = lowest wire above ground, near = highest wire.
    far = _ground_depth(pair, scene, uv_left, -GROUND_SEARCH_BELOW)
    near = _ground_depth(pair, scene, uv_left, options.max_wire_height)
    offset = pair.column_offset_px
    # Clipped to the row: the keys below stack the rows, so an unclipped range would run
    # into the neighbouring rows (a low flight gives disparities wider than the image).
    width_right = float(pair.widths_px[1])
    u_right_min = np.clip(left.u - offset - pair.disparity_px(near), 0.0, width_right)
    u_right_max = np.clip(left.u - offset - pair.disparity_px(far), 0.0, width_right)

    big = float(max(pair.widths_px) + 10)
    key_right = right.rows * big + right.u
    order = np.argsort(key_right, kind="stable")
    key_sorted = key_right[order]
    lo = np.searchsorted(key_sorted, left.rows * big + u_right_min, side="left")
    hi = np.searchsorted(key_sorted, left.rows * big + u_right_max, side="right")
    counts = np.maximum(hi - lo, 0)
    total = int(counts.sum())
    if total > options.max_primitives:
        logger.warning(
            "pair %s|%s skipped: %d primitives exceed triangulate.max_primitives=%d (its "
            "wire masks are mostly texture, e.g. field rows along the wires)",
            pair.left.name,
            pair.right.name,
            total,
            options.max_primitives,
        )
        return empty
    if total == 0:
        return empty
    li = np.repeat(np.arange(len(left)), counts)
    first = np.repeat(lo, counts)
    within = np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts)
    ri = order[first + within]
    if options.same_polarity:
        keep = left.polarity[li] == right.polarity[ri]
        li, ri = li[keep], ri[keep]
    v = left.rows[li] + 0.5
    pts = pair.triangulate(left.u[li], right.u[ri], v)
    ok = np.isfinite(pts).all(axis=1)
    return Primitives(pts[ok], left.u[li][ok], right.u[ri][ok], v[ok], pair_index)
