"""Where each wire was measured, and why not elsewhere: exact pinhole views of straight wires."""

from __future__ import annotations

import csv
import dataclasses
import io
import json
from pathlib import Path

import numpy as np
import pycolmap
import pytest

from colmap_powerline.clearance import measure_wire, measures_csv
from colmap_powerline.coverage import (
    FEW_VIEWS,
    MIN_REPORTED_GAP,
    NOT_FOUND,
    ONE_POSITION,
    UNSEEN,
    measured_coverage,
    pairs_onto_traced,
)
from colmap_powerline.export import export_results
from colmap_powerline.scene import Scene, SceneImage
from colmap_powerline.wires import FittedWire, WiresOptions

HEIGHT = 20.0  # the wire, 30 m below the cameras


def _view(k: int, x: float, y: float) -> SceneImage:
    """A 2000 × 1500 px nadir view 50 m up at (x, y), f = 1000 px (60 × 45 m at the wire)."""
    camera = pycolmap.Camera(
        model="PINHOLE", width=2000, height=1500, params=[1000, 1000, 1000, 750], camera_id=1
    )
    rot = np.diag([1.0, -1.0, -1.0])
    return SceneImage(k, f"v{k}.jpg", Path(f"v{k}.jpg"), camera, rot, -rot @ [x, y, 50.0])


def _scene(positions) -> Scene:
    ground = np.array([[x, y, 0.0] for x in (-50, 0, 50) for y in (-50, 0, 50)])
    return Scene(
        Path("."),
        Path("."),
        tuple(_view(k + 1, x, y) for k, (x, y) in enumerate(positions)),
        ground,
        np.zeros((len(ground), 3), np.uint8),
        np.zeros(len(ground)),
        np.full(len(ground), 3),
    )


def _wire(wire_id: int, y: float, z: float, s: np.ndarray, base: int = 0):
    """A straight wire along x at (y, z) (a very flat catenary), its points at ``s``."""
    wire = FittedWire(
        wire_id,
        np.array([0.0, y]),
        np.array([1.0, 0.0]),
        1e7,
        0.0,
        z,
        (-30.0, 30.0),
        base + np.arange(len(s)),
        0.01,
    )
    return wire, wire.points(s)


# Measured from -30 to 30 but for a 10 m hole in the middle and a 0.5 m one at +20.
S = np.r_[np.arange(-30.0, -5.0, 0.05), np.arange(5.0, 19.8, 0.05), np.arange(20.3, 30.01, 0.05)]


def _coverage(positions, others=()):
    wire, pts = _wire(0, 0.0, HEIGHT, S)
    wires, all_pts = [wire], [pts]
    for k, (y, z) in enumerate(others):
        o, p = _wire(k + 1, y, z, np.arange(-30.0, 30.01, 0.05), sum(map(len, all_pts)))
        wires.append(o)
        all_pts.append(p)
    cov = measured_coverage(_scene(positions), wires, np.concatenate(all_pts), 0.12, 3.0, 1, 0.15)
    return cov[0]


def test_the_gaps_and_the_measured_share():
    cov = _coverage([(0, -15), (0, -5), (0, 5), (0, 15)])
    # 10 m of 60 unmeasured, less the inlier radius at either side; the 0.5 m hole: 0.26 m.
    assert cov.measured_share == pytest.approx(1 - (10 - 0.24 + 0.26) / 60, abs=0.005)
    (gap,) = cov.gaps  # the 0.5 m hole is shorter than MIN_REPORTED_GAP
    assert MIN_REPORTED_GAP > 0.5
    assert gap.from_m == pytest.approx(25.0, abs=0.15) and gap.to_m == pytest.approx(35.0, abs=0.15)
    assert gap.at == pytest.approx((0.0, 0.0, HEIGHT), abs=0.1)
    assert cov.longest_gap_m == pytest.approx(10.0, abs=0.3)


def test_a_gap_the_views_see_clearly_is_a_wire_not_found():
    gap = _coverage([(0, -15), (0, -5), (0, 5), (0, 15)]).gaps[0]
    assert (gap.views, gap.clear_views, gap.clear_positions) == (4, 4, 4)
    assert gap.why == NOT_FOUND and not gap.flight_limited


def test_a_gap_two_views_see_is_one_the_flight_cannot_measure():
    # Two views see the middle; the others are 60 m away along the line.
    gap = _coverage([(0, -15), (0, 15), (-60, -15), (60, 15)]).gaps[0]
    assert (gap.views, gap.clear_views) == (2, 2)
    assert gap.why == FEW_VIEWS and gap.flight_limited
    assert "only 2 image(s) see it" in gap.describe()


def test_a_view_where_another_wire_lies_on_it_is_not_clear():
    # A wire 15 m higher, halfway towards the views at y = +15 m: on the same rays from them.
    gap = _coverage([(-3, 15), (3, 15), (0, -15), (0, -5)], others=[(7.5, 35.0)]).gaps[0]
    assert (gap.views, gap.clear_views) == (4, 2)
    assert gap.why == FEW_VIEWS
    assert "only 2 of the 4 images that see it are clear" in gap.describe()
    # Beside it by more than the search's reach, it spoils none.
    gap = _coverage([(-3, 15), (3, 15), (0, -15), (0, -5)], others=[(9.0, 35.0)]).gaps[0]
    assert gap.clear_views == 4 and gap.why == NOT_FOUND
    # A piece of the same wire through the gap (the next span's, overlapping at a support)
    # lies on it in every view, and is not another wire there.
    gap = _coverage([(0, -15), (0, -5), (0, 5), (0, 15)], others=[(0.0, HEIGHT + 0.1)]).gaps[0]
    assert gap.clear_views == 4 and gap.why == NOT_FOUND


def test_views_at_one_position_across_the_wire_cannot_fix_it():
    gap = _coverage([(-6, 10), (0, 10), (6, 10)]).gaps[0]
    assert (gap.views, gap.clear_views, gap.clear_positions) == (3, 3, 1)
    assert gap.why == ONE_POSITION and gap.flight_limited


def test_a_gap_no_view_sees():
    gap = _coverage([(-60, 0), (60, 0)]).gaps[0]
    assert gap.views == 0 and gap.why == UNSEEN


def test_coverage_in_wires_json_and_csv(tmp_path):
    wire, pts = _wire(0, 0.0, HEIGHT, S)
    scene = _scene([(0, -15), (0, 15)])
    cov = measured_coverage(scene, [wire], pts, 0.12, 3.0, 1, 0.15)
    measures = [measure_wire(wire, scene.ground)]
    export_results(
        tmp_path,
        wires=[wire],
        points=pts,
        labels=np.zeros(len(pts), np.int64),
        primitives=None,
        metadata={},
        measures=measures,
        coverage=cov,
        to_crs=(lambda xyz: xyz + [1000.0, 2000.0, 0.0], "shifted"),
    )
    doc = json.loads((tmp_path / "wires.json").read_text())["wires"][0]["coverage"]
    assert doc["measured_share"] == pytest.approx(cov[0].measured_share, abs=1e-4)
    (gap,) = doc["gaps"]
    assert gap["why"] == FEW_VIEWS and gap["length_m"] == pytest.approx(10.0, abs=0.3)
    assert gap["at"] == pytest.approx([1000.0, 2000.0, HEIGHT], abs=0.1)  # in the output CRS
    rows = list(csv.DictReader(io.StringIO((tmp_path / "wires.csv").read_text())))
    assert float(rows[0]["longest_gap_m"]) == pytest.approx(10.0, abs=0.3)
    assert float(rows[0]["flight_limited_gap_m"]) == pytest.approx(10.0, abs=0.3)
    assert rows[0]["gaps"] == "1" and rows[0]["pairs_vs_traced_m"] == ""  # nothing traced
    # It sags most at mid-span (30 m from its first end), in its gap (25-35 m): its sag
    # there comes from its curve, and both files say so.
    assert measures[0].sag_max_at_m == pytest.approx(30.0, abs=0.5)
    assert rows[0]["sag_max_at_measured"] == "no" and doc["sag_max_at_measured"] is False
    assert cov[0].measured_at(10.0) and not cov[0].measured_at(30.0)
    # Without coverage the table keeps its columns.
    assert "measured_share" not in measures_csv(measures).splitlines()[0]


def test_how_far_the_pairs_points_lie_from_the_traced_ones():
    """Traced points on the wire, the pairs' points 8 cm above it with 3 cm of scatter (a
    blend of two wires' lines in a pair's image): the median offset is the 8 cm, in height."""
    rng = np.random.default_rng(3)
    s_pair = np.arange(-30.0, 30.0, 0.01)
    s_traced = np.arange(-30.0, 30.0, 0.1)
    wire, on = _wire(0, 0.0, HEIGHT, np.r_[s_pair, s_traced])
    pts = (
        on
        + np.r_[
            np.c_[rng.normal(0, 0.03, (len(s_pair), 2)), 0.08 + rng.normal(0, 0.03, len(s_pair))],
            rng.normal(0, 0.01, (len(s_traced), 3)),
        ]
    )
    from_pairs = np.r_[np.ones(len(s_pair), bool), np.zeros(len(s_traced), bool)]
    scene = _scene([(0, -15), (0, -5), (0, 5), (0, 15)])
    (cov,) = measured_coverage(scene, [wire], pts, 0.12, 3.0, 1, 0.15, from_pairs)
    assert cov.pairs_vs_traced is not None and cov.compared_share > 0.99  # the last bin: 1 traced
    across, height = cov.pairs_vs_traced
    assert height == pytest.approx(0.08, abs=0.005) and abs(across) < 0.005
    assert cov.disagreement_m == pytest.approx(0.08, abs=0.005)
    assert cov.to_json()["pairs_vs_traced"]["height_m"] == pytest.approx(0.08, abs=0.005)
    # Without traced points (or without telling them apart) there is nothing to compare.
    (cov,) = measured_coverage(scene, [wire], pts, 0.12, 3.0, 1, 0.15, np.ones(len(pts), bool))
    assert cov.pairs_vs_traced is None and cov.to_json()["pairs_vs_traced"] is None
    (cov,) = measured_coverage(scene, [wire], pts, 0.12, 3.0, 1, 0.15)
    assert cov.pairs_vs_traced is None


def test_each_pair_s_points_are_moved_onto_the_traced_points_by_its_own_offset():
    """A sagging wire traced every 10 cm (1 cm noise) and measured by three pairs: one 10 cm
    high along the whole wire (a blend of two lines in its images), one 3 cm off across it,
    and one whose points lie where the trace has only two points per window (its 8 cm
    offset cannot be told there, so it stays). Each compared pair's points end on the wire
    (their median within 5 mm of it, their scatter kept), the wire is fitted again to them,
    the traced points do not move, and a point two wires share is moved once."""
    rng = np.random.default_rng(5)
    a, z_low = 400.0, HEIGHT
    curve = FittedWire(
        0,
        np.array([0.0, 0.0]),
        np.array([1.0, 0.0]),
        a,
        0.0,
        z_low,
        (-30.0, 30.0),
        np.zeros(0, np.int64),
        0.01,
    )
    s_traced = np.r_[np.arange(-30.0, 20.0, 0.1), np.arange(20.0, 30.0, 0.25)]
    s_pairs = [
        np.arange(-30.0, 20.0, 0.01),
        np.arange(-10.0, 20.0, 0.01),
        np.arange(21.0, 29.0, 0.01),
    ]
    offsets = [np.array([0.0, 0.0, 0.10]), np.array([0.0, 0.03, 0.0]), np.array([0.0, 0.0, 0.08])]
    pts = [curve.points(s_traced) + rng.normal(0, 0.01, (len(s_traced), 3))]
    pair_index = [np.full(len(s_traced), -1, np.int32)]
    for p, (s, off) in enumerate(zip(s_pairs, offsets, strict=True)):
        pts.append(curve.points(s) + off + rng.normal(0, 0.03, (len(s), 3)))
        pair_index.append(np.full(len(s), p, np.int32))
    all_pts, pair_index = np.concatenate(pts), np.concatenate(pair_index)
    from colmap_powerline.wires import _fit

    wire = _fit(all_pts, np.arange(len(all_pts)), np.array([1.0, 0.0]), WiresOptions())
    assert wire is not None
    wire = dataclasses.replace(wire, point_indices=np.arange(len(all_pts)))
    # A second wire sharing the first pair's first 100 points.
    shared = np.flatnonzero(pair_index == 0)[:100]
    other = FittedWire(
        1,
        wire.plane_origin_xy,
        wire.plane_direction_xy,
        wire.catenary_a,
        wire.s0,
        wire.z0,
        wire.s_range,
        shared,
        wire.rms_residual,
    )
    moved, (fitted, _), summary = pairs_onto_traced(
        [wire, other], all_pts, pair_index, WiresOptions()
    )
    assert summary[0][0] == 2 and summary[0][1] == pytest.approx(0.10, abs=0.01)
    truth = lambda q: curve.plane_coords(q)  # noqa: E731
    for p, moved_by in ((0, True), (1, True), (2, False)):
        mine = pair_index == p
        _, across, dz = truth(moved[mine])
        if moved_by:
            assert abs(np.median(across)) < 0.005 and abs(np.median(dz)) < 0.005
            assert np.std(dz) == pytest.approx(0.03, abs=0.005)
        else:
            assert np.array_equal(moved[mine], all_pts[mine])
    traced = pair_index < 0
    assert np.array_equal(moved[traced], all_pts[traced])
    # The shared points moved once (by the first wire's offset for their pair).
    assert np.median(truth(moved[shared])[2]) == pytest.approx(0.0, abs=0.01)
    assert summary[1] == (0, 0.0)
    # The refitted wire lies on the truth where the biased pair had pulled it up.
    s_mid = np.linspace(-25, 10, 8)  # (past 20 the uncompared pair still pulls it up)
    assert np.max(np.abs(fitted.z_at(s_mid) - curve.z_at(s_mid))) < 0.01
    assert np.max(np.abs(wire.z_at(s_mid) - curve.z_at(s_mid))) > 0.02


def test_the_command_line_says_where_a_sag_comes_from_the_curve():
    """Printed after a wire's sag, where the wire was not measured where it sags most."""
    from types import SimpleNamespace

    from colmap_powerline.cli import _sag_from

    wire, pts = _wire(0, 0.0, HEIGHT, S)
    scene = _scene([(0, -15), (0, 15)])
    cov = measured_coverage(scene, [wire], pts, 0.12, 3.0, 1, 0.15)
    measures = [measure_wire(wire, scene.ground)]
    said = _sag_from(SimpleNamespace(coverage=cov, measures=measures), 0)
    assert said.startswith(" (from its curve: measured along 8")  # 10 m of 60 unmeasured
    full = measured_coverage(
        scene, [wire], wire.points(np.arange(-30, 30.01, 0.05)), 0.12, 3.0, 1, 0.15
    )
    assert _sag_from(SimpleNamespace(coverage=full, measures=measures), 0) == ""
    assert _sag_from(SimpleNamespace(coverage=[], measures=measures), 0) == ""
    # The report's profile says it by the sag too.
    from colmap_powerline.report import _sag_label

    label = _sag_label(SimpleNamespace(coverage=cov, measures=measures), 0, "m")
    assert label.endswith("(from its curve: not measured there)")
    assert _sag_label(SimpleNamespace(coverage=full, measures=measures), 0, "m").startswith("sag")
    assert "curve" not in _sag_label(SimpleNamespace(coverage=full, measures=measures), 0, "m")
