"""Epipolar resampling of an image pair from the known poses (no matching).

Both images are re-projected onto one virtual pinhole camera orientation whose x axis
runs along the baseline (the common-rotation form of Oh & Lee's Eq. 1): rows are epipolar
lines, so a 3D point lands on the same row in both rectified images, and wires that cross
the baseline run roughly vertically. Lens distortion of any COLMAP camera model is removed
through pycolmap's own camera (``img_from_cam``). Each side is cropped to the part of the
common footprint that the scene's depth range can make visible in the other image.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import ClassVar

import cv2
import numpy as np
import numpy.typing as npt

from .errors import InputError, PairGeometryError
from .options import check_limits
from .scene import Scene, SceneImage

logger = logging.getLogger(__name__)

F64 = npt.NDArray[np.float64]
F32 = npt.NDArray[np.float32]


@dataclass(kw_only=True)
class RectifyOptions:
    depth_margin: float = 0.05  # relative margin on the scene's depth range
    resolution_scale: float = 1.0  # rectified focal length relative to the mean of the two cameras
    max_side_px: int = 8000  # refuse pairs whose rectified images would be larger

    LIMITS: ClassVar[dict[str, str]] = {
        "depth_margin": "[0, 1]",
        "resolution_scale": "(0, 4]",
        "max_side_px": ">= 100",
    }

    def __post_init__(self) -> None:
        check_limits(self)


@dataclass(frozen=True, eq=False)
class RectifiedPair:
    """The geometry of one rectified pair. Side 0 is the left image, side 1 the right.

    Pixel coordinates follow COLMAP: the top-left pixel's centre is (0.5, 0.5). A rectified
    pixel (u, v) of side k has normalised coordinates ``((u - cx[k]) / f, (v - cy) / f)`` in
    the common frame ``rect_from_world``, whose origin is the left camera centre and whose x
    axis points to the right camera centre.
    """

    left: SceneImage
    right: SceneImage
    rect_from_world: F64  # (3, 3) rotation
    focal_px: float
    cx_px: tuple[float, float]  # principal point column of each side
    cy_px: float  # principal point row (shared)
    widths_px: tuple[int, int]
    height_px: int
    baseline: float  # distance between the camera centres, model units
    depth_range: tuple[float, float]  # (near, far) depth along the rectified z axis

    @property
    def sides(self) -> tuple[SceneImage, SceneImage]:
        return (self.left, self.right)

    def _center(self, side: int) -> F64:
        return self.sides[side].center_in_world

    def rays_in_world(self, side: int, uv: F64) -> F64:
        """(N, 2) rectified pixels of one side → (N, 3) ray directions (unnormalised, z = 1)."""
        uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        xy = np.c_[
            (uv[:, 0] - self.cx_px[side]) / self.focal_px, (uv[:, 1] - self.cy_px) / self.focal_px
        ]
        return np.c_[xy, np.ones(len(xy))] @ self.rect_from_world

    def project(self, side: int, pts_in_world: F64) -> tuple[F64, F64]:
        """(N, 3) world points → (N, 2) rectified pixels of one side and (N,) depths."""
        pts = np.asarray(pts_in_world, dtype=np.float64).reshape(-1, 3) - self._center(side)
        pts_in_rect = pts @ self.rect_from_world.T
        z = pts_in_rect[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = np.c_[
                self.focal_px * pts_in_rect[:, 0] / z + self.cx_px[side],
                self.focal_px * pts_in_rect[:, 1] / z + self.cy_px,
            ]
        return uv, z

    def triangulate(self, u_left: F64, u_right: F64, v: F64) -> F64:
        """Matched columns on rectified row(s) ``v`` → (N, 3) world points.

        With normalised columns ``x_l``, ``x_r`` the depth is ``Z = B / (x_l - x_r)``.
        Non-positive disparities give NaN.
        """
        x_l = (np.asarray(u_left, np.float64) - self.cx_px[0]) / self.focal_px
        x_r = (np.asarray(u_right, np.float64) - self.cx_px[1]) / self.focal_px
        y = (np.asarray(v, np.float64) - self.cy_px) / self.focal_px
        disparity = x_l - x_r
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.where(disparity > 0, self.baseline / disparity, np.nan)
        pts_in_rect = np.c_[x_l * z, y * z, z]
        return pts_in_rect @ self.rect_from_world + self.left.center_in_world

    def disparity_px(self, depth: F64 | float) -> F64:
        """Disparity in columns (u_left - u_right, after removing the crop offsets) at a depth."""
        return self.focal_px * self.baseline / np.asarray(depth, dtype=np.float64)

    @property
    def column_offset_px(self) -> float:
        """``u_left - u_right`` for a point at infinity (from the two sides' crops)."""
        return self.cx_px[0] - self.cx_px[1]

    def remap_maps(self, side: int, grid_step_px: int = 8) -> tuple[F32, F32]:
        """cv2.remap maps (H, W) of one side: source pixel coordinates (OpenCV convention).

        The lens model is evaluated exactly on a grid every ``grid_step_px`` pixels and
        interpolated bilinearly in between (the maps are smooth: < 0.01 px error).
        """
        w, h = self.widths_px[side], self.height_px
        step = max(int(grid_step_px), 1)
        pad = 2 * step
        gw, gh = -(-(w + 2 * pad) // step), -(-(h + 2 * pad) // step)
        # Grid sample k sits where cv2.resize (INTER_LINEAR) puts it: at full-resolution pixel
        # index (k + 0.5) * step - 0.5 of the padded image.
        xs = (np.arange(gw) + 0.5) * step - 0.5 - pad + 0.5  # COLMAP pixel coordinates
        ys = (np.arange(gh) + 0.5) * step - 0.5 - pad + 0.5
        u, v = np.meshgrid(xs, ys)
        map_x, map_y = self._source_pixels(side, np.c_[u.ravel(), v.ravel()])
        map_x, map_y = map_x.reshape(gh, gw), map_y.reshape(gh, gw)
        if step > 1:
            size = (gw * step, gh * step)
            map_x = cv2.resize(map_x, size, interpolation=cv2.INTER_LINEAR)
            map_y = cv2.resize(map_y, size, interpolation=cv2.INTER_LINEAR)
        return (
            np.ascontiguousarray(map_x[pad : pad + h, pad : pad + w]),
            np.ascontiguousarray(map_y[pad : pad + h, pad : pad + w]),
        )

    def _source_pixels(self, side: int, uv: F64) -> tuple[F32, F32]:
        """(N, 2) rectified pixels → source pixel coordinates (OpenCV convention; -1e5 where
        the source camera cannot see them)."""
        im = self.sides[side]
        pts_in_cam = self.rays_in_world(side, uv) @ im.rot_cam_from_world.T
        uv_src = np.full((len(pts_in_cam), 2), -1e5)
        ok = pts_in_cam[:, 2] > 1e-9
        xy = pts_in_cam[ok, :2] / pts_in_cam[ok, 2:]
        ok_idx = np.flatnonzero(ok)[np.linalg.norm(xy, axis=1) < im._max_normalized_radius]
        uv_src[ok_idx] = im.camera.img_from_cam(pts_in_cam[ok_idx]) - 0.5
        return uv_src[:, 0].astype(np.float32), uv_src[:, 1].astype(np.float32)

    def rectify_image(
        self, side: int, image: np.ndarray
    ) -> tuple[np.ndarray, npt.NDArray[np.bool_]]:
        """Resample one side's image. Returns the rectified image and its (H, W) valid mask."""
        im = self.sides[side]
        if image.shape[0] != im.height or image.shape[1] != im.width:
            raise InputError(
                f"{im.path}: image is {image.shape[1]}x{image.shape[0]} px but the model says "
                f"{im.width}x{im.height}"
            )
        map_x, map_y = self.remap_maps(side)
        rect = cv2.remap(image, map_x, map_y, cv2.INTER_CUBIC, borderMode=cv2.BORDER_CONSTANT)
        valid = (map_x >= 0) & (map_y >= 0) & (map_x <= im.width - 1) & (map_y <= im.height - 1)
        return rect, valid


def _scene_depth_range(
    scene: Scene,
    rect_from_world: F64,
    left: SceneImage,
    right: SceneImage,
    max_wire_height: float,
    options: RectifyOptions,
) -> tuple[float, float]:
    """Depth range (along the rectified z axis) of the ground and of wires above it."""
    pts = scene.pts_in_world
    seen = left.project(pts)[2] & right.project(pts)[2]
    if seen.sum() < 3:
        seen = left.project(pts)[2] | right.project(pts)[2]
    if seen.sum() < 3:
        raise PairGeometryError(
            f"{scene.model_path}: no sparse points seen by {left.name} and {right.name}"
        )
    ground = pts[seen]
    ground = ground.copy()
    ground[:, 2] = scene.ground_height(ground[:, :2])
    top = ground + np.array([0.0, 0.0, max_wire_height])
    depths = [(p - left.center_in_world) @ rect_from_world[2] for p in (ground, top)]
    near = float(np.min(np.r_[depths[0], depths[1]]))
    far = float(np.max(np.r_[depths[0], depths[1]]))
    near = max(near * (1 - options.depth_margin), 1e-3 * far)
    return near, far * (1 + options.depth_margin)


def rectify_pair(
    scene: Scene,
    left: SceneImage,
    right: SceneImage,
    options: RectifyOptions | None = None,
    max_wire_height: float = 60.0,
) -> RectifiedPair:
    """Build the epipolar geometry of a pair (paper Eq. 1 as one common rotation).

    Args:
        scene: the oriented scene (for the depth range from its sparse points).
        left: the image whose camera centre is the origin of the rectified frame.
        right: the other image; the rectified x axis points from ``left`` to ``right``.
        options: resampling options.
        max_wire_height: highest wire above the ground (model units): with the ground from
            the sparse points it bounds the depth range, hence the crop.

    Returns:
        A :class:`RectifiedPair`; call ``rectify_image`` to resample the images.
    """
    options = options or RectifyOptions()
    baseline_vec = right.center_in_world - left.center_in_world
    baseline = float(np.linalg.norm(baseline_vec))
    if baseline <= 0:
        raise PairGeometryError(
            f"{left.name} and {right.name} have the same camera centre: no stereo"
        )
    x_axis = baseline_vec / baseline
    z_mean = left.viewing_dir_in_world + right.viewing_dir_in_world
    z_axis = z_mean - (z_mean @ x_axis) * x_axis
    if np.linalg.norm(z_axis) < 1e-6:
        raise PairGeometryError(
            f"{left.name} and {right.name} look along their baseline: no stereo"
        )
    z_axis /= np.linalg.norm(z_axis)
    y_axis = np.cross(z_axis, x_axis)
    rect_from_world = np.stack([x_axis, y_axis, z_axis])
    near, far = _scene_depth_range(scene, rect_from_world, left, right, max_wire_height, options)

    focal = options.resolution_scale * 0.5 * (left.focal_px + right.focal_px)
    # Border of each image in normalised rectified coordinates.
    extents = []
    for im in (left, right):
        n = 64
        t = np.linspace(0, 1, n)
        w, h = im.width, im.height
        border = np.r_[
            np.c_[t * w, np.zeros(n)],
            np.c_[np.full(n, w), t * h],
            np.c_[(1 - t) * w, np.full(n, h)],
            np.c_[np.zeros(n), (1 - t) * h],
        ]
        rays = im.rays_in_world(border) @ rect_from_world.T
        if (rays[:, 2] <= 0).any():
            raise PairGeometryError(
                f"{im.name}: image border looks behind the rectified plane; pair too oblique"
            )
        xy = rays[:, :2] / rays[:, 2:]
        extents.append((xy[:, 0].min(), xy[:, 0].max(), xy[:, 1].min(), xy[:, 1].max()))
    (lx0, lx1, ly0, ly1), (rx0, rx1, ry0, ry1) = extents
    y0, y1 = max(ly0, ry0), min(ly1, ry1)
    d_near, d_far = baseline / near, baseline / far  # normalised disparities
    # x_left = x_right + B / Z: keep the columns that can see something the other side sees.
    xl0, xl1 = max(lx0, rx0 + d_far), min(lx1, rx1 + d_near)
    xr0, xr1 = max(rx0, lx0 - d_near), min(rx1, lx1 - d_far)
    if y1 <= y0 or xl1 <= xl0 or xr1 <= xr0:
        raise PairGeometryError(f"{left.name} and {right.name} have no common footprint")
    height = int(np.ceil((y1 - y0) * focal))
    widths = (int(np.ceil((xl1 - xl0) * focal)), int(np.ceil((xr1 - xr0) * focal)))
    if max(height, *widths) > options.max_side_px:
        raise PairGeometryError(
            f"{left.name}/{right.name}: rectified images would be {widths}x{height} px "
            f"(> max_side_px={options.max_side_px}); pair too oblique"
        )
    pair = RectifiedPair(
        left=left,
        right=right,
        rect_from_world=rect_from_world,
        focal_px=float(focal),
        cx_px=(float(-xl0 * focal), float(-xr0 * focal)),
        cy_px=float(-y0 * focal),
        widths_px=widths,
        height_px=height,
        baseline=baseline,
        depth_range=(near, far),
    )
    logger.debug(
        "rectified %s|%s: %dx%d + %dx%d px, baseline %.2f, depth %.1f–%.1f",
        left.name,
        right.name,
        widths[0],
        height,
        widths[1],
        height,
        baseline,
        near,
        far,
    )
    return pair
