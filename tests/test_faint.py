"""The faint-wire sweep: a wire too faint for the detector, found from all views' evidence."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pycolmap
import pytest

from colmap_powerline.detect import DetectOptions, detect_wires
from colmap_powerline.evaluate import distance_to_polyline
from colmap_powerline.faint import (
    FaintHypothesis,
    evidence_stretches,
    faint_hypotheses,
    sweep_refs,
)
from colmap_powerline.scene import Scene, SceneImage
from colmap_powerline.wires import FittedWire

W, H, F = 600, 600, 600.0  # px; 26 m below the views (the wires) a pixel is 4.3 cm


def _wire(
    wire_id: int, y: float, z_end: float, sag: float, x0: float = -20.0, x1: float = 20.0
) -> FittedWire:
    """A wire along x (``x0``..``x1`` m, 40 m by default) at ``y``, its ends at ``z_end``,
    sagging ``sag``."""
    span = x1 - x0
    a = span**2 / (8.0 * sag)
    return FittedWire(
        wire_id=wire_id,
        plane_origin_xy=np.array([0.0, y]),
        plane_direction_xy=np.array([1.0, 0.0]),
        catenary_a=a,
        s0=0.5 * (x0 + x1),
        z0=z_end - a * (np.cosh(0.5 * span / a) - 1.0),
        s_range=(x0, x1),
        point_indices=np.zeros(0, np.int64),
        rms_residual=0.0,
    )


def _scene(tmp_path, drawn: list[tuple[FittedWire, float]], seed: int = 0) -> Scene:
    """Fifteen nadir views 50 m up, three strips 8 m apart along the wires, of noisy ground
    (grey 128, sd 8) with each wire drawn about a pixel wide at its contrast (grey levels)."""
    rng = np.random.default_rng(seed)
    camera = pycolmap.Camera(
        model="PINHOLE", width=W, height=H, params=[F, F, W / 2, H / 2], camera_id=1
    )
    rot = np.diag([1.0, -1.0, -1.0])  # world x is image u, world y image -v
    images = []
    for k, (x, y) in enumerate(
        (x, y) for y in (-8.0, 0.0, 8.0) for x in (-10.0, -5.0, 0.0, 5.0, 10.0)
    ):
        path = tmp_path / f"view{k}.png"
        im = SceneImage(k + 1, path.name, path, camera, rot, -rot @ np.array([x, y, 50.0]))
        up = 4  # drawn at 4x, then averaged down
        canvas = np.zeros((H * up, W * up), np.float32)
        for w, contrast in drawn:
            uv, _, ok = im.project(w.polyline(0.02))
            line = np.zeros_like(canvas)
            pts = np.round((uv[ok] + 0.5) * up - 0.5).astype(np.int32)
            cv2.polylines(line, [pts], False, 1.0, thickness=up)
            canvas += contrast * line
        grey = 128.0 + cv2.resize(canvas, (W, H), interpolation=cv2.INTER_AREA)
        grey += rng.normal(0.0, 8.0, grey.shape)
        cv2.imwrite(str(path), np.clip(grey, 0, 255).astype(np.uint8))
        images.append(im)
    ground = np.zeros((1, 3))
    return Scene(
        tmp_path, tmp_path, tuple(images), ground, np.zeros((1, 3), np.uint8), np.zeros(1),
        np.full(1, 3),
    )  # fmt: skip


def test_a_wire_too_faint_for_the_detector_is_found_by_all_views_together(tmp_path):
    """A wire 2 m beside and 4 m above a confirmed one, drawn at half the image noise: the
    detector marks few of its pixels, and the sweep puts a hypothesis on it within a few
    centimetres (a pixel is 4.3 cm). The views of one strip see it as well from hypotheses
    metres higher, which the sweep may also make: tracing, with every view checked by the
    others, is what tells them apart (``pipeline._faint_wires``)."""
    confirmed = _wire(0, 0.0, 20.0, 0.5)
    faint = _wire(1, 2.0, 24.0, 0.8)
    scene = _scene(tmp_path, [(confirmed, -60.0), (faint, 4.0)])
    # Too faint for the detector: it marks few of the faint wire's pixels (in pieces, too
    # short to pair into a wire).
    marked = []
    for im in scene.images:
        mask = detect_wires(cv2.imread(str(im.path), cv2.IMREAD_GRAYSCALE), 0.0).mask
        uv, _, ok = im.project(faint.polyline(0.1))
        px = np.round(uv[ok]).astype(int)
        px = px[(px[:, 0] >= 0) & (px[:, 0] < W) & (px[:, 1] >= 0) & (px[:, 1] < H)]
        marked.append(mask[px[:, 1], px[:, 0]])
    assert np.concatenate(marked).mean() < 0.2
    hyps, decoded = faint_hypotheses(scene, [confirmed], DetectOptions(), 6.0)
    assert len(decoded) == 15
    assert 1 <= len(hyps) <= 4
    d = [np.median(distance_to_polyline(h.wire.polyline(0.5), faint.polyline(0.05))) for h in hyps]
    assert min(d) < 0.1
    assert all(h.z_score >= 6.0 for h in hyps)
    # None on the confirmed wire: its image is masked in every view.
    assert all(
        np.median(distance_to_polyline(h.wire.polyline(0.5), confirmed.polyline(0.05))) > 1.0
        for h in hyps
    )


def test_each_span_of_a_line_is_swept(tmp_path):
    """Two spans in one tile: span 1's conductor, traced 4 m past the pole into span 2, is the
    line's longest wire; span 2's conductor is shorter, and a faint wire (drawn at the image
    noise's level) hangs beside it in span 2 only. The sweep along the longest wire's
    stretch sees 4 m of that wire and puts no hypothesis near it (all the sweep did before:
    on the real road flight one span's lower cable went unswept); span 2's stretch is swept
    too, and its best hypothesis lies on the wire (11 sd, 7 cm off; a pixel is 4.3 cm)."""
    span1 = _wire(0, 0.0, 20.0, 0.3, -20.0, 4.0)
    span2 = _wire(1, 0.0, 20.0, 0.2, 0.0, 20.0)
    piece = _wire(2, 1.0, 20.0, 0.1, -15.0, -5.0)  # inside span 1's stretch: not swept
    faint = _wire(3, 2.0, 24.0, 0.3, 0.0, 20.0)
    assert [w.wire_id for w in sweep_refs([piece, span2, span1])] == [0, 1]
    scene = _scene(tmp_path, [(span1, -60.0), (span2, -60.0), (faint, 8.0)])
    hyps, _ = faint_hypotheses(scene, [span1, span2], DetectOptions(), 6.0)
    assert {h.ref_id for h in hyps} <= {0, 1}

    def off(h: FaintHypothesis) -> float:
        return float(np.median(distance_to_polyline(h.wire.polyline(0.5), faint.polyline(0.05))))

    assert all(off(h) > 0.5 for h in hyps if h.ref_id == 0)
    on_span2 = [h for h in hyps if h.ref_id == 1]
    assert on_span2[0].wire.s_range == span2.s_range
    assert off(on_span2[0]) < 0.1


@pytest.mark.parametrize("seed", [1, 2])
def test_no_faint_wire_no_hypothesis(tmp_path, seed):
    """The same views with the confirmed wire alone: the sweep's chance peaks stay below
    the threshold, and no hypothesis is made."""
    confirmed = _wire(0, 0.0, 20.0, 0.5)
    scene = _scene(tmp_path, [(confirmed, -60.0)], seed)
    hyps, _ = faint_hypotheses(scene, [confirmed], DetectOptions(), 6.0)
    assert hyps == []


def test_remap_takes_any_number_of_rows():
    """OpenCV's remap takes fewer than 2^15 rows: a sweep of 300 x 150 cells has 45,000."""
    from scipy.ndimage import map_coordinates

    from colmap_powerline.faint import _remap

    rng = np.random.default_rng(0)
    image = rng.random((50, 60)).astype(np.float32)
    x = (rng.random((45000, 4)) * 59).astype(np.float32)
    y = (rng.random((45000, 4)) * 49).astype(np.float32)
    np.testing.assert_allclose(
        _remap(image, x, y), map_coordinates(image, [y, x], order=1), atol=1e-5
    )


def _measured_to(wire: FittedWire, x_end: float) -> tuple[FittedWire, np.ndarray]:
    """The wire with points every 5 cm from x = -19 to ``x_end`` (what tracing measured)."""
    pts = wire.points(np.arange(-19.0, x_end, 0.05))
    return dataclasses.replace(wire, point_indices=np.arange(len(pts))), pts


@pytest.mark.parametrize("drawn_to", [8.0, -6.0])
def test_a_span_wire_s_stretches_the_views_show_only_together_are_measured(tmp_path, drawn_to):
    """A span-wire (x = -20..20) measured along x = -19..-6, drawn in the images from
    x = -20 to ``drawn_to`` at half the image noise: the detector marks few of its pixels.
    Where it is drawn, the views' evidence together measures its stretches on from the
    measured ones, within a few centimetres; where it is not, nothing is taken."""
    wire = _wire(0, 0.0, 24.0, 0.8)
    scene = _scene(tmp_path, [(dataclasses.replace(wire, s_range=(-20.0, drawn_to)), 4.0)])
    measured, pts = _measured_to(wire, -6.0)
    new, views, decoded = evidence_stretches(scene, [measured], pts, DetectOptions(), 4.0, 3, 1)
    assert len(decoded) == 15
    if drawn_to < 0:
        assert len(new[0]) == 0
        return
    s = measured.plane_coords(new[0])[0]
    assert s.min() > -6.5 and 4.0 < s.max() < drawn_to + 2.0
    assert np.median(distance_to_polyline(new[0], wire.polyline(0.02))) < 0.05
    assert (views[0] >= 3).all()


@pytest.mark.parametrize("beside_m", [0.18, 0.3])
def test_a_stretch_whose_wire_runs_beside_the_curve_is_measured_on_the_wire_or_not(
    tmp_path, beside_m
):
    """From x = -6 on, the wire the images show runs ``beside_m`` beside the span-wire's
    curve (where the curve, continued, misses it). Whatever is taken there lies on the wire
    the images show (its peak within 15 cm of the curve), not on the curve; where the wire
    lies farther out, a higher peak just outside vetoes the stretch."""
    wire = _wire(0, 0.0, 24.0, 0.8)
    beside = _wire(0, beside_m, 24.0, 0.8)
    drawn = [
        (dataclasses.replace(wire, s_range=(-20.0, -6.0)), 4.0),
        (dataclasses.replace(beside, s_range=(-6.0, 8.0)), 4.0),
    ]
    scene = _scene(tmp_path, drawn)
    measured, pts = _measured_to(wire, -6.0)
    new, _, _ = evidence_stretches(scene, [measured], pts, DetectOptions(), 4.0, 3, 1)
    s = measured.plane_coords(new[0])[0]
    assert len(s) == 0 or s.max() < 8.0 + 2.0  # the stretch at the drawn end, at most
    past = new[0][(s > -5.0) & (s < 7.0)]
    if len(past):
        shown = [w.polyline(0.02) for w, _ in drawn]
        d = np.min([distance_to_polyline(past, c) for c in shown], axis=0)
        assert np.median(d) < 0.06 and d.max() < 0.1  # 18 cm beside: 4.6, 9.8 cm
    if beside_m > 0.25:
        assert len(past) == 0


def test_a_wire_drifting_off_its_curve_continued_is_measured_where_the_evidence_leads(tmp_path):
    """A span-wire measured along x = -19..-6 whose curve, continued, drifts off the wire
    the images show: from x = -6 the wire turns 2 % away across (0.28 m at x = 8; a
    catenary fitted to part of its span is off past it by its slope's error). Judged around
    the curve alone, its stretches end where the wire leaves the 15 cm around it (x = 3);
    judged, where the evidence does not hold on the curve, around the curve of the family
    the evidence prefers (:func:`faint._continued`), they are measured on (to x = 7), on
    the wire."""
    wire = _wire(0, 0.0, 24.0, 0.8)
    turn = np.arctan(0.02)
    turned = dataclasses.replace(
        wire,
        plane_origin_xy=np.array([-6.0, 0.0]),
        plane_direction_xy=np.array([np.cos(turn), np.sin(turn)]),
        s0=6.0,  # the vertex at x = 0, as the wire's
        s_range=(0.0, 14.0),
    )
    drawn = [(dataclasses.replace(wire, s_range=(-20.0, -6.0)), 4.0), (turned, 4.0)]
    scene = _scene(tmp_path, drawn)
    measured, pts = _measured_to(wire, -6.0)
    new, views, _ = evidence_stretches(scene, [measured], pts, DetectOptions(), 4.0, 3, 1)
    s = measured.plane_coords(new[0])[0]
    assert s.min() > -6.5 and 5.0 < s.max() < 8.0 + 2.0  # 6.9 (2.9 around the curve)
    d = distance_to_polyline(new[0][(s > -5.0) & (s < 7.5)], turned.polyline(0.02))
    assert np.median(d) < 0.04 and d.max() < 0.08  # 2.7, 5.8 cm
    assert (views[0] >= 3).all()


def test_stretches_are_taken_from_the_measured_ones_on_past_unjudged_ones_and_one_miss():
    """From a measured stretch outwards, stretches are taken while the evidence holds; a
    stretch too few views see is passed over (neither taken nor ending the run), and so is
    one stretch that does not hold where the next judged one does; two in a row end it."""
    from colmap_powerline.faint import _walked

    T, F = True, False
    measured = np.array([T, T, F, F, F, F, F, F, F, F, F])
    holds = np.array([T, T, T, F, T, F, T, F, F, T, T])
    judged = np.array([T, T, T, T, T, F, T, T, T, T, T])
    taken = _walked(holds, judged, measured)
    # 2 holds; 3 misses, 4 holds (one miss passed over); 5 unjudged; 6 holds; 7, 8 miss:
    # the run ends, and 9, 10 are not reached.
    assert taken.tolist() == [F, F, T, F, T, F, T, F, F, F, F]
    # Nothing on its own: without a measured stretch nothing is taken.
    assert not _walked(holds, judged, np.zeros(11, bool)).any()
    # Both ways from a measured stretch in the middle.
    mid = np.zeros(11, bool)
    mid[5] = True
    assert _walked(np.ones(11, bool), np.ones(11, bool), mid).sum() == 10


def test_past_its_measured_stretches_a_wire_is_judged_around_the_curve_the_evidence_holds_best():
    """Past 20 measured stretches the views' evidence peaks on a curve climbing 1.5 % off
    the curve continued (a catenary fitted to part of a span is off past it by its slope's
    error: the shared twolines seed 12's shield), and from 25 m on a fainter line lies on
    the curve continued itself (the next wire's image, a fence). A curve of the family that
    climbs with the first and comes back down onto the second holds nearly as much evidence
    and lies nearest the curve at the far end; judged around it, the run's stretches went
    from the one curve to the other (the shield's walk took 13 or 7 of its stretches as its
    span's ends moved by 0.1 m). The curve the evidence holds best is the one used."""
    from colmap_powerline.faint import OFFSETS_ACROSS, OFFSETS_UP, STRETCH_M, _continued

    rng = np.random.default_rng(4)
    n_meas, n = 20, 40
    measured = np.arange(n) < n_meas
    a, u = np.meshgrid(OFFSETS_ACROSS, OFFSETS_UP, indexing="ij")
    m = rng.normal(0.0, 1.0, (len(OFFSETS_ACROSS), len(OFFSETS_UP), n))
    t = (np.arange(n) - (n_meas - 1) - 0.5) * STRETCH_M
    for b in range(n):
        if measured[b]:
            m[:, :, b] += 10.0 * np.exp(-(a**2 + u**2) / (2 * 0.15**2))
            continue
        m[:, :, b] += 10.0 * np.exp(-(a**2 + (u - 0.015 * t[b]) ** 2) / (2 * 0.15**2))
        if t[b] > 25.0:
            m[:, :, b] += 8.0 * np.exp(-(a**2 + u**2) / (2 * 0.15**2))
    centre, reach = _continued(m, measured, np.full(n, 4.0), 3)
    past = ~measured & reach
    assert past.sum() >= 15
    assert np.abs(centre[past, 1] - 0.015 * t[past]).max() < 0.1
    assert np.abs(centre[past, 0]).max() < 0.05


def test_every_wire_that_gained_stretches_is_judged_again_without_its_taken_ones(monkeypatch):
    """The views' evidence is judged in rounds, each on the curve refitted to what the
    round before took. Every wire that gained is judged again, though its refitted curve
    left some of the points it gained (the release before stopped there: shared twolines
    seed 12's shield then stopped where its first round's reach ended, 57.6 % of it; judged
    again, 76 %); and a stretch taken once stays taken (its points count as measured in
    the next round, wherever the refitted curve lies), so it is not taken twice."""
    from types import SimpleNamespace

    from colmap_powerline import pipeline
    from colmap_powerline.pipeline import ReconstructionOptions
    from colmap_powerline.verify import VerifiedPoints

    pts = np.c_[np.linspace(-20.0, 0.0, 10), np.zeros(10), np.full(10, 25.0)]
    n = len(pts)
    ones = np.ones(n, np.int32)
    verified = VerifiedPoints(
        pts, 3 * ones, 4 * ones, 2 * ones, 2 * ones, np.full(n, 0.999), 0 * ones,
        np.ones(n, bool), [], np.full(3, 0.8), [], np.arange(n), None,
    )  # fmt: skip
    wire = dataclasses.replace(_wire(0, 0.0, 26.0, 1.0), point_indices=np.arange(n))
    calls = []
    gains = [np.array([[2.0, 0.0, 25.0], [4.0, 0.0, 25.1], [6.0, 0.0, 25.2]]),
             np.array([[8.0, 0.0, 25.3], [10.0, 0.0, 25.4]])]  # fmt: skip

    def evidence(scene, wires, pts_in_world, detect, min_z, min_views, threads, only=None):
        calls.append((set(only) if only is not None else None, wires[0].point_indices.copy()))
        new = gains[len(calls) - 1] if len(calls) <= len(gains) else np.zeros((0, 3))
        return [new], [np.full(len(new), 3, np.int32)], []

    def refit(w, pts_in_world, idx, along, options):
        # The refitted curve leaves the first point the first round gained.
        return dataclasses.replace(w, point_indices=np.setdiff1d(idx, [n]))

    monkeypatch.setattr(pipeline, "evidence_stretches", evidence)
    monkeypatch.setattr(pipeline, "refit", refit)
    corridors = [SimpleNamespace(azimuth_deg=90.0)]
    spans = SimpleNamespace(legs=[0])
    out, more, _ = pipeline._measured_by_evidence(
        [wire], corridors, spans, verified, None, ReconstructionOptions()
    )
    assert len(calls) == 3  # judged again after each round that gained, until none does
    assert calls[1][0] == {0}
    # The second round counts every point the first gained as measured, the one the
    # refitted curve left too; the third, both rounds' points.
    assert set(range(n, n + 3)) <= set(calls[1][1].tolist())
    assert set(range(n, n + 5)) <= set(calls[2][1].tolist())
    assert len(more) == n + 5
