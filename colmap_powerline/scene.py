"""The oriented scene: a COLMAP sparse model read once through pycolmap into small types.

Everything downstream (pair selection, rectification, verification) sees images, poses and
cameras only through :class:`Scene` and :class:`SceneImage`. Projection and back-projection
go through pycolmap's own camera functions, so every COLMAP camera model (with its lens
distortion) is supported without re-implementing any of them.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt
import pycolmap
from PIL import Image
from scipy.interpolate import LinearNDInterpolator, NearestNDInterpolator
from scipy.spatial import cKDTree

from .errors import InputError

logger = logging.getLogger(__name__)

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

_MODEL_FILES = ("cameras", "images", "points3D")


def cam_from_img(camera: pycolmap.Camera, uv: FloatArray) -> FloatArray:
    """(N, 2) pixels → (N, 2) normalised camera coordinates through pycolmap's lens model."""
    xy = camera.cam_from_img(np.asarray(uv, dtype=np.float64).reshape(-1, 2))
    if xy is None:
        raise InputError(f"pycolmap could not undistort pixels with camera {camera.model_name}")
    return np.asarray(xy, dtype=np.float64)


@dataclass(frozen=True, eq=False)
class SceneImage:
    """One registered image: its camera, pose and file.

    Attributes:
        image_id: COLMAP image id.
        name: the image name as the model stores it (may contain sub-folders).
        path: the image file on disk (``image_path / name``).
        camera: the pycolmap camera (any COLMAP model, lens distortion included).
        rot_cam_from_world: (3, 3) rotation of ``cam_from_world``.
        t_cam_from_world: (3,) translation of ``cam_from_world``.
    """

    image_id: int
    name: str
    path: Path
    camera: pycolmap.Camera
    rot_cam_from_world: FloatArray
    t_cam_from_world: FloatArray

    @property
    def width(self) -> int:
        return int(self.camera.width)

    @property
    def height(self) -> int:
        return int(self.camera.height)

    @property
    def focal_px(self) -> float:
        """Mean focal length in pixels."""
        return float(self.camera.mean_focal_length())

    @cached_property
    def center_in_world(self) -> FloatArray:
        """(3,) projection centre in the model frame."""
        return -self.rot_cam_from_world.T @ self.t_cam_from_world

    @property
    def viewing_dir_in_world(self) -> FloatArray:
        """(3,) unit optical axis in the model frame."""
        return self.rot_cam_from_world[2].copy()

    @cached_property
    def _max_normalized_radius(self) -> float:
        """Largest normalised image radius inside the image, with a margin.

        Distortion polynomials can fold back far outside the image; points beyond this
        radius are reported as not visible instead of being projected through the fold.
        """
        w, h = self.width, self.height
        border = np.array(
            [[0, 0], [w, 0], [0, h], [w, h], [w / 2, 0], [w / 2, h], [0, h / 2], [w, h / 2]],
            dtype=np.float64,
        )
        xy = cam_from_img(self.camera, border)
        return float(np.linalg.norm(xy, axis=1).max() * 1.1)

    def to_cam(self, pts_in_world: FloatArray) -> FloatArray:
        """(N, 3) world points → (N, 3) camera-frame points."""
        return pts_in_world @ self.rot_cam_from_world.T + self.t_cam_from_world

    def project(self, pts_in_world: FloatArray) -> tuple[FloatArray, FloatArray, BoolArray]:
        """Project world points into this image, lens distortion included.

        Args:
            pts_in_world: (N, 3) points in the model frame.

        Returns:
            uv: (N, 2) pixel coordinates (COLMAP convention: the top-left pixel's centre is
                (0.5, 0.5)); NaN where not projectable.
            depth: (N,) z in the camera frame, model units.
            in_image: (N,) True where the point is in front of the camera, within the lens
                model's valid range and inside the image.
        """
        pts_in_world = np.asarray(pts_in_world, dtype=np.float64).reshape(-1, 3)
        pts_in_cam = self.to_cam(pts_in_world)
        depth = pts_in_cam[:, 2]
        uv = np.full((len(pts_in_cam), 2), np.nan)
        front = depth > 1e-9
        if front.any():
            xy = pts_in_cam[front, :2] / depth[front, None]
            ok = np.linalg.norm(xy, axis=1) < self._max_normalized_radius
            idx = np.flatnonzero(front)[ok]
            if len(idx):
                uv[idx] = self.camera.img_from_cam(pts_in_cam[idx])
        with np.errstate(invalid="ignore"):
            in_image = (
                (uv[:, 0] >= 0)
                & (uv[:, 0] < self.width)
                & (uv[:, 1] >= 0)
                & (uv[:, 1] < self.height)
            )
        return uv, depth, in_image

    def rays_in_world(self, uv: FloatArray) -> FloatArray:
        """(N, 2) pixel coordinates → (N, 3) unit ray directions in the model frame."""
        uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        xy = cam_from_img(self.camera, uv)
        rays_in_cam = np.c_[xy, np.ones(len(xy))]
        rays_in_world = rays_in_cam @ self.rot_cam_from_world
        return rays_in_world / np.linalg.norm(rays_in_world, axis=1, keepdims=True)

    def gsd_at_depth(self, depth: float | FloatArray) -> float | FloatArray:
        """Ground sampling distance (model units per pixel) at a camera depth."""
        return np.asarray(depth) / self.focal_px


def _drop_stray_points(pts: FloatArray, k: int = 16) -> FloatArray:
    """Sparse points without their SfM outliers: points far outside the bulk in plan view, and
    points well below their plan neighbours (real SfM models have a few points hundreds of
    metres off, which would otherwise size the cells or pull the ground down)."""
    if len(pts) < 4 * k:
        return pts
    lo, hi = np.quantile(pts[:, :2], [0.01, 0.99], axis=0)
    pad = 0.25 * (hi - lo)
    inside = np.all((pts[:, :2] >= lo - pad) & (pts[:, :2] <= hi + pad), axis=1)
    pts = pts[inside]
    _, nn = cKDTree(pts[:, :2]).query(pts[:, :2], k=k + 1)
    z_nn = pts[nn[:, 1:], 2]  # the neighbours, without the point itself
    med = np.median(z_nn, axis=1)
    mad = np.median(np.abs(z_nn - med[:, None]), axis=1)
    # Only points below their neighbours pull the ground down; those above (towers, trees)
    # are left to the cell quantile.
    below = med - pts[:, 2]
    return pts[below <= np.maximum(6.0 * 1.4826 * mad, 0.5)]


@dataclass(frozen=True, eq=False)
class GroundModel:
    """A terrain surface interpolated from the sparse points.

    The model's points are binned in plan view; the lower quantile of each cell stands for
    the ground (towers, trees and stray points sit above it), and heights between cells are
    linearly interpolated (nearest cell outside their convex hull).
    """

    cells_xy: FloatArray  # (K, 2) plan position of each ground sample
    cells_z: FloatArray  # (K,) ground height of each sample
    cell_size: float  # model units

    @classmethod
    def from_points(cls, pts_in_world: FloatArray, quantile: float = 0.2) -> GroundModel:
        if len(pts_in_world) < 3:
            raise InputError("the sparse model has fewer than 3 points: no ground surface")
        pts_in_world = _drop_stray_points(pts_in_world)
        xy = pts_in_world[:, :2]
        extent = np.ptp(xy, axis=0)
        area = max(float(extent[0] * extent[1]), 1e-12)
        # About 15 points per occupied cell on average.
        cell = max(np.sqrt(15.0 * area / len(xy)), 1e-6)
        ij = np.floor((xy - xy.min(axis=0)) / cell).astype(np.int64)
        keys = ij[:, 0] * (int(ij[:, 1].max()) + 1) + ij[:, 1]
        order = np.argsort(keys, kind="stable")
        keys_sorted = keys[order]
        starts = np.flatnonzero(np.r_[True, keys_sorted[1:] != keys_sorted[:-1]])
        ends = np.r_[starts[1:], len(keys_sorted)]
        cells_xy, cells_z = [], []
        for s, e in zip(starts, ends, strict=True):
            members = order[s:e]
            if e - s < 3 and len(starts) > 3:
                continue
            z = pts_in_world[members, 2]
            zq = float(np.quantile(z, quantile))
            low = members[z <= zq + 1e-12]
            cells_xy.append(xy[low].mean(axis=0))
            cells_z.append(zq)
        return cls(np.array(cells_xy), np.array(cells_z), float(cell))

    @cached_property
    def _linear(self) -> LinearNDInterpolator | None:
        if len(self.cells_xy) < 3:
            return None
        try:
            return LinearNDInterpolator(self.cells_xy, self.cells_z)
        except Exception:  # degenerate (collinear) samples
            return None

    @cached_property
    def _nearest(self) -> NearestNDInterpolator:
        return NearestNDInterpolator(self.cells_xy, self.cells_z)

    def height(self, xy: FloatArray) -> FloatArray:
        """(N, 2) plan positions → (N,) ground heights."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        z = self._linear(xy) if self._linear is not None else np.full(len(xy), np.nan)
        missing = ~np.isfinite(z)
        if missing.any():
            z[missing] = self._nearest(xy[missing])
        return np.asarray(z, dtype=np.float64)


@dataclass(frozen=True, eq=False)
class Scene:
    """A registered COLMAP model with its images.

    Attributes:
        model_path: the sparse model folder.
        image_path: the image root folder.
        images: the registered images, sorted by name.
        pts_in_world: (M, 3) sparse points.
        pts_rgb: (M, 3) uint8 colours of the sparse points.
        pts_error_px: (M,) mean reprojection error of each sparse point.
        pts_track_length: (M,) number of observations of each sparse point.
    """

    model_path: Path
    image_path: Path
    images: tuple[SceneImage, ...]
    pts_in_world: FloatArray
    pts_rgb: npt.NDArray[np.uint8]
    pts_error_px: FloatArray
    pts_track_length: npt.NDArray[np.int64]
    _by_name: dict[str, SceneImage] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_by_name", {im.name: im for im in self.images})

    def __len__(self) -> int:
        return len(self.images)

    def image(self, name: str) -> SceneImage:
        """The registered image with this name."""
        try:
            return self._by_name[name]
        except KeyError:
            raise KeyError(f"no registered image named {name!r} in {self.model_path}") from None

    def with_images(self, images: Sequence[SceneImage]) -> Scene:
        """The same model restricted to some of its images; the ground model is shared, not
        rebuilt."""
        sub = dataclasses.replace(self, images=tuple(images))
        if "ground" in self.__dict__:
            sub.__dict__["ground"] = self.__dict__["ground"]
        return sub

    @cached_property
    def ground(self) -> GroundModel:
        """Terrain surface from the sparse points (built on first use)."""
        return GroundModel.from_points(self.pts_in_world)

    def ground_height(self, xy: FloatArray) -> FloatArray:
        """(N, 2) plan positions → (N,) ground height below them, from the sparse points."""
        return self.ground.height(xy)

    def visibility(self, pts_in_world: FloatArray) -> BoolArray:
        """(n_images, N) True where image i sees point j (in front and inside the frame).

        Occlusion is not modelled: the scenes are seen from above, wires in front.
        """
        pts_in_world = np.asarray(pts_in_world, dtype=np.float64).reshape(-1, 3)
        vis = np.zeros((len(self.images), len(pts_in_world)), dtype=bool)
        for i, im in enumerate(self.images):
            vis[i] = im.project(pts_in_world)[2]
        return vis

    def images_seeing(self, pt_in_world: FloatArray) -> list[SceneImage]:
        """The registered images that see one (3,) point."""
        vis = self.visibility(np.asarray(pt_in_world).reshape(1, 3))[:, 0]
        return [im for im, v in zip(self.images, vis, strict=True) if v]

    @cached_property
    def centers_in_world(self) -> FloatArray:
        """(n_images, 3) projection centres."""
        return np.array([im.center_in_world for im in self.images]).reshape(-1, 3)

    def gsd_at_depth(self, depth: float) -> float:
        """Median ground sampling distance (model units per pixel) at a camera depth."""
        return float(np.median([im.gsd_at_depth(depth) for im in self.images]))


def _model_format(path: Path) -> str | None:
    """'bin' or 'txt' when ``path`` holds a COLMAP model, else None."""
    for ext in ("bin", "txt"):
        if all((path / f"{name}.{ext}").is_file() for name in _MODEL_FILES):
            return ext
    return None


def read_image(path: Path | str, flags: int = cv2.IMREAD_COLOR) -> np.ndarray:
    """Decode an image (RGB uint8, or grey with ``cv2.IMREAD_GRAYSCALE``), or raise one line."""
    img = cv2.imread(str(path), flags)
    if img is None:
        raise InputError(f"{path}: cannot decode the image (missing, empty or not an image)")
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB) if img.ndim == 3 else img


def resolve_inputs(image_path: Path | str | None, input_path: Path | str) -> tuple[Path, Path]:
    """(model folder, image folder), accepting an undistorted COLMAP workspace as input.

    ``input_path`` may be a sparse model, or a workspace written by COLMAP's
    ``image_undistorter`` (``dense/`` with ``images/`` and ``sparse/``); the workspace's own
    ``images/`` is used unless ``image_path`` is given.
    """
    input_path = Path(input_path)
    if _model_format(input_path) is None and _model_format(input_path / "sparse") is not None:
        if image_path is None:
            image_path = input_path / "images"
        input_path = input_path / "sparse"
    if image_path is None:
        raise InputError(f"{input_path}: --image_path is needed (not an undistorted workspace)")
    return input_path, Path(image_path)


def _image_problem(path: Path, width: int, height: int) -> str | None:
    """Why an image named by the model cannot be used, or None when it can."""
    if not path.is_file():
        return "missing on disk"
    try:
        with Image.open(path) as f:
            size = f.size
    except Exception as exc:
        return f"not a readable image ({type(exc).__name__})"
    if size != (width, height):
        return (
            f"{size[0]}x{size[1]} px but its camera is {width}x{height} "
            "(images from another model, or undistorted ones?)"
        )
    return None


def load_scene(
    model_path: Path | str,
    image_path: Path | str,
    check_images: bool = True,
    skip_bad_images: bool = False,
) -> Scene:
    """Read a COLMAP sparse model (binary or text) and its images into a :class:`Scene`.

    Args:
        model_path: folder with ``cameras``, ``images`` and ``points3D`` (.bin or .txt).
        image_path: folder the model's image names are relative to (names may hold
            sub-folders, as the model writes them).
        check_images: require every registered image to exist on disk, be readable and
            have its camera's size.
        skip_bad_images: drop (with one warning each) the images that fail those checks,
            instead of stopping.

    Raises:
        InputError: with one line naming the path and the problem.
    """
    model_path = Path(model_path)
    image_path = Path(image_path)
    if not model_path.exists():
        raise InputError(f"{model_path}: model folder does not exist")
    if not model_path.is_dir():
        raise InputError(f"{model_path}: not a folder (expected a COLMAP sparse model folder)")
    if _model_format(model_path) is None:
        hint = ""
        if (model_path / "0").is_dir() and _model_format(model_path / "0"):
            hint = f" (did you mean {model_path / '0'}?)"
        raise InputError(
            f"{model_path}: not a COLMAP model: needs cameras, images and points3D "
            f"as .bin or .txt{hint}"
        )
    if not image_path.is_dir():
        raise InputError(f"{image_path}: image folder does not exist")
    try:
        rec = pycolmap.Reconstruction(model_path)
    except Exception as exc:  # pycolmap raises plain RuntimeError/ValueError on bad files
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InputError(f"{model_path}: cannot read the COLMAP model: {first}") from exc

    for camera_id, cam in rec.cameras.items():
        params = np.asarray(cam.params, dtype=np.float64)
        if (
            cam.width <= 1
            or cam.height <= 1
            or not np.isfinite(params).all()
            or cam.mean_focal_length() <= 0
            or not cam.verify_params()
        ):
            raise InputError(
                f"{model_path}: camera {camera_id} is invalid ({cam.model_name} "
                f"{cam.width}x{cam.height}, params {params.tolist()}): corrupt or truncated "
                "cameras file?"
            )
    images: list[SceneImage] = []
    for image_id in rec.reg_image_ids():
        image = rec.image(image_id)
        if not image.has_pose:
            continue
        cam_from_world = image.cam_from_world()
        camera = rec.camera(image.camera_id)
        path = image_path / image.name
        problem = _image_problem(path, camera.width, camera.height) if check_images else None
        if problem is not None:
            if not skip_bad_images:
                raise InputError(f"{path}: image named by {model_path} is {problem}")
            logger.warning("skipping %s: %s", path, problem)
            continue
        images.append(
            SceneImage(
                image_id=int(image_id),
                name=image.name,
                path=path,
                camera=camera,
                rot_cam_from_world=np.asarray(cam_from_world.rotation.matrix(), dtype=np.float64),
                t_cam_from_world=np.asarray(cam_from_world.translation, dtype=np.float64),
            )
        )
    if not images:
        raise InputError(f"{model_path}: the model has no registered images (that can be used)")
    images.sort(key=lambda im: im.name)

    pts = list(rec.points3D.values())
    scene = Scene(
        model_path=model_path,
        image_path=image_path,
        images=tuple(images),
        pts_in_world=np.array([p.xyz for p in pts], dtype=np.float64).reshape(-1, 3),
        pts_rgb=np.array([p.color for p in pts], dtype=np.uint8).reshape(-1, 3),
        pts_error_px=np.array([p.error for p in pts], dtype=np.float64),
        pts_track_length=np.array([p.track.length() for p in pts], dtype=np.int64),
    )
    logger.info(
        "scene: %d registered images, %d cameras, %d sparse points from %s",
        len(images),
        len({im.camera.camera_id for im in images}),
        len(pts),
        model_path,
    )
    return scene
