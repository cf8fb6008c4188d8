"""Scoring against the truth, and the output files read back with their own libraries."""

from __future__ import annotations

import json

import numpy as np
import open3d as o3d
import pytest

from colmap_powerline.evaluate import distance_to_polyline, evaluate
from colmap_powerline.export import export_results, read_point_cloud
from colmap_powerline.files import write_atomic
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
