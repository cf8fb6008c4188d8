"""Pair selection: find where the wires run, then pick image pairs whose baseline crosses them.

The paper picked its epipolar pairs by hand. Here the wires' horizontal direction and
corridor are estimated from 2D line evidence in a few images, turned into the world frame
with the poses (or the direction is given by the user), and every overlapping pair is
scored: crossing angle between baseline and wires (90° best, parallel useless), base/height
ratio, and how much of the wire corridor both images cover. The best few pairs that
together cover the span are kept.
"""

from __future__ import annotations

import dataclasses
import functools
import logging
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import cv2
import numpy as np
import numpy.typing as npt

from .errors import InputError
from .geometry import (
    across_of,
    axial_diff_deg,
    axial_mean_deg,
    azimuth_deg_of,
    crossing_views,
    image_axes,
    image_direction_of_azimuth,
    plan_axes,
)
from .options import OptionError, check_limits
from .scene import Scene, SceneImage, read_image

logger = logging.getLogger(__name__)

F64 = npt.NDArray[np.float64]


@dataclass(kw_only=True)
class PairsOptions:
    wire_azimuth_deg: float | None = None  # the wires' direction, clockwise from +y; None: estimate
    candidate_tolerance_deg: float = 2.5  # image directions this close form one candidate
    # (a road and the line beside it may differ by only a few degrees)
    max_candidates: int = 5  # candidate directions found in the images
    line_tolerance_deg: float = 5.0  # wires measured this far from a found line's direction
    # are another line (or leg of a line turning at an angle tower): the wires' planes give
    # their direction to under 1°, and a turn of less keeps the next leg in the corridor
    # (5° over 170 m is 15 m, the corridor's margin)
    probe_candidates: int = 5  # of those, the strongest this many are probed in 3D (wires
    # are thin: their image lines are often weaker than a road's or a field's)
    probe_pairs: int = 4  # pairs triangulated and verified to probe a direction
    probe_views: int = 8  # the views nearest those pairs that verify the probe
    probe_bands: int = 2  # bands across a direction probed: the densest, and all of them
    # (a road may outdo the wires; a few metres of something in the densest band must not
    # stop the wider probe)
    num_direction_images: int = 6  # images used to estimate the direction and corridor
    # (when no direction they give has wires, 1.5 √N of the N images, 6-24, are read and
    # ranked alike at every angle: a line crossing an area survey is seen by a share of its
    # images that falls as 1/√N)
    analysis_width_px: int = 800  # those images are analysed at about this width
    scan_step_deg: float = 3.0  # orientation scan step
    template_length_frac: float = 0.04  # line template length as a share of the analysis width
    corridor_margin: float = 15.0  # added to each side of the estimated corridor (model units)
    min_crossing_deg: float = (
        45.0  # pairs whose baseline is closer to the wire direction are useless
    )
    min_base_height: float = 0.15  # base/height ratio range of useful pairs
    max_base_height: float = 1.6
    target_base_height: float = 0.7  # ratios beyond this gain no score
    max_pairs: int = 30  # pairs used at most (fewer when they already cover the corridor)
    pairs_per_point: int = 2  # how many pairs should cover each part of the corridor
    border_margin_frac: float = 0.05  # corridor points this close to an image border do not count

    LIMITS: ClassVar[dict[str, str]] = {
        "candidate_tolerance_deg": "(0, 45]",
        "max_candidates": ">= 1",
        "line_tolerance_deg": "(0, 90)",
        "probe_candidates": ">= 1",
        "probe_pairs": ">= 1",
        "probe_views": ">= 0",
        "probe_bands": "1 or 2",
        "num_direction_images": ">= 1",
        "analysis_width_px": ">= 100",
        "scan_step_deg": "(0, 45]",
        "template_length_frac": "(0, 0.5]",
        "corridor_margin": ">= 0",
        "min_crossing_deg": "[0, 90]",
        "min_base_height": "> 0",
        "max_base_height": "> 0",
        "target_base_height": "> 0",
        "max_pairs": ">= 1",
        "pairs_per_point": ">= 1",
        "border_margin_frac": "[0, 0.5)",
    }

    def __post_init__(self) -> None:
        check_limits(self)
        if not self.max_base_height > self.min_base_height:
            raise OptionError(
                "max_base_height",
                self.max_base_height,
                f"> min_base_height ({self.min_base_height})",
            )


@dataclass(frozen=True)
class WireCorridor:
    """Where the wires are, in plan: a band along ``azimuth_deg`` through ``centre_xy``."""

    azimuth_deg: float
    centre_xy: F64  # (2,) a point on the corridor's centre line
    half_width: float  # model units, with the margin
    wires_half_width: float  # half the width of the band where the wires were seen
    s_range: tuple[float, float]  # extent along the line from centre_xy
    height: float  # absolute height of the corridor's centre line (model units)
    height_range: tuple[float, float]  # absolute heights between which the wires hang
    from_images: bool  # False when the direction was given by the user
    measured: bool  # True when band and heights come from wire points measured in 3D
    decoded: tuple[Path, ...] = ()  # the images decoded for the estimate

    @property
    def direction_xy(self) -> F64:
        return plan_axes(self.azimuth_deg)[0]

    @property
    def normal_xy(self) -> F64:
        return across_of(self.direction_xy)

    def sample_points(self, step: float = 1.0, margin: float = 5.0) -> F64:
        """(2, N, 3) points on five lines along the wire band (its width plus ``margin``), at
        the lowest and at the highest wire height: a place counts as seen when both are."""
        line = self.centreline(step)
        w = self.wires_half_width + margin
        flat = np.concatenate(
            [line + np.r_[k * w * self.normal_xy, 0.0] for k in (-1, -0.5, 0, 0.5, 1)]
        )
        return np.stack([np.c_[flat[:, :2], np.full(len(flat), z)] for z in self.height_range])

    def centreline(self, step: float = 1.0) -> F64:
        """(N, 3) points along the corridor's centre line at the corridor height."""
        s = np.arange(self.s_range[0], self.s_range[1] + 1e-9, step)
        xy = self.centre_xy + s[:, None] * self.direction_xy
        return np.c_[xy, np.full(len(s), self.height)]


@dataclass(frozen=True)
class ImagePair:
    left: SceneImage
    right: SceneImage
    crossing_deg: float  # angle between the baseline and the wires in plan (90 = perpendicular)
    base_height: float  # baseline / height above the ground
    coverage: float  # length of the corridor both images see (model units)
    score: float

    def __str__(self) -> str:
        return (
            f"{self.left.name}|{self.right.name}: crossing {self.crossing_deg:.0f}°, "
            f"B/H {self.base_height:.2f}, corridor {self.coverage:.0f}, score {self.score:.1f}"
        )


def _oriented_response(
    gray: npt.NDArray[np.float32], angle_deg: float, length_px: int, along_step: int = 1
) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float64]]:
    """|line template| response with lines of direction ``angle_deg`` turned vertical.

    Only the central disc (which stays inside the image at every rotation) is kept, so all
    directions are judged on the same pixels. Returns the (H, W) response in the rotated
    frame (0 outside the disc) and the 2x3 affine transform from the image to that frame.

    ``along_step``: the rotated image is sampled every this many pixels along the lines
    (H / along_step rows). A line turned vertical crosses every row, so it keeps its full
    contrast across, which shrinking the image across would average away (a 0.5 px wire at
    a fifth of the width); the template still spans ``length_px`` along it.
    """
    h, w = gray.shape
    rot = cv2.getRotationMatrix2D((w / 2, h / 2), angle_deg - 90.0, 1.0)
    out_h = h
    if along_step > 1:
        out_h = -(-h // along_step)
        rot[1] = (rot[1] - [0.0, 0.0, (along_step - 1) / 2]) / along_step
    img = cv2.warpAffine(
        gray, rot, (w, out_h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
    )
    across = 2 * img - np.roll(img, 1, axis=1) - np.roll(img, -1, axis=1)
    resp = np.abs(cv2.blur(across, (1, max(1, round(length_px / along_step)))))
    resp[~_disc(gray.shape, length_px, along_step)] = 0
    return resp, rot


def _line_energy(
    gray: npt.NDArray[np.float32],
    angle_deg: float,
    length_px: int,
    fair: bool = False,
    along_step: int = 1,
) -> float:
    """How strongly long thin lines of one image direction stand out: the top 0.2 % of the
    response (``fair``: of the central disc's, over its median there).

    Rotating by anything but a right angle interpolates, which smooths the whole response,
    so the top share alone favours the image axes a little — where flights along or across
    the line put the wires (faint at the analysis width, they rank high there partly by it).
    Over the median, what long lines add to the texture counts alike at every angle: an
    area survey's line at 70° to its strips, which a few of its images see, ranks above the
    image axes (shared grid seed 3), but a flight across loses its wires (shared cross
    seed 1)."""
    resp, _ = _oriented_response(gray, angle_deg, length_px, along_step)
    if not fair:
        flat = resp.ravel()  # (the disc's outside is 0)
        k = max(flat.size // 500, 10)
        return float(np.partition(flat, flat.size - k)[-k:].mean())
    inside = resp[_disc(gray.shape, length_px, along_step)]
    k = max(inside.size // 500, 10)
    top = float(np.partition(inside, inside.size - k)[-k:].mean())
    sample = inside[::7]
    median = float(np.partition(sample, sample.size // 2)[sample.size // 2])
    return top / max(median, 1e-6)


@functools.lru_cache(maxsize=4)
def _disc(shape: tuple[int, ...], length_px: int, along_step: int = 1) -> npt.NDArray[np.bool_]:
    """The central disc that stays inside the image at every rotation (in the rotated frame
    sampled every ``along_step`` rows)."""
    h, w = shape[:2]
    if along_step > 1:
        yy = np.arange(-(-h // along_step))[:, None] * along_step + (along_step - 1) / 2
        xx = np.arange(w)[None, :]
    else:
        yy, xx = np.ogrid[:h, :w]
    radius = min(h, w) / 2 - length_px
    return np.asarray((xx - w / 2) ** 2 + (yy - h / 2) ** 2 <= radius**2)


def _image_directions(
    gray: npt.NDArray[np.float32],
    options: PairsOptions,
    num_peaks: int = 3,
    fair: bool = False,
    along_step: int = 1,
) -> list[tuple[float, float]]:
    """The strongest thin-line directions of an image (degrees, 0 = +x, 90 = down), each with
    its contrast against the median direction, strongest first (``fair``: see
    :func:`_line_energy`; ``along_step``: :func:`_oriented_response`)."""
    length = max(int(options.template_length_frac * gray.shape[1]), 9)
    # Rotating by anything but a right angle interpolates, which smooths: smooth every
    # direction alike first, or the image axes stand out on plain texture.
    gray = cv2.GaussianBlur(gray, (0, 0), 0.7)
    angles = np.arange(0.0, 180.0, options.scan_step_deg)
    energy = np.array([_line_energy(gray, a, length, fair, along_step) for a in angles])
    median = max(float(np.median(energy)), 1e-9)
    peaks = [
        k
        for k in range(len(angles))
        if energy[k] >= energy[k - 1] and energy[k] >= energy[(k + 1) % len(angles)]
    ]
    peaks = sorted(peaks, key=lambda k: -energy[k])[:num_peaks]
    out = []
    for k in peaks:
        fine = angles[k] + np.arange(-options.scan_step_deg, options.scan_step_deg + 1e-9, 0.5)
        fine_energy = np.array([_line_energy(gray, a, length, fair, along_step) for a in fine])
        out.append((float(fine[int(np.argmax(fine_energy))] % 180.0), float(energy[k] / median)))
    return out


def _line_pixels(
    view: SceneImage,
    gray: npt.NDArray[np.float32],
    factor: int,
    angle: float,
    options: PairsOptions,
) -> F64:
    """(N, 2) full-resolution pixels of the strongest lines along ``angle`` in an image."""
    length = max(int(options.template_length_frac * gray.shape[1]), 9)
    resp, rot = _oriented_response(gray, angle, length)
    ys, xs = np.nonzero(resp >= np.quantile(resp, 0.998))
    pts = np.c_[xs, ys, np.ones(len(xs))] @ cv2.invertAffineTransform(rot).T
    return (pts + 0.5) * factor


def _world_azimuth(view: SceneImage, angle: float, height: float) -> float:
    """Image direction at the image centre → azimuth of a horizontal line at ``height``."""
    c_px = np.array([view.width / 2, view.height / 2])
    step = 0.05 * view.width * image_axes(angle)[0]
    xy = _to_plane(view, np.stack([c_px - step, c_px + step]), height)
    return azimuth_deg_of(xy[1] - xy[0])


def _image_angle(view: SceneImage, azimuth: float, height: float) -> float:
    """Azimuth of a horizontal line at ``height`` → its image direction near the image centre."""
    c_px = np.array([[view.width / 2, view.height / 2]])
    centre = np.r_[_to_plane(view, c_px, height)[0], height]
    return image_direction_of_azimuth(lambda p: view.project(p)[0], centre, azimuth)


def _to_plane(view: SceneImage, uv: F64, z: float) -> F64:
    """(N, 2) pixels → (N, 2) plan positions where their rays cross the height ``z``."""
    rays = view.rays_in_world(uv)
    c = view.center_in_world
    t = (z - c[2]) / np.where(np.abs(rays[:, 2]) > 1e-9, rays[:, 2], -1e-9)
    return c[:2] + t[:, None] * rays[:, :2]


def _footprint_across(view: SceneImage, normal: F64, z: float) -> float:
    """How wide the image's footprint at the height ``z`` is along ``normal``."""
    w, h = view.width, view.height
    corners = np.array([[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]])
    return float(np.ptp(_to_plane(view, corners, z) @ normal))


def _pick_spread(scene: Scene, n: int) -> list[SceneImage]:
    """Up to ``n`` images spread over the flight (farthest-point sampling of centres)."""
    centres = scene.centers_in_world[:, :2]
    chosen = [int(np.argmin(np.linalg.norm(centres - centres.mean(axis=0), axis=1)))]
    dist = np.linalg.norm(centres - centres[chosen[0]], axis=1)
    while len(chosen) < min(n, len(centres)):
        k = int(np.argmax(dist))
        chosen.append(k)
        dist = np.minimum(dist, np.linalg.norm(centres - centres[k], axis=1))
    return [scene.images[k] for k in chosen]


def _ranked_directions(
    azimuths: F64, contrast: F64, tolerance_deg: float, most: int
) -> list[tuple[float, float]]:
    """Up to ``most`` (azimuth, weight) directions the images' line peaks (``azimuths``,
    each with its ``contrast`` against its image's median direction) agree on, strongest
    first: repeatedly the peak with the most weight within ``tolerance_deg`` of it (mod
    180), its neighbours' mean, and those peaks set aside.

    A peak weighs what its lines add to its image's typical direction (contrast 1: nothing):
    many images' peaks at the texture's level outvoted a line that one image shows plainly
    (shared grid seed 6: its 70°, twice the median in the one image that sees it well,
    ranked 22nd by contrast; 9th so). A direction's azimuth is its members' mean weighted
    by their contrast."""
    weights = np.maximum(contrast - 1.0, 0.0)
    close = axial_diff_deg(azimuths[:, None], azimuths[None, :]) < tolerance_deg
    cands: list[tuple[float, float]] = []
    remaining = np.ones(len(azimuths), bool)
    while remaining.any() and len(cands) < most:
        left = np.flatnonzero(remaining)
        support = close[np.ix_(left, left)] @ weights[left]
        best = left[int(np.argmax(support))]
        if support.max() <= 0.0:
            break  # only peaks that add nothing are left
        members = remaining & close[best]
        cand = axial_mean_deg(azimuths[members], contrast[members])
        near = axial_diff_deg(azimuths, cand) < tolerance_deg
        cands.append((cand, float(weights[near & remaining].sum())))
        remaining &= ~near
    return cands


@dataclass(frozen=True, eq=False)
class DirectionCandidates:
    """Line directions that several images agree on, strongest first, and the images read."""

    azimuths_deg: tuple[float, ...]
    weights: tuple[float, ...]  # what the agreeing images' lines add (contrast - 1, summed)
    analysed: tuple[tuple[SceneImage, F64, int], ...]  # (view, grey image, downscale factor)
    ground_z: float  # median ground height under the cameras
    flying_height: float  # median camera height above that ground

    @property
    def decoded(self) -> tuple[Path, ...]:
        return tuple(v.path for v, _, _ in self.analysed)


# The wider look (when no direction of the first has wires) takes more directions per image
# and more candidates: the line is seen by a few of the images read, where roads, field edges
# and the strips' image axes outdo it (shared grid seeds 3 and 4: its 70° ranks 2nd-6th in
# the images that see it, 5th of the candidates).
WIDE_PEAKS = 5
WIDE_CANDIDATES = 2
# When the wider look's first candidates have no line either, the probes go on down its
# list, up to this many times ``max_candidates`` in all (shared grid seeds 4 and 6: roads'
# and field edges' directions rank first, the line's 70° 6th and 9th): an area survey's
# line is looked for before the run gives up on it.
LOST_CANDIDATES = 4


def direction_candidates(
    scene: Scene,
    options: PairsOptions | None = None,
    wide: bool = False,
    read: Sequence[tuple[SceneImage, F64, int]] = (),
) -> DirectionCandidates:
    """Long thin image lines → horizontal directions in the world that several images share.

    Wires are among them, but so are roads, field rows, shadows and field edges; which one is
    the wires is decided in 3D (:func:`colmap_powerline.pipeline.probe_corridor`). A given
    ``wire_azimuth_deg`` is the only candidate. ``wide``: 1.5 √N images (6-24) instead of
    ``num_direction_images``, each direction ranked alike at every angle (see
    :func:`_line_energy`), ``WIDE_PEAKS`` directions per image, ``LOST_CANDIDATES`` times
    ``max_candidates``. ``read``: images already analysed (``analysed`` of a first look),
    not decoded again.
    """
    options = options or PairsOptions()
    ground_z = float(np.median(scene.ground_height(scene.centers_in_world[:, :2])))
    flying = float(np.median(scene.centers_in_world[:, 2])) - ground_z
    height = ground_z + 0.3 * flying  # for image directions only (nadir: hardly matters)
    n_views = options.num_direction_images
    if wide:
        n_views = max(n_views, int(np.clip(round(1.5 * np.sqrt(len(scene.images))), 6, 24)))
    views = _pick_spread(scene, n_views)
    analysed = []
    azimuths, contrasts = [], []
    known = {v.name: (g, f) for v, g, f in read if not wide or f == 1}
    for view in views:
        if view.name in known:
            gray, factor = known[view.name]
        elif wide:
            # At full resolution: a thin conductor is half a pixel wide or less there (a
            # distribution line's 10-25 mm at 4-7 cm per pixel), and any shrinking across
            # averages it into the texture (shared twolines seed 7: the pole line's
            # direction is among an image's five strongest at 2000 px, not at 800).
            gray, factor = read_image(view.path, cv2.IMREAD_GRAYSCALE).astype(np.float32), 1
        else:
            raw = read_image(view.path, cv2.IMREAD_GRAYSCALE)
            factor = max(1, int(round(raw.shape[1] / options.analysis_width_px)))
            gray = cv2.resize(
                raw, (raw.shape[1] // factor, raw.shape[0] // factor), interpolation=cv2.INTER_AREA
            ).astype(np.float32)
        analysed.append((view, gray, factor))
        if options.wire_azimuth_deg is None:
            peaks = WIDE_PEAKS if wide else 3
            # Sampled along the lines at 1/16 of the template (the wide look reads full
            # resolution: 16 samples along are as good as all of them, at a fraction).
            step = max(1, int(options.template_length_frac * gray.shape[1]) // 16) if wide else 1
            for angle, contrast in _image_directions(gray, options, peaks, wide, step):
                azimuths.append(_world_azimuth(view, angle, height))
                contrasts.append(contrast)
    if options.wire_azimuth_deg is not None:
        cands = [(float(options.wire_azimuth_deg) % 180.0, 1.0)]
    else:
        most = LOST_CANDIDATES * options.max_candidates if wide else options.max_candidates
        cands = _ranked_directions(
            np.asarray(azimuths), np.asarray(contrasts), options.candidate_tolerance_deg, most
        )
    if not cands:
        raise InputError(
            f"{scene.image_path}: no long straight line found in the images; "
            "give the wires' direction with --pairs.wire_azimuth_deg"
        )
    logger.info(
        "line directions seen by several images (azimuth, weight): %s",
        [(round(a, 1), round(w, 1)) for a, w in cands],
    )
    return DirectionCandidates(
        tuple(a for a, _ in cands),
        tuple(w for _, w in cands),
        tuple(analysed),
        ground_z,
        flying,
    )


# How far around a support its images are read for lines leaving it (model units): a
# branch line's first span or more.
NEAR_SUPPORT_M = 30.0


def directions_near(
    scene: Scene, top: F64, ground_z: float, options: PairsOptions
) -> tuple[list[tuple[float, float]], list[Path]]:
    """The horizontal directions of the long thin lines around a support (``top``: its
    highest attachment; ``ground_z``: the ground under it), (azimuth, weight) strongest
    first, and the images read.

    The images that see the support from its foot to its top, up to
    ``num_direction_images`` of them whose centres lie nearest it, are read at full
    resolution within ``NEAR_SUPPORT_M`` of it, and their directions ranked as the wider look
    ranks an image's (:func:`direction_candidates`), the template as long in pixels as
    there. Around a support, the lines that leave it are a large share of what the images
    show: the road flight's line across the field, 2 wires of ~10 mm, is the second direction
    around the pole it leaves and twenty-somethingth over the whole survey."""
    pts = np.array([top, [top[0], top[1], ground_z]])
    seeing = []
    for view in scene.images:
        uv, depth, ok = view.project(pts)
        margin = 0.05 * view.width
        if ok.all() and (
            (uv[:, 0] > margin).all()
            and (uv[:, 0] < view.width - margin).all()
            and (uv[:, 1] > margin).all()
            and (uv[:, 1] < view.height - margin).all()
        ):
            seeing.append((float(np.hypot(*(view.center_in_world[:2] - top[:2]))), view, uv, depth))
    seeing.sort(key=lambda t: t[0])
    azimuths, contrasts, read = [], [], []
    for _, view, uv, depth in seeing[: options.num_direction_images]:
        r = int(view.focal_px * NEAR_SUPPORT_M / depth[0])
        c = np.round(uv[0]).astype(int)
        x0, x1 = max(c[0] - r, 0), min(c[0] + r, view.width)
        y0, y1 = max(c[1] - r, 0), min(c[1] + r, view.height)
        gray = read_image(view.path, cv2.IMREAD_GRAYSCALE)[y0:y1, x0:x1].astype(np.float32)
        read.append(view.path)
        # The template as long (in pixels) as the wider look's on the whole image.
        crop_options = dataclasses.replace(
            options, template_length_frac=options.template_length_frac * view.width / gray.shape[1]
        )
        step = max(1, int(crop_options.template_length_frac * gray.shape[1]) // 16)
        for angle, contrast in _image_directions(gray, crop_options, WIDE_PEAKS, True, step):
            azimuths.append(_world_azimuth(view, angle, float(top[2])))
            contrasts.append(contrast)
    if not azimuths:
        return [], read
    return _ranked_directions(
        np.asarray(azimuths), np.asarray(contrasts), options.candidate_tolerance_deg,
        LOST_CANDIDATES * options.max_candidates,
    ), read  # fmt: skip


def anchored_corridor(
    scene: Scene,
    azimuth: float,
    at_xy: F64,
    half_width: float,
    z: float,
    height_range: tuple[float, float],
    options: PairsOptions,
) -> WireCorridor:
    """A provisional band of ``half_width`` either side of a line in direction ``azimuth``
    through plan point ``at_xy`` (a support it leaves), its wires near height ``z``."""
    direction, normal = plan_axes(azimuth)
    c0, s0 = float(at_xy @ normal), float(at_xy @ direction)
    reach = np.array([s0 - NEAR_SUPPORT_M, s0 + NEAR_SUPPORT_M])
    return _band_corridor(
        scene, azimuth, (c0 - half_width, c0 + half_width), reach, z, height_range, options,
        False, (),
    )  # fmt: skip


def footprint_along(scene: Scene, corridor: WireCorridor) -> float:
    """Median length of the images' footprints along the corridor, at its lowest wires."""
    z = corridor.height_range[0]
    lengths = []
    for v in scene.images:
        corners = np.array([[0, 0], [v.width, 0], [v.width, v.height], [0, v.height]], float)
        if np.any(v.rays_in_world(corners)[:, 2] >= 0):
            continue  # an image looking at the horizon has no footprint
        lengths.append(float(np.ptp(_to_plane(v, corners, z) @ corridor.direction_xy)))
    return float(np.median(lengths)) if lengths else np.inf


def _along_extent(scene: Scene, centre: F64, direction: F64, z: float, s_guess: F64) -> F64:
    """The stretch along the line (from ``centre``) that at least two images see at ``z``:
    looked for as far as the images reach (a probe measures a few pairs' stretch of a line
    that may run for kilometres)."""
    s_cams = (scene.centers_in_world[:, :2] - centre) @ direction
    lo = min(s_guess.min(), s_cams.min()) - 200.0
    hi = max(s_guess.max(), s_cams.max()) + 200.0
    s_all = np.arange(lo, hi, 1.0)
    probe = np.c_[centre + s_all[:, None] * direction, np.full(len(s_all), z)]
    seen = np.sum([v.project(probe)[2] for v in scene.images], axis=0)
    if (seen >= 2).any():
        return np.array([s_all[seen >= 2].min(), s_all[seen >= 2].max()])
    return np.quantile(s_guess, [0.01, 0.99])


def _band_corridor(
    scene: Scene,
    azimuth: float,
    c_range: tuple[float, float],
    s_guess: F64,
    z: float,
    height_range: tuple[float, float],
    options: PairsOptions,
    measured: bool,
    decoded: tuple[Path, ...],
) -> WireCorridor:
    """The corridor of a band ``c_range`` across the direction, as long as two images see it."""
    direction, normal = plan_axes(azimuth)
    c_lo, c_hi = c_range
    c_mid = 0.5 * (c_lo + c_hi)
    s_lo, s_hi = _along_extent(scene, c_mid * normal, direction, z, s_guess)
    s_mid = 0.5 * (s_lo + s_hi)
    return WireCorridor(
        azimuth_deg=azimuth,
        centre_xy=c_mid * normal + s_mid * direction,
        half_width=0.5 * (c_hi - c_lo) + options.corridor_margin,
        wires_half_width=0.5 * (c_hi - c_lo),
        s_range=(float(s_lo - s_mid), float(s_hi - s_mid)),
        height=z,
        height_range=height_range,
        from_images=options.wire_azimuth_deg is None,
        measured=measured,
        decoded=decoded,
    )


def provisional_corridors(
    scene: Scene,
    candidates: DirectionCandidates,
    azimuth: float,
    options: PairsOptions,
    wire_heights: tuple[float, float],
    slices: bool = False,
) -> list[WireCorridor]:
    """The bands where the lines of one direction run, before anything is measured in 3D.

    The line pixels of the analysed images are put on a plane halfway up the plausible wire
    heights. Across the direction they pile up in bands: the wires' band, but a road or a
    field edge may pile up more. The densest band and the whole band they fill are returned
    (``options.probe_bands`` of them), at the usual wire heights (each only has to find a
    few pairs that see the wires); with ``slices``, then the whole band in footprint-wide
    slices, those holding the most line pixels first.

    Args:
        wire_heights: the lowest and highest a wire may hang above the ground.
    """
    lo_h = wire_heights[0]
    hi_h = min(wire_heights[1], 0.8 * candidates.flying_height)
    z = candidates.ground_z + 0.5 * (lo_h + hi_h)
    # The pairs only have to see the wires' usual heights, not the extremes.
    band = (lo_h + 0.25 * (hi_h - lo_h), lo_h + 0.6 * (hi_h - lo_h))
    xy = np.concatenate(
        [
            _to_plane(v, _line_pixels(v, g, f, _image_angle(v, azimuth, z), options), z)
            for v, g, f in candidates.analysed
        ]
    )
    direction, normal = plan_axes(azimuth)
    c, s = xy @ normal, xy @ direction
    bins = np.arange(c.min() - 1, c.max() + 2, 1.0)
    hist, _ = np.histogram(c, bins)
    hist = np.convolve(hist, np.ones(5) / 5, mode="same")
    peak = int(np.argmax(hist))
    lo = hi = peak
    while lo > 0 and hist[lo - 1] > 0.2 * hist[peak]:
        lo -= 1
    while hi < len(hist) - 1 and hist[hi + 1] > 0.2 * hist[peak]:
        hi += 1
    # The densest band, then the whole band the lines fill (the wires' own when a road or a
    # field edge piles up more line pixels than they do).
    bands = [(bins[lo], bins[hi + 1]), tuple(np.quantile(c, [0.05, 0.95]))]
    if slices:
        # The whole band in slices as wide as an image's footprint across it, those
        # holding the most line pixels first: a few pairs over the whole band of a large
        # survey see a few places of it, and a line crossing the survey lies in one slice
        # (on the full road flight, 162 images over 400 m: the road line's direction
        # probed in its densest and whole bands, no wires; in its slice, the line).
        width = float(
            np.median([_footprint_across(v, normal, z) for v, _, _ in candidates.analysed])
        )
        w_lo, w_hi = bands[1]
        n = max(int(np.ceil((w_hi - w_lo) / max(width, 1.0))), 1)
        if n > 1:
            edges = np.linspace(w_lo, w_hi, n + 1)
            counts = np.histogram(c, edges)[0]
            for k in np.argsort(counts)[::-1]:
                if counts[k] > 0:
                    bands.append((float(edges[k]), float(edges[k + 1])))
    heights = (candidates.ground_z + band[0], candidates.ground_z + band[1])
    out = [
        _band_corridor(
            scene, azimuth, b, s, z, heights, options, measured=False, decoded=candidates.decoded
        )
        for b in (bands if slices else bands[: options.probe_bands])
    ]
    return out


def corridor_from_points(
    scene: Scene,
    pts_in_world: F64,
    azimuth: float,
    options: PairsOptions,
    provisional: WireCorridor,
    decoded: tuple[Path, ...] = (),
) -> WireCorridor:
    """The corridor where wires were measured: their direction, band and heights.

    A probe sees some of the wires — those that its pairs see, often the lowest — so the
    heights keep the provisional range as well as the measured one.

    Args:
        pts_in_world: (N, 3) verified points on wires (a probe of a few pairs).
        azimuth: the wires' direction measured from them (degrees clockwise from +y).
        provisional: the corridor the probe was chosen for.
    """
    direction, normal = plan_axes(azimuth)
    c, s = pts_in_world[:, :2] @ normal, pts_in_world[:, :2] @ direction
    z = pts_in_world[:, 2]
    z_lo, z_hi = np.quantile(z, [0.02, 0.98])
    corridor = _band_corridor(
        scene,
        azimuth,
        tuple(np.quantile(c, [0.01, 0.99])),
        s,
        float(np.median(z)),
        (
            float(min(z_lo, provisional.height_range[0])),
            float(max(z_hi, provisional.height_range[1])),
        ),
        options,
        measured=True,
        decoded=decoded,
    )
    s_lo, s_hi = corridor.s_range
    ground = float(np.median(scene.ground_height(pts_in_world[:, :2])))
    logger.info(
        "wire corridor (measured): azimuth %.1f°, %.0f wide, %.0f long, wires measured "
        "%.0f–%.0f above the ground",
        azimuth,
        2 * corridor.half_width,
        s_hi - s_lo,
        z_lo - ground,
        z_hi - ground,
    )
    return corridor


# A stretch of the corridor that no third view can judge counts this much in a pair's score.
WEAK_COVERAGE_WEIGHT = 0.1


def select_pairs(
    scene: Scene,
    corridor: WireCorridor,
    options: PairsOptions | None = None,
    crossing_offset: float = 0.15,
) -> list[ImagePair]:
    """Score every pair and pick the best few that together cover the wire corridor.

    A part of the corridor counts as covered by a pair when both images see it and so does
    a third view offset across the wires from both (``crossing_offset`` × height, see
    :func:`colmap_powerline.geometry.crossing_views`): only such a view can reject the pair's
    false matches there.
    """
    options = options or PairsOptions()
    # Each place at the lowest and at the highest wire height: a pair covers the place at a
    # height only where both images see it there (a strip beside the line may see the low
    # wires of the far side and not the high ones).
    samples = corridor.sample_points(1.0).reshape(-1, 3)  # (2N, 3)
    n_samples = len(samples)
    seen = np.zeros((len(scene.images), n_samples), bool)
    m = options.border_margin_frac
    for i, view in enumerate(scene.images):
        uv, _, inside = view.project(samples)
        with np.errstate(invalid="ignore"):
            seen[i] = (
                inside
                & (uv[:, 0] > m * view.width)
                & (uv[:, 0] < (1 - m) * view.width)
                & (uv[:, 1] > m * view.height)
                & (uv[:, 1] < (1 - m) * view.height)
            )
    centres = scene.centers_in_world
    ground = scene.ground_height(centres[:, :2])
    direction = corridor.direction_xy
    above_wires = float(np.median(centres[:, 2]) - corridor.height)  # cameras above the wires
    candidates: list[tuple[ImagePair, F64]] = []
    best_crossing = 0.0
    for i in range(len(scene.images)):
        for j in range(i + 1, len(scene.images)):
            common = seen[i] & seen[j]
            if common.sum() < 2:
                continue
            judges = crossing_views(
                centres, centres[[i, j]][None], corridor.azimuth_deg, above_wires, crossing_offset
            )[0]
            # Where a third view offset across the wires sees it too, false matches can be
            # rejected point by point; elsewhere only whole wires can be judged.
            judged = common & seen[judges].any(axis=0)
            base = centres[j] - centres[i]
            b_xy = float(np.linalg.norm(base[:2]))
            if b_xy < 1e-9:
                continue
            cos_angle = abs(float(base[:2] @ direction)) / b_xy
            crossing = float(np.rad2deg(np.arccos(np.clip(cos_angle, 0, 1))))
            best_crossing = max(best_crossing, crossing)
            above_ground = float(np.mean(centres[[i, j], 2] - ground[[i, j]]))
            bh = float(np.linalg.norm(base)) / max(above_ground, 1e-9)
            if crossing < options.min_crossing_deg:
                continue
            if not options.min_base_height <= bh <= options.max_base_height:
                continue
            coverage = float(common.sum()) / 10.0  # five sample lines at two heights
            weight = judged + WEAK_COVERAGE_WEIGHT * (common & ~judged)
            score = (
                float(weight.sum())
                / 10.0
                * np.sin(np.deg2rad(crossing))
                * min(bh / options.target_base_height, 1.0)
            )
            pair = ImagePair(scene.images[i], scene.images[j], crossing, bh, coverage, score)
            candidates.append((pair, weight))
    if not candidates:
        raise InputError(
            f"{scene.model_path}: no image pair crosses the wires (best crossing angle "
            f"{best_crossing:.0f}° < {options.min_crossing_deg:.0f}° or base/height out of "
            f"[{options.min_base_height}, {options.max_base_height}]); the flight needs images "
            "side by side across the line (a second strip, or strips across the line)"
        )
    count = np.zeros(n_samples)
    chosen: list[ImagePair] = []
    while len(chosen) < options.max_pairs:
        # First cover every part of the corridor once, then add redundancy.
        need = np.where(count == 0, 1.0, np.where(count < options.pairs_per_point, 0.25, 0.0))
        gains = [
            p.score / max(p.coverage, 1.0) * float((need * common).sum())
            for p, common in candidates
        ]
        k = int(np.argmax(gains))
        if gains[k] <= 0:
            break
        pair, common = candidates.pop(k)
        chosen.append(pair)
        count += common
        if not candidates:
            break
    covered = float((count > 0).mean())
    for p in chosen:
        logger.info("pair %s", p)
    logger.info(
        "pairs: %d chosen of %d crossing candidates; they cover %.0f %% of the corridor",
        len(chosen),
        len(candidates) + len(chosen),
        100 * covered,
    )
    return chosen
