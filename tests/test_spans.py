"""Lines, spans and supports found from the wires (exact catenaries between known towers)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from colmap_powerline.pairs import WireCorridor
from colmap_powerline.spans import (
    LineSupport,
    SpanOptions,
    Spans,
    find_kink,
    find_spans,
    supports_csv,
)
from colmap_powerline.wires import FittedWire, WiresOptions, refit, split_wires


class _Sees:
    """A stand-in view 80 m up at ``(0, y)`` that sees every point within ``reach`` of the
    origin in plan (its image shows nothing: whether a wire goes on cannot be read)."""

    def __init__(self, reach: float, y: float = 0.0) -> None:
        self.reach = reach
        self.center_in_world = np.array([0.0, y, 80.0])

    def project(self, pts: np.ndarray):
        inside = np.hypot(pts[:, 0], pts[:, 1]) <= self.reach
        return np.zeros((len(pts), 2)), np.ones(len(pts)), inside


def _views(reach: float) -> list[_Sees]:
    """Three views from two strips, 30 m apart across the line."""
    return [_Sees(reach, -15.0), _Sees(reach, -15.0), _Sees(reach, 15.0)]


def _flat(xy: np.ndarray) -> np.ndarray:
    return np.zeros(len(xy))


def _corridor(azimuth_deg: float, centre=(0.0, 0.0)) -> WireCorridor:
    return WireCorridor(
        azimuth_deg=azimuth_deg, centre_xy=np.array(centre), half_width=30.0,
        wires_half_width=10.0, s_range=(-200.0, 200.0), height=30.0,
        height_range=(20.0, 45.0), from_images=True, measured=True,
    )  # fmt: skip


def _span_points(a_xyz, b_xyz, a_cat: float, rng, step=0.05, noise=0.02, keep=(2.0, 2.0)):
    """Points on the catenary of parameter ``a_cat`` hanging from a_xyz to b_xyz, every
    ``step``, ``keep`` metres short of each attachment (the insulators' hardware)."""
    a_xyz, b_xyz = np.asarray(a_xyz, float), np.asarray(b_xyz, float)
    d = b_xyz[:2] - a_xyz[:2]
    length = float(np.hypot(*d))
    u = d / length
    # z(s) = z0 + a(cosh((s - s0)/a) - 1) through both ends: solve s0 from the height step.
    h = b_xyz[2] - a_xyz[2]
    s0 = length / 2 - a_cat * np.arcsinh(h / (2 * a_cat * np.sinh(length / (2 * a_cat))))
    z0 = a_xyz[2] - a_cat * (np.cosh(s0 / a_cat) - 1)
    s = np.arange(keep[0], length - keep[1], step)
    z = z0 + a_cat * (np.cosh((s - s0) / a_cat) - 1)
    pts = np.c_[a_xyz[:2] + s[:, None] * u, z]
    return pts + rng.normal(0, noise, pts.shape)


def _wire(pts: np.ndarray, idx: np.ndarray, azimuth_xy: np.ndarray, wire_id: int) -> FittedWire:
    w0 = FittedWire(wire_id, np.zeros(2), azimuth_xy, 1e3, 0.0, 0.0, (0.0, 1.0), idx, 0.0)
    w = refit(w0, pts, idx, azimuth_xy, WiresOptions())
    assert w is not w0
    # All its points (one curve through a support leaves some of them by more than the
    # inlier distance; the pipeline's pieces hold them).
    lo, hi = w.plane_coords(pts[idx])[0][[0, -1]]
    return dataclasses.replace(w, point_indices=idx, s_range=(float(lo), float(hi)))


def _towers(turn_deg: float = 0.0):
    """Five towers 90 m apart along +x, the line turning by ``turn_deg`` at the third."""
    xy = [np.array([-180.0, 0.0]), np.array([-90.0, 0.0]), np.array([0.0, 0.0])]
    t = np.deg2rad(turn_deg)
    leg2 = np.array([np.cos(t), np.sin(t)])
    xy += [xy[2] + 90.0 * leg2, xy[2] + 180.0 * leg2]
    return xy, leg2


# Conductors: (offset across the line, attachment height).
PHASES = [(-5.0, 30.0), (5.0, 30.0), (-5.0, 35.0), (5.0, 35.0)]


def _line(rng, turn_deg: float, join_first_two: bool):
    """Every conductor of every span as points; span 1 and 2 of each conductor measured as
    one wire when ``join_first_two`` (measured across the support between them)."""
    towers, leg2 = _towers(turn_deg)
    pts, idx_of = [], []
    n = 0
    for c, z in PHASES:
        for k in range(4):
            a, b = towers[k], towers[k + 1]
            d = (b - a) / np.linalg.norm(b - a)
            normal = np.array([d[1], -d[0]])
            # At the angle tower the cross-arm bisects the turn: the same point for both legs.
            na = normal if k != 2 else _bisector_normal(leg2)
            nb = normal if k != 1 else _bisector_normal(leg2)
            p = _span_points(np.r_[a + c * na, z], np.r_[b + c * nb, z], 900.0, rng)
            pts.append(p)
            idx_of.append(np.arange(n, n + len(p)))
            n += len(p)
    pts = np.concatenate(pts)
    wires, wire_legs = [], []
    az = [np.array([1.0, 0.0]), leg2]
    for j in range(len(PHASES)):
        spans = idx_of[4 * j : 4 * j + 4]
        groups = [np.r_[spans[0], spans[1]], spans[2], spans[3]] if join_first_two else spans
        for g in groups:
            leg = 0 if np.mean(pts[g, 0]) < 0 else 1
            wires.append(_wire(pts, g, az[leg], len(wires)))
            wire_legs.append(leg)
    return pts, wires, wire_legs, towers


def _bisector_normal(leg2: np.ndarray) -> np.ndarray:
    d = np.array([1.0, 0.0]) + leg2
    d /= np.linalg.norm(d)
    n = np.array([d[1], -d[0]])
    return n / float(n @ np.array([0.0, -1.0]))  # offsets kept across each leg


def _over_a_support(rng, keep_a, keep_b, z_end=30.0):
    """Points of one conductor's two spans (90 m, attached at 30 m) either side of a
    support at the origin, and how many of them are the first span's."""
    a = _span_points([-90, 0, 30], [0, 0, 30], 900.0, rng, keep=keep_a)
    b = _span_points([0, 0, 30], [90, 0, z_end], 900.0, rng, keep=keep_b)
    return np.r_[a, b], len(a)


def test_a_kink_is_found_where_a_wire_passes_a_support():
    rng = np.random.default_rng(0)
    pts, n_a = _over_a_support(rng, (2.0, 0.0), (0.0, 2.0), z_end=29.0)
    a = pts[:n_a]
    w = _wire(pts, np.arange(len(pts)), np.array([1.0, 0.0]), 0)
    t = find_kink(w, pts, SpanOptions())
    assert t is not None
    assert abs(float(w.points(np.array([t]))[0, 0])) < 0.5
    # One span: no kink anywhere.
    w1 = _wire(a, np.arange(len(a)), np.array([1.0, 0.0]), 0)
    assert find_kink(w1, a, SpanOptions()) is None


def _pole_line(rng, conductors):
    """A pole line's conductors over two 45 m spans kinked at a pole at the origin (0.6 m
    of sag, attached at 10 m), each held by one curve over both spans: the curve fitted to
    the spans' outer parts, where it holds their points (the package's `parallel` layout),
    with their points by the pole in the cloud but not the curve's."""
    parts = [
        np.r_[
            _span_points([-45, c, 10], [0, c, 10], 420.0, rng, keep=(1.0, 0.3)),
            _span_points([0, c, 10], [45, c, 10], 420.0, rng, keep=(0.3, 1.0)),
        ]
        for c in conductors
    ]
    pts = np.concatenate(parts)
    starts = np.cumsum([0] + [len(p) for p in parts])
    wires = []
    for k in range(len(parts)):
        idx = np.arange(starts[k], starts[k + 1])
        outer = idx[np.abs(pts[idx, 0]) > 22.0]
        w = _wire(pts, outer, np.array([1.0, 0.0]), k)
        held = outer[w.distance(pts[outer]) < WiresOptions().inlier_distance]
        wires.append(dataclasses.replace(w, point_indices=held))
    return pts, wires


def test_a_support_is_found_where_one_curve_over_two_spans_lets_go_of_their_points():
    # One curve over two short spans kinked at a pole holds only their outer parts, and fits
    # them: no kink in the points it holds. The points in its plane by the pole lie up to
    # 0.6 m above it, and two conductors' curves let go of them at the same place.
    rng = np.random.default_rng(3)
    pts, wires = _pole_line(rng, [-1.0, 0.0, 1.0])
    assert all(find_kink(w, pts, SpanOptions()) is None for w in wires)
    sp = find_spans(_views(50.0), _flat, wires, [0, 0, 0], [_corridor(90.0)], pts)
    inner = [s for s in sp.supports if s.kind != "end"]
    assert len(inner) == 1 and np.hypot(*inner[0].position[:2]) < 0.5
    # Each conductor cut there: two spans of three conductors, each reaching the pole.
    assert len(sp.wires) == 6
    assert sorted(p.span for p in sp.placement) == [1, 1, 1, 2, 2, 2]
    for w in sp.wires:
        ends = w.points(np.array(w.s_range))
        assert np.min(np.abs(ends[:, 0])) < 0.5
    # One conductor's curve letting go of the points by a place is no support.
    sp = find_spans(_views(50.0), _flat, wires[:1], [0], [_corridor(90.0)], pts)
    assert not [s for s in sp.supports if s.kind != "end"] and len(sp.wires) == 1


@pytest.mark.parametrize(
    ("turn_deg", "flipped"), [(0.0, ()), (25.0, ()), (25.0, (0,)), (25.0, (1,)), (25.0, (0, 1))]
)
def test_supports_spans_and_conductors_of_a_line(turn_deg, flipped):
    # ``flipped``: the legs whose corridor's azimuth was measured the other way round (an
    # axial direction: either way is the line's). Walked away from the angle support, a
    # first leg folded the line back on itself, and both legs' spans were numbered 1 and 2
    # (the package's angle layout at half scale).
    rng = np.random.default_rng(1)
    pts, wires, legs, towers = _line(rng, turn_deg, join_first_two=True)
    corridors = [
        _corridor((az + (180.0 if k in flipped else 0.0)) % 360.0)
        for k, az in enumerate((90.0, 90.0 - turn_deg))
    ]
    if turn_deg == 0.0:  # a straight line is one corridor
        corridors, legs = corridors[:1], [0] * len(legs)
    views = _views(220.0)  # the images see 40 m past the end towers
    sp = find_spans(views, _flat, wires, legs, corridors, pts)
    # Five supports where the towers are, on one line: ends, suspension, angle. Inner ones
    # where the curves meet (within 0.5 m); the line's ends where its wires end, short of
    # the towers by the 2 m the measurements stop short of them.
    assert len(sp.supports) == 5
    found = np.array([s.position[:2] for s in sp.supports])
    err = [np.min(np.linalg.norm(found - t, axis=1)) for t in towers]
    assert max(err[1:4]) < 0.5 and max(err[0], err[4]) < 2.5
    kinds = [s.kind for s in sp.supports]
    middle = "angle" if turn_deg else "suspension"
    assert kinds == ["end", "suspension", middle, "suspension", "end"]
    assert {s.line for s in sp.supports} == {1}
    for s in sp.supports:
        assert s.top_z == pytest.approx(35.0, abs=0.1)
    if turn_deg:
        angle = next(s for s in sp.supports if s.kind == "angle")
        assert angle.turn_deg == pytest.approx(turn_deg, abs=1.0)
    # The wire measured across the support at x = -90 is cut there: 4 spans x 4 conductors.
    assert len(sp.wires) == 16
    spans = {}
    for w, p in zip(sp.wires, sp.placement, strict=True):
        ends = w.points(np.array(w.s_range))
        # Each wire reaches its two attachments (the insulators' tips), within 5 cm.
        for e in ends:
            assert np.min([np.hypot(*(e[:2] - t)) for t in towers]) < 5.5 + 0.05
        assert None not in p.supports
        spans.setdefault(p.span, []).append(p)
    assert sorted(spans) == [1, 2, 3, 4]
    # Each conductor keeps its number from span to span: four conductors, one per span.
    by_conductor = {}
    for p in sp.placement:
        by_conductor.setdefault(p.conductor, []).append(p.span)
    assert len(by_conductor) == 4
    assert all(sorted(v) == [1, 2, 3, 4] for v in by_conductor.values())


def test_a_wire_carried_a_little_past_its_support_ends_at_its_attachment():
    """Every conductor measured span by span, and span 2's top conductor carried 3 m past
    the support at x = 0 (tracing past a pole takes the next span's wire, nearly in line,
    until it bends away): too little to be cut there (4 m), so the tail was kept and the
    wire was written and drawn 3 m past the pole. It ends at its attachment now, as the
    wires that stop short of it are extended to theirs."""
    rng = np.random.default_rng(1)
    towers, _ = _towers(0.0)
    pts, idx_of = [], []
    n = 0
    for c, z in PHASES:
        for k in range(4):
            a, b = np.r_[towers[k] + (0.0, -c), z], np.r_[towers[k + 1] + (0.0, -c), z]
            p = _span_points(a, b, 900.0, rng)
            if (c, z, k) == (PHASES[2][0], PHASES[2][1], 1):
                nxt = _span_points(
                    b, np.r_[towers[k + 2] + (0.0, -c), z], 900.0, rng, keep=(0.0, 0.0)
                )
                p = np.r_[p, nxt[nxt[:, 0] < b[0] + 3.0]]
            pts.append(p)
            idx_of.append(np.arange(n, n + len(p)))
            n += len(p)
    pts = np.concatenate(pts)
    wires = [_wire(pts, idx, np.array([1.0, 0.0]), k) for k, idx in enumerate(idx_of)]
    carried = wires[4 * 2 + 1]
    assert carried.points(np.array(carried.s_range))[:, 0].max() > 2.5
    sp = find_spans(_views(220.0), _flat, wires, [0] * len(wires), [_corridor(90.0)], pts)
    assert len(sp.supports) == 5
    x_ends = np.array([w.points(np.array(w.s_range))[:, 0] for w in sp.wires])
    inner = [t[0] for t in towers[1:4]]
    near_inner = np.min(np.abs(x_ends[..., None] - np.array(inner)), axis=-1)
    # At an attachment: within half a metre of an inner tower, or at a line's end (where
    # the wires' measurements end, 2 m short of the end towers).
    at_end = np.abs(np.abs(x_ends) - 180.0) < 2.5
    assert np.all((near_inner < 0.5) | at_end), x_ends
    # Its points past the pole are the next span's: left out, and the wire fitted without
    # them (within the wires' tolerance of the attachment, 2.5 inlier distances).
    out = sp.wires[[sp.source[k] for k in range(len(sp.wires))].index(4 * 2 + 1)]
    assert pts[out.point_indices, 0].max() <= 0.3
    assert out.catenary_a == pytest.approx(900.0, rel=0.05)


def test_a_straight_line_s_conductors_are_split_into_one_wire_per_span():
    # Measured to within half a metre of the attachments, one conductor's spans of a
    # straight line touch at each support: the voxel chains join them, and one curve holds
    # none of that chain. Each span's wire is its own.
    rng = np.random.default_rng(4)
    towers, _ = _towers(0.0)
    pts = np.concatenate(
        [
            _span_points(
                np.r_[towers[k] + (0.0, -c), z],
                np.r_[towers[k + 1] + (0.0, -c), z],
                900.0,
                rng,
                keep=(0.3, 0.3),
            )  # fmt: skip
            for c, z in PHASES
            for k in range(4)
        ]
    )
    wires = split_wires(pts, 90.0)  # the line along +x
    assert len(wires) == 16
    for w in wires:
        # Its points within one span (between two neighbouring towers), along most of it.
        x = pts[w.point_indices, 0]
        k = int(np.floor((np.median(x) + 180.0) / 90.0))
        inside = (x >= towers[k][0] - 1.0) & (x <= towers[k + 1][0] + 1.0)
        assert inside.mean() > 0.99
        assert np.ptp(x[inside]) > 85.0
        assert w.rms_residual < 0.04


def test_a_span_s_wire_takes_no_stray_points_past_the_support_it_ends_at():
    # As above, and a few stray points (false matches) lie on span 1's curves continued
    # 20 m into span 2, 2 m apart: too few for a wire, close enough to the continued curve
    # to be taken as its points, which would carry the wire's end into span 2 (shared
    # multispan seed 3: span 1's L2 ran 23 m on, and the views then rejected it).
    rng = np.random.default_rng(6)
    towers, _ = _towers(0.0)
    parts = []
    for c, z in PHASES:
        for k in range(4):
            a, b = np.r_[towers[k] + (0.0, -c), z], np.r_[towers[k + 1] + (0.0, -c), z]
            parts.append(_span_points(a, b, 900.0, rng, keep=(0.3, 0.3)))
            if k == 0:
                run_on = _span_points(a, b, 900.0, rng, keep=(0.3, -20.0))
                parts.append(run_on[run_on[:, 0] > b[0] + 0.5][::40])
    pts = np.concatenate(parts)
    wires = split_wires(pts, 90.0)
    assert len(wires) == 16
    for w in wires:
        x = pts[w.point_indices, 0]
        k = int(np.floor((np.median(x) + 180.0) / 90.0))
        assert towers[k][0] - 1.0 <= x.min() and x.max() <= towers[k + 1][0] + 1.0
        assert np.ptp(x) > 85.0


def test_pieces_meeting_where_the_next_span_s_wires_run_through_are_no_support(caplog):
    # A straight line of four spans, every conductor measured span by span; the upper two
    # conductors' wires of spans 1 and 3 carry a tail of stray points 17-27 m into span 2
    # (on their curves continued, as a few false matches lie). Continued, those curves
    # meet mid-span in a downward bend, where the span-2 wires are measured straight
    # through: no support there, the tails left out, every wire kept.
    rng = np.random.default_rng(5)
    pts, wires, legs, towers = _line(rng, 0.0, join_first_two=False)
    extra = []
    n = len(pts)
    for j, w in enumerate(wires):
        span = j % 4
        if PHASES[j // 4][1] != 35.0 or span not in (0, 2):
            continue
        at = np.array([towers[1][0] + 22.0 if span == 0 else towers[2][0] - 22.0, 0.0])
        s_mid = float(w.plane_coords(np.r_[at, 30.0][None])[0][0])
        tail = w.points(np.linspace(s_mid - 5.0, s_mid + 5.0, 60))
        tail += rng.normal(0, 0.02, tail.shape)
        idx = np.arange(n, n + len(tail))
        n += len(tail)
        extra.append(tail)
        s_all = w.plane_coords(np.r_[pts[w.point_indices], tail])[0]
        wires[j] = dataclasses.replace(
            w,
            point_indices=np.r_[w.point_indices, idx],
            s_range=(float(s_all.min()), float(s_all.max())),
        )
    pts = np.r_[pts, *extra]
    with caplog.at_level("INFO", logger="colmap_powerline.spans"):
        sp = find_spans(_views(220.0), _flat, wires, [0] * len(legs), [_corridor(90.0)], pts)
    found = np.array([s.position[:2] for s in sp.supports])
    assert len(sp.supports) == 5
    assert max(np.min(np.linalg.norm(found - t, axis=1)) for t in towers[1:4]) < 0.5
    assert "no support at" in caplog.text
    assert len(sp.wires) == 16
    for w in sp.wires:
        x = w.points(np.array(w.s_range))[:, 0]
        k = int(np.floor((float(np.mean(x)) + 180.0) / 90.0))
        assert towers[k][0] - 6.0 <= x.min() and x.max() <= towers[k + 1][0] + 6.0


def test_a_wire_measured_from_one_support_of_its_span_hangs_from_the_other_too():
    """A span's conductors reach both its supports; a faint shield measured along 38 m of
    its 90 m span from one of them (its end 50 m from the other: farther than pieces
    meet) hangs from the other too: it is drawn to both attachments, and tracing and the
    views' evidence may measure the rest."""
    rng = np.random.default_rng(4)
    pts, wires, legs, towers = _line(rng, 0.0, join_first_two=False)
    half = _span_points([-90, 0, 42], [0, 0, 42], 1500.0, rng, keep=(2.0, 50.0))
    pts = np.r_[pts, half]
    idx = np.arange(len(pts) - len(half), len(pts))
    wires = wires + [_wire(pts, idx, np.array([1.0, 0.0]), len(wires))]
    sp = find_spans(_views(220.0), _flat, wires, [0] * len(wires), [_corridor(90.0)], pts)
    assert len(sp.supports) == 5
    at = {i: s.position[0] for i, s in enumerate(sp.supports)}
    shield = [(w, p) for w, p in zip(sp.wires, sp.placement, strict=True) if w.z0 > 40.0]
    assert len(shield) == 1
    w, p = shield[0]
    assert None not in p.supports
    assert sorted(at[i] for i in p.supports) == pytest.approx([-90.0, 0.0], abs=0.5)
    assert sorted(w.points(np.array(w.s_range))[:, 0]) == pytest.approx([-90.0, 0.0], abs=0.5)
    assert p.span == next(q.span for q in sp.placement if set(q.supports) == set(p.supports))


def test_tracing_takes_a_wire_drawn_far_past_its_points_on_from_where_they_end():
    """Tracing looks along the whole curve it is given at once: a wire drawn on to a support
    farther past its points than pieces of one conductor meet (40 m) is given to it ending
    where they end there (past that, its curve is a prediction, traced round by round with
    tracing's tests); one drawn nearer to its attachment is given as drawn."""
    from colmap_powerline.pipeline import _measured_part

    rng = np.random.default_rng(5)
    pts = _span_points([-90, 0, 42], [0, 0, 42], 1500.0, rng, keep=(2.0, 50.0))
    w = _wire(pts, np.arange(len(pts)), np.array([1.0, 0.0]), 0)
    lo, hi = w.s_range
    drawn = dataclasses.replace(w, s_range=(lo - 2.0, hi + 48.0))
    given = _measured_part(drawn, pts, 40.0)
    assert given.s_range == pytest.approx((lo - 2.0, hi), abs=0.05)
    assert _measured_part(drawn, pts, 60.0).s_range == drawn.s_range


def test_a_wire_hangs_at_the_end_only_from_the_supports_its_points_reach():
    """Drawn to its span's far support so that tracing and the views' evidence could
    measure it on, a wire whose points still end farther from that support than pieces
    meet (40 m) ends at its points there and hangs from no support at that end; one
    measured to within that hangs from both."""
    from colmap_powerline.pipeline import ReconstructionOptions, _hung_where_reached
    from colmap_powerline.spans import Spans, WireSpan

    rng = np.random.default_rng(6)
    short = _span_points([0, 0, 42], [100, 0, 42], 1500.0, rng, keep=(2.0, 65.0))
    long = _span_points([0, 5, 42], [100, 5, 42], 1500.0, rng, keep=(2.0, 35.0))
    pts = np.r_[short, long]
    az = np.array([1.0, 0.0])
    wires = [
        _wire(pts, np.arange(len(short)), az, 0),
        _wire(pts, np.arange(len(short), len(pts)), az, 1),
    ]
    drawn = []
    for w in wires:  # drawn to both attachments, x = 0 and 100
        s = w.plane_coords(
            np.array([[0.0, w.plane_origin_xy[1], 0.0], [100.0, w.plane_origin_xy[1], 0.0]])
        )[0]
        drawn.append(dataclasses.replace(w, s_range=(float(s.min()), float(s.max()))))
    placement = [WireSpan(1, 1, (0, 1), 0), WireSpan(1, 1, (0, 1), 1)]
    spans = Spans(drawn, placement, [], [0, 1])
    out, sp = _hung_where_reached(drawn, spans, pts, ReconstructionOptions())
    assert sp.placement[1].supports == (0, 1) and out[1].s_range == drawn[1].s_range
    near, far = sorted(out[0].points(np.array(out[0].s_range))[:, 0])
    assert near == pytest.approx(0.0, abs=0.05) and far == pytest.approx(35.0, abs=0.5)
    s_far = 0 if out[0].plane_direction_xy[0] < 0 else 1
    assert sp.placement[0].supports[s_far] is None and sp.placement[0].supports[1 - s_far] == 0
    assert sp.wires is out and spans.placement[0].supports == (0, 1)


def test_wires_running_out_of_the_images_end_at_no_support():
    rng = np.random.default_rng(2)
    pts, wires, legs, towers = _line(rng, 0.0, join_first_two=False)
    # The images see only up to 185 m from the centre: the end towers' wires run out.
    sp = find_spans(_views(181.0), _flat, wires, [0] * len(legs), [_corridor(90.0)], pts)
    kinds = sorted(s.kind for s in sp.supports)
    assert kinds == ["suspension"] * 3


def test_lines_spans_and_supports_are_written(tmp_path):
    import csv
    import json

    from colmap_powerline.clearance import measure_wire
    from colmap_powerline.export import export_results
    from colmap_powerline.scene import GroundModel

    rng = np.random.default_rng(3)
    pts, wires, legs, _ = _line(rng, 25.0, join_first_two=False)
    sp = find_spans(_views(220.0), _flat, wires, legs, [_corridor(90.0), _corridor(65.0)], pts)
    x, y = np.meshgrid(np.arange(-250, 251, 5.0), np.arange(-150, 151, 5.0))
    ground = GroundModel(np.c_[x.ravel(), y.ravel()], np.zeros(x.size), 5.0)
    labels = np.full(len(pts), -1)
    for w in sp.wires:
        labels[w.point_indices] = w.wire_id
    export_results(
        tmp_path, wires=sp.wires, points=pts, labels=labels, primitives=None,
        metadata={"input_model": "test"}, measures=[measure_wire(w, ground) for w in sp.wires],
        placement=sp.placement, line_supports=sp.supports,
        to_crs=(lambda xyz: xyz + [1000.0, 2000.0, 0.0], "shifted"),
    )  # fmt: skip
    doc = json.loads((tmp_path / "wires.json").read_text())
    assert [s["kind"] for s in doc["supports"]] == [
        "end", "suspension", "angle", "suspension", "end"
    ]  # fmt: skip
    assert doc["supports"][2]["turn_deg"] == pytest.approx(25.0, abs=1.0)
    assert doc["supports"][1]["position"][0] == pytest.approx(1000.0 - 90.0, abs=0.5)
    assert doc["supports"][1]["height_m"] == pytest.approx(35.0, abs=0.1)
    for w in doc["wires"]:
        assert w["line"] == 1 and 1 <= w["span"] <= 4 and None not in w["support_ids"]
        # Sag from the chord between the attachments: the level 90 m span's true sag (the
        # end spans' only to where the wires end, short of the end towers).
        if w["span"] == 2:
            assert w["measures"]["sag_max_m"] == pytest.approx(
                900.0 * (np.cosh(45.0 / 900.0) - 1.0), abs=0.03
            )
    rows = list(csv.DictReader((tmp_path / "supports.csv").open()))
    assert [r["kind"] for r in rows] == [s["kind"] for s in doc["supports"]]
    assert float(rows[1]["x"]) == pytest.approx(910.0, abs=0.5)
    assert {r["lines"] for r in rows} == {"1"}
    table = list(csv.DictReader((tmp_path / "wires.csv").open()))
    assert {(r["line"], r["span"]) for r in table} == {("1", str(k)) for k in (1, 2, 3, 4)}
    assert len({r["conductor"] for r in table}) == len(PHASES)


def test_a_support_topped_by_a_conductor_where_the_line_has_shields_stands_as_the_others(caplog):
    """A support's top is its highest attachment found. Where the line's shields were found
    at other supports but not at this one, its top is a conductor's and the structure stands
    higher: its top is put as far above its highest conductor as the shields stand above
    the conductors at the others (top_from ``line``), and the log says so. A line without
    shields keeps its conductors' tops."""
    from types import SimpleNamespace

    from colmap_powerline.pipeline import _tops_from
    from colmap_powerline.spans import WireSpan

    def sup(i: int, top: float, top_wire: int, line: int = 1) -> LineSupport:
        return LineSupport(i, line, "end", np.zeros(3), top, 0.0, (0, 1), "wires ending",
                           top_wire=top_wire)  # fmt: skip

    def wire(i: int, z0: float, z1: float) -> SimpleNamespace:
        # its ends at s = 0 and 1 (its first and last support), heights z0 and z1
        return SimpleNamespace(
            wire_id=i, s_range=(0.0, 1.0),
            points=lambda s: np.c_[s, 0 * s, z0 + (z1 - z0) * s],
        )  # fmt: skip

    wires = [wire(0, 38.0, 38.5), wire(1, 45.0, 45.5), wire(2, 38.5, 37.0), wire(3, 20.0, 21.0)]
    kinds = ["conductor", "shield", "conductor", "conductor"]
    measures = [SimpleNamespace(kind=k) for k in kinds]
    placement = [WireSpan(1, 1, (0, 1), 0), WireSpan(1, 1, (0, 1), 1), WireSpan(1, 2, (1, 2), 0),
                 WireSpan(2, 1, (3, None), 0)]  # fmt: skip
    supports = [sup(0, 45.0, 1), sup(1, 45.5, 1), sup(2, 37.0, 2), sup(3, 20.0, 3, line=2)]
    with caplog.at_level("WARNING", logger="colmap_powerline.pipeline"):
        out = _tops_from(supports, wires, measures, placement)
    assert [s.top_from for s in out] == ["shield", "shield", "line", "conductor"]
    assert [s.to_json()["top_from"] for s in out] == ["shield", "shield", "line", "conductor"]
    # the shields stand 7.0 above the conductors at supports 0 and 1
    assert [s.top_z for s in out] == pytest.approx([45.0, 45.5, 44.0, 20.0])
    said = [r.getMessage() for r in caplog.records]
    assert len(said) == 1 and said[0].startswith("support 2 (line 1)")


def test_a_support_s_top_is_read_from_its_wires_as_they_are_drawn_at_the_end():
    """The wires are traced on and refitted after the supports are found: each support's
    top, top wire, wires and reach are read again from the wires' ends at it as they are
    drawn then (a shield's curve fitted to a short piece and continued to the support put
    the package's `angle` layout's towers 8 m high)."""
    from colmap_powerline.spans import WireSpan, attached_again

    def wire(i: int, x0: float, x1: float, z: float) -> FittedWire:
        # along x from x0 to x1, all but straight at height z
        return FittedWire(i, np.zeros(2), np.array([1.0, 0.0]), 1e6, 50.0, z, (x0, x1),
                          np.zeros(0, np.int64), 0.0)  # fmt: skip

    def sup(i: int, x: float, top: float) -> LineSupport:
        return LineSupport(i, 1, "end", np.array([x, 0.0, 0.0]), top, 0.0, (), "wires ending",
                           top_wire=9)  # fmt: skip

    wires = [wire(0, 0.0, 100.0, 20.0), wire(1, 0.0, 100.0, 28.0), wire(2, 0.0, 40.0, 36.5)]
    placement = [WireSpan(1, 1, (0, 1), 0), WireSpan(1, 1, (0, 1), 1), WireSpan(1, 1, (0, None), 2)]
    stale = [sup(0, 0.0, 44.8), sup(1, 100.0, 51.2)]
    out = attached_again(stale, wires, placement)
    z = [float(w.points(np.array([w.s_range[0]]))[0, 2]) for w in wires]
    assert out[0].top_z == pytest.approx(max(z), abs=1e-6) and out[0].top_wire == 2
    assert out[0].wire_ids == (0, 1, 2)
    z1 = [float(w.points(np.array([w.s_range[1]]))[0, 2]) for w in wires[:2]]
    assert out[1].top_z == pytest.approx(max(z1), abs=1e-6) and out[1].top_wire == 1
    assert out[1].wire_ids == (0, 1) and out[1].reach_m == pytest.approx(0.0, abs=1e-6)
    assert stale[0].top_z == 44.8  # the caller's supports are not changed


def _drawn_views(tmp_path, truth: list[np.ndarray], places, rng, poles=()) -> list:
    """Nadir views 50 m up at ``places`` (x, y), 90° across (a pixel is 8 cm at 25 m), of
    noisy grey ground with the ``truth`` curves (dense 3D points) drawn a pixel wide, and
    ``poles`` (foot, top, width) drawn as bars of their width."""
    import cv2
    import pycolmap

    from colmap_powerline.scene import SceneImage

    f, size = 300.0, 600
    camera = pycolmap.Camera(
        model="PINHOLE", width=size, height=size, params=[f, f, size / 2, size / 2], camera_id=1
    )
    rot = np.diag([1.0, -1.0, -1.0])  # world x is image u, world y image -v
    views = []
    for k, (x, y) in enumerate(places):
        path = tmp_path / f"view{k}.png"
        im = SceneImage(k + 1, path.name, path, camera, rot, -rot @ np.array([x, y, 50.0]))
        line = np.zeros((size * 4, size * 4), np.float32)  # drawn at 4x, averaged down
        for p in truth:
            uv, _, ok = im.project(p)
            q = np.round((uv[ok] + 0.5) * 4 - 0.5).astype(np.int32)
            if len(q) > 1:
                cv2.polylines(line, [q], False, 1.0, thickness=4)
        for foot, top, width in poles:
            uv, depth, _ = im.project(np.array([foot, top], float))
            t = (uv[1] - uv[0]) / np.linalg.norm(uv[1] - uv[0])
            half = 0.5 * width * f / depth[:, None] * np.array([-t[1], t[0]])
            quad = np.array([uv[0] - half[0], uv[0] + half[0], uv[1] + half[1], uv[1] - half[1]])
            cv2.fillConvexPoly(line, np.round((quad + 0.5) * 4 - 0.5).astype(np.int32), 0.5)
        grey = 128.0 + 60.0 * cv2.resize(line, (size, size), interpolation=cv2.INTER_AREA)
        grey += rng.normal(0.0, 6.0, grey.shape)
        cv2.imwrite(str(path), np.clip(grey, 0, 255).astype(np.uint8))
        views.append(im)
    return views


def test_a_wire_carried_far_past_its_support_in_the_next_span_s_plane_gives_that_stretch_up(
    tmp_path, caplog
):
    # Two conductors 3 m apart hang in two spans from a support at x = 0 (the outer supports
    # lie outside the images). One conductor's first-span wire carries 25 m of points past
    # the support, on its own curve continued, in the plane of its second-span wire (as
    # matches in views from above put them). Cut at the support, such a tail runs on
    # smoothly, and the old code left the whole wire out as a false pairing. The views
    # beside the plane show the second span's wire there, not the tail: the tail is left
    # out, the wire kept, and the support found where the pieces meet.
    rng = np.random.default_rng(3)
    a_cat = 600.0
    ends = {(y, k): (np.array([60.0 * k - 60.0, y, 30.0]), np.array([60.0 * k, y, 30.0]))
            for y in (0.0, 3.0) for k in (0, 1)}  # fmt: skip
    truth = [_span_points(a, b, a_cat, rng, step=0.02, noise=0.0, keep=(0.0, 0.0))
             for a, b in ends.values()]  # fmt: skip
    places = [(x, y) for y in (-12.0, 0.0, 14.0) for x in (-5.0, 8.0, 20.0)]
    views = _drawn_views(tmp_path, truth, places, rng)
    pts, wires, n = [], [], 0
    for j, ((y, k), (a, b)) in enumerate(ends.items()):
        p = _span_points(a, b, a_cat, rng)
        if (y, k) == (0.0, 0):
            d = 60.0 + np.linspace(2.0, 25.0, 1200)  # along the plane from x = -60
            z = 30.0 + a_cat * (np.cosh((d - 30.0) / a_cat) - np.cosh(30.0 / a_cat))
            tail = np.c_[d - 60.0, np.zeros_like(d), z] + rng.normal(0, 0.02, (len(d), 3))
            p = np.r_[p, tail]
        pts.append(p)
        idx = np.arange(n, n + len(p))
        n += len(p)
        wires.append(_wire(np.concatenate(pts), idx, np.array([1.0, 0.0]), j))
    pts = np.concatenate(pts)
    with caplog.at_level("INFO", logger="colmap_powerline.spans"):
        sp = find_spans(views, _flat, wires, [0] * 4, [_corridor(90.0)], pts)
    assert "wire 0 lies in one plane with another wire and the views show the other" in caplog.text
    assert len(sp.supports) == 1
    assert abs(sp.supports[0].position[0]) < 0.5  # (midway between the conductors across)
    assert len(sp.wires) == 4
    for w in sp.wires:  # each wire hangs on one side of the support
        x = w.points(np.array(w.s_range))[:, 0]
        assert x.max() <= 0.5 or x.min() >= -0.5


def test_wires_in_one_plane_stay_where_no_view_parts_them_or_they_never_touch(tmp_path):
    # A conductor over two spans with a cable hanging 2 m under it in the same vertical plane
    # (they never touch: both stay), and a second copy of the conductor's first span carried
    # on 25 m, seen only by views right above the plane (none parts the two curves: both
    # stay, as before).
    rng = np.random.default_rng(4)
    a_cat = 600.0
    spans = [(np.array([-60.0, 0.0, 30.0]), np.array([0.0, 0.0, 30.0])),
             (np.array([0.0, 0.0, 30.0]), np.array([60.0, 0.0, 30.0]))]  # fmt: skip
    cable = (np.array([-60.0, 0.0, 28.0]), np.array([60.0, 0.0, 28.0]))
    truth = [_span_points(a, b, a_cat, rng, step=0.02, noise=0.0, keep=(0.0, 0.0))
             for a, b in spans + [cable]]  # fmt: skip
    views = _drawn_views(tmp_path, truth, [(x, 0.0) for x in (-5.0, 8.0, 20.0)], rng)
    pts = [_span_points(a, b, a_cat, rng) for a, b in spans]
    pts.append(_span_points(*cable, 1800.0, rng))
    d = 60.0 + np.linspace(2.0, 25.0, 1200)  # the first span's curve continued past x = 0
    z = 30.0 + a_cat * (np.cosh((d - 30.0) / a_cat) - np.cosh(30.0 / a_cat))
    pts.append(np.c_[d - 60.0, np.zeros_like(d), z] + rng.normal(0, 0.02, (len(d), 3)))
    n = np.cumsum([0] + [len(p) for p in pts])
    pts = np.concatenate(pts)
    wires = [_wire(pts, np.arange(n[k], n[k + 1]), np.array([1.0, 0.0]), k) for k in range(4)]
    before = [(w.wire_id, w.s_range) for w in wires]
    from colmap_powerline import spans as spans_module

    work = spans_module._Work(list(wires), [0, 1, 2, 3], [0, 0, 0, 0], set(), 4)
    leg = spans_module._Leg(_corridor(90.0))
    spans_module._one_per_plane(
        work, [leg], views, pts, SpanOptions(), WiresOptions(), 2.5 * WiresOptions().inlier_distance
    )
    assert [(w.wire_id, w.s_range) for w in work.wires] == before


def test_two_supports_placed_again_at_one_place_are_one():
    from colmap_powerline.spans import _one_per_place

    found = [(0, 17.9, "pieces meeting", {0, 1}), (0, -40.7, "kink", {2}),
             (0, 17.5, "pieces meeting", {7, 10}), (1, 17.6, "pieces meeting", {3, 4}),
             (0, 95.0, "wires ending", {5, 6})]  # fmt: skip
    out = _one_per_place(found, SpanOptions())
    assert [(li, round(u, 1), how, ids) for li, u, how, ids in out] == [
        (0, -40.7, "kink", {2}),
        (0, 17.7, "pieces meeting", {0, 1, 7, 10}),
        (0, 95.0, "wires ending", {5, 6}),
        (1, 17.6, "pieces meeting", {3, 4}),
    ]


def test_pieces_do_not_meet_where_a_curve_is_carried_far_from_its_points():
    # One conductor over a support at x = 0; its first-span piece stops 25 m short of it
    # (more than half the 40 m gap allowed), the second starts 1 m past it: their curves,
    # continued, cross at the support, but the first's is a guess that far out.
    from colmap_powerline.spans import _Leg, _pieces_meet

    pts, n_a = _over_a_support(np.random.default_rng(6), (2.0, 25.0), (1.0, 2.0))
    wa = _wire(pts, np.arange(n_a), np.array([1.0, 0.0]), 0)
    wb = _wire(pts, np.arange(n_a, len(pts)), np.array([1.0, 0.0]), 1)
    leg = _Leg(_corridor(90.0))
    assert _pieces_meet(wa, wb, leg, SpanOptions(), 0.3) is None
    # Each within 20 m of its points, they meet at the support.
    near = SpanOptions(max_meeting_gap=60.0)
    assert abs(_pieces_meet(wa, wb, leg, near, 0.3)) < 1.0


# Three level conductors 3 m apart on a 120 m span (a = 600) ending at a terminal tower at
# x = 60 (the tower at x = -60 outside every view).
_TERMINAL_YS = (-3.0, 0.0, 3.0)
_TERMINAL_A = 600.0


def _terminal_curves(far: dict[float, float]) -> list[np.ndarray]:
    """The three conductors' curves as the images show them: each from x = -60 on to
    ``far[y]`` (60: it ends at the tower; more: a line on its curve continued past it)."""
    out = []
    for y in _TERMINAL_YS:
        x = np.arange(-60.0, far.get(y, 60.0), 0.02)
        z = 30.0 + _TERMINAL_A * (np.cosh(x / _TERMINAL_A) - np.cosh(60.0 / _TERMINAL_A))
        out.append(np.c_[x, np.full_like(x, y), z])
    return out


def _terminal_spans(views, rng, short_m: float = 2.0) -> Spans:
    """The supports the spans stage finds for the three conductors, measured to ``short_m``
    short of each tower (negative: carried past it), seen by ``views``."""
    ends = [(np.array([-60.0, y, 30.0]), np.array([60.0, y, 30.0])) for y in _TERMINAL_YS]
    pts = [_span_points(a, b, _TERMINAL_A, rng, keep=(2.0, short_m)) for a, b in ends]
    n = np.cumsum([0] + [len(p) for p in pts])
    pts = np.concatenate(pts)
    wires = [_wire(pts, np.arange(n[k], n[k + 1]), np.array([1.0, 0.0]), k) for k in range(3)]
    return find_spans(views, _flat, wires, [0] * 3, [_corridor(90.0)], pts)


@pytest.mark.parametrize("goes_on", [False, True])
def test_a_line_s_end_seen_past_by_two_views_only(tmp_path, goes_on):
    # Past the terminal tower only two views see the line (the shared cross seed 2: a strip
    # across the line sees 5-10 m past the tower from two images): fewer than tracing
    # needs, so the wires may end for want of views. Both show the wires plainly before
    # their ends and no line past them: the line ends there. Where they show the wires
    # going on (the wires stopped short of the images' edge), no support is made up.
    rng = np.random.default_rng(7)
    far = dict.fromkeys(_TERMINAL_YS, 100.0 if goes_on else 60.0)
    views = _drawn_views(tmp_path, _terminal_curves(far), [(62.0, -8.0), (62.0, 8.0)], rng)
    sp = _terminal_spans(views, rng)
    if goes_on:
        assert sp.supports == []
    else:
        assert [s.kind for s in sp.supports] == ["end"]
        assert abs(sp.supports[0].position[0] - 59.0) < 1.5


@pytest.mark.parametrize("short_m", [2.0, -2.5, -4.5])
def test_a_line_s_end_is_placed_where_its_wires_line_evidence_stops(tmp_path, short_m):
    # The wires' measurements stop 2 m short of the terminal tower (its insulators'
    # hardware), or run 2.5 m past it (carried on its members: the shared mixed seed 3,
    # 1.8 m), or 4.5 m past it (a round of tracing past the end took ground texture near
    # the curve continued: the package's parallel layout, its first pole). The images show
    # the wires up to the tower at x = 60: the end support is placed there, not where the
    # measurements end.
    rng = np.random.default_rng(11)
    places = [(56.0, -8.0), (56.0, 8.0), (62.0, 0.0)]
    views = _drawn_views(tmp_path, _terminal_curves({}), places, rng)
    sp = _terminal_spans(views, rng, short_m)
    assert [s.kind for s in sp.supports] == ["end"]
    assert abs(sp.supports[0].position[0] - 60.0) < 0.5


_POLE = ((60.0, 0.0, 0.0), (60.0, 0.0, 30.0), 0.3)
_MEMBER = ((58.5, -1.5, 0.0), (60.5, 0.0, 30.0), 0.3)


@pytest.mark.parametrize(("poles", "at"), [([], 60.7), ([_POLE], 60.0), ([_MEMBER], 60.7)])
def test_a_line_s_end_is_placed_at_the_pole_the_images_show(tmp_path, poles, at):
    # The images show the wires running 0.7 m past the terminal pole at x = 60 (along its
    # arm: the package's parallel layout, its end poles placed 0.4-0.6 m out). Where they
    # also show the pole (a 0.3 m bar from the ground to the wires), the end is placed at
    # it; where they show none, or a slanting bar (a lattice tower's member), where the
    # wires' evidence ends. Three views read the pole (the fourth, 2 m from it, sees it
    # end-on), from three directions (two views on one line through the pole read it
    # along that line both).
    rng = np.random.default_rng(11)
    places = [(56.0, -8.0), (56.0, 8.0), (62.0, 0.0), (67.0, -3.0)]
    views = _drawn_views(tmp_path, _terminal_curves(dict.fromkeys(_TERMINAL_YS, 60.7)), places,
                         rng, poles)  # fmt: skip
    sp = _terminal_spans(views, rng, -0.7)
    assert [s.kind for s in sp.supports] == ["end"]
    assert abs(sp.supports[0].position[0] - at) < 0.2


def test_a_line_ends_where_the_views_of_all_its_wires_together_say_so(tmp_path):
    # Past the terminal tower, two of the three views show a line on one wire's curve
    # continued (a fence, a road edge, the next line's conductor beside it: the shared
    # cross seed 6, one view of one wire), none on the others': the reads of all three
    # wires together say the line ends, and it does.
    rng = np.random.default_rng(8)
    (tmp_path / "b").mkdir()
    views = _drawn_views(tmp_path, _terminal_curves({}), [(62.0, -8.0)], rng)
    views += _drawn_views(
        tmp_path / "b", _terminal_curves({0.0: 100.0}), [(62.0, 0.0), (62.0, 8.0)], rng
    )
    sp = _terminal_spans(views, rng)
    assert [s.kind for s in sp.supports] == ["end"]


@pytest.mark.parametrize(
    ("votes", "loser"),
    [((1, 0), 1), ((0, 3), 0), ((3, 1), 1), ((2, 1), 2), ((2, 2), 2), ((0, 0), None)],
)
def test_a_stretch_the_views_disagree_on_goes_to_neither_wire(monkeypatch, votes, loser):
    """Two curves in one plane: the stretch where they lie apart goes to the one the views
    show; where a third or more of those views show the other, to neither (2: both give it
    up; on the road flight 2 views against 1 decided a stretch that ran across a pole, and a
    hair's change in the points turned it); where no view parts them, to both (None)."""
    from colmap_powerline import spans

    monkeypatch.setattr(spans, "_told_apart", lambda *a: votes)
    pts = np.c_[np.linspace(0.0, 30.0, 200), np.zeros(200), np.linspace(30.0, 31.0, 200)]
    a = _wire(pts, np.arange(200), np.array([1.0, 0.0]), 0)
    b = dataclasses.replace(a, wire_id=1, z0=a.z0 + 1.0)
    u = np.linspace(0.0, 30.0, 121)
    leg = spans._Leg(_corridor(90.0))
    lost = spans._stretches_lost(a, b, leg, u, np.full(121, -1.0), 0.3, [], {})
    assert (None if lost is None else lost[0]) == loser


def test_both_wires_give_up_a_stretch_the_views_disagree_on(monkeypatch):
    """Two wires in one plane crossing at x = 15: where the views disagree, neither keeps
    its points in the stretch past the crossing (both are refitted to the rest)."""
    from colmap_powerline import spans

    # No view parts them before the crossing; past it they disagree.
    monkeypatch.setattr(
        spans, "_told_apart", lambda views, a, b, greys: (2, 1) if a[:, 0].mean() > 15 else (0, 0)
    )
    x = np.linspace(0.0, 30.0, 301)
    pts = np.r_[np.c_[x, 0 * x, 30.0 + 0.04 * x], np.c_[x, 0 * x, 31.2 - 0.04 * x]]
    wires = [_wire(pts, np.arange(301) + 301 * k, np.array([1.0, 0.0]), k) for k in (0, 1)]
    work = spans._Work(list(wires), [0, 1], [0, 0], set(), 2)
    axes = [spans._Leg(_corridor(90.0))]
    spans._one_per_plane(work, axes, [], pts, SpanOptions(), WiresOptions(), 0.3)
    assert len(work.wires) == 2
    for w in work.wires:
        x_kept = pts[w.point_indices, 0]
        assert x_kept.max() < 16.0 and x_kept.min() < 1.0  # the stretch past 15 given up


@pytest.mark.parametrize("unmeasured_m", [0.0, 11.0])
def test_a_line_leaving_a_support_of_another_is_a_line_of_its_own(unmeasured_m):
    # A straight line of four spans along +x; at its middle support (the origin) a branch
    # line of two wires leaves at 70 deg to it and runs 60 m to a pole of its own. The main
    # line's span past the junction may be measured only from ``unmeasured_m`` past it.
    rng = np.random.default_rng(5)
    pts, wires, legs, towers = _line(rng, 0.0, join_first_two=False)
    legs = [0] * len(legs)
    for k, w in enumerate(wires):
        x = pts[w.point_indices, 0]
        if x.min() > -1.0 and x.max() < 91.0 and unmeasured_m:
            idx = w.point_indices[x > unmeasured_m]
            wires[k] = _wire(pts, idx, np.array([1.0, 0.0]), w.wire_id)
    t = np.deg2rad(70.0)
    d = np.array([np.cos(t), np.sin(t)])
    across = np.array([d[1], -d[0]])
    end = 60.0 * d
    for c in (-1.0, 1.0):
        p = _span_points(np.r_[c * across, 28.0], np.r_[end + c * across, 27.0], 600.0, rng)
        idx = np.arange(len(pts), len(pts) + len(p))
        pts = np.r_[pts, p]
        wires.append(_wire(pts, idx, d, len(wires)))
        legs.append(1)
    corridors = [_corridor(90.0), _corridor(20.0, centre=(10.0, 28.0))]
    sp = find_spans(_views(220.0), _flat, wires, legs, corridors, pts)
    junction = [s for s in sp.supports if s.kind == "junction"]
    assert len(junction) == 1
    j = junction[0]
    # Placed where the line running through found it, carrying both lines.
    assert np.hypot(*j.position[:2]) < 0.5
    assert j.line == 1 and j.lines == (1, 2)
    assert j.turn_deg == pytest.approx(70.0, abs=1.0)
    main = [s for s in sp.supports if s.line == 1]
    assert [s.kind for s in main] == ["end", "suspension", "junction", "suspension", "end"]
    branch = [(w, p) for w, p in zip(sp.wires, sp.placement, strict=True) if p.line == 2]
    assert len(branch) == 2
    ends = [s for s in sp.supports if s.line == 2]
    assert len(ends) == 1 and ends[0].kind == "end"
    assert np.linalg.norm(ends[0].position[:2] - end) < 2.5
    for w, p in branch:
        assert p.span == 1 and set(p.supports) == {j.support_id, ends[0].support_id}
        # Each branch wire reaches the junction pole's attachment (its end within a few cm
        # of where it hangs, 1 m beside the pole across the branch).
        near = w.points(np.array(w.s_range))[:, :2]
        assert np.min(np.linalg.norm(near, axis=1)) == pytest.approx(1.0, abs=0.1)
    row = next(r for r in supports_csv(sp.supports).splitlines()[1:] if ",junction," in r)
    assert row.endswith(",1 2")
    # The main line's spans are as without the branch: 4 spans x 4 conductors.
    assert sum(p.line == 1 for p in sp.placement) == 16
    assert sorted({p.span for p in sp.placement if p.line == 1}) == [1, 2, 3, 4]


def test_wires_hanging_in_groups_apart_are_lines_of_their_own():
    """A double circuit (conductors 10 m apart across, 5 m apart in height) and a pole line
    28 m beside it, lower, in one corridor: two lines, the pole line's corridor centred on
    it; the double circuit alone stays one line (its two sides 10 m apart)."""
    from colmap_powerline.pipeline import _lines_apart
    from colmap_powerline.results import CorridorResult

    rng = np.random.default_rng(2)
    places = [(c, z) for c in (-5.0, 5.0) for z in (21.0, 26.0, 31.0)]
    places += [(26.8, 10.5), (28.0, 12.0), (29.2, 10.5)]
    pts, wires = [], []
    for k, (c, z) in enumerate(places):
        p = _span_points(np.r_[-50.0, c, z], np.r_[50.0, c, z], 600.0, rng)
        idx = np.arange(sum(len(q) for q in pts), sum(len(q) for q in pts) + len(p))
        pts.append(p)
        wires.append(_wire(np.concatenate(pts), idx, np.array([1.0, 0.0]), k))
    corridor = _corridor(90.0)

    def part(ws):
        return CorridorResult(corridor, [], [], None, ws, [], [], len(ws), 0, [0] * len(ws),
                              [corridor])  # fmt: skip

    out = _lines_apart(part(wires))
    assert out.legs == [0] * 6 + [1] * 3 and len(out.corridors) == 2
    assert abs(out.corridors[1].centre_xy @ corridor.normal_xy) == pytest.approx(28.0, abs=0.1)
    assert out.corridors[1].azimuth_deg == corridor.azimuth_deg
    alone = part(wires[:6])
    assert _lines_apart(alone) is alone


def test_a_line_beside_another_passes_its_support_by_and_is_told_apart():
    # A pole line's three conductors (1 m apart, 10 m up) over two 45 m spans kinked at a
    # pole at the origin, each measured across it as one wire; 8 m beside it (within
    # LINE_LINK_M, so one corridor) a tower line's two conductors, 17 and 21 m up, run
    # straight past the pole on a 160 m span. The pole is found where the pole line's
    # wires bend; the tower line's wires pass it without a bend, across beyond them: a line
    # beside (the package's `parallel` layout 12 m apart: dropped as false pairings before,
    # the tower line's conductors 0-50 % complete).
    rng = np.random.default_rng(3)
    parts = []
    for y in (-1.0, 0.0, 1.0):
        a = _span_points([-45, y, 10.0], [0, y, 10.0], 420.0, rng, keep=(2.0, 0.0))
        b = _span_points([0, y, 10.0], [45, y, 10.0], 420.0, rng, keep=(0.0, 2.0))
        parts.append(np.r_[a, b])
    for y, z in ((-9.0, 17.0), (-11.0, 21.0)):
        parts.append(_span_points([-80, y, z], [80, y, z], 900.0, rng, keep=(20.0, 20.0)))
    n = np.cumsum([0] + [len(p) for p in parts])
    pts = np.concatenate(parts)
    wires = [_wire(pts, np.arange(n[k], n[k + 1]), np.array([1.0, 0.0]), k) for k in range(5)]
    sp = find_spans([], _flat, wires, [0] * 5, [_corridor(90.0)], pts)
    # Across is -y along +x: the tower line lies on the side of more across, beyond 1 m.
    assert len(sp.beside) == 1
    leg, across, side = sp.beside[0]
    assert leg == 0 and side == 1 and 1.0 < across < 9.0
    # Its wires are not dropped; given a corridor of their own (as the pipeline gives them,
    # `_beside_apart`), they are a line of their own, whole, and the pole line's wires
    # hang in two spans from the pole.
    assert sum(src >= 3 for src in sp.source) == 2
    beside = dataclasses.replace(_corridor(90.0), centre_xy=np.array([0.0, -10.0]))
    sp = find_spans([], _flat, wires, [0, 0, 0, 1, 1], [_corridor(90.0), beside], pts)
    assert sp.beside == []
    tower = [w for w, src in zip(sp.wires, sp.source, strict=True) if src >= 3]
    assert len(tower) == 2 and all(np.ptp(w.s_range) > 100.0 for w in tower)
    lines = {p.line for p, src in zip(sp.placement, sp.source, strict=True) if src >= 3}
    poles = {p.line for p, src in zip(sp.placement, sp.source, strict=True) if src < 3}
    assert len(lines) == 1 and len(poles) == 1 and lines != poles
    assert sorted(p.span for p, src in zip(sp.placement, sp.source, strict=True) if src < 3) == [
        1,
        1,
        1,
        2,
        2,
        2,
    ]


# A cross-arm 0.2 m under the conductors at x = 0 (their lowest point, 27.0 m up), across the
# line (y from -3.8 to 3.8), and
# a bar as long across it on the ground at x = 20 (a road edge, a field's end).
_ARM = ((0.0, -3.8, 26.8), (0.0, 3.8, 26.8), 0.12)
_GROUND_BAR = ((20.0, -3.8, 0.0), (20.0, 3.8, 0.0), 0.12)


@pytest.mark.parametrize(("bars", "found"), [([_ARM], True), ([], False), ([_GROUND_BAR], False)])
def test_a_pole_the_wires_hang_straight_through_is_found_by_its_cross_arm(tmp_path, bars, found):
    # Three conductors hang in one smooth curve through x = 0, where a pole holds them on a
    # cross-arm: the road flight's 45-59 m spans sag about 0.2 m and bend there by about 2°,
    # below what a kink needs. The images show the arm, a bar across the line a little
    # under the wires, in every view at one place: a support there (a suspension pole).
    # With no arm drawn, or a bar on the ground (each view sees it at another place along
    # the line at the wires' height), none.
    rng = np.random.default_rng(5)
    places = [(x, y) for x in (-12.0, -4.0, 4.0, 12.0, 24.0) for y in (-6.0, 6.0)]
    views = _drawn_views(tmp_path, _terminal_curves({}), places, rng, bars)
    ends = [(np.array([-60.0, y, 30.0]), np.array([60.0, y, 30.0])) for y in _TERMINAL_YS]
    pts = [_span_points(a, b, _TERMINAL_A, rng) for a, b in ends]
    n = np.cumsum([0] + [len(p) for p in pts])
    pts = np.concatenate(pts)
    wires = [_wire(pts, np.arange(n[k], n[k + 1]), np.array([1.0, 0.0]), k) for k in range(3)]
    sp = find_spans(views, _flat, wires, [0] * 3, [_corridor(90.0)], pts)
    arms = [s for s in sp.supports if s.found_by == "cross-arm"]
    if found:
        assert len(arms) == 1
        assert arms[0].kind == "suspension"
        assert abs(arms[0].position[0]) < 0.2
        # Each conductor cut there: two spans of three.
        assert sorted({p.span for p in sp.placement}) == [1, 2]
    else:
        assert arms == []


@pytest.mark.parametrize(("past", "kind"), [(3.5, "end"), (6.0, "suspension")])
def test_a_line_s_end_is_moved_to_the_cross_arm_its_wires_hang_from(tmp_path, past, kind):
    # The wires and the images' lines stop ``past`` metres beyond the terminal pole at
    # x = 60, whose cross-arm (0.2 m under the conductors) the images show: the end is
    # placed at the arm, not where the wires stop. Stopping more than a support's radius
    # past it (the full road flight's north-west end: 4.7 m; the images there show the
    # wires going on), they go on past the pole: a suspension, the stretch past it kept.
    rng = np.random.default_rng(12)
    far = dict.fromkeys(_TERMINAL_YS, 60.0 + past)
    arm = ((60.0, -3.8, 29.8), (60.0, 3.8, 29.8), 0.12)
    places = [(x, y) for x in (44.0, 52.0, 60.0, 68.0, 76.0) for y in (-6.0, 6.0)]
    views = _drawn_views(tmp_path, _terminal_curves(far), places, rng, [arm])
    sp = _terminal_spans(views, rng, -past)
    assert [s.kind for s in sp.supports] == [kind]
    assert abs(sp.supports[0].position[0] - 60.0) < 0.2
    if kind == "suspension":
        assert sorted({p.span for p in sp.placement}) == [1, 2]


@pytest.mark.parametrize("turn", [0.0, 12.0, -25.0])
def test_a_line_turning_on_at_its_last_measured_pole_is_an_angle_not_an_end(tmp_path, turn):
    # The three conductors' measurements end at the pole at x = 60; the images show the
    # line going on past it turned by ``turn`` in plan (the 40-image road flight's field
    # line: about 9°, its next leg not measured), or (0) not at all. Turned, the support is
    # an angle support with that turn, not the line's end.
    rng = np.random.default_rng(13)
    truth = _terminal_curves({})
    if turn:
        t = np.radians(turn)
        d = np.arange(0.0, 40.0, 0.02)
        for y in _TERMINAL_YS:
            # Clockwise from above by ``turn``, as azimuths grow: +x turns toward -y.
            # The next span hangs as this one: mirrored about the pole.
            z = 30.0 + _TERMINAL_A * (
                np.cosh((60.0 - d) / _TERMINAL_A) - np.cosh(60.0 / _TERMINAL_A)
            )
            truth.append(np.c_[60.0 + d * np.cos(t), y - d * np.sin(t), z])
    places = [(56.0, -8.0), (56.0, 8.0), (62.0, 0.0), (66.0, -6.0), (66.0, 6.0)]
    views = _drawn_views(tmp_path, truth, places, rng)
    sp = _terminal_spans(views, rng)
    assert len(sp.supports) == 1
    s = sp.supports[0]
    assert abs(s.position[0] - 60.0) < 1.0
    if turn:
        assert s.kind == "angle" and s.found_by == "wires turning"
        assert s.turn_deg == pytest.approx(abs(turn), abs=2.0)
    else:
        assert s.kind == "end" and s.found_by == "wires ending"


def test_a_span_wire_traced_down_to_the_floor_goes_with_its_line():
    # After tracing on to the supports, a "line" of one wire across the span that now comes
    # down to the floor of the heights searched (5 m above the ground: shared cross seed 22,
    # a road's edges paired, 5.09 m at its lowest) is left out; its line goes and the other
    # line is line 1, its supports numbered from 0.
    import types

    from colmap_powerline.pipeline import ReconstructionOptions, _spans_above_the_floor
    from colmap_powerline.spans import LineSupport, Spans, WireSpan

    def flat(a, z0):
        return FittedWire(0, np.zeros(2), np.asarray(a, float), 1e4, 0.0, z0, (-40.0, 40.0),
                          np.arange(3), 0.03)  # fmt: skip

    wires = [
        dataclasses.replace(flat([0.0, 1.0], 5.09), wire_id=7),  # across: the ghost
        dataclasses.replace(flat([1.0, 0.0], 25.0), wire_id=3),
        dataclasses.replace(flat([1.0, 0.0], 27.0), wire_id=4),
    ]
    sups = [
        LineSupport(i, 2, "end", np.array([x, 0.0, 0.0]), 28.0, 0.0, (3, 4), "wires ending")
        for i, x in ((0, -40.0), (1, 40.0))
    ]
    placement = [WireSpan(1, 1, (None, None), 0)] + [WireSpan(2, 1, (0, 1), k) for k in (0, 1)]
    spans = Spans(list(wires), placement, sups, [0, 1, 2], [0, 1, 1])
    scene = types.SimpleNamespace(ground_height=lambda xy: np.zeros(len(xy)))
    judged = ["a", "b", "c"]  # the wires' supports, in their order
    out, sp, kept = _spans_above_the_floor(wires, spans, judged, scene, ReconstructionOptions())
    assert [w.wire_id for w in out] == [3, 4] and kept == ["b", "c"]
    assert [p.line for p in sp.placement] == [1, 1]
    assert [p.supports for p in sp.placement] == [(0, 1), (0, 1)]
    assert [(t.support_id, t.line, t.lines) for t in sp.supports] == [(0, 1, (1,)), (1, 1, (1,))]
    assert sp.source == [1, 2] and sp.legs == [1, 1]
    # Nothing at the floor: all as given.
    assert (
        _spans_above_the_floor(wires[1:], spans, judged, scene, ReconstructionOptions())[1] is spans
    )


def test_a_line_going_on_over_brighter_ground_than_its_wires_is_not_ended(tmp_path):
    # The wires (grey 170) show bright over the field (110) and dark over a concrete drive
    # (210) that the line crosses from x = 59 on, just past where their measurements end
    # (the full road flight's south-east end: a drive beside the road, the wires going on
    # over it). Read for the wires' polarity over the field, the stretch over the drive
    # held none, and the line "ended" there; over ground beyond the wires' own grey, a line
    # of either polarity holds them: the line goes on, no support is made up.
    import cv2
    import pycolmap

    from colmap_powerline.scene import SceneImage

    rng = np.random.default_rng(14)
    truth = _terminal_curves(dict.fromkeys(_TERMINAL_YS, 100.0))
    f, size = 300.0, 600
    camera = pycolmap.Camera(
        model="PINHOLE", width=size, height=size, params=[f, f, size / 2, size / 2], camera_id=1
    )
    rot = np.diag([1.0, -1.0, -1.0])
    views = []
    for k, (x, y) in enumerate([(62.0, -8.0), (62.0, 8.0), (56.0, 0.0)]):
        path = tmp_path / f"view{k}.png"
        im = SceneImage(k + 1, path.name, path, camera, rot, -rot @ np.array([x, y, 50.0]))
        line = np.zeros((size * 4, size * 4), np.float32)
        for p in truth:
            uv, _, ok = im.project(p)
            q = np.round((uv[ok] + 0.5) * 4 - 0.5).astype(np.int32)
            cv2.polylines(line, [q], False, 1.0, thickness=4)
        cover = cv2.resize(line, (size, size), interpolation=cv2.INTER_AREA)
        ground = np.full((size, size), 110.0)
        edge = im.project(np.array([[59.0, 0.0, 30.0]]))[0][0, 0]  # the drive behind x = 59
        ground[:, int(np.ceil(edge)) :] = 210.0
        grey = ground + cover * (170.0 - ground) + rng.normal(0.0, 4.0, ground.shape)
        cv2.imwrite(str(path), np.clip(grey, 0, 255).astype(np.uint8))
        views.append(im)
    sp = _terminal_spans(views, rng)
    assert sp.supports == []
