"""Points that join the hypotheses or the confirmed wires without a posterior of their own:
pending points the views across the wires see (``_settled_by_the_views``) and primitives
on a confirmed curve (``_consensus``)."""

from __future__ import annotations

import numpy as np
import pytest

from colmap_powerline.pipeline import CONSENSUS_SIGMAS, _consensus, _settled_by_the_views
from colmap_powerline.triangulate import Primitives
from colmap_powerline.verify import PendingPoints, VerifiedPoints
from colmap_powerline.wires import split_wires


def _verified(pts: np.ndarray, index: np.ndarray, pending: PendingPoints | None = None):
    n = len(pts)
    ones = np.ones(n, np.int32)
    return VerifiedPoints(
        pts, 3 * ones, 4 * ones, 2 * ones, 2 * ones, np.full(n, 0.999), 0 * ones,
        np.ones(n, bool), [], np.full(3, 0.8), [], index, pending,
    )  # fmt: skip


def _pending(pts: np.ndarray, evidence: np.ndarray, crossing: np.ndarray) -> PendingPoints:
    n = len(pts)
    return PendingPoints(
        pts, evidence, np.full(n, 2, np.int32), np.full(n, 4, np.int32),
        crossing.astype(np.int32), np.minimum(crossing, 1).astype(np.int32),
        np.zeros(n, np.int32), np.zeros(n, bool), 100 + np.arange(n),
    )  # fmt: skip


def test_pending_points_seen_across_the_wires_join_the_hypotheses():
    """Sure on every view's evidence and seen by a view that can tell: they join the
    verified points. Short of sure, seen only along the wires, missed by most views that
    can tell, or beside a verified point (nothing to add there): still pending."""
    rng = np.random.default_rng(0)
    kept = rng.normal(size=(5, 3)) * 10
    pts = np.r_[rng.normal(size=(4, 3)) * 10, kept[:1] + 0.005, rng.normal(size=(1, 3)) * 10]
    logit = np.log(0.99 / 0.01)
    # One hit per point: the last one most views that can tell miss.
    pending = _pending(
        pts,
        np.array([logit + 1, logit + 1, logit - 1, 9.0, 9.0, 9.0]),
        np.array([2, 0, 3, 1, 1, 4]),
    )
    out = _settled_by_the_views(_verified(kept, np.arange(5), pending), 0.99, 0.01)
    assert len(out) == 7
    np.testing.assert_array_equal(out.pts_in_world[5:], pts[[0, 3]])
    np.testing.assert_array_equal(out.primitive_index, [0, 1, 2, 3, 4, 100, 103])
    assert out.pending is not None and len(out.pending) == 4
    np.testing.assert_array_equal(out.pending.pts_in_world, pts[[1, 2, 4, 5]])
    np.testing.assert_array_equal(out.pending.primitive_index, [101, 102, 104, 105])


def _on_curve(s: np.ndarray, noise: float, rng) -> np.ndarray:
    z = 20.0 + 800.0 * (np.cosh(s / 800.0) - 1)
    return np.c_[s, np.full(len(s), 4.0), z] + rng.normal(0, noise, (len(s), 3))


def test_primitives_on_a_confirmed_wire_join_its_points():
    """Primitives in a gap of a confirmed wire, on its curve within its noise, join it;
    one off the curve, one past its ends, and one already verified do not; the curve stays."""
    rng = np.random.default_rng(1)
    s_seen = np.r_[np.arange(-50, -10, 0.1), np.arange(10, 50, 0.1)]
    seen = _on_curve(s_seen, 0.02, rng)
    (wire,) = split_wires(seen, 90.0)
    in_gap = _on_curve(np.arange(-9, 9, 0.1), 0.005, rng)
    off = _on_curve(np.arange(-9, 9, 0.5), 0.0, rng) + [0.0, 0.0, 1.0]  # a false match 1 m up
    past = _on_curve(np.arange(55, 60, 0.5), 0.0, rng)  # past the observed end
    # Primitives of two pairs: the first holds the verified points, then the candidates.
    prims = [
        Primitives(seen, *np.zeros((3, len(seen))), 0),
        Primitives(np.r_[in_gap, off, past], *np.zeros((3, len(in_gap) + len(off) + len(past))), 1),
    ]
    verified = _verified(seen, np.arange(len(seen)))
    wires, out = _consensus([wire], verified, prims)
    new = wires[0].point_indices[wires[0].point_indices >= len(seen)]
    assert CONSENSUS_SIGMAS * wire.rms_residual > 0.015
    assert len(new) == len(in_gap)
    np.testing.assert_allclose(out.pts_in_world[new], in_gap)
    np.testing.assert_array_equal(out.pair_index[new], 1)
    assert np.isnan(out.posterior[new]).all() and not np.isnan(out.posterior[: len(seen)]).any()
    assert len(out) == len(seen) + len(in_gap)
    assert wires[0].catenary_a == wire.catenary_a and wires[0].s_range == wire.s_range
    # Nothing more to take: the same call leaves the points as they are.
    again, out2 = _consensus(wires, out, prims)
    assert len(out2) == len(out) and len(again[0].point_indices) == len(wires[0].point_indices)
    assert wires[0].s_range == pytest.approx(wire.s_range)


def test_verified_points_of_two_corridors_concatenate():
    """Pair and primitive numbers of the second set shift past the first's (-1 stays -1);
    every per-point field is carried; the views' hit rates are the better of the two."""
    import dataclasses

    from colmap_powerline.verify import VerifiedPoints

    def points(n: int, pair: int, rate: float) -> VerifiedPoints:
        z = np.zeros(n, np.int32)
        return VerifiedPoints(
            pts_in_world=np.full((n, 3), float(pair)), hits=z + 1, views=z + 2,
            crossing_views=z + 3, crossing_hits=z + 4, posterior=np.full(n, 0.99),
            pair_index=np.r_[np.full(n - 1, pair), -1].astype(np.int32),
            refined=np.ones(n, bool), decoded=[], view_hit_rates=np.array([rate, np.nan]),
            wire_pixels=[], primitive_index=np.r_[np.arange(n - 1), -1].astype(np.int64),
        )  # fmt: skip

    a, b = points(4, 0, 0.5), points(3, 1, 0.7)
    both = a.concatenated(b, pair_offset=2, primitive_offset=10)
    assert len(both) == 7
    assert both.pair_index.tolist() == [0, 0, 0, -1, 3, 3, -1]
    assert both.primitive_index.tolist() == [0, 1, 2, -1, 10, 11, -1]
    for f in ("hits", "views", "crossing_views", "crossing_hits", "posterior", "refined"):
        assert np.array_equal(getattr(both, f), np.r_[getattr(a, f), getattr(b, f)])
    assert both.view_hit_rates[0] == 0.7 and np.isnan(both.view_hit_rates[1])
    assert dataclasses.replace(both, pending=None).pending is None
