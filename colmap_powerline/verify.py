"""Multi-view verification: keep a primitive only where the redundant images see a wire.

Every primitive is projected into every other registered image that sees it; it survives
when it lands on (or within a tolerance of) extracted wire pixels in all of them (the
paper) or in enough of them (options). Each image is decoded and searched for wires once,
only inside the region where primitives project.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from collections import deque
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import cv2
import numpy as np
import numpy.typing as npt
from tqdm import tqdm

from .detect import WireMask
from .geometry import crossing_views, image_axes, image_direction_of_azimuth
from .options import check_limits
from .scene import Scene, SceneImage, read_image
from .triangulate import Primitives

logger = logging.getLogger(__name__)

F64 = npt.NDArray[np.float64]
F32 = npt.NDArray[np.float32]
Mask = npt.NDArray[np.bool_]


@dataclass(kw_only=True)
class VerifyOptions:
    tolerance_px: float = 1.5  # a projection this close to a wire pixel is a hit (px)
    min_posterior: float = 0.99  # a kept primitive is the right match with at least this
    # probability, given the hits and misses of the views that can tell it from a false match
    crossing_offset: float = 0.15  # such a view is offset across the wires by ≥ this × its height
    prior_hit_rate: float = 0.7  # starting guess of a view's hit rate on true wire points;
    # each view's own rate is then estimated from the points it confirms
    refine: bool = True  # move each kept point onto the wire centres of the redundant views
    num_threads: int = 2  # views processed at once (peak memory grows with it)
    margin_px: int = 24  # wire search region: bounding box of the projections plus this margin
    template_length_px: int = 25  # the line template in the views checked: longer than the
    # pairs' (--detect.template_length_px), as the wires' direction there comes from the
    # poses, and a faint wire over soil needs the length (0: the pairs' template)

    LIMITS: ClassVar[dict[str, str]] = {
        "tolerance_px": "(0, 20)",
        "min_posterior": "[0.5, 1)",
        "crossing_offset": "[0, 2)",
        "prior_hit_rate": "(0, 1)",
        "num_threads": ">= 1",
        "margin_px": ">= 0",
        "template_length_px": "0 or >= 3",
    }

    def __post_init__(self) -> None:
        check_limits(self)


@dataclass(frozen=True, eq=False)
class ViewWirePixels:
    """Where one view saw wires: the pixels near a wire pixel in the crop that was searched."""

    view_index: int  # index into ``scene.images``
    x0: int  # the crop's top-left pixel in the image
    y0: int
    shape: tuple[int, int]  # (H, W) of the crop
    packed: npt.NDArray[np.uint8]  # the (H, W) mask, bit-packed (np.packbits)
    direction_deg: float  # the wires' image direction used for the search

    @classmethod
    def pack(
        cls, view_index: int, x0: int, y0: int, mask: npt.NDArray[np.bool_], direction: float
    ) -> ViewWirePixels:
        return cls(view_index, x0, y0, mask.shape, np.packbits(mask, axis=None), direction)

    def near_wire(self) -> npt.NDArray[np.bool_]:
        """(H, W) True within the verification tolerance of a wire pixel."""
        n = self.shape[0] * self.shape[1]
        return np.unpackbits(self.packed, count=n).reshape(self.shape).astype(bool)


@dataclass(frozen=True, eq=False)
class VerifiedPoints:
    """Primitives that passed verification."""

    pts_in_world: F64  # (N, 3)
    hits: npt.NDArray[np.int32]  # (N,) redundant images in which the point lies on a wire
    views: npt.NDArray[np.int32]  # (N,) redundant images that see the point
    crossing_views: npt.NDArray[np.int32]  # (N,) of those, the views offset across the
    # wires from both pair cameras (the only ones that can reject a false match)
    crossing_hits: npt.NDArray[np.int32]  # (N,) crossing views in which it lies on a wire
    posterior: F64  # (N,) probability that the point is a true match
    pair_index: npt.NDArray[np.int32]  # (N,) the pair that produced it
    refined: npt.NDArray[np.bool_]  # (N,) moved onto the wire centres of its views
    decoded: list[Path]  # the images decoded for the verification
    view_hit_rates: F64  # (V,) each view's estimated hit rate on true wire points (NaN:
    # the view saw no confirmed point)
    wire_pixels: list[ViewWirePixels]  # what each searched view saw, for checking whole wires
    primitive_index: npt.NDArray[np.int64]  # (N,) each point's primitive, numbered over all
    # pairs in order
    pending: PendingPoints | None = None  # primitives the views favour, short of sure

    def __len__(self) -> int:
        return len(self.pts_in_world)

    def _appended(self, **more: np.ndarray) -> VerifiedPoints:
        """These points plus more, one array per per-point field (all of them)."""
        return dataclasses.replace(
            self, **{name: np.r_[getattr(self, name), a] for name, a in more.items()}
        )

    def _appended_from(
        self, src: VerifiedPoints | PendingPoints, **given: np.ndarray
    ) -> VerifiedPoints:
        """These points plus ``src``'s (its per-point fields, those ``given`` instead)."""
        names = (
            "pts_in_world", "hits", "views", "crossing_views", "crossing_hits", "posterior",
            "pair_index", "refined", "primitive_index",
        )  # fmt: skip
        return self._appended(**{n: given[n] if n in given else getattr(src, n) for n in names})

    def with_consensus(
        self,
        pts_in_world: F64,
        primitive_index: npt.NDArray[np.int64],
        pair_index: npt.NDArray[np.int32],
    ) -> VerifiedPoints:
        """These points plus primitives kept for lying on a confirmed wire (no posterior of
        their own: NaN; hits and views not counted: 0)."""
        n = len(pts_in_world)
        zeros = np.zeros(n, np.int32)
        return self._appended(
            pts_in_world=pts_in_world,
            hits=zeros,
            views=zeros,
            crossing_views=zeros,
            crossing_hits=zeros,
            posterior=np.full(n, np.nan),
            pair_index=pair_index,
            refined=np.zeros(n, bool),
            primitive_index=primitive_index,
        )

    def with_traced(self, pts_in_world: F64, views: npt.NDArray[np.int32]) -> VerifiedPoints:
        """These points plus points measured along the confirmed wires in the views
        (:mod:`colmap_powerline.trace`): ``views`` agree on each; no pair, primitive or
        posterior of their own (-1, -1, NaN)."""
        n = len(pts_in_world)
        zeros = np.zeros(n, np.int32)
        return self._appended(
            pts_in_world=pts_in_world,
            hits=views.astype(np.int32),
            views=views.astype(np.int32),
            crossing_views=zeros,
            crossing_hits=zeros,
            posterior=np.full(n, np.nan),
            pair_index=np.full(n, -1, np.int32),
            refined=np.ones(n, bool),
            primitive_index=np.full(n, -1, np.int64),
        )

    def concatenated(
        self, other: VerifiedPoints, pair_offset: int, primitive_offset: int
    ) -> VerifiedPoints:
        """These points, then ``other``'s (verified from other pairs: its pair and primitive
        numbers shifted past these). The views' hit rates are the better of the two; the
        wire pixels and pending points stay these (they belong to one set of pairs)."""
        shift_pair = np.where(other.pair_index >= 0, other.pair_index + pair_offset, -1)
        shift_prim = np.where(
            other.primitive_index >= 0, other.primitive_index + primitive_offset, -1
        )
        out = self._appended_from(
            other,
            pair_index=shift_pair.astype(np.int32),
            primitive_index=shift_prim.astype(np.int64),
        )
        return dataclasses.replace(
            out,
            decoded=self.decoded + other.decoded,
            view_hit_rates=np.fmax(self.view_hit_rates, other.view_hit_rates),
        )

    def with_pending(self, take: npt.NDArray[np.int64], min_posterior: float) -> VerifiedPoints:
        """These points plus the pending ones ``take`` (their posterior with the prior 1/2 of
        a point whose match is settled), the other pending points still pending."""
        p = self.pending
        if p is None or len(take) == 0:
            return self
        post = 1 / (1 + np.exp(-np.clip(p.evidence[take], -50, 50)))  # prior 1/2
        assert (post >= min_posterior).all()
        rest = np.ones(len(p), bool)
        rest[take] = False
        taken = p.subset(take)
        out = self._appended_from(taken, posterior=post)
        return dataclasses.replace(out, pending=p.subset(rest) if rest.any() else None)


@dataclass(frozen=True, eq=False)
class PendingPoints:
    """Primitives whose views favour a wire without reaching the posterior on their own."""

    pts_in_world: F64  # (M, 3) refined like the kept points
    evidence: F64  # (M,) log likelihood ratio that it lies on a wire, from every view that
    # sees it (without the match prior: the crossing views did not make it sure)
    hits: npt.NDArray[np.int32]
    views: npt.NDArray[np.int32]
    crossing_views: npt.NDArray[np.int32]
    crossing_hits: npt.NDArray[np.int32]
    pair_index: npt.NDArray[np.int32]
    refined: npt.NDArray[np.bool_]
    primitive_index: npt.NDArray[np.int64]

    def __len__(self) -> int:
        return len(self.pts_in_world)

    def subset(self, keep: npt.NDArray[np.bool_] | npt.NDArray[np.int64]) -> PendingPoints:
        """The points ``keep`` (a mask or indices) selects."""
        return dataclasses.replace(
            self, **{f.name: getattr(self, f.name)[keep] for f in dataclasses.fields(self)}
        )


# Across-wire offsets (px) of the control copies of a point: a hit there is chance (as in
# the held-out image check).
CONTROL_OFFSETS_PX = np.array([-22.0, -18.0, -14.0, -10.0, 10.0, 14.0, 18.0, 22.0])

# A wire detector for one image: (view, image, direction_deg, crop (x0, y0, x1, y1)) → the
# WireMask of the crop.
WireMaskFn = Callable[[SceneImage, np.ndarray, float, tuple[int, int, int, int]], WireMask]


@dataclass(frozen=True, eq=False)
class _ViewResult:
    idx: npt.NDArray[np.int64]  # primitives this view sees
    hit: npt.NDArray[np.bool_]  # which of them land on a wire
    chance: F64  # the chance of a hit by accident at each of them
    refine_idx: npt.NDArray[np.int64]  # primitives with a wire-centre observation here
    rows: F64  # (n, 3) their observation rows (d offset / d point)
    offsets: F64  # (n,) their across-wire offsets to the wire centre (px)
    wire_pixels: ViewWirePixels
    t_read: float
    t_detect: float


def image_wire_direction_deg(view: SceneImage, pt_in_world: F64, azimuth_deg: float) -> float:
    """Direction (degrees, 0 = +x, 90 = +y i.e. down) of a horizontal line of the given
    azimuth through ``pt_in_world`` in the image."""
    return image_direction_of_azimuth(lambda p: view.project(p)[0], pt_in_world, azimuth_deg)


def samples_across(image: np.ndarray, uv: F64, normal: F64, steps: F64) -> F64:
    """(N, len(steps)) ``image`` sampled (bilinear, edges replicated) at ``uv + steps *
    normal`` (pixel-centre coordinates, COLMAP's convention; ``normal``: (2,) or one per
    point (N, 2))."""
    if len(uv) == 0:
        return np.zeros((0, len(steps)))
    normal = np.asarray(normal, np.float64)
    across = normal[None, None, :] if normal.ndim == 1 else normal[:, None, :]  # one or (N, 2)
    xy = uv[:, None, :] - 0.5 + steps[None, :, None] * across  # array index coordinates
    flat = xy.reshape(-1, 2).astype(np.float32)
    width = 4096  # cv2.remap maps must stay below 32767 px a side
    pad = (-len(flat)) % width
    flat = np.concatenate([flat, np.zeros((pad, 2), np.float32)]).reshape(-1, width, 2)
    sampled = cv2.remap(
        image.astype(np.float32),
        flat[..., 0],
        flat[..., 1],
        cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_REPLICATE,
    )
    return sampled.ravel()[: xy.shape[0] * xy.shape[1]].reshape(xy.shape[:2]).astype(np.float64)


def _wire_offsets(response: np.ndarray, uv: F64, normal: F64, reach: float) -> F64:
    """Signed distance (px, along ``normal``: (2,) or one per point (N, 2)) from each point
    to the wire centre near it.

    The template response is sampled across the wire at whole-pixel steps; the centre is the
    parabola vertex through the strongest sample and its neighbours. NaN when the strongest
    sample is at the end of the reach (no peak there).
    """
    steps = np.arange(-np.ceil(reach), np.ceil(reach) + 1)
    samples = samples_across(np.abs(response), uv, normal, steps)
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


def _match_prior(primitives: Sequence[Primitives]) -> F64:
    """(N,) prior probability that each primitive is the right match.

    A wire centre of the left image is matched with every centre of its right row within
    the disparity range: at most one of those K candidates is right (and the same holds
    from the right image's side), so each has a prior of 1 / K, at most 1/2.
    """
    out = []
    for p in primitives:
        k = np.ones(len(p))
        for u in (p.u_left, p.u_right):
            _, inverse, counts = np.unique(
                np.c_[p.v, u], axis=0, return_inverse=True, return_counts=True
            )
            k = np.maximum(k, counts[inverse.ravel()])
        # A centre alone on its row may still be texture: never more likely than not.
        out.append(np.minimum(1.0 / k, 0.5))
    return np.concatenate(out) if out else np.zeros(0)


def _log_likelihood_ratio(hit: npt.NDArray[np.bool_], chance: F64, hit_rate: float) -> F64:
    """Evidence (natural log) that points are on a wire rather than off it, per observation.

    A true point lands on a wire pixel with the view's hit rate; a false one by chance, at
    the density of wire pixels around it. A hit never counts against a point, nor a miss for
    it.
    """
    p0 = np.clip(chance.astype(np.float64), 1e-3, 0.95)
    p1 = np.maximum(hit_rate, p0 + 0.02)
    return np.where(hit, np.log(p1 / p0), np.log((1 - p1) / (1 - p0)))


def verify_primitives(
    scene: Scene,
    primitives: Sequence[Primitives],
    pair_images: Sequence[tuple[str, str]],
    wire_mask: WireMaskFn,
    azimuth_deg: float,
    options: VerifyOptions | None = None,
    show_progress: bool = True,
    min_height_above_ground: float = 0.0,
) -> VerifiedPoints:
    """Check every primitive against the wire pixels of the redundant images.

    Each view that sees a primitive either lands on a wire pixel (a hit) or not. Only views
    offset across the wires from both cameras of the primitive's pair can tell a false match
    from a true one (:func:`crossing_views`); their hits and misses are weighed as a
    likelihood ratio — a true point hits with the view's hit rate, estimated from the data,
    a false one with the local density of wire pixels — and combined with the prior that
    one of the K candidates of a wire centre is right. A primitive is kept when its
    posterior probability reaches ``options.min_posterior``.

    Args:
        scene: the oriented scene.
        primitives: the candidates of each pair (``primitives[k].pair_index`` = k).
        pair_images: (left name, right name) of each pair: these images do not vote on the
            primitives they produced.
        wire_mask: the detector, called once per image on the region where primitives land.
        azimuth_deg: the wires' horizontal direction, turned into each image's direction.
        min_height_above_ground: the views' hit rates on true wires are measured on the
            confirmed points at least this high above the ground (not on road markings).
    """
    options = options or VerifyOptions()
    if not primitives:
        raise ValueError("no primitives to verify")
    pts = np.concatenate([p.pts_in_world for p in primitives])
    pair_of = np.concatenate([np.full(len(p), k, np.int32) for k, p in enumerate(primitives)])
    by_name = {im.name: im for im in scene.images}
    pair_centres = np.array(
        [[by_name[a].center_in_world, by_name[b].center_in_world] for a, b in pair_images]
    ).reshape(-1, 2, 3)
    height = float(np.median(scene.centers_in_world[:, 2]) - np.median(pts[:, 2]))
    crossing = crossing_views(
        scene.centers_in_world, pair_centres, azimuth_deg, height, options.crossing_offset
    )  # (P, V)
    normal_eq = np.zeros((len(pts) if options.refine else 0, 3, 3))
    rhs = np.zeros((len(pts) if options.refine else 0, 3))

    def check(v: int, view: SceneImage) -> _ViewResult | None:
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
        near_wire = wires.dilated(options.tolerance_px)
        hit = near_wire[px[:, 1] - y0, px[:, 0] - x0]
        # The chance of a hit by accident: the same test on copies of the point displaced
        # across the wire direction, shrunk towards the crop's wire-pixel density.
        normal = image_axes(direction)[1]
        shifted = (uv - [x0, y0])[:, None, :] + CONTROL_OFFSETS_PX[None, :, None] * normal
        sx = np.clip(np.floor(shifted[..., 0]).astype(np.int64), 0, near_wire.shape[1] - 1)
        sy = np.clip(np.floor(shifted[..., 1]).astype(np.int64), 0, near_wire.shape[0] - 1)
        n_ctrl = len(CONTROL_OFFSETS_PX)
        chance = (near_wire[sy, sx].sum(axis=1) + n_ctrl * near_wire.mean()) / (2 * n_ctrl)
        t_detect = time.perf_counter() - t0
        hid = idx[hit] if options.refine else np.zeros(0, np.int64)
        rows = offset = np.zeros(0)
        if options.refine and hit.any():
            # One Gauss-Newton observation per hit: the across-wire offset to the centre.
            offset = _wire_offsets(
                wires.response, uv[hit] - [x0, y0], normal, options.tolerance_px + 1
            )
            ok = np.isfinite(offset)
            hid, offset = hid[ok], offset[ok]
            rows = np.einsum("j,njk->nk", normal, _projection_jacobian(view, pts[hid]))
        pixels = ViewWirePixels.pack(v, x0, y0, near_wire, direction)
        return _ViewResult(idx, hit, chance, hid, rows, offset, pixels, t_read, t_detect)

    t_detect = t_read = 0.0
    decoded: list[Path] = []
    wire_pixels: list[ViewWirePixels] = []
    # Per view: (view index, primitives seen, hit, chance, crossing); kept to weigh them once
    # every view's hit rate is known.
    observations: list[tuple[int, npt.NDArray[np.int64], npt.NDArray[np.bool_], F64, Mask]] = []
    # Two views at a time: decoding, filtering and projecting release the GIL.
    with ThreadPoolExecutor(max_workers=options.num_threads) as pool:
        # A short queue of views in flight keeps memory to a few views' results.
        pending: deque = deque()
        images = iter(enumerate(scene.images))
        for _ in range(options.num_threads + 1):
            view0 = next(images, None)
            if view0 is not None:
                pending.append(pool.submit(check, *view0))
        for v, view in enumerate(
            tqdm(scene.images, desc="verify", unit="img", disable=not show_progress)
        ):
            res = pending.popleft().result()
            nxt = next(images, None)
            if nxt is not None:
                pending.append(pool.submit(check, *nxt))
            if res is None:
                continue
            decoded.append(view.path)
            wire_pixels.append(res.wire_pixels)
            t_read += res.t_read
            t_detect += res.t_detect
            observations.append(
                (v, res.idx.astype(np.int64), res.hit, res.chance, crossing[pair_of[res.idx], v])
            )
            if len(res.refine_idx):
                # refine_idx is unique within one view: fancy-index accumulation is exact.
                normal_eq[res.refine_idx] += res.rows[:, :, None] * res.rows[:, None, :]
                rhs[res.refine_idx] += res.rows * res.offsets[:, None]

    views = np.zeros(len(pts), np.int32)
    hits = np.zeros(len(pts), np.int32)
    n_crossing = np.zeros(len(pts), np.int32)
    crossing_hits = np.zeros(len(pts), np.int32)
    for _, idx, hit, _, cross in observations:
        views[idx] += 1
        hits[idx] += hit
        n_crossing[idx] += cross
        crossing_hits[idx] += hit & cross
    prior = _match_prior(primitives)
    prior_logit = np.log(prior) - np.log1p(-np.minimum(prior, 1 - 1e-9))
    hit_rate = np.full(len(scene.images), options.prior_hit_rate)

    # Where no view can tell (only two strips see the wires), the views along the wires
    # still tell wire points from texture and, where the wires slope towards their supports,
    # from false pairings; whole wires are judged afterwards (support).
    weak = n_crossing == 0

    def summed_evidence(telling_only: bool) -> F64:
        """Each point's evidence from the views that can tell it from a false pairing
        (``telling_only``), or from every view that sees it: on a wire already confirmed
        as a whole, whether it is a false pairing is settled."""
        evidence = np.zeros(len(pts))
        for v, idx, hit, chance, cross in observations:
            use = cross | weak[idx] if telling_only else np.ones(len(idx), bool)
            llr = _log_likelihood_ratio(hit[use], chance[use], hit_rate[v])
            np.add.at(evidence, idx[use], llr)
        return evidence

    def posterior() -> F64:
        logit = prior_logit + summed_evidence(telling_only=True)
        return 1.0 / (1.0 + np.exp(-np.clip(logit, -50, 50)))

    # Each view's hit rate on true points, from the points the other views confirm.
    post = posterior()
    for _ in range(2):
        # Only the few sure points need their height above the ground (not every primitive).
        confident = post > options.min_posterior
        sure = np.flatnonzero(confident)
        low = pts[sure, 2] - scene.ground_height(pts[sure, :2]) < min_height_above_ground
        confident[sure[low]] = False
        rates = np.full(len(scene.images), np.nan)
        for v, idx, hit, _, _ in observations:
            sure = confident[idx]
            if sure.sum() >= 30:
                rates[v] = float(hit[sure].mean())
        hit_rate = np.where(np.isfinite(rates), np.clip(rates, 0.05, 0.99), options.prior_hit_rate)
        post = posterior()
    keep = post >= options.min_posterior
    # Points that every view seeing them favours, short of sure: on a wire confirmed as a
    # whole (support) only whether they lie on a wire is in question, prior 1/2 (see
    # pipeline). Crossing views that cannot see a faint wire (textured ground, image edge)
    # no longer outvote the views that do.
    evidence = summed_evidence(telling_only=False)
    pending = ~keep & (evidence > 0) & (hits >= 2)

    def refine(sel: Mask) -> tuple[F64, Mask]:
        out = pts[sel]
        moved = np.zeros(len(out), bool)
        if options.refine and sel.any():
            a_mat, b_vec = normal_eq[sel], rhs[sel]
            # Views constrain only the directions across the wire: damp the step along it.
            trace = np.trace(a_mat, axis1=1, axis2=2)
            damp = (1e-3 * trace + 1e-9)[:, None, None] * np.eye(3)
            step = np.linalg.solve(a_mat + damp, b_vec[..., None])[..., 0]
            max_step = 5.0 * height / scene.images[0].focal_px  # five pixels at the wires
            moved = (np.linalg.norm(step, axis=1) < max_step) & (hits[sel] >= 2)
            out[moved] += step[moved]
        return out, moved

    kept_pts, refined = refine(keep)
    pending_pts, pending_refined = refine(pending)
    logger.info(
        "verify: %d of %d primitives kept (%.1f %%; posterior ≥ %.2f), median %d redundant "
        "views of which %d cross; hit rate of the views on true points %s; decode %.1f s, "
        "wire masks %.1f s (summed over threads)",
        keep.sum(),
        len(pts),
        100 * keep.mean() if len(pts) else 0.0,
        options.min_posterior,
        int(np.median(views)) if len(views) else 0,
        int(np.median(n_crossing)) if len(views) else 0,
        np.round(np.nanquantile(rates, [0.1, 0.5, 0.9]), 2).tolist()
        if np.isfinite(rates).any()
        else "unknown",
        t_read,
        t_detect,
    )
    return VerifiedPoints(
        kept_pts,
        hits[keep],
        views[keep],
        n_crossing[keep],
        crossing_hits[keep],
        post[keep],
        pair_of[keep],
        refined,
        decoded,
        rates,
        wire_pixels,
        np.flatnonzero(keep),
        PendingPoints(
            pending_pts,
            evidence[pending],
            hits[pending],
            views[pending],
            n_crossing[pending],
            crossing_hits[pending],
            pair_of[pending],
            pending_refined,
            np.flatnonzero(pending),
        ),
    )
