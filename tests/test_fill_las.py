"""Sag/clearance definitions, wire kinds, filling a COLMAP-format dense cloud, LAS."""

from __future__ import annotations

import json

import laspy
import numpy as np
import open3d as o3d
import pytest
from conftest import write_fused_ply

from colmap_powerline import InputError
from colmap_powerline.clearance import assign_kinds, measure_wire, measures_csv
from colmap_powerline.cli import main
from colmap_powerline.dense import fill, open_ply
from colmap_powerline.export import export_results
from colmap_powerline.scene import GroundModel
from colmap_powerline.wires import FittedWire


def _wire(wire_id: int, y: float, z0: float, a: float = 600.0) -> FittedWire:
    """A 100 m level span along +x at plan offset y, lowest point z0 at mid-span."""
    return FittedWire(
        wire_id=wire_id,
        plane_origin_xy=np.array([0.0, y]),
        plane_direction_xy=np.array([1.0, 0.0]),
        catenary_a=a,
        s0=50.0,
        z0=z0,
        s_range=(0.0, 100.0),
        point_indices=np.arange(100),
        rms_residual=0.01,
    )


def _ground(slope: float = 0.0, bump_at: float | None = None) -> GroundModel:
    x, y = np.meshgrid(np.arange(-20, 121, 2.0), np.arange(-30, 31, 2.0))
    z = slope * x
    if bump_at is not None:  # a 3 m high mound 8 m wide under the wire
        z = z + 3.0 * np.exp(-(((x - bump_at) / 4.0) ** 2) - (y / 4.0) ** 2)
    return GroundModel(np.c_[x.ravel(), y.ravel()], z.ravel(), 2.0)


def test_sag_and_clearance_definitions():
    w = _wire(0, 0.0, 12.0)
    m = measure_wire(w, _ground(), min_clearance_m=10.0)
    true_sag = 600.0 * (np.cosh(50.0 / 600.0) - 1.0)  # level span: max sag at mid-span
    assert m.sag_max_m == pytest.approx(true_sag, abs=1e-4)
    assert m.sag_midspan_m == pytest.approx(true_sag, abs=1e-4)
    assert m.sag_max_at_m == pytest.approx(50.0, abs=0.1)
    assert m.span_length_m == pytest.approx(100.0) and m.chord_length_m == pytest.approx(100.0)
    assert m.conductor_length_m == pytest.approx(2 * 600.0 * np.sinh(50.0 / 600.0), abs=1e-3)
    assert m.clearance_vertical_m == pytest.approx(12.0, abs=1e-3)
    assert m.clearance_3d_m == pytest.approx(12.0, abs=0.01)
    assert m.lowest_point == pytest.approx([50.0, 0.0, 12.0])
    assert m.flagged == []  # never below 10 m over flat ground
    # A mound under the wire: vertical and 3D clearance drop there, and get flagged.
    m2 = measure_wire(w, _ground(bump_at=30.0), min_clearance_m=10.5)
    z_at_30 = 12.0 + 600.0 * (np.cosh(20.0 / 600.0) - 1.0)
    assert m2.clearance_vertical_m == pytest.approx(z_at_30 - 3.0, abs=0.05)
    assert m2.clearance_vertical_at_m == pytest.approx(30.0, abs=0.5)
    assert m2.clearance_3d_m < m2.clearance_vertical_m
    assert len(m2.flagged) == 1
    f = m2.flagged[0]
    assert f.s_start_m < 30.0 < f.s_end_m and f.min_clearance_m == pytest.approx(
        m2.clearance_vertical_m
    )
    # An inclined span: sag from the chord, not from the lowest end.
    incl = FittedWire(**{**w.__dict__, "s0": 80.0})
    mi = measure_wire(incl, _ground())
    s = np.linspace(0, 100, 100001)
    z = incl.z_at(s)
    chord = z[0] + (z[-1] - z[0]) * s / 100.0
    assert mi.sag_max_m == pytest.approx(np.max(chord - z), abs=1e-4)
    assert mi.sag_midspan_m == pytest.approx(chord[50000] - z[50000], abs=1e-4)
    rows = measures_csv([m, m2]).splitlines()
    assert rows[0].startswith("wire_id,kind,catenary_a_m") and len(rows) == 3
    assert rows[2].split(",")[-3] == "1"  # one flagged stretch


def test_shield_wires_are_the_ones_clearly_above():
    ground = _ground()
    heights = [19.0, 19.2, 24.0, 24.1, 29.0, 29.2, 37.0, 37.1]
    measures = [measure_wire(_wire(k, float(k), h), ground) for k, h in enumerate(heights)]
    assign_kinds(measures)
    assert [m.kind for m in measures] == ["conductor"] * 6 + ["shield"] * 2
    # One shield over two circuits.
    measures = [measure_wire(_wire(k, float(k), h), ground) for k, h in enumerate(heights[:7])]
    assign_kinds(measures)
    assert [m.kind for m in measures] == ["conductor"] * 6 + ["shield"]
    # The shields not found: the top phases of the two circuits, 5 m above the others, are
    # not shield wires (four conductors are no whole number of three-phase circuits).
    measures = [
        measure_wire(_wire(k, float(k), h), ground)
        for k, h in enumerate([16.0, 16.2, 20.5, 20.7, 26.0, 26.3])
    ]
    assign_kinds(measures)
    assert {m.kind for m in measures} == {"conductor"}
    # A distribution line (no shield wire): nothing clearly above the rest.
    measures = [measure_wire(_wire(k, float(k), h), ground) for k, h in enumerate([8, 9, 9, 10])]
    assign_kinds(measures)
    assert {m.kind for m in measures} == {"conductor"}


def test_shield_wires_are_judged_per_span():
    """Over a line of several spans the wires of each span are judged on their own: two
    spans on lower ground (every wire of them lower than the first span's conductors' tops)
    keep their shields; over the whole survey only the highest one or two wires could be."""
    ground = _ground()
    span_1 = [19.0, 19.2, 24.0, 24.1, 29.0, 29.2, 37.0, 37.1]
    span_2 = [h - 9.0 for h in span_1]
    heights = span_1 + span_2
    measures = [measure_wire(_wire(k, float(k), h), ground) for k, h in enumerate(heights)]
    assign_kinds(measures)
    assert [m.kind for m in measures].count("shield") < 4  # judged together: wrong
    measures = [measure_wire(_wire(k, float(k), h), ground) for k, h in enumerate(heights)]
    assign_kinds(measures, spans=[(1, 1)] * 8 + [(1, 2)] * 8)
    assert [m.kind for m in measures] == (["conductor"] * 6 + ["shield"] * 2) * 2


def _fused_ply(path, n: int, seed: int = 0) -> None:
    """A dense cloud exactly as COLMAP's stereo_fusion writes fused.ply: binary, float
    xyz and normals, uchar colours. Ground over 140 x 60 m, a halo of stray points around
    the wire at y = 0, and a bush (2 m high) under it."""
    rng = np.random.default_rng(seed)
    n_halo, n_bush = 2000, 3000
    n_ground = n - n_halo - n_bush
    ground = np.c_[
        rng.uniform(-20, 120, n_ground),
        rng.uniform(-30, 30, n_ground),
        rng.normal(0, 0.02, n_ground),
    ]
    s = rng.uniform(5, 95, n_halo)
    wire_z = 12.0 + 600.0 * (np.cosh((s - 50.0) / 600.0) - 1.0)
    halo = np.c_[s, rng.uniform(-0.8, 0.8, n_halo), wire_z + rng.choice([-0.6, 0.6], n_halo)]
    bush = np.c_[
        rng.uniform(40, 44, n_bush), rng.uniform(-2, 2, n_bush), rng.uniform(0.5, 2.0, n_bush)
    ]
    rgb = np.zeros((n, 3), np.uint8)
    rgb[:, 1] = 120
    write_fused_ply(path, np.concatenate([ground, halo, bush]), rgb)


@pytest.fixture(scope="module")
def wires_json(tmp_path_factory):
    out = tmp_path_factory.mktemp("wires")
    w = _wire(0, 0.0, 12.0)
    export_results(
        out,
        wires=[w],
        points=w.polyline(0.5) + 0.01,
        labels=np.zeros(len(w.polyline(0.5)), np.int64),
        primitives=None,
        metadata={"input_model": "test"},
        measures=[measure_wire(w, _ground())],
    )
    return out / "wires.json"


def test_fill_a_colmap_fused_ply_of_millions_of_points(tmp_path, wires_json):
    n = 3_000_000
    dense = tmp_path / "fused.ply"
    _fused_ply(dense, n)
    assert open_ply(dense).count == n
    out = tmp_path / "merged.ply"
    # Small chunks: the cloud is streamed, never read whole.
    result = fill(dense, wires_json, out, drop_stray=True, las=True, chunk=400_000)
    assert result.num_dense == n
    assert result.num_dropped == 2000  # the halo, not the bush below the wire
    pcd = o3d.t.io.read_point_cloud(str(out))
    xyz = pcd.point.positions.numpy()
    cls = pcd.point["class"].numpy().ravel()
    wid = pcd.point.wire_id.numpy().ravel()
    n_wire = len(json.loads(wires_json.read_text())["wires"][0]["polyline"])
    assert len(xyz) == n - 2000 + n_wire == result.num_wire_points + n - 2000
    assert np.count_nonzero(cls == 14) == n_wire and set(wid[cls == 14]) == {0}
    assert abs(np.count_nonzero(cls == 2) - (n - 5000)) < 0.001 * n  # the ground points
    assert np.all(xyz[cls == 14][:, 2] > 11.9)
    # LAS 1.4 with the same points, classes, wire ids, millimetre scale.
    las = laspy.read(result.las_path)
    assert str(las.header.version) == "1.4" and len(las.points) == len(xyz)
    assert np.allclose(las.header.scales, 0.001)
    assert np.count_nonzero(las.classification == 14) == n_wire
    assert np.all(np.asarray(las.wire_id)[np.asarray(las.classification) == 14] == 0)
    assert np.abs(np.asarray(las.x) - xyz[:, 0]).max() < 0.0006
    # Without drop_stray nothing is removed; measured points can be added too.
    result2 = fill(dense, wires_json, tmp_path / "all.ply", include_measured=True)
    assert result2.num_dropped == 0 and result2.num_wire_points > n_wire


def test_fill_errors_are_one_line(tmp_path, wires_json, capsys):
    bad = tmp_path / "bad.ply"
    bad.write_text("not a ply\n")
    with pytest.raises(InputError, match="not a PLY file"):
        fill(bad, wires_json, tmp_path / "o.ply")
    short = tmp_path / "short.ply"
    _fused_ply(short, 10_000)
    short.write_bytes(short.read_bytes()[:-100])
    with pytest.raises(InputError, match="truncated"):
        fill(short, wires_json, tmp_path / "o.ply")
    assert not (tmp_path / "o.ply").exists()
    code = main(
        ["fill", "--dense_path", str(tmp_path / "none.ply"), "--wires_path", str(wires_json),
         "--output_path", str(tmp_path / "o.ply")]
    )  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2 and "none.ply: dense cloud does not exist" in err and err.count("\n") == 1


def test_fill_with_an_output_crs_puts_the_dense_cloud_in_it(tmp_path):
    """Wires written in UTM (--output_crs) and a fused.ply in the model frame: the merged
    cloud is all in UTM (the bug: the cloud stayed in the model frame, stamped UTM)."""
    from colmap_powerline.georef import crs_converter

    origin = (42.9, -76.8, 150.0)  # the model frame: ENU metres at this WGS84 point
    to_utm, name = crs_converter(origin, "utm")
    w = _wire(0, 0.0, 12.0)
    out = tmp_path / "wires"
    export_results(
        out,
        wires=[w],
        points=w.polyline(0.5),
        labels=np.zeros(len(w.polyline(0.5)), np.int64),
        primitives=None,
        metadata={
            "georeference": {"origin_wgs84": list(origin)},
            "options": {"output_crs": "utm"},
        },
        to_crs=(to_utm, name),
        measures=[measure_wire(w, _ground())],
    )
    dense = tmp_path / "fused.ply"
    _fused_ply(dense, 20_000)
    result = fill(dense, out / "wires.json", tmp_path / "m.ply", drop_stray=True, las=True)
    # The halo around the wire is found (so cloud and wires met in one frame) and dropped.
    assert result.num_dropped == 2000
    xyz = o3d.t.io.read_point_cloud(str(tmp_path / "m.ply")).point.positions.numpy()
    src = o3d.t.io.read_point_cloud(str(dense)).point.positions.numpy()
    ground = np.abs(src[:, 2]) < 0.2
    assert np.allclose(
        np.sort(xyz[:, 0])[:100], np.sort(to_utm(src[ground])[:, 0])[:100], atol=1e-3
    )
    assert xyz[:, 0].min() > 300_000 and xyz[:, 1].min() > 4_700_000  # UTM 18N metres
    las = laspy.read(result.las_path)
    assert "UTM zone 18N" in las.header.parse_crs().name
    # A cloud said to be in the wires' frame that is not: refused, nothing written.
    with pytest.raises(InputError, match="lie outside this cloud.*not the same frame"):
        fill(dense, out / "wires.json", tmp_path / "x.ply", dense_frame="wires")
    assert not (tmp_path / "x.ply").exists()


def test_fill_classifies_the_supports_dense_points_as_towers(tmp_path):
    """Dense points above the ground within a support's reach (and up to its top) are class
    15; a tree of the same height 20 m away is not."""
    from colmap_powerline.spans import LineSupport, WireSpan

    w = _wire(0, 0.0, 12.0)
    sup = LineSupport(0, 1, "end", np.array([0.0, 0.0, 0.0]), 16.0, 0.0, (0,), "wires ending",
                      reach_m=3.0)  # fmt: skip
    export_results(
        tmp_path, wires=[w], points=w.polyline(0.5), labels=np.zeros(len(w.polyline(0.5)), int),
        primitives=None, metadata={"input_model": "test"}, measures=[measure_wire(w, _ground())],
        placement=[WireSpan(1, 1, (0, None), 0)], line_supports=[sup],
    )  # fmt: skip
    rng = np.random.default_rng(0)
    ground = np.c_[rng.uniform(-20, 120, 20_000), rng.uniform(-30, 30, 20_000), np.zeros(20_000)]
    tower = np.c_[rng.uniform(-2.5, 2.5, (3000, 2)), rng.uniform(1.0, 16.5, 3000)]
    tree = np.c_[rng.uniform(18, 22, (1000, 2)), rng.uniform(1.0, 15.0, 1000)]
    dense = tmp_path / "fused.ply"
    write_fused_ply(dense, np.concatenate([ground, tower, tree]))
    result = fill(dense, tmp_path / "wires.json", tmp_path / "m.ply", las=True)
    # (the ground surface, the 5th percentile per 1 m cell, is lifted where the tower's
    # points outnumber the ground's: a few of its lowest count as ground)
    assert 0.95 * 3000 <= result.num_tower <= 3000
    cls = np.asarray(laspy.read(result.las_path).classification)
    assert np.count_nonzero(cls == 15) == result.num_tower
    assert np.all(cls[20_000:23_000][cls[20_000:23_000] != 2] == 15)
    assert not np.any(cls[23_000:24_000] == 15)  # the tree
