"""Wire extraction with the oriented line template."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from colmap_powerline.detect import (
    DetectOptions,
    Polarity,
    detect_wires,
    line_kernel,
    line_response,
)
from colmap_powerline.synthetic import load_true_wires


def _line_image(angle_deg, value, size=200, offset=0.0, length=150, seed=0):
    """Noise plus one anti-aliased 1 px line through the centre at ``angle_deg``."""
    rng = np.random.default_rng(seed)
    img = 100 + rng.normal(0, 2.0, (size, size))
    d = np.array([np.cos(np.radians(angle_deg)), np.sin(np.radians(angle_deg))])
    n = np.array([-d[1], d[0]])
    yy, xx = np.mgrid[:size, :size] + 0.5
    rel = np.stack([xx - size / 2, yy - size / 2], -1)
    across = rel @ n - offset
    along = rel @ d
    cover = np.clip(1.0 - np.abs(across), 0, 1) * (np.abs(along) < length / 2)
    return (img + value * cover).astype(np.float32)


@pytest.mark.parametrize("angle", [90.0, 0.0, 35.0, 120.0])
@pytest.mark.parametrize("value", [40.0, -40.0])
def test_recovers_bright_and_dark_lines_at_any_angle(angle, value):
    img = _line_image(angle, value)
    wm = detect_wires(img, angle, DetectOptions(min_component_length_px=50))
    assert wm.mask.shape == img.shape and wm.mask.dtype == bool
    assert wm.response.dtype == np.float32
    d = np.array([np.cos(np.radians(angle)), np.sin(np.radians(angle))])
    ys, xs = np.nonzero(wm.mask)
    along = (np.c_[xs, ys] + 0.5 - 100) @ d
    assert np.ptp(along) > 130  # the whole 150 px line
    across = (np.c_[xs, ys] + 0.5 - 100) @ np.array([-d[1], d[0]])
    assert np.abs(across).max() <= 2.5  # and nothing else (a slanted line is a staircase)
    centre = np.abs(across) < 1.0  # the line's own pixels have its polarity
    assert (np.sign(wm.response[ys, xs][centre]) == np.sign(value)).all()
    assert centre.sum() > 140


def test_polarity_option_selects_bright_or_dark():
    img = _line_image(90.0, -40.0)
    assert (
        detect_wires(
            img, 90.0, DetectOptions(polarity=Polarity.BRIGHT, min_component_length_px=50)
        ).mask.sum()
        == 0
    )
    assert (
        detect_wires(
            img, 90.0, DetectOptions(polarity=Polarity.DARK, min_component_length_px=50)
        ).mask.sum()
        > 100
    )


def test_short_segments_are_dropped():
    img = _line_image(90.0, 40.0, length=30)
    assert detect_wires(img, 90.0, DetectOptions(min_component_length_px=50)).num_components == 0
    kept = detect_wires(img, 90.0, DetectOptions(min_component_length_px=20))
    assert kept.num_components >= 1
    assert kept.mask[90:110, 99:101].any()  # the segment itself survives


def test_vertical_fast_path_matches_general_kernel():
    img = _line_image(90.0, 40.0)
    opts = DetectOptions()
    fast = line_response(img, 90.0, opts)
    general = cv2.filter2D(
        img,
        cv2.CV_32F,
        line_kernel(90.0, opts.template_length_px, 1),
        borderType=cv2.BORDER_REPLICATE,
    )
    inner = (slice(20, -20), slice(20, -20))
    # Same template; the general kernel samples it with bilinear weights, so not bit-equal.
    assert np.corrcoef(fast[inner].ravel(), general[inner].ravel())[0, 1] > 0.95
    assert general[100, 100] == pytest.approx(fast[100, 100], rel=0.15)


def test_dilated_grows_by_radius():
    img = _line_image(90.0, 40.0)
    wm = detect_wires(img, 90.0, DetectOptions(min_component_length_px=50))
    grown = wm.dilated(2.0)
    assert grown.sum() > wm.mask.sum() and (grown | wm.mask).sum() == grown.sum()
    assert np.array_equal(wm.dilated(0), wm.mask)


def test_bad_input_is_rejected():
    with pytest.raises(ValueError, match="shape"):
        detect_wires(np.zeros((10, 10, 4)), 90.0)
    with pytest.raises(ValueError, match="template_length_px"):
        DetectOptions(template_length_px=1)
    with pytest.raises(ValueError, match="threshold_k"):
        DetectOptions(threshold_k=0)


def test_finds_the_rendered_wires(small_span, small_scene):
    """Recall on a rendered 1000x750 image: wires there are only ~0.35 px wide."""
    wires = load_true_wires(small_span.truth_wires)
    recalls, false_share = [], []
    for view in small_scene.images[8:16]:
        pts = np.concatenate(
            [w.points(np.arange(3, w.length_m - 3, 0.05)) for w in wires if w.kind == "conductor"]
        )
        uv, _, ok = view.project(pts)
        if ok.sum() < 1000:
            continue
        uv = uv[ok]
        d = np.diff(uv[:50], axis=0).mean(axis=0)
        img = cv2.cvtColor(cv2.imread(str(view.path)), cv2.COLOR_BGR2RGB)
        wm = detect_wires(img, float(np.degrees(np.arctan2(d[1], d[0]))))
        truth = np.zeros(wm.mask.shape, np.uint8)
        px = np.floor(uv).astype(int)
        truth[px[:, 1], px[:, 0]] = 1
        near_truth = cv2.distanceTransform(1 - truth, cv2.DIST_L2, 5) <= 3
        recalls.append(wm.dilated(1.0)[px[:, 1], px[:, 0]].mean())
        false_share.append((wm.mask & ~near_truth).sum() / wm.mask.size)
    assert len(recalls) >= 3
    # Measured: conductor recall ≈ 0.75, false wire pixels ≈ 0.1 % of the image.
    assert np.mean(recalls) > 0.55
    assert np.mean(false_share) < 0.01
