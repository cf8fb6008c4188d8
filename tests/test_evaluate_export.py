"""Scoring against the truth, and the output files read back with their own libraries."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import open3d as o3d
import pycolmap
import pytest

from colmap_powerline.evaluate import (
    Evaluation,
    WireScore,
    distance_to_polyline,
    evaluate,
    measurable_points,
    positions_seen,
)
from colmap_powerline.export import export_results, read_point_cloud
from colmap_powerline.files import write_atomic
from colmap_powerline.scene import SceneImage
from colmap_powerline.synthetic import SyntheticSpanOptions, build_span
from colmap_powerline.wires import split_wires


@pytest.fixture(scope="module")
def truth():
    return build_span(SyntheticSpanOptions(scale=0.05, show_progress=False)).wires


def test_distance_to_polyline_is_exact():
    line = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]])
    pts = np.array([[0.5, 1, 0], [3, 0, 0], [1, 0, 2], [-1, -1, 0]])
    np.testing.assert_allclose(distance_to_polyline(pts, line), [1, 1, 2, np.sqrt(2)])


def test_evaluate_perfect_partial_and_ghost(truth):
    rng = np.random.default_rng(0)
    pts = np.concatenate([w.points(np.arange(0, w.length_m, 0.05)) for w in truth])
    noisy = pts + rng.normal(0, 0.01, pts.shape)
    wires = split_wires(noisy, 35.0)
    ev = evaluate(noisy, wires, truth)
    assert all(w.completeness > 0.99 for w in ev.wires)
    assert all(0.005 < w.median_error_m < 0.03 for w in ev.wires)
    assert all(abs(w.sag_error_m) < 0.01 for w in ev.wires)
    assert ev.ghost_wires == 0 and ev.outlier_share == 0
    assert all(ev.meets_targets().values())
    # Half of wire 0 missing, 5 % outliers, and a ghost wire 1 m beside wire 0.
    s = np.arange(0, truth[0].length_m, 0.05)
    half = truth[0].points(s[s < truth[0].length_m / 2])
    others = np.concatenate([w.points(np.arange(0, w.length_m, 0.05)) for w in truth[1:]])
    outliers = rng.uniform(-60, 60, (int(0.05 * len(others)), 3))
    ghost = truth[0].points(s) + np.array([0.0, 0.0, 1.0])
    pts2 = np.concatenate([half, others, outliers])
    ev2 = evaluate(pts2, split_wires(np.concatenate([pts2, ghost]), 35.0), truth)
    assert ev2.wires[0].completeness == pytest.approx(0.5, abs=0.03)
    assert all(w.completeness > 0.99 for w in ev2.wires[1:])
    assert ev2.ghost_wires == 1
    assert ev2.outlier_share == pytest.approx(len(outliers) / len(pts2), abs=0.01)
    assert "found 8/8" in ev2.summary_table()


def test_export_round_trip(tmp_path, truth):
    pts = np.concatenate([w.points(np.arange(0, w.length_m, 0.1)) for w in truth])
    wires = split_wires(pts, 35.0)
    labels = np.full(len(pts), -1)
    for w in wires:
        labels[w.point_indices] = w.wire_id
    out = export_results(
        tmp_path,
        wires=wires,
        points=pts,
        labels=labels,
        primitives=pts[:10],
        metadata={"input_model": "m", "bad": float("nan")},
        ground_height=lambda xy: np.zeros(len(xy)),
    )
    assert set(out) == {"wires.json", "wires.ply", "wire_points.ply", "primitives.ply"}
    doc = json.loads((tmp_path / "wires.json").read_text())  # strict JSON: NaN became null
    assert doc["bad"] is None and len(doc["wires"]) == 8
    assert doc["wires"][0]["clearance_m"] > 10
    xyz, rgb, ids = read_point_cloud(tmp_path / "wire_points.ply")
    np.testing.assert_allclose(xyz, pts, atol=1e-9)
    np.testing.assert_array_equal(ids, labels)
    assert rgb.shape == (len(pts), 3)
    dense = o3d.io.read_point_cloud(str(tmp_path / "wires.ply"))  # legacy reader too
    assert len(dense.points) == sum(len(w.polyline(0.1)) for w in wires)
    assert not any(p.name.startswith(".") for p in tmp_path.iterdir())


def test_atomic_write_leaves_nothing_half_written(tmp_path):
    target = tmp_path / "a.json"
    target.write_text("old")

    def failing(path):
        path.write_text("partial")
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError):
        write_atomic(target, failing)
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["a.json"]


def _nadir(k: int, x: float, y: float) -> SceneImage:
    """A 2000 × 1500 px nadir view 50 m up at (x, y), f = 1000 px."""
    camera = pycolmap.Camera(
        model="PINHOLE", width=2000, height=1500, params=[1000, 1000, 1000, 750], camera_id=1
    )
    rot = np.diag([1.0, -1.0, -1.0])
    return SceneImage(k, f"v{k}.jpg", Path(f"v{k}.jpg"), camera, rot, -rot @ [x, y, 50.0])


def test_views_of_one_strip_along_a_wire_do_not_measure_it_and_a_second_strip_does():
    # A straight wire along x, 20 m up; views 50 m up every 10 m along it.
    pts = np.c_[np.linspace(-10, 10, 21), np.zeros(21), np.full(21, 20.0)]
    tangent = np.tile([1.0, 0.0, 0.0], (21, 1))
    none = np.zeros((0, 3))
    over = [_nadir(k, x, 0.0) for k, x in enumerate(range(-20, 21, 10))]
    beside = [_nadir(10 + k, x, 12.0) for k, x in enumerate(range(-20, 21, 10))]
    # One strip right over the wire: every ray lies in its vertical plane, nothing fixes
    # the height.
    assert not measurable_points(over, pts, tangent, none).any()
    # One strip beside it fixes only the plane through the strip and the wire.
    assert not measurable_points(beside, pts, tangent, none).any()
    assert measurable_points(over + beside, pts, tangent, none).all()
    # Fewer than three views: not measurable, however well they cross.
    assert not measurable_points(over[2:3] + beside[2:3], pts, tangent, none).any()
    # Another wire's image within the hidden distance takes the views it hides.
    other = pts + [0.0, 0.001, 0.0]
    assert not measurable_points(over + beside, pts, tangent, other, hidden_px=3.0).any()


def test_positions_across_count_strips_along_and_views_spread_across():
    # A straight wire along x, 20 m up; views 50 m up (30 m over it): a view counts as a new
    # position 0.15 x 30 = 4.5 m across from the one before.
    pts = np.c_[np.linspace(-10, 10, 21), np.zeros(21), np.full(21, 20.0)]
    tangent = np.tile([1.0, 0.0, 0.0], (21, 1))
    none = np.zeros((0, 3))

    def strip(k0: int, y: float) -> list[SceneImage]:
        return [_nadir(k0 + k, x, y) for k, x in enumerate(range(-20, 21, 10))]

    assert (positions_seen(strip(0, 0.0), pts, tangent, none) == 1).all()
    assert (positions_seen(strip(0, 0.0) + strip(10, 12.0), pts, tangent, none) == 2).all()
    three = strip(0, 0.0) + strip(10, 12.0) + strip(20, -12.0)
    assert (positions_seen(three, pts, tangent, none) == 3).all()
    # Two strips 3 m apart are one position; a strip across the line, views 6 m apart
    # across the wire, gives one position per view.
    assert (positions_seen(strip(0, 0.0) + strip(10, 3.0), pts, tangent, none) == 1).all()
    across = [_nadir(30 + k, 0.0, y) for k, y in enumerate((-6.0, 0.0, 6.0))]
    assert positions_seen(across, pts[8:13], tangent[8:13], none).tolist() == [3] * 5
    # A view where another wire's image lies on this one does not count.
    other = pts + [0.0, 0.001, 0.0]
    assert (positions_seen(three, pts, tangent, other, hidden_px=3.0) == 0).all()


def test_the_targets_hold_on_the_wires_the_flight_measures():
    def score(k: int, kind: str, complete: float, measurable: float | None) -> WireScore:
        return WireScore(
            k, kind, complete, complete >= 0.5, 100, 0.01, 0.015, 0.01, 0.01,
            measurable, None if measurable is None or complete == 0 else complete,
        )  # fmt: skip

    seen = [score(k, "conductor", 1.0, 1.0) for k in range(6)]
    unseen = [score(6, "shield", 0.0, 0.0), score(7, "shield", 0.0, 0.1)]
    ev = Evaluation(seen + unseen, 0, 0.0, 1000, 0.02)
    assert all(ev.meets_targets().values())
    assert "wire 6 (shield, 0 %), wire 7 (shield, 10 %)" in ev.summary_table()
    # Measured by the flight and missed: missed.
    ev = Evaluation(seen + [score(6, "shield", 0.0, 0.9)], 0, 0.0, 1000, 0.02)
    targets = ev.meets_targets()
    assert not targets["all wires found"] and not targets["completeness ≥ 98 %"]
    # Without the views (measurability not judged) every wire counts.
    ev = Evaluation(
        [dataclasses.replace(w, measurable=None) for w in seen + unseen], 0, 0.0, 1000, 0.02
    )
    assert not ev.meets_targets()["all wires found"]
    assert not Evaluation(seen, 0, 0.0, 1000, 0.031).meets_targets()["median ≤ 3 cm"]
