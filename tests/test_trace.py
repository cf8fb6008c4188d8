"""Measuring confirmed wires in every view (``colmap_powerline.trace``), on the small span of
the package's renderer with its true model: the traced points measure where the wire is
(not where the curve guessed it), the wire grows to where the views see it, and a curve with
no wire under it gets no points."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from colmap_powerline.detect import DetectOptions
from colmap_powerline.evaluate import distance_to_polyline
from colmap_powerline.pipeline import crop_wire_mask
from colmap_powerline.synthetic import TrueWire, load_true_wires
from colmap_powerline.trace import TraceOptions, trace_wires
from colmap_powerline.wires import FittedWire, WiresOptions


def _curve(t: TrueWire, wire_id: int, lo: float, hi: float, lift: float) -> FittedWire:
    """The true wire's curve between ``lo`` and ``hi`` (shares of its length), ``lift`` higher:
    what a confirmed wire fitted to part of the wire, a little off, looks like."""
    return FittedWire(
        wire_id=wire_id,
        plane_origin_xy=np.asarray(t.attach_a[:2], np.float64),
        plane_direction_xy=t.direction_xy,
        catenary_a=t.catenary_a_m,
        s0=t.s0,
        z0=t.z0 + lift,
        s_range=(lo * t.length_m, hi * t.length_m),
        point_indices=np.zeros(0, np.int64),
        rms_residual=0.02,
    )


def _with_points(wires: list[FittedWire]) -> tuple[list[FittedWire], np.ndarray]:
    """Each curve's own samples as its measured points (every 0.2 m)."""
    pts, out = [], []
    n = 0
    for w in wires:
        p = w.points(np.arange(w.s_range[0], w.s_range[1], 0.2))
        out.append(dataclasses.replace(w, point_indices=n + np.arange(len(p))))
        pts.append(p)
        n += len(p)
    return out, np.concatenate(pts)


def _azimuth(w: FittedWire) -> float:
    return float(np.degrees(np.arctan2(w.plane_direction_xy[0], w.plane_direction_xy[1])))


@pytest.fixture(scope="module")
def conductors(small_span):
    return [t for t in load_true_wires(small_span.truth_wires) if t.kind == "conductor"]


def test_traced_points_measure_the_wire_and_reach_past_the_curve(small_scene, conductors):
    """Curves over the middle 40 % of each conductor, 5 cm too high: the traced points lie
    on the true wires (not on the curves), and the wires grow over most of the span."""
    truth = conductors[:3]
    wires, pts = _with_points(
        [_curve(t, k, 0.3, 0.7, 0.05) for k, t in enumerate(truth)]
    )
    out, traced = trace_wires(
        small_scene,
        wires,
        pts,
        crop_wire_mask(DetectOptions(), 25),
        _azimuth(wires[0]),
        TraceOptions(),
        WiresOptions(),
        tolerance_px=1.5,
    )
    assert [w.wire_id for w in out] == [0, 1, 2]
    for k, t in enumerate(truth):
        mine = traced.pts_in_world[traced.wire_id == k]
        assert len(mine) > 100
        d = distance_to_polyline(mine, t.polyline(0.05))
        # Measured on the wire, not on the curve given 5 cm above it (quarter scale: a
        # pixel is about 8 cm at the wires).
        dz = mine[:, 2] - t.z_at((mine[:, :2] - t.attach_a[:2]) @ t.direction_xy)
        assert abs(np.median(dz)) < 0.015
        assert np.median(d) < 0.04
        assert np.mean(d < WiresOptions().inlier_distance) > 0.95
        lo, hi = out[k].s_range
        assert hi - lo > 0.7 * t.length_m  # grew from 40 % of the span
        assert np.all(traced.sigma[traced.wire_id == k] <= WiresOptions().inlier_distance / 2.33)
    # The traced points are the wires' points past the measured ones.
    assert all(out[k].point_indices.max() >= len(pts) for k in range(3))


def test_no_wire_under_the_curve_no_points(small_scene, conductors):
    """A curve 6 m below a conductor, where no wire hangs: the views find nothing on it."""
    wires, pts = _with_points([_curve(conductors[0], 0, 0.2, 0.8, -6.0)])
    out, traced = trace_wires(
        small_scene,
        wires,
        pts,
        crop_wire_mask(DetectOptions(), 25),
        _azimuth(wires[0]),
        TraceOptions(),
        WiresOptions(),
        tolerance_px=1.5,
    )
    assert len(traced) < 0.02 * len(pts)
    assert out[0].s_range[1] - out[0].s_range[0] < 0.65 * conductors[0].length_m


def test_trace_options_are_checked():
    with pytest.raises(ValueError, match="reach_px"):
        TraceOptions(reach_px=0)
    with pytest.raises(ValueError, match="step_px"):
        TraceOptions(step_px=float("nan"))
