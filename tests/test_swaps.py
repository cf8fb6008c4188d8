"""Swapped pairings of a wire's image lines (``colmap_powerline.swaps``): how far the views
put a wire's curve beside the line it should lie on, and which side of a swap goes."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from colmap_powerline import swaps
from colmap_powerline.detect import DetectOptions
from colmap_powerline.wires import FittedWire


def _flat_wire(wire_id: int, y: float, height: float = 20.0) -> FittedWire:
    """A straight, level wire along x at ``y``, ``height`` up, from x = −5.4 to 5.4."""
    return FittedWire(
        wire_id=wire_id,
        plane_origin_xy=np.array([0.0, y]),
        plane_direction_xy=np.array([1.0, 0.0]),
        catenary_a=1e6,
        s0=0.0,
        z0=height,
        s_range=(-5.4, 5.4),
        point_indices=np.zeros(0, np.int64),
        rms_residual=0.01,
    )


@pytest.mark.parametrize("beside_px", [0.0, 1.0, 3.0])
def test_a_curve_beside_its_line_is_measured_that_far_off(nadir_view, beside_px):
    """A line along the image's rows on textured ground; a wire whose curve the view puts
    ``beside_px`` px from it (30 m from the camera: 33.3 px/m) disagrees by that much (to a
    quarter pixel), over the stretches of 100 px it spans."""
    rng = np.random.default_rng(5)
    img = 100 + rng.normal(0, 6.0, (300, 400))
    rows = np.arange(300)[:, None] + 0.5
    img += 30 * np.exp(-0.5 * ((rows - 150.0) / 0.7) ** 2)
    view = nadir_view(np.clip(img, 0, 255).astype(np.uint8))
    scene = SimpleNamespace(images=[view])
    wire = _flat_wire(0, -beside_px / (1000 / 30))  # world −y is image +v
    got = swaps._disagreement(
        swaps._Projected(scene, [wire]), 0, {}, 90.0, DetectOptions(), 6.0, 1.5
    )
    assert got == pytest.approx(beside_px, abs=0.25)


@pytest.mark.parametrize(
    ("off", "dropped"),
    [
        ({0: 0.5, 1: 2.5, 2: 3.0}, {1, 2}),  # the views agree on T only: g and h go
        ({0: 1.4, 1: 2.0, 2: 3.0}, {0, 1, 2}),  # g beyond the tolerance, not twice T: unknown
        ({0: 2.5, 1: 0.5, 2: 0.4}, {0}),  # they agree on g and h: T goes
        ({0: 0.5, 1: 0.6, 2: 0.7}, {0, 1, 2}),  # on all three: which is real is unknown
        ({0: 2.0, 1: 2.5, 2: 3.0}, {0, 1, 2}),  # on none of them: the same
    ],
)
def test_of_a_swap_the_side_the_views_disagree_with_goes(monkeypatch, off, dropped):
    """T (wire 0) with g (1) on T's image in views 0-1 and h (2) on it in views 2-3: T, or g
    and h, are false pairings. The side the views put off its lines (beyond the tolerance)
    goes; when they do not tell, all three go (on two strips a false wire costs more than a
    missing one)."""
    on = {(1, 0): {0, 1}, (2, 0): {2, 3}}
    monkeypatch.setattr(swaps, "_on_image_of", lambda pr, g, t, tol: on.get((g, t), set()))
    monkeypatch.setattr(swaps, "_disagreement", lambda pr, k, *a: off[k])
    wires = [_flat_wire(k, 0.5 * k) for k in range(3)]
    weak = [SimpleNamespace(geometry="weak")] * 3
    scene = SimpleNamespace(images=[])
    assert swaps.swapped_pairings(scene, wires, weak, 90.0, DetectOptions(), 1.5)[0] == dropped


def test_without_a_swap_or_on_strong_geometry_nothing_goes(monkeypatch):
    """g on T's image from one strip, h nowhere on it (a wire hidden behind another from one
    strip): no swap. And a swap among wires the views that can tell confirmed is not looked
    at."""
    monkeypatch.setattr(swaps, "_disagreement", lambda pr, k, *a: {0: 0.5, 1: 3.0, 2: 3.0}[k])
    wires = [_flat_wire(k, 0.5 * k) for k in range(3)]
    scene = SimpleNamespace(images=[])
    weak = [SimpleNamespace(geometry="weak")] * 3
    one = {(1, 0): {0, 1}}
    monkeypatch.setattr(swaps, "_on_image_of", lambda pr, g, t, tol: one.get((g, t), set()))
    assert swaps.swapped_pairings(scene, wires, weak, 90.0, DetectOptions(), 1.5)[0] == set()
    both = {(1, 0): {0, 1}, (2, 0): {2, 3}}
    monkeypatch.setattr(swaps, "_on_image_of", lambda pr, g, t, tol: both.get((g, t), set()))
    strong = [SimpleNamespace(geometry="strong")] * 3
    assert swaps.swapped_pairings(scene, wires, strong, 90.0, DetectOptions(), 1.5)[0] == set()


def test_another_wires_line_beside_it_is_left_out(nadir_view):
    """A brighter line 4 px beside the wire's own: searched as it is, its peak wins; with
    that line's wire among the others, the wire is measured on its own line."""
    rng = np.random.default_rng(6)
    img = 100 + rng.normal(0, 3.0, (300, 400))
    rows = np.arange(300)[:, None] + 0.5
    img += 25 * np.exp(-0.5 * ((rows - 150.0) / 0.7) ** 2)
    img += 60 * np.exp(-0.5 * ((rows - 154.0) / 0.7) ** 2)
    scene = SimpleNamespace(images=[nadir_view(np.clip(img, 0, 255).astype(np.uint8))])
    wire, other = _flat_wire(0, 0.0), _flat_wire(1, -4 / (1000 / 30))
    alone = swaps._disagreement(
        swaps._Projected(scene, [wire]), 0, {}, 90.0, DetectOptions(), 6.0, 1.5
    )
    assert alone == pytest.approx(4.0, abs=0.25)
    beside = swaps._disagreement(
        swaps._Projected(scene, [wire, other]), 0, {}, 90.0, DetectOptions(), 6.0, 1.5
    )
    assert beside == pytest.approx(0.0, abs=0.25)
