"""Wire pixels: the paper's long line template turned to the wires' direction.

Across the wire the template is −1 2 −1, along it it is long (9 px in the paper), so thin
straight bright or dark lines respond and texture does not. The threshold follows the
local contrast (vegetation gives strong wire contrast, bare soil and roads weak), and
4-connected components shorter than a length scaled to the image are dropped.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from enum import StrEnum
from typing import ClassVar

import cv2
import numpy as np
import numpy.typing as npt

from .geometry import image_axes
from .options import check_limits

logger = logging.getLogger(__name__)

F32 = npt.NDArray[np.float32]
Mask = npt.NDArray[np.bool_]


class Polarity(StrEnum):
    BRIGHT = "bright"  # wires brighter than the ground
    DARK = "dark"  # wires darker than the ground
    BOTH = "both"


@dataclass(kw_only=True)
class DetectOptions:
    template_length_px: int = 15  # along the wire (paper: 9; 15 measured better on thin wires)
    side_offset_px: int = 1  # distance of the −1 taps from the centre tap (paper: 1)
    angle_spread_deg: float = 0.0  # also try directions within ± this of the given one
    angle_step_deg: float = 2.0
    polarity: Polarity = Polarity.BOTH
    threshold_k: float = 2.0  # wire pixel: |response| > k × local mean |response|
    contrast_window_px: int = 41  # window of the local mean |response|
    min_response: float = 1.5  # and |response| above this (grey levels)
    min_component_length_frac: float = 0.025  # drop components shorter along the wire than
    # this share of the image width (paper: 100 px at 4000 px)
    min_component_length_px: float | None = None  # or this many px (overrides the share)

    LIMITS: ClassVar[dict[str, str]] = {
        "template_length_px": ">= 3",
        "side_offset_px": ">= 1",
        "angle_spread_deg": "[0, 90]",
        "angle_step_deg": "> 0",
        "threshold_k": "> 0",
        "contrast_window_px": ">= 3",
        "min_response": ">= 0",
        "min_component_length_frac": "[0, 1]",
        "min_component_length_px": ">= 0",
    }

    def __post_init__(self) -> None:
        check_limits(self)
        self.polarity = Polarity(self.polarity)

    def min_length_px(self, image_width: int) -> float:
        if self.min_component_length_px is not None:
            return float(self.min_component_length_px)
        return self.min_component_length_frac * image_width


@dataclass(frozen=True, eq=False)
class WireMask:
    mask: Mask  # (H, W) kept wire pixels
    response: F32  # (H, W) signed response at the best direction (+ = brighter than sides)
    direction_deg: float  # image direction of the wires (0 = +x, 90 = +y, i.e. down)
    num_components: int  # components kept

    def dilated(self, radius_px: float) -> Mask:
        """The mask grown by ``radius_px`` (pixels whose centre is that close to a wire pixel)."""
        if radius_px <= 0:
            return self.mask.copy()
        dist = cv2.distanceTransform((~self.mask).astype(np.uint8), cv2.DIST_L2, 5)
        return dist <= radius_px


def _to_gray(image: np.ndarray) -> F32:
    if image.ndim == 3 and image.shape[2] == 3:
        if image.dtype == np.uint8:
            return cv2.cvtColor(image, cv2.COLOR_RGB2GRAY).astype(np.float32)
        return cv2.cvtColor(image.astype(np.float32), cv2.COLOR_RGB2GRAY)
    if image.ndim == 2:
        return image.astype(np.float32)
    raise ValueError(f"{image.shape=} but expected (H, W) or (H, W, 3)")


def line_kernel(direction_deg: float, length_px: int, side_offset_px: int) -> F32:
    """The −1 2 −1 × length template as a (k, k) kernel along ``direction_deg``."""
    d, n = image_axes(direction_deg)
    half = int(np.ceil(length_px / 2 + side_offset_px)) + 1
    k = np.zeros((2 * half + 1, 2 * half + 1), np.float32)
    ts = np.linspace(-(length_px - 1) / 2, (length_px - 1) / 2, 2 * length_px)
    for t in ts:
        for off, w in ((0.0, 2.0), (side_offset_px, -1.0), (-side_offset_px, -1.0)):
            x, y = t * d + off * n + half
            x0, y0 = int(np.floor(x)), int(np.floor(y))
            fx, fy = x - x0, y - y0
            k[y0, x0] += w * (1 - fx) * (1 - fy)
            k[y0, x0 + 1] += w * fx * (1 - fy)
            k[y0 + 1, x0] += w * (1 - fx) * fy
            k[y0 + 1, x0 + 1] += w * fx * fy
    return k / len(ts)


def line_response(gray: F32, direction_deg: float, options: DetectOptions | None = None) -> F32:
    """(H, W) signed response of the template along ``direction_deg`` (grey levels)."""
    options = options or DetectOptions()
    a = direction_deg % 180.0
    o, n = options.side_offset_px, options.template_length_px
    if abs(a - 90.0) < 1e-6:  # vertical: separable (edges replicated, never wrapped round)
        pad = np.pad(gray, ((0, 0), (o, o)), mode="edge")
        across = 2 * gray - pad[:, : -2 * o] - pad[:, 2 * o :]
        return cv2.blur(across, (1, n), borderType=cv2.BORDER_REPLICATE)
    if a < 1e-6 or abs(a - 180.0) < 1e-6:  # horizontal: separable
        pad = np.pad(gray, ((o, o), (0, 0)), mode="edge")
        across = 2 * gray - pad[: -2 * o] - pad[2 * o :]
        return cv2.blur(across, (n, 1), borderType=cv2.BORDER_REPLICATE)
    kernel = line_kernel(a, n, o)
    return cv2.filter2D(gray, cv2.CV_32F, kernel, borderType=cv2.BORDER_REPLICATE)


def contrast_threshold(magnitude: F32, options: DetectOptions) -> F32:
    """(H, W) the response a wire pixel must exceed: ``threshold_k`` times the local mean
    |response| (a ``contrast_window_px`` window), and at least ``min_response``."""
    win = options.contrast_window_px
    local = cv2.blur(magnitude, (win, win), borderType=cv2.BORDER_REFLECT)
    local *= options.threshold_k
    np.maximum(local, options.min_response, out=local)
    return local


def detect_wires(
    image: np.ndarray, direction_deg: float, options: DetectOptions | None = None
) -> WireMask:
    """Wire pixels of an image whose wires run along ``direction_deg``.

    Args:
        image: (H, W) grey or (H, W, 3) RGB image.
        direction_deg: the wires' direction in this image (0 = +x, 90 = +y).
        options: template, threshold and length filter.
    """
    options = options or DetectOptions()
    gray = _to_gray(image)
    h, w = gray.shape
    spread, step = options.angle_spread_deg, max(options.angle_step_deg, 1e-3)
    angles = (
        direction_deg + np.arange(-spread, spread + 1e-9, step) if spread > 0 else [direction_deg]
    )
    response = line_response(gray, float(angles[0]), options)
    magnitude = np.abs(response)
    for a in angles[1:]:
        r = line_response(gray, float(a), options)
        r_mag = np.abs(r)
        better = r_mag > magnitude
        np.copyto(response, r, where=better)
        np.copyto(magnitude, r_mag, where=better)
    if options.polarity is Polarity.BRIGHT:
        strength = np.maximum(response, 0)
    elif options.polarity is Polarity.DARK:
        strength = np.maximum(-response, 0)
    else:
        strength = magnitude
    candidate = strength > contrast_threshold(magnitude, options)
    # The −1 taps make a wire respond with the opposite sign beside it: drop those side
    # lobes (a stronger response of the other sign one tap away across the wire).
    # Judged on a slightly smoothed response, so that a wire straddling two pixels (whose
    # lobes are as strong as its centre pixels) still has a stronger centre.
    smooth = cv2.GaussianBlur(response, (0, 0), 0.7)
    smooth_mag = np.abs(smooth)
    smooth_pos = smooth > 0
    sx0, sy0 = options.side_offset_px * image_axes(direction_deg)[1]
    for sx, sy in ((sx0, sy0), (-sx0, -sy0)):
        # nb[y, x] = smooth[y + sy, x + sx], sub-pixel.
        shift = np.array([[1.0, 0.0, -sx], [0.0, 1.0, -sy]])
        nb = cv2.warpAffine(
            smooth, shift, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
        )
        candidate &= ~((np.abs(nb) > smooth_mag) & ((nb > 0) != smooth_pos))
    # 4-connected components, kept when long enough along the wire direction.
    n, labels, stats, _ = cv2.connectedComponentsWithStats(candidate.astype(np.uint8), None, 4)
    # Extent along the wire direction from the bounding box (exact for thin straight lines).
    d = np.abs(image_axes(direction_deg)[0])
    extent = stats[:, cv2.CC_STAT_WIDTH] * d[0] + stats[:, cv2.CC_STAT_HEIGHT] * d[1]
    long_enough = extent >= options.min_length_px(w)
    long_enough[0] = False
    mask = long_enough[labels]
    logger.debug(
        "detect: %d of %d components kept, %d wire pixels (%.2f %%)",
        int(long_enough.sum()),
        n - 1,
        int(mask.sum()),
        100 * mask.mean(),
    )
    return WireMask(mask, response.astype(np.float32), float(direction_deg), int(long_enough.sum()))
