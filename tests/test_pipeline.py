"""End to end on a half-scale span, and the CLI on the small one."""

from __future__ import annotations

import csv
import json

import laspy
import numpy as np
import pytest

from colmap_powerline.cli import main
from colmap_powerline.evaluate import distance_to_polyline, evaluate
from colmap_powerline.export import read_point_cloud
from colmap_powerline.pipeline import (
    OutputOptions,
    ReconstructionOptions,
    reconstruct,
    write_outputs,
)
from colmap_powerline.synthetic import Terrain, load_true_wires


@pytest.fixture(scope="module")
def run(medium_span, medium_dense, tmp_path_factory):
    out = tmp_path_factory.mktemp("out")
    options = ReconstructionOptions(show_progress=False, min_clearance_m=21.0)
    outputs = OutputOptions(debug=True, dense_path=medium_dense, las=True, report=True)
    # In memory first (the dense cloud's ground for the clearance), then written.
    result = reconstruct(medium_span.images, medium_span.sparse, None, options, outputs)
    assert not out.exists() or not any(out.iterdir())
    write_outputs(result, out, outputs)
    return result, out


def test_the_options_are_not_changed(run):
    result, _ = run
    assert result.options == ReconstructionOptions(show_progress=False, min_clearance_m=21.0)


def test_end_to_end_accuracy_and_completeness(run, medium_span):
    result, _ = run
    # The points reported (wire_points.ply): those assigned to a wire that passed the
    # whole-wire support check. Verified points on dropped wires are not reported.
    assigned = result.verified.pts_in_world[result.labels >= 0]
    ev = evaluate(assigned, result.wires, load_true_wires(medium_span.truth_wires))
    print(ev.summary_table())
    conductors = [w for w in ev.wires if w.kind == "conductor"]
    # Half scale (wire GSD 4.4 cm, conductors 0.7 px wide), measured by the benchmark:
    # completeness 88-97 %, median 1.8-2.5 cm, catenary 0.4-1.9 cm, sag error < 2 cm,
    # 1.7 % outliers, no ghost. Shield wires (0.5 px) are not found at this scale. The
    # 12 MP targets are checked by scripts/benchmark.py. Measured here with the posterior
    # verification and whole-wire support: completeness 99.7-100 %, median 1.8-2.4 cm,
    # catenary 0.9-2.4 cm, sag error < 1.7 cm, 0.02 % of ~53 000 assigned points > 30 cm
    # (12.5 % of all ~65 000 verified points: those on the dropped false pairings).
    # With 30 pairs, the points every view favours on confirmed wires and 4-pair probes:
    # completeness 100 %, median 1.8-2.4 cm, catenary 1.2-3.0 cm (one wire 3.02 cm: the
    # favoured points widen the spread a little), sag error < 1.9 cm, shield wires found at
    # 49 and 63 %, 0.04 % of ~83 000 points > 30 cm. Traced in every view: conductors 100 %,
    # median 1.8-2.3 cm, catenary 1.8-3.1 cm, sag error < 1.8 cm, shield wires 74 and 85 %,
    # 0.04 % of ~88 000 points > 30 cm.
    assert all(w.found for w in conductors)
    assert min(w.completeness for w in conductors) > 0.8
    assert max(w.median_error_m for w in conductors) < 0.035
    assert max(w.catenary_rms_m for w in conductors) < 0.035
    assert max(abs(w.sag_error_m) for w in conductors) < 0.05
    assert ev.ghost_wires == 0
    assert ev.outlier_share < 0.02
    assert len(result.pairs) >= 2
    # Each image was read about 11 times (measured 348 reads of 32 images; 441 when the
    # conductors the line's spacing predicts were looked for in one pass per group of
    # hypotheses apart in the images, now in one pass for all; 270 before the wires were
    # traced in every view, 181 with 2-pair probes): the corridor probe triangulates and
    # verifies four pairs per candidate direction and band before the run proper, and
    # tracing reads each image once more and those near the wires' ends again at each 5 m
    # past them. Looking for more lines (the wider look's 8 images, and the densest band
    # of five more directions probed) reads 101 more: 449 reads, 14 per image. The sweep
    # for wires too faint for the detector reads each image that sees the line twice (its
    # coarse and fine passes) and tracing its hypotheses twice more: 541 reads, 17 per
    # image. Looking for lines that leave a support (each support's nearest 6 images read
    # around it, 2 directions probed there with 4 pairs each) reads 102 more: 643 reads,
    # 20 per image. Sharing those reads with the run is the speed issue's work; this
    # bounds it.
    assert len(result.decoded) <= 21 * len(result.scene)


def test_outputs_follow_the_contract(run, medium_span):
    result, out = run
    doc = json.loads((out / "wires.json").read_text())
    assert doc["input_model"].endswith("0") and len(doc["pairs"]) == len(result.pairs)
    assert {"timings_s", "options", "image_reads", "images_read"} <= set(doc)
    assert 0 < doc["images_read"] <= doc["image_reads"]
    assert len(doc["wires"]) == len(result.wires)
    for w in doc["wires"]:
        assert w["sag_m"] >= 0 and w["clearance_m"] > 10 and w["num_points"] > 0
        if w["s_range"][1] - w["s_range"][0] > 80:  # a whole span sags visibly
            assert w["sag_m"] > 0.5
        poly = np.array(w["polyline"])
        steps = np.linalg.norm(np.diff(poly[:, :2], axis=0), axis=1)
        assert np.allclose(steps, 0.1, atol=0.01)
    # Only the points assigned to a reported wire, each with its wire's id.
    pts, _, labels = read_point_cloud(out / "wire_points.ply")
    assert labels is not None and len(pts) == int((result.labels >= 0).sum()) > 0
    assert set(np.unique(labels)) <= set(range(len(result.wires)))
    np.testing.assert_allclose(pts, result.verified.pts_in_world[result.labels >= 0])
    assert (out / "primitives.ply").exists() and (out / "wires.ply").exists()
    # LAS of the wires: measured + fitted points, conductors class 14, wire ids.
    las = laspy.read(out / "wires.las")
    assigned = int((labels >= 0).sum())
    n_fitted = sum(len(w.polyline(0.1)) for w in result.wires)
    assert len(las.points) == assigned + n_fitted
    kinds = {w["id"]: w["kind"] for w in doc["wires"]}
    cls = np.asarray(las.classification)
    ids = np.asarray(las.wire_id)
    for wid, kind in kinds.items():
        assert set(cls[ids == wid]) == {14 if kind == "conductor" else 13}
    xyz = np.c_[las.x, las.y, las.z]
    truth = load_true_wires(medium_span.truth_wires)
    d = np.min([distance_to_polyline(xyz, t.polyline(0.05)) for t in truth], axis=0)
    assert np.mean(d < 0.3) > 0.95  # the LAS coordinates are the wires' (mm scale)
    # The dense cloud filled with the wires, classified.
    merged = laspy.read(out / "merged.las")
    mcls = np.asarray(merged.classification)
    assert np.count_nonzero(np.isin(mcls, (13, 14))) == n_fitted
    assert np.count_nonzero(mcls == 2) > 0.95 * np.count_nonzero(mcls < 13)
    assert (out / "merged.ply").exists()
    # Clearance measured on the dense ground, the limit flagged where wires come close.
    assert all(w["measures"]["ground_source"] == "dense cloud" for w in doc["wires"])
    low = [w for w in doc["wires"] if w["measures"]["clearance_vertical_m"] < 21.0]
    assert low and all(w["measures"]["flagged"] for w in low)
    # Where each wire was measured: its share between its ends and its gaps, each with why.
    shares = [w["coverage"]["measured_share"] for w in doc["wires"]]
    assert all(0 <= x <= 1 for x in shares) and np.median(shares) > 0.9
    for w, cov in zip(doc["wires"], result.coverage, strict=True):
        assert [g["why"] for g in w["coverage"]["gaps"]] == [g.why for g in cov.gaps]
    # The pairs' points against the traced ones: compared on the traced wires, within the
    # bound tracing holds its own points to (no two lines stack in this flight's pairs).
    agree = [w["coverage"]["pairs_vs_traced"] for w in doc["wires"]]
    assert sum(a is not None for a in agree) >= 3
    assert all(a["distance_m"] < 0.12 / 2.33 for a in agree if a is not None)
    # The report: every figure it promises, and a page linking them.
    report = out / "report"
    page = (report / "index.html").read_text()
    assert "<th>measured</th>" in page and "<th>pairs vs traced</th>" in page
    names = ["plan.png", "cameras.png"]
    names += [
        f"span_{line}_{span}.png" for line, span in {(p.line, p.span) for p in result.placement}
    ]
    names += [f"profile_{k}.png" for k in range(len(result.wires))]
    names += [f"pair_{k}.png" for k in range(len(result.pairs))]
    for name in names:
        assert (report / name).stat().st_size > 10_000 and name in page


def test_cli_reconstruct_runs(small_span, tmp_path, capsys):
    code = main(
        [
            "--quiet",
            "reconstruct",
            "--image_path",
            str(small_span.images),
            "--input_path",
            str(small_span.sparse),
            "--output_path",
            str(tmp_path),
            "--pairs.wire_azimuth_deg",
            "35",
            "--verify.min_posterior",
            "0.95",
            "--pairs.max_pairs",
            "2",
        ]
    )
    assert code == 0
    printed = capsys.readouterr().out
    assert "wires from" in printed
    doc = json.loads((tmp_path / "wires.json").read_text())
    assert doc["options"]["pairs"]["max_pairs"] == 2
    assert doc["options"]["verify"]["min_posterior"] == 0.95
    assert doc["wire_azimuth_deg"] == 35.0


def test_cli_errors_are_one_line(tmp_path, capsys):
    code = main(
        [
            "reconstruct",
            "--image_path",
            str(tmp_path),
            "--input_path",
            str(tmp_path / "nope"),
            "--output_path",
            str(tmp_path / "out"),
        ]
    )
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "nope" in err and "does not exist" in err
    assert not (tmp_path / "out").exists()


def test_sag_and_clearance_against_the_truth(run, medium_span):
    """Sag within 5 cm and clearance within 10 cm of the true wires over the true terrain
    (the ground from the dense cloud; from the sparse points alone it is 0.2-0.6 m off)."""
    result, out = run
    truth = load_true_wires(medium_span.truth_wires)
    terrain = Terrain.load(medium_span.terrain)
    rows = list(csv.DictReader((out / "wires.csv").open()))
    assert [int(r["wire_id"]) for r in rows] == [w.wire_id for w in result.wires]
    assert [int(r["confirming_strips"]) for r in rows] == [
        s.confirming_strips for s in result.supports
    ]
    checked = 0
    for wire, m, row in zip(result.wires, result.measures, rows, strict=True):
        poly = wire.polyline(1.0)
        dist = [np.median(distance_to_polyline(poly, t.polyline(0.05))) for t in truth]
        t = truth[int(np.argmin(dist))]
        if min(dist) > 0.3 or t.kind != "conductor":
            continue
        # The true wire over the same stretch, sampled every 5 cm.
        ends = wire.points(np.asarray(wire.s_range))
        s_ends = (ends[:, :2] - np.asarray(t.attach_a[:2])) @ t.direction_xy
        s = np.linspace(s_ends.min(), s_ends.max(), 4001)
        pts = t.points(s)
        chord = pts[0, 2] + (pts[-1, 2] - pts[0, 2]) * (s - s[0]) / (s[-1] - s[0])
        assert m.sag_max_m == pytest.approx(np.max(chord - pts[:, 2]), abs=0.05)
        mid = np.interp(0.5 * (s[0] + s[-1]), s, chord - pts[:, 2])
        assert m.sag_midspan_m == pytest.approx(mid, abs=0.05)
        clear = pts[:, 2] - terrain.height(pts[:, :2])
        print(wire.wire_id, m.clearance_vertical_m, clear.min(), m.sag_max_m)
        assert m.clearance_vertical_m == pytest.approx(clear.min(), abs=0.10)
        assert m.span_length_m == pytest.approx(np.ptp(s), abs=0.05)
        assert float(row["sag_max_m"]) == pytest.approx(m.sag_max_m, abs=0.001)
        assert m.clearance_3d_m <= m.clearance_vertical_m + 1e-9
        checked += 1
    assert checked >= 5
