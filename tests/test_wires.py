"""Splitting verified points into wires and fitting catenaries."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from colmap_powerline.pipeline import ReconstructionOptions, _confirm_grown
from colmap_powerline.support import WireSupport, support_members
from colmap_powerline.synthetic import SyntheticSpanOptions, TrueWire, build_span
from colmap_powerline.wires import (
    FittedWire,
    WiresOptions,
    _supports_of_line,
    fit_catenary,
    merge_pieces,
    split_wires,
)


@pytest.fixture(scope="module")
def truth() -> list[TrueWire]:
    return build_span(SyntheticSpanOptions(scale=0.05, show_progress=False)).wires


def _noisy_points(truth, rng, gaps=True):
    pts = []
    for w in truth:
        s = np.arange(2.0, w.length_m - 2.0, 0.03)
        if gaps:  # a missed stretch per wire
            start = rng.uniform(10, 80)
            s = s[(s < start) | (s > start + rng.uniform(3, 8))]
        pts.append(w.points(s) + rng.normal(0, 0.02, (len(s), 3)))
    pts.append(truth[0].points(np.arange(30, 50, 0.05)) + 0.01)  # a second pair's duplicate
    core = np.concatenate(pts)
    lo, hi = core.min(axis=0), core.max(axis=0)
    outliers = rng.uniform(lo - 5, hi + 5, (int(0.02 * len(core)), 3))
    blob = core[0] + np.array([3.0, 3.0, -6.0]) + rng.normal(0, 0.05, (200, 3))
    return np.concatenate([core, outliers, blob])


def test_fit_catenary_recovers_parameters():
    rng = np.random.default_rng(1)
    s = np.linspace(0, 100, 400)
    for a, s0, z0 in [(600.0, 48.0, 20.0), (900.0, 20.0, 31.0)]:  # level and inclined spans
        z = z0 + a * (np.cosh((s - s0) / a) - 1) + rng.normal(0, 0.02, len(s))
        fa, fs0, fz0, res = fit_catenary(s, z)
        assert abs(fa - a) / a < 0.05 and abs(fs0 - s0) < 1.0 and abs(fz0 - z0) < 0.02
        assert res.shape == s.shape and np.sqrt(np.mean(res**2)) < 0.025
    fa, _, _, res = fit_catenary(s, np.full(len(s), 12.0))  # straight and level
    assert fa > 1e4 and np.abs(res).max() < 2e-4
    with pytest.raises(ValueError, match="at least 3"):
        fit_catenary(s[:2], s[:2])


def test_split_separates_stacked_and_side_by_side_wires(truth):
    rng = np.random.default_rng(0)
    pts = _noisy_points(truth, rng)
    wires = split_wires(pts, 35.0)
    assert len(wires) == len(truth) == 8
    assert all(isinstance(w, FittedWire) for w in wires)
    assert [w.wire_id for w in wires] == list(range(8))
    matched = set()
    for w in wires:
        poly = w.polyline(0.5)
        t = min(
            truth,
            key=lambda t: np.median(
                np.abs(poly[:, 2] - t.z_at((poly[:, :2] - t.attach_a[:2]) @ t.direction_xy))
                + np.abs(
                    (poly[:, :2] - t.attach_a[:2])
                    @ np.array([t.direction_xy[1], -t.direction_xy[0]])
                )
            ),
        )
        matched.add(t.wire_id)
        s = (poly[:, :2] - t.attach_a[:2]) @ t.direction_xy
        dz = poly[:, 2] - t.z_at(s)
        assert np.sqrt(np.mean(dz**2)) < 0.02  # measured ≈ 0.3 cm
        assert w.s_range[1] - w.s_range[0] > 90  # the gap was bridged: one wire, not two
        assert w.rms_residual < 0.04
        assert len(w.polyline(0.1)) == pytest.approx((w.s_range[1] - w.s_range[0]) / 0.1, abs=2)
    assert matched == {t.wire_id for t in truth}


def test_short_sloping_piece_is_fitted_closely():
    # 8 m of a wire 40 m from its lowest point: the lowest point is far and ill-determined,
    # the curve over the piece is not.
    a, s0, z0 = 700.0, -40.0, 20.0
    s = np.linspace(0, 8, 200)
    z = z0 + a * (np.cosh((s - s0) / a) - 1) + np.random.default_rng(4).normal(0, 0.02, len(s))
    fa, fs0, fz0, res = fit_catenary(s, z)
    fitted = fz0 + fa * (np.cosh((s - fs0) / fa) - 1)
    true = z0 + a * (np.cosh((s - s0) / a) - 1)
    assert np.abs(fitted - true).max() < 0.02 and np.sqrt(np.mean(res**2)) < 0.025


def test_points_more_curved_than_any_wire_are_not_a_wire():
    """A 7 m piece whose heights bend the way no overhead wire hangs (a = 12 m: 60 m of it
    would sag 37 m; on the real road flight, a piece mixing a lower cable's heights with a
    conductor's) is not fitted as a wire; the same piece hanging as wires do is."""
    rng = np.random.default_rng(3)
    s = np.linspace(0.0, 7.0, 300)
    for a, is_wire in ((12.0, False), (500.0, True)):
        z = 20.0 + a * (np.cosh((s - 3.5) / a) - 1.0) + rng.normal(0.0, 0.02, len(s))
        pts = np.c_[s, rng.normal(0.0, 0.02, len(s)), z]
        assert len(split_wires(pts, 90.0)) == int(is_wire)


def test_split_without_azimuth_hint(truth):
    pts = _noisy_points(truth, np.random.default_rng(2), gaps=False)
    assert len(split_wires(pts)) == 8


def test_sag_and_json(truth):
    t = truth[0]
    pts = t.points(np.arange(0, t.length_m, 0.05))
    (w,) = split_wires(pts, 35.0)
    assert w.sag() == pytest.approx(t.sag_m(), abs=0.01)
    d = w.to_json(lambda xy: np.zeros(len(xy)))
    assert d["clearance_m"] == pytest.approx(w.lowest_point()[2], abs=0.01)
    assert d["num_points"] == len(pts) and len(d["polyline"]) > 900
    assert set(d) >= {"id", "catenary", "plane", "ends", "sag_m", "lowest_point", "rms_m"}


def test_bad_input():
    with pytest.raises(ValueError, match="shape"):
        split_wires(np.zeros((10, 2)))
    assert split_wires(np.zeros((5, 3))) == []
    rng = np.random.default_rng(3)
    assert split_wires(rng.uniform(0, 50, (3000, 3)), 35.0) == []  # noise is not a wire


def _piece(wire_id: int, y: float, s_lo: float, s_hi: float, z: float) -> FittedWire:
    return FittedWire(
        wire_id=wire_id,
        plane_origin_xy=np.array([0.0, y]),
        plane_direction_xy=np.array([1.0, 0.0]),
        catenary_a=1000.0,
        s0=0.5 * (s_lo + s_hi),
        z0=z,
        s_range=(s_lo, s_hi),
        point_indices=np.arange(10),
        rms_residual=0.01,
    )


def test_tower_members_are_told_from_wires():
    """Conductors end at their supports; a short straight piece that runs through the place
    where they end, past it on both sides, is a member of the tower (the shared generator's
    towers gave two such 6-8 m pieces at 8 and 13 m height)."""
    span = [
        _piece(k, y, -49.5 + 0.3 * k, 48.0 + 0.4 * k, z)
        for k, (y, z) in enumerate([(4, 21), (4, 26), (5, 31), (-4, 21), (-4, 26), (-5, 31)])
    ]
    member = _piece(6, -2.5, 45.2, 53.6, 13.0)  # through the tower at ~49
    short_end = _piece(7, 5.0, 30.0, 48.5, 31.0)  # a conductor's last stretch: stops there
    mid_piece = _piece(8, 5.0, -10.0, 5.0, 30.0)  # a short piece in the middle of the span
    far_member = _piece(9, 2.0, -53.0, -46.0, 12.0)  # through the other tower
    wires = [*span, member, short_end, mid_piece, far_member]
    found = dict(support_members(wires, np.array([1.0, 0.0]), long_length=25.0))
    assert set(found) == {6, 9}
    assert found[6] == pytest.approx(48.9, abs=1.0) and found[9] == pytest.approx(-49, abs=1.0)
    # One long wire alone marks no support (its end may be where the images stop).
    assert support_members([span[0], member], np.array([1.0, 0.0]), 25.0) == []


def _catenary_points(s: np.ndarray, y: float, z0: float, a: float = 800.0) -> np.ndarray:
    rng = np.random.default_rng(int(z0 * 10))
    z = z0 + a * (np.cosh(s / a) - 1)
    return np.c_[s, np.full(len(s), y), z] + rng.normal(0, 0.02, (len(s), 3))


def _pieces(left: np.ndarray, right: np.ndarray) -> list[FittedWire]:
    """One fitted wire per point set, indexed into their concatenation."""
    (a,) = split_wires(left, 90.0)
    (b,) = split_wires(right, 90.0)
    b = dataclasses.replace(b, wire_id=1, point_indices=b.point_indices + len(left))
    return [a, b]


def test_pieces_of_one_wire_are_joined_across_a_long_gap():
    """Two pieces 30 m apart (beyond ``max_gap``) that one catenary fits are one wire; a
    piece of the wire 5 m above in the same vertical plane is not."""
    s_left, s_right = np.arange(-50, -20, 0.05), np.arange(10, 50, 0.05)
    left, right = _catenary_points(s_left, 4.0, 20.0), _catenary_points(s_right, 4.0, 20.0)
    joined, into = merge_pieces(_pieces(left, right), np.r_[left, right], 90.0, WiresOptions())
    assert len(joined) == 1 and into == {1: 0}
    assert joined[0].s_range[1] - joined[0].s_range[0] == pytest.approx(100, abs=0.5)
    # The split does it too.
    assert len(split_wires(np.r_[left, right], 90.0)) == 1

    above = _catenary_points(s_right, 4.0, 25.0)
    joined, into = merge_pieces(_pieces(left, above), np.r_[left, above], 90.0, WiresOptions())
    assert len(joined) == 2 and into == {}
    assert len(split_wires(np.r_[left, above], 90.0)) == 2


def test_a_chain_holding_a_wire_and_a_false_pairing_above_it_gives_both():
    """The shared generator's two-strip flight, seed 3: the lowest conductor's points and a
    false pairing's 1 m above it, all along, are one chain (points between join them); one
    curve through the chain lies between the two and keeps neither. Each is split out."""
    rng = np.random.default_rng(3)
    s = np.arange(-50, 50, 0.01)
    wire = _catenary_points(s, 4.0, 20.0)
    false = _catenary_points(s + 0.005, 4.0, 21.0) + [0.0, 0.1, 0.0]
    between = _catenary_points(rng.uniform(-50, 50, 3000), 4.0, 20.0)
    between[:, 2] += rng.uniform(0.1, 0.9, len(between))
    pts = np.r_[wire, false, between]
    wires = split_wires(pts, 90.0)
    for z, own in ((20.0, np.arange(len(wire))), (21.0, len(wire) + np.arange(len(false)))):
        (w,) = [w for w in wires if abs(w.z_at(np.array([0.0]))[0] - z) < 0.05]
        assert w.s_range[0] < -49 and w.s_range[1] > 49
        assert np.isin(own, w.point_indices).mean() > 0.99 and w.rms_residual < 0.04
    # The scattered points between may give pieces of their own (the views judge them),
    # each far thinner than a wire.
    assert all(len(w.point_indices) < 0.1 * len(wire) for w in wires if len(w.point_indices) < 5000)
    # The corridor probe keeps one curve per chain (layers of a wrong direction's scattered
    # matches would make it look like more wire).
    assert len(split_wires(pts, 90.0, layers=False)) <= 1


def _span_points(s: np.ndarray, ends: tuple[float, float], z: tuple[float, float], a: float):
    """Points of a span hanging between heights ``z`` at ``ends`` along +x (parabola of the
    catenary ``a``), 2 cm noise."""
    rng = np.random.default_rng(len(s) + int(10 * z[0]))
    (sa, sb), (za, zb) = ends, z
    height = za + (zb - za) * (s - sa) / (sb - sa) + (s - sa) * (s - sb) / (2 * a)
    return np.c_[s, np.zeros(len(s)), height] + rng.normal(0, 0.02, (len(s), 3))


def test_a_straight_line_s_wires_are_cut_where_their_spans_meet_beside_false_pairings():
    """The package's branch layout, full scale: a pole line's 70 m spans and the 25 m spans
    after them meet at the junction pole, bending down by 10 degrees; each conductor's chain
    also carries false pairings 0.12-0.5 m above and below it (a fifth of its points, as
    there). Least squares counted those: two curves fit 0.4 of one curve's squares there,
    not the quarter that cuts, and the 25 m span was never measured. On the points the
    curves hold, the three chains bend at one place, where their two curves cross."""
    rng = np.random.default_rng(5)
    pts, spans = [], []
    for y, z in ((-1.2, 13.4), (0.0, 14.9), (1.2, 13.4)):
        first = _span_points(np.arange(-70, 0, 0.01), (-70, 0), (z - 2.7, z), 550.0)
        second = _span_points(np.arange(0, 25, 0.01), (0, 25), (z, z - 1.2), 440.0)
        wire = np.r_[first, second] + [0.0, y, 0.0]
        false = wire[rng.choice(len(wire), len(wire) // 4)]
        false[:, 2] += rng.uniform(0.12, 0.5, len(false)) * rng.choice([-1, 1], len(false))
        n = sum(len(p) for p in pts)
        spans += [n + np.arange(len(first)), n + len(first) + np.arange(len(second))]
        pts += [wire, false]
    wires = split_wires(np.concatenate(pts), 90.0)
    for own in spans:
        (w,) = [w for w in wires if np.isin(own, w.point_indices).mean() > 0.97]
        assert w.rms_residual < 0.04
        assert (w.s_range[0] < -69 and abs(w.s_range[1]) < 0.5) or (
            abs(w.s_range[0]) < 0.5 and w.s_range[1] > 24
        )


def test_one_chain_bending_alone_is_no_support():
    """A support holds all its conductors at one place: two chains or more bend there. On
    the shared cross seed 8, rows of ground texture 5-10 m up bent alone, each at its own
    place; cut there, their pieces passed the views as four false wires."""
    options = WiresOptions()
    assert _supports_of_line([10.0], options) == []
    assert _supports_of_line([10.0, 10.4, 60.0], options) == [pytest.approx(10.2)]


def test_a_short_piece_beside_a_long_wire_is_not_joined_to_it():
    """A 20 m piece of a wire 8 m higher is a small share of the points of both; one
    catenary through all of them keeps most points (the long wire's) but not the piece's."""
    long_pts = _catenary_points(np.arange(-50, 50, 0.05), 4.0, 20.0)
    short_pts = _catenary_points(np.arange(10, 30, 0.2), 4.0, 28.0)
    pts = np.r_[long_pts, short_pts]
    joined, into = merge_pieces(_pieces(long_pts, short_pts), pts, 90.0, WiresOptions())
    assert len(joined) == 2 and into == {}


def test_tower_member_found_when_some_wires_end_short_of_the_tower():
    """The shared cross flight: the top conductors are seen only to 8-10 m short of the
    tower, so the lower ends run from -49 to -39; the tower is where the outermost meet,
    and the 6.5 m piece at 3 m height across it is a member."""
    lows = [(-39.5, 36.5), (-39.7, -10.4), (-49.0, 38.7), (-47.7, 49.4), (-47.6, 49.1)]
    wires = [_piece(k, 4.0, lo, hi, 25.0) for k, (lo, hi) in enumerate(lows)]
    wires += [_piece(5, -4.2, -44.9, 39.1, 26.0), _piece(6, -5.3, -40.8, 32.7, 30.0)]
    wires.append(_piece(7, -3.0, -52.6, -46.1, 3.2))
    found = dict(support_members(wires, np.array([1.0, 0.0]), long_length=25.0))
    assert set(found) == {7}
    assert found[7] == pytest.approx(-47.6, abs=0.5)


def test_tower_member_reaching_just_past_the_conductor_ends():
    """The package's corridor: the conductors end within 0.7 m of each other at the tower;
    a 7 m piece at conductor height reaches 0.95 m past their median end, 0.65 m past the
    outermost, and was kept (it then grew along a false pairing into a 68 m wire). A
    conductor piece ending within the ends' spread is not a member."""
    ends = [-50.6, -50.5, -50.3, -50.3, -50.3, -49.9]
    wires = [_piece(k, 4.0 * (-1) ** k, lo, 49.0, 21.0 + k) for k, lo in enumerate(ends)]
    wires.append(_piece(6, 0.5, -51.25, -44.4, 21.3))
    wires.append(_piece(7, 4.5, -50.55, -30.0, 24.0))
    found = dict(support_members(wires, np.array([1.0, 0.0]), long_length=25.0))
    assert set(found) == {6}
    assert found[6] == pytest.approx(-50.3, abs=0.2)


def _support(wire_id: int, confidence: float | None, supported_s=None) -> WireSupport:
    return WireSupport(
        wire_id=wire_id,
        views=10,
        strips=3,
        crossing_views=4,
        hit_rate=0.9,
        crossing_hit_rate=0.9,
        chance=0.05,
        confidence=confidence,
        geometry="strong",
        height_above_ground=20.0,
        supported_s=supported_s,
    )


def test_grown_wires_are_judged_again():
    """After the confirmed wires took more points: an unchanged wire keeps its support and
    is not judged on its own; a grown one the views still confirm gets its new support; one
    they reject only past a stretch is cut back to it; one they support nowhere goes with
    the pieces it grew from; one whose cut is rejected too goes back to its pieces, judged
    again with the rest (one that lies on another wire's curve stays)."""
    rng = np.random.default_rng(0)
    lines = [(4.0, 21.0), (-4.0, 21.0), (0.0, 25.0), (8.0, 30.0), (9.0, 33.0)]
    s = np.arange(-50.0, 50.0, 0.5)
    pts = np.concatenate(
        [np.c_[s, np.full(len(s), y), np.full(len(s), z)] for y, z in lines]
    ) + rng.normal(0, 0.01, (len(lines) * len(s), 3))
    n = len(s)

    def piece(k, lo, hi):
        idx = k * n + np.flatnonzero((s >= lo) & (s <= hi))
        (w,) = split_wires(pts[idx], 90.0)
        return dataclasses.replace(w, wire_id=k, point_indices=idx[w.point_indices])

    confirmed_wires = [
        piece(0, -40, 20),
        piece(1, -30, 30),
        piece(2, -50, -20),
        piece(3, -50, -30),
        piece(3, 30, 50),
    ]
    # A stretch of wire 0 past its end that was not joined to it, then falsely joined to
    # points of the wire above.
    tail = np.flatnonzero((s >= 25) & (s <= 50))
    (w4,) = split_wires(pts[tail], 90.0)
    stretch = dataclasses.replace(w4, wire_id=4, point_indices=tail[w4.point_indices])
    both = np.r_[tail, 4 * n + np.flatnonzero(s <= -25)]
    confirmed_wires.append(stretch)
    confirmed = [(w, _support(w.wire_id, 1.0)) for w in confirmed_wires]
    false_join = dataclasses.replace(stretch, point_indices=both)
    grown = [
        piece(0, -40, 20),
        piece(1, -48, 48),
        piece(2, -50, 40),
        piece(3, -50, 50),
        false_join,
    ]
    calls = []

    def judge(wires):
        calls.append([(w.wire_id, round(w.s_range[1] - w.s_range[0])) for w in wires])
        out = []
        for w in wires:
            extent = w.s_range[1] - w.s_range[0]
            if w.wire_id == 2 and extent > 50:  # right only over its first 50 m
                out.append(_support(2, 0.3, supported_s=(w.s_range[0], w.s_range[0] + 50)))
            elif w.wire_id == 3 and (extent > 50 or w.s_range[0] > 0):  # a false join, and
                out.append(_support(3, 0.3))  # a piece now explained by a better wire
            elif w.wire_id == 4 and len(w.point_indices) > 60:  # right only over the tail
                out.append(_support(4, 0.3, supported_s=(25.0, 50.0)))
            elif w.wire_id == 4:  # the tail, cut or as confirmed: explained by wire 0
                out.append(_support(4, None))
            else:
                out.append(_support(w.wire_id, 1.0))
        return out

    wires, supports = _confirm_grown(grown, confirmed, judge, pts, 90.0, ReconstructionOptions())
    extents = [round(w.s_range[1] - w.s_range[0]) for w in wires]
    # Wire 3 (a false join the views support nowhere) goes with its pieces.
    assert extents[:3] == [60, 96, 50] and extents[3] == pytest.approx(25, abs=1)
    assert [w.wire_id for w in wires] == [s.wire_id for s in supports] == [0, 1, 2, 3]
    assert len(wires[3].point_indices) == len(tail)  # the stretch of wire 0, kept
    assert all(s.confidence == 1.0 for s in supports)
    assert len(calls) == 3 and (0, 60) in calls[0]

    # Nothing grew: nothing is judged.
    wires, supports = _confirm_grown(
        confirmed_wires, confirmed, judge, pts, 90.0, ReconstructionOptions()
    )
    assert len(calls) == 3 and len(wires) == len(confirmed_wires)


def test_a_short_piece_wholly_past_the_supports_is_not_a_wire():
    """The shared corridor: a 9 m piece 1-10 m past where every conductor ends (a false
    pairing by the tower) is outside the span; the same piece where a long wire of the next
    span hangs is kept."""
    ends = [(-50.6, 48.4), (-50.5, 48.6), (-50.3, 48.5), (-50.3, 48.3), (-49.9, 48.7)]
    wires = [_piece(k, 4.0 * (-1) ** k, lo, hi, 21.0 + k) for k, (lo, hi) in enumerate(ends)]
    wires.append(_piece(5, 10.8, 49.4, 58.6, 20.7))  # past the upper support
    wires.append(_piece(6, -10.0, -62.0, -55.0, 12.0))  # past the lower one
    wires.append(_piece(7, 5.0, 10.0, 20.0, 25.0))  # inside the span
    found = dict(support_members(wires, np.array([1.0, 0.0]), long_length=25.0))
    assert set(found) == {5, 6}
    # A span beyond: its long wires hang where piece 5 lies.
    wires.append(_piece(8, 4.0, 48.6, 140.0, 21.0))
    found = dict(support_members(wires, np.array([1.0, 0.0]), long_length=25.0))
    assert 5 not in found and 6 in found


def test_a_short_piece_far_below_the_wire_ends_at_a_support_is_a_member():
    """The shared cross seed 6: a 5.6 m piece 9 m above the ground at the tower, ending where
    the outermost wire ends (not past it), while the wires end 21-25 m up: a member of the
    structure. The same piece at the wires' height, or inside the span, stays."""
    ends = [(-50.6, 48.4), (-50.5, 48.6), (-50.3, 48.5), (-50.3, 48.3), (-49.9, 48.7)]
    wires = [_piece(k, 4.0 * (-1) ** k, lo, hi, 21.0 + k) for k, (lo, hi) in enumerate(ends)]
    wires.append(_piece(5, 2.7, -50.6, -45.0, 8.9))  # at the lower support, low
    wires.append(_piece(6, 2.7, -50.6, -45.0, 20.5))  # the same at the wires' height
    wires.append(_piece(7, 2.7, -20.0, -14.0, 8.9))  # low, but inside the span
    found = dict(support_members(wires, np.array([1.0, 0.0]), long_length=25.0))
    assert set(found) == {5}


def test_a_line_of_pieces_at_another_lines_support_is_its_bracing():
    """The shared corridor seed 1: the wider look probed a second line at 45° to the first,
    along a tower's bracing, and it gave three straight 4.5-6.4 m pieces 13-23 m up on the
    tower, confirmed by the views (they are there). A piece of such a line that is a member
    of the first line's support is that support's; one in mid-span (a line seen only in
    pieces, crossing it) is not."""
    from types import SimpleNamespace

    from colmap_powerline.pipeline import _support_members_of

    def diagonal(wire_id: int, x: float, z: float) -> FittedWire:
        d = np.array([1.0, 1.0]) / np.sqrt(2.0)
        return dataclasses.replace(
            _piece(wire_id, 0.0, -3.0, 3.0, z), plane_origin_xy=np.array([x, 0.0]),
            plane_direction_xy=d,
        )  # fmt: skip

    span = [
        _piece(k, y, -49.5 + 0.3 * k, 48.0 + 0.4 * k, z)
        for k, (y, z) in enumerate([(4, 21), (4, 26), (5, 31), (-4, 21), (-4, 26), (-5, 31)])
    ]
    line = SimpleNamespace(wires=span, corridor=SimpleNamespace(direction_xy=np.array([1.0, 0.0])))

    def member_of(piece: FittedWire, lines: list) -> object:
        return _support_members_of([piece], lines, 25.0).get(0)

    assert member_of(diagonal(0, 49.0, 13.0), [line]) is line
    assert member_of(diagonal(0, 49.0, 18.0), [line]) is line
    assert member_of(diagonal(0, 0.0, 18.0), [line]) is None  # mid-span
    assert member_of(diagonal(0, 49.0, 13.0), []) is None


def test_pieces_are_joined_when_one_curve_misses_only_a_near_end_of_one():
    """The shared corridor seed 1: a shield wire's 30 m piece whose first 8 m, next to a
    3 m gap, lie 10-20 cm high beside a 38 m piece of it. One curve keeps all of the one
    and the far 22 m of the other: one wire, without the near end's points. A stretch off
    the curve at the far end, or a near end longer than the rest, keep the pieces apart."""
    s_left, s_right = np.arange(-50, -12, 0.05), np.arange(-9, 21, 0.05)
    left = _catenary_points(s_left, 4.0, 20.0)
    clean = _catenary_points(s_right, 4.0, 20.0)
    rng = np.random.default_rng(1)

    def joined_with(at_far_end: bool, length: float, lift: float) -> list[FittedWire]:
        d = (s_right[-1] - s_right) if at_far_end else (s_right - s_right[0])
        right = clean + np.c_[0 * d, 0 * d, (d < length) * rng.uniform(lift, 2 * lift, len(d))]
        # The piece as the split left it: its curve, with every point it holds.
        a, b = _pieces(left, clean)
        b = dataclasses.replace(b, point_indices=len(left) + np.arange(len(right)))
        return merge_pieces([a, b], np.r_[left, right], 90.0, WiresOptions())[0]

    (one,) = joined_with(False, 8.0, 0.1)
    kept = np.isin(len(left) + np.arange(len(clean)), one.point_indices)
    assert kept[s_right > s_right[0] + 8].mean() > 0.95
    assert kept[s_right < s_right[0] + 8].mean() < 0.5
    assert len(joined_with(False, 20.0, 0.3)) == 2
    assert len(joined_with(True, 8.0, 0.3)) == 2
