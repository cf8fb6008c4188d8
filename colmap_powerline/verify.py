"""Multi-view verification: keep a primitive only where the redundant images see a wire.

Every primitive is projected into every other registered image that sees it; it survives
when it lands on (or within a tolerance of) extracted wire pixels in all of them (the
paper) or in enough of them (options). Each image is decoded and searched for wires once,
only inside the region where primitives project.
"""

from __future__ import annotations

import logging
import time
from collections import deque
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt
from tqdm import tqdm

from .detect import WireMask
from .scene import Scene, SceneImage, read_image
from .triangulate import Primitives

logger = logging.getLogger(__name__)

F64 = npt.NDArray[np.float64]


@dataclass(kw_only=True)
class VerifyOptions:
    tolerance_px: float = 1.5  # a projection this close to a wire pixel is a hit (px)
    min_views: int = 2  # a primitive must be seen by at least this many redundant images
    min_hit_ratio: float = 0.8  # share of the redundant images that must see a wire (paper: 1)
    min_crossing_hits: int = 1  # hits needed from views offset across the wires from the pair
    crossing_offset: float = 0.15  # such a view is offset across the wires by ≥ this × its height
    refine: bool = True  # move each kept point onto the wire centres of the redundant views
    num_threads: int = 2  # views processed at once (peak memory grows with it)
    margin_px: int = 24  # wire search region: bounding box of the projections plus this margin


@dataclass(frozen=True, eq=False)
class VerifiedPoints:
    """Primitives that passed verification."""

    pts_in_world: F64  # (N, 3)
    hits: npt.NDArray[np.int32]  # (N,) redundant images in which the point lies on a wire
    views: npt.NDArray[np.int32]  # (N,) redundant images that see the point
    pair_index: npt.NDArray[np.int32]  # (N,) the pair that produced it
    refined: npt.NDArray[np.bool_]  # (N,) moved onto the wire centres of its views
    decoded: list[Path]  # the images decoded for the verification

    def __len__(self) -> int:
        return len(self.pts_in_world)


# A wire detector for one image: (view, image, direction_deg, crop (x0, y0, x1, y1)) → the
# WireMask of the crop.
WireMaskFn = Callable[[SceneImage, np.ndarray, float, tuple[int, int, int, int]], WireMask]


@dataclass(frozen=True, eq=False)
class _ViewResult:
    idx: npt.NDArray[np.int64]  # primitives this view sees
    hit: npt.NDArray[np.bool_]  # which of them land on a wire
    refine_idx: npt.NDArray[np.int64]  # primitives with a wire-centre observation here
    rows: F64  # (n, 3) their observation rows (d offset / d point)
    offsets: F64  # (n,) their across-wire offsets to the wire centre (px)
    t_read: float
    t_detect: float


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
    az = np.deg2rad(azimuth_deg)
    normal = np.array([np.cos(az), -np.sin(az)])
    lateral = (view_centres[None, None, :, :2] - pair_centres[:, :, None, :2]) @ normal  # (P,2,V)
    return np.abs(lateral).min(axis=1) > offset * height


def image_wire_direction_deg(view: SceneImage, pt_in_world: F64, azimuth_deg: float) -> float:
    """Direction (degrees, 0 = +x, 90 = +y i.e. down) of a horizontal line of the given
    azimuth through ``pt_in_world`` in the image."""
    az = np.deg2rad(azimuth_deg)
    d = np.array([np.sin(az), np.cos(az), 0.0])
    uv, _, _ = view.project(np.stack([pt_in_world - d, pt_in_world + d]))
    du = uv[1] - uv[0]
    return float(np.rad2deg(np.arctan2(du[1], du[0])) % 180.0)


def _wire_offsets(response: np.ndarray, uv: F64, normal: F64, reach: float) -> F64:
    """Signed distance (px, along ``normal``) from each point to the wire centre near it.

    The template response is sampled across the wire at whole-pixel steps; the centre is the
    parabola vertex through the strongest sample and its neighbours. NaN when the strongest
    sample is at the end of the reach (no peak there).
    """
    steps = np.arange(-np.ceil(reach), np.ceil(reach) + 1)
    xy = uv[:, None, :] - 0.5 + steps[None, :, None] * normal  # array index coordinates
    flat = xy.reshape(-1, 2).astype(np.float32)
    width = 4096  # cv2.remap maps must stay below 32767 px a side
    pad = (-len(flat)) % width
    flat = np.concatenate([flat, np.zeros((pad, 2), np.float32)]).reshape(-1, width, 2)
    sampled = cv2.remap(
        np.abs(response).astype(np.float32),
        flat[..., 0],
        flat[..., 1],
        cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_REPLICATE,
    )
    samples = sampled.ravel()[: xy.shape[0] * xy.shape[1]].reshape(xy.shape[:2]).astype(np.float64)
    k = np.argmax(samples, axis=1)
    inner = (k > 0) & (k < len(steps) - 1)
    kc = np.clip(k, 1, len(steps) - 2)
    rows = np.arange(len(uv))
    left, mid, right = samples[rows, kc - 1], samples[rows, kc], samples[rows, kc + 1]
    denom = left - 2 * mid + right
    with np.errstate(divide="ignore", invalid="ignore"):
        vertex = np.where(denom < 0, 0.5 * (left - right) / denom, 0.0)
    return np.where(inner, steps[kc] + np.clip(vertex, -0.5, 0.5), np.nan)


def _roughly_in_view(view: SceneImage, pts: F64, margin: float = 0.25) -> npt.NDArray[np.bool_]:
    """(N,) points in front of the camera whose pinhole projection falls within the image
    grown by ``margin`` of its size (a superset of the exact test, for culling)."""
    pts_in_cam = view.to_cam(pts)
    z = pts_in_cam[:, 2]
    f = view.focal_px
    with np.errstate(divide="ignore", invalid="ignore"):
        u = f * pts_in_cam[:, 0] / z + view.width / 2
        v = f * pts_in_cam[:, 1] / z + view.height / 2
    mw, mh = margin * view.width, margin * view.height
    return (z > 0) & (u > -mw) & (u < view.width + mw) & (v > -mh) & (v < view.height + mh)


def _projection_jacobian(view: SceneImage, pts: F64) -> F64:
    """(N, 2, 3) d(pixel)/d(world point), pinhole approximation of the lens."""
    pts_in_cam = view.to_cam(pts)
    z = pts_in_cam[:, 2]
    x, y = pts_in_cam[:, 0] / z, pts_in_cam[:, 1] / z
    f = view.focal_px
    d = np.zeros((len(pts), 2, 3))
    d[:, 0, 0] = d[:, 1, 1] = f / z
    d[:, 0, 2] = -f * x / z
    d[:, 1, 2] = -f * y / z
    return d @ view.rot_cam_from_world


def verify_primitives(
    scene: Scene,
    primitives: Sequence[Primitives],
    pair_images: Sequence[tuple[str, str]],
    wire_mask: WireMaskFn,
    azimuth_deg: float,
    options: VerifyOptions | None = None,
    show_progress: bool = True,
) -> VerifiedPoints:
    """Check every primitive against the wire pixels of the redundant images.

    Args:
        scene: the oriented scene.
        primitives: the candidates of each pair (``primitives[k].pair_index`` = k).
        pair_images: (left name, right name) of each pair: these images do not vote on the
            primitives they produced.
        wire_mask: the detector, called once per image on the region where primitives land.
        azimuth_deg: the wires' horizontal direction, turned into each image's direction.
    """
    options = options or VerifyOptions()
    if not primitives:
        raise ValueError("no primitives to verify")
    pts = np.concatenate([p.pts_in_world for p in primitives])
    pair_of = np.concatenate([np.full(len(p), k, np.int32) for k, p in enumerate(primitives)])
    hits = np.zeros(len(pts), np.int32)
    views = np.zeros(len(pts), np.int32)
    crossing_hits = np.zeros(len(pts), np.int32)
    by_name = {im.name: im for im in scene.images}
    pair_centres = np.array(
        [[by_name[a].center_in_world, by_name[b].center_in_world] for a, b in pair_images]
    )
    height = float(np.median(scene.centers_in_world[:, 2]) - np.median(pts[:, 2]))
    crossing = crossing_views(
        scene.centers_in_world, pair_centres, azimuth_deg, height, options.crossing_offset
    )  # (P, V)
    normal_eq = np.zeros((len(pts) if options.refine else 0, 3, 3))
    rhs = np.zeros((len(pts) if options.refine else 0, 3))

    def check(view: SceneImage) -> _ViewResult | None:
        """Project, decode, detect and compare for one view (runs in a worker thread)."""
        own = np.array([view.name in names for names in pair_images])
        # Cheap pinhole pre-cull with a wide margin, then the exact lens model.
        cand = np.flatnonzero(~own[pair_of] & _roughly_in_view(view, pts))
        if len(cand) == 0:
            return None
        uv_c, _, inside_c = view.project(pts[cand])
        idx = cand[inside_c]
        if len(idx) == 0:
            return None
        uv = uv_c[inside_c]  # (len(idx), 2)
        px = np.floor(uv).astype(np.int64)  # pixel containing the projection
        x0 = max(int(px[:, 0].min()) - options.margin_px, 0)
        y0 = max(int(px[:, 1].min()) - options.margin_px, 0)
        x1 = min(int(px[:, 0].max()) + options.margin_px + 1, view.width)
        y1 = min(int(px[:, 1].max()) + options.margin_px + 1, view.height)
        t0 = time.perf_counter()
        image = read_image(view.path)
        t_read = time.perf_counter() - t0
        # The wires' direction here, at a primitive this image sees.
        direction = image_wire_direction_deg(view, pts[idx[len(idx) // 2]], azimuth_deg)
        t0 = time.perf_counter()
        wires = wire_mask(view, image, direction, (x0, y0, x1, y1))
        del image
        hit = wires.dilated(options.tolerance_px)[px[:, 1] - y0, px[:, 0] - x0]
        t_detect = time.perf_counter() - t0
        hid = idx[hit] if options.refine else np.zeros(0, np.int64)
        rows = offset = np.zeros(0)
        if options.refine and hit.any():
            # One Gauss-Newton observation per hit: the across-wire offset to the centre.
            a = np.deg2rad(direction)
            normal = np.array([-np.sin(a), np.cos(a)])
            offset = _wire_offsets(
                wires.response, uv[hit] - [x0, y0], normal, options.tolerance_px + 1
            )
            ok = np.isfinite(offset)
            hid, offset = hid[ok], offset[ok]
            rows = np.einsum("j,njk->nk", normal, _projection_jacobian(view, pts[hid]))
        return _ViewResult(idx, hit, hid, rows, offset, t_read, t_detect)

    t_detect = t_read = 0.0
    decoded: list[Path] = []
    # Two views at a time: decoding, filtering and projecting release the GIL.
    with ThreadPoolExecutor(max_workers=max(1, options.num_threads)) as pool:
        # A short queue of views in flight keeps memory to a few views' results.
        pending: deque = deque()
        images = iter(scene.images)
        for _ in range(options.num_threads + 1):
            view0 = next(images, None)
            if view0 is not None:
                pending.append(pool.submit(check, view0))
        for v, view in enumerate(
            tqdm(scene.images, desc="verify", unit="img", disable=not show_progress)
        ):
            res = pending.popleft().result()
            nxt = next(images, None)
            if nxt is not None:
                pending.append(pool.submit(check, nxt))
            if res is None:
                continue
            decoded.append(view.path)
            t_read += res.t_read
            t_detect += res.t_detect
            views[res.idx] += 1
            hits[res.idx] += res.hit
            crossing_hits[res.idx] += res.hit & crossing[pair_of[res.idx], v]
            if len(res.refine_idx):
                # refine_idx is unique within one view: fancy-index accumulation is exact.
                normal_eq[res.refine_idx] += res.rows[:, :, None] * res.rows[:, None, :]
                rhs[res.refine_idx] += res.rows * res.offsets[:, None]
    need = np.maximum(np.ceil(options.min_hit_ratio * views - 1e-9), 1).astype(np.int32)
    keep = (views >= options.min_views) & (hits >= need)
    keep &= crossing_hits >= options.min_crossing_hits
    kept_pts = pts[keep]
    refined = np.zeros(len(kept_pts), bool)
    if options.refine and keep.any():
        a_mat, b_vec = normal_eq[keep], rhs[keep]
        # Views constrain only the directions across the wire: damp the step along it.
        trace = np.trace(a_mat, axis1=1, axis2=2)
        damp = (1e-3 * trace + 1e-9)[:, None, None] * np.eye(3)
        step = np.linalg.solve(a_mat + damp, b_vec[..., None])[..., 0]
        max_step = 5.0 * height / scene.images[0].focal_px  # five pixels at the wires
        refined = np.linalg.norm(step, axis=1) < max_step
        refined &= hits[keep] >= 2
        kept_pts[refined] += step[refined]
    logger.info(
        "verify: %d of %d primitives kept (%.1f %%), median %d redundant views; "
        "decode %.1f s, wire masks %.1f s (summed over threads)",
        keep.sum(),
        len(pts),
        100 * keep.mean() if len(pts) else 0.0,
        int(np.median(views)) if len(views) else 0,
        t_read,
        t_detect,
    )
    return VerifiedPoints(kept_pts, hits[keep], views[keep], pair_of[keep], refined, decoded)
