"""Raster helpers for the synthetic renderer: noise fields, thin-line coverage, ray casting.

Kept apart from :mod:`colmap_powerline.synthetic` (scene geometry and files) so that each
stays short. Nothing here is used by the reconstruction pipeline.
"""

from __future__ import annotations

import cv2
import numpy as np
import numpy.typing as npt

F32 = npt.NDArray[np.float32]
F64 = npt.NDArray[np.float64]


def fbm(
    shape: tuple[int, int],
    rng: np.random.Generator,
    cell_px: list[float],
    amps: list[float] | None = None,
) -> F32:
    """Multi-scale smooth noise: one band per cell size, bicubically upsampled.

    Args:
        shape: (H, W) of the output.
        rng: random generator.
        cell_px: correlation length of each band, in output pixels.
        amps: weight of each band (default 1 each).

    Returns:
        (H, W) float32 field with unit standard deviation (approximately).
    """
    h, w = shape
    out = np.zeros(shape, np.float32)
    amps = amps or [1.0] * len(cell_px)
    for cell, amp in zip(cell_px, amps, strict=True):
        gh, gw = max(int(h / cell) + 3, 3), max(int(w / cell) + 3, 3)
        grid = rng.standard_normal((gh, gw)).astype(np.float32)
        # Resize a slightly larger grid and crop, so the field has no edge artefacts.
        big = cv2.resize(
            grid, (int((gw - 1) * cell), int((gh - 1) * cell)), interpolation=cv2.INTER_CUBIC
        )
        oy = int(rng.integers(0, max(big.shape[0] - h, 0) + 1))
        ox = int(rng.integers(0, max(big.shape[1] - w, 0) + 1))
        band = big[oy : oy + h, ox : ox + w]
        if band.shape != (h, w):  # tiny shapes
            band = cv2.resize(band, (w, h), interpolation=cv2.INTER_LINEAR)
        out += amp * band
    std = float(out.std())
    return out / std if std > 0 else out


def periodic_noise(size: int, rng: np.random.Generator, beta: float = 1.6) -> F32:
    """A seamless (periodic) square tile of 1/f^beta noise with unit std."""
    fy = np.fft.fftfreq(size)[:, None]
    fx = np.fft.rfftfreq(size)[None, :]
    f = np.sqrt(fx**2 + fy**2)
    f[0, 0] = 1.0
    spectrum = (rng.standard_normal(f.shape) + 1j * rng.standard_normal(f.shape)) / f ** (beta / 2)
    spectrum[0, 0] = 0
    tile = np.fft.irfft2(spectrum, s=(size, size)).astype(np.float32)
    return tile / tile.std()


def draw_thin_polyline(
    canvas: F32,
    uv: F64,
    width_px: F64 | float,
    value: F64 | float = 1.0,
) -> None:
    """Draw a thin curve with exact pixel coverage (anti-aliased to its true width).

    Each pixel gets ``max(coverage * value)``, where the coverage of a pixel by a bar of
    width ``w`` at perpendicular distance ``d`` from the pixel centre is the overlap of
    ``[d - 0.5, d + 0.5]`` with ``[-w / 2, w / 2]``. Widths below one pixel give partial
    coverage, which is what a real sensor integrates.

    Args:
        canvas: (H, W) float32, modified in place.
        uv: (K, 2) the curve in pixels (COLMAP convention, pixel centres at +0.5), sampled
            densely enough (≤ 0.5 px apart); NaN rows break the curve.
        width_px: scalar or (K,) width of the curve at each sample.
        value: scalar or (K,) value to draw (e.g. a brightness factor).
    """
    h, w = canvas.shape
    k = len(uv)
    if k < 2:
        return
    widths = np.broadcast_to(np.asarray(width_px, np.float64), (k,))
    values = np.broadcast_to(np.asarray(value, np.float64), (k,))
    tangent = np.gradient(uv, axis=0)
    norm = np.linalg.norm(tangent, axis=1)
    ok = np.isfinite(uv).all(axis=1) & np.isfinite(norm) & (norm > 1e-9)
    ok &= (uv[:, 0] > -4) & (uv[:, 0] < w + 4) & (uv[:, 1] > -4) & (uv[:, 1] < h + 4)
    if not ok.any():
        return
    uv, tangent, norm = uv[ok], tangent[ok], norm[ok]
    widths, values = widths[ok], values[ok]
    tangent = tangent / norm[:, None]
    step = np.maximum(norm, 0.05)
    r = int(np.ceil(widths.max() / 2 + 1.0))
    offs = np.arange(-r, r + 1)
    gx, gy = np.meshgrid(offs, offs)
    ox, oy = gx.ravel(), gy.ravel()
    # Pixel indices around each sample and their centres (pixel (i, j) has centre j+.5, i+.5).
    base = np.floor(uv).astype(np.int64)
    cols = base[:, :1] + ox[None, :]
    rows = base[:, 1:] + oy[None, :]
    dx = cols + 0.5 - uv[:, :1]
    dy = rows + 0.5 - uv[:, 1:]
    along = np.abs(dx * tangent[:, :1] + dy * tangent[:, 1:])
    perp = np.abs(dx * tangent[:, 1:] - dy * tangent[:, :1])
    half = widths[:, None] / 2
    cover = np.clip(np.minimum(perp + 0.5, half) - np.maximum(perp - 0.5, -half), 0, 1)
    keep = (along <= step[:, None] * 0.75) & (cover > 0)
    keep &= (cols >= 0) & (cols < w) & (rows >= 0) & (rows < h)
    vals = (cover * values[:, None])[keep].astype(np.float32)
    flat = rows[keep] * w + cols[keep]
    np.maximum.at(canvas.reshape(-1), flat, vals)


def remap(src: np.ndarray, map_x: F32, map_y: F32, wrap: bool = False) -> np.ndarray:
    """cv2.remap with linear interpolation; ``src`` must be smaller than 32767 px per side."""
    border = cv2.BORDER_WRAP if wrap else cv2.BORDER_REPLICATE
    return cv2.remap(src, map_x, map_y, cv2.INTER_LINEAR, borderMode=border)
