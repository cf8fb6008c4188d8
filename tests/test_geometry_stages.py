"""Rectify, triangulate, pairs and verify on known geometry (true wires, exact masks)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.spatial import cKDTree

from colmap_powerline import InputError
from colmap_powerline.detect import WireMask
from colmap_powerline.pairs import PairsOptions, estimate_corridor, select_pairs
from colmap_powerline.rectify import rectify_pair
from colmap_powerline.synthetic import load_true_wires
from colmap_powerline.triangulate import (
    TriangulateOptions,
    WireCentres,
    triangulate_pair,
    wire_centres,
)
from colmap_powerline.verify import VerifyOptions, crossing_views, verify_primitives

AZIMUTH = 35.0  # the synthetic line's azimuth


@pytest.fixture(scope="module")
def truth(small_span):
    return load_true_wires(small_span.truth_wires)


@pytest.fixture(scope="module")
def truth_tree(truth):
    return cKDTree(np.concatenate([w.polyline(0.01) for w in truth]))


@pytest.fixture(scope="module")
def corridor(small_scene):
    return estimate_corridor(small_scene, PairsOptions(wire_azimuth_deg=AZIMUTH))


@pytest.fixture(scope="module")
def pairs(small_scene, corridor):
    return select_pairs(small_scene, corridor)


def _oracle_mask(shape, uv):
    """Pixels containing the projected true wires."""
    mask = np.zeros(shape, bool)
    ok = np.isfinite(uv).all(axis=1)
    px = np.floor(uv[ok]).astype(int)
    inside = (px[:, 0] >= 0) & (px[:, 0] < shape[1]) & (px[:, 1] >= 0) & (px[:, 1] < shape[0])
    mask[px[inside, 1], px[inside, 0]] = True
    return mask


def _oracle_centres(geom, side, truth):
    shape = (geom.height_px, geom.widths_px[side])
    uv = np.concatenate([geom.project(side, w.polyline(0.005))[0] for w in truth])
    mask = _oracle_mask(shape, uv)
    return wire_centres(mask, np.ones(shape, np.float32))


# ---------------------------------------------------------------- pairs


def test_corridor_direction_estimated_from_images(small_scene):
    corridor = estimate_corridor(small_scene)
    err = abs((corridor.azimuth_deg - AZIMUTH + 90) % 180 - 90)
    assert err < 2.0, corridor.azimuth_deg  # measured: 0.3°
    assert corridor.from_images
    assert len(corridor.decoded) > 0


def test_pairs_cross_the_wires(pairs, corridor):
    assert 1 <= len(pairs) <= PairsOptions().max_pairs
    for p in pairs:
        assert p.crossing_deg >= PairsOptions().min_crossing_deg
        assert PairsOptions().min_base_height <= p.base_height <= PairsOptions().max_base_height
        assert p.coverage > 0
        assert p.left.name != p.right.name


def test_no_crossing_pair_is_a_clear_error(small_scene, corridor):
    # Images whose centres lie on one line along the wires: every baseline is parallel to them.
    c = small_scene.centers_in_world[:, :2] @ corridor.normal_xy
    line = [im for im, ci in zip(small_scene.images, c, strict=True) if abs(ci - c[0]) < 3.0]
    assert len(line) >= 3
    scene = dataclasses.replace(small_scene, images=tuple(line))
    with pytest.raises(InputError, match="no image pair crosses the wires"):
        select_pairs(scene, corridor)


# ---------------------------------------------------------------- rectify


def test_rectified_rows_agree_on_true_model(small_scene, pairs, truth):
    geom = rectify_pair(small_scene, pairs[0].left, pairs[0].right)
    pts = np.concatenate([w.polyline(0.5) for w in truth])
    uv_l, _ = geom.project(0, pts)
    uv_r, _ = geom.project(1, pts)
    assert np.nanmax(np.abs(uv_l[:, 1] - uv_r[:, 1])) <= 0.05
    back = geom.triangulate(uv_l[:, 0], uv_r[:, 0], uv_l[:, 1])
    assert np.nanmax(np.linalg.norm(back - pts, axis=1)) < 1e-6


def test_rectified_wires_run_vertically(small_scene, pairs, truth):
    for p in pairs:
        geom = rectify_pair(small_scene, p.left, p.right)
        for side in (0, 1):
            for w in truth:
                uv, _ = geom.project(side, w.points(np.array([20.0, 80.0])))
                d = uv[1] - uv[0]
                angle = np.degrees(np.arctan2(abs(d[0]), abs(d[1])))  # 0 = vertical
                assert angle < 90 - p.crossing_deg + 10


def test_remap_maps_follow_the_lens_model(small_scene, pairs):
    geom = rectify_pair(small_scene, pairs[0].left, pairs[0].right)
    for side, view in enumerate(geom.sides):
        map_x, map_y = geom.remap_maps(side)
        assert map_x.shape == (geom.height_px, geom.widths_px[side])
        rng = np.random.default_rng(0)
        u = rng.uniform(0, geom.widths_px[side], 200)
        v = rng.uniform(0, geom.height_px, 200)
        rays = geom.rays_in_world(side, np.c_[u, v])
        pts = view.center_in_world + 30.0 * rays
        uv, _, inside = view.project(pts)
        j, i = np.floor(u).astype(int), np.floor(v).astype(int)
        # Maps are sampled at pixel centres: compare there.
        rays_c = geom.rays_in_world(side, np.c_[j + 0.5, i + 0.5])
        uv_c, _, inside = view.project(view.center_in_world + 30.0 * rays_c)
        got = np.c_[map_x[i, j], map_y[i, j]] + 0.5
        assert np.abs(got[inside] - uv_c[inside]).max() < 0.01


def test_rectify_image_shapes_and_errors(small_scene, pairs):
    geom = rectify_pair(small_scene, pairs[0].left, pairs[0].right)
    view = geom.left
    image = np.zeros((view.height, view.width, 3), np.uint8)
    rect, valid = geom.rectify_image(0, image)
    assert rect.shape == (geom.height_px, geom.widths_px[0], 3)
    assert valid.dtype == bool and valid.shape == rect.shape[:2]
    assert 0.3 < valid.mean() <= 1.0
    with pytest.raises(InputError, match="model says"):
        geom.rectify_image(0, image[:-1])
    with pytest.raises(InputError, match="same camera centre"):
        rectify_pair(small_scene, view, view)


# ---------------------------------------------------------------- triangulate


def test_wire_centres_of_runs():
    mask = np.zeros((3, 10), bool)
    mask[0, 2:5] = True  # one run of 3 pixels, symmetric weights → centre at column 3.5
    mask[1, 7] = True
    response = np.ones((3, 10), np.float32)
    response[1, 7] = -2.0
    c = wire_centres(mask, response)
    assert isinstance(c, WireCentres) and len(c) == 2
    np.testing.assert_allclose(c.u, [3.5, 7.5])
    np.testing.assert_array_equal(c.rows, [0, 1])
    np.testing.assert_array_equal(c.polarity, [1, -1])
    with pytest.raises(ValueError, match="shape"):
        wire_centres(mask, response[:2])


def test_true_matches_are_among_the_primitives(small_scene, pairs, truth, truth_tree):
    geom = rectify_pair(small_scene, pairs[0].left, pairs[0].right)
    left, right = _oracle_centres(geom, 0, truth), _oracle_centres(geom, 1, truth)
    prims = triangulate_pair(geom, small_scene, left, right)
    assert prims.pts_in_world.shape == (len(prims), 3)
    assert len(prims.u_left) == len(prims.v) == len(prims)
    d, _ = truth_tree.query(prims.pts_in_world)
    # Many wrong candidates (all wire pairs on a row), but the right ones are there: the true
    # wire samples seen by both images each have a primitive within 10 cm (pixel-quantised
    # oracle centres at ~9 cm GSD).
    assert 0.03 < (d < 0.1).mean() < 0.9
    samples = np.concatenate([w.polyline(1.0)[3:-3] for w in truth])
    both = np.ones(len(samples), bool)
    for side in (0, 1):
        uv, z = geom.project(side, samples)
        both &= (z > 0) & (uv[:, 0] > 2) & (uv[:, 0] < geom.widths_px[side] - 2)
        both &= (uv[:, 1] > 2) & (uv[:, 1] < geom.height_px - 2)
    found = cKDTree(prims.pts_in_world).query(samples[both])[0]
    assert np.mean(found < 0.15) > 0.95


def test_triangulate_options_are_checked(small_scene, pairs):
    geom = rectify_pair(small_scene, pairs[0].left, pairs[0].right)
    empty = wire_centres(np.zeros((2, 2), bool), np.zeros((2, 2), np.float32))
    assert len(triangulate_pair(geom, small_scene, empty, empty)) == 0
    with pytest.raises(ValueError, match="max_wire_height"):
        triangulate_pair(
            geom,
            small_scene,
            empty,
            empty,
            options=TriangulateOptions(min_wire_height=10, max_wire_height=5),
        )


# ---------------------------------------------------------------- verify


def test_crossing_views_geometry():
    az = 0.0  # wires along +y
    views = np.array([[0.0, 50.0, 80.0], [0.5, -30.0, 80.0], [30.0, 0.0, 80.0]])
    pair = np.array([[[0.0, 0.0, 80.0], [20.0, 0.0, 80.0]]])
    judges = crossing_views(views, pair, az, height=60.0, offset=0.15)
    assert judges.shape == (1, 3)
    # In line with the left camera along the wires (twice), then 10 m across from the right.
    np.testing.assert_array_equal(judges[0], [False, False, True])


def test_verification_with_exact_masks_keeps_only_wire_points(
    small_scene, pairs, truth, truth_tree
):
    prims = []
    for k, p in enumerate(pairs[:2]):
        geom = rectify_pair(small_scene, p.left, p.right)
        prims.append(
            triangulate_pair(
                geom,
                small_scene,
                _oracle_centres(geom, 0, truth),
                _oracle_centres(geom, 1, truth),
                k,
            )
        )
    polylines = [w.polyline(0.005) for w in truth]

    def exact_mask(view, image, direction, crop):
        uv = np.concatenate([view.project(pl)[0] for pl in polylines])
        mask = _oracle_mask((view.height, view.width), uv)
        x0, y0, x1, y1 = crop
        mask = mask[y0:y1, x0:x1]
        return WireMask(mask, mask.astype(np.float32), direction, 1)

    kept = verify_primitives(
        small_scene,
        prims,
        [(p.left.name, p.right.name) for p in pairs[:2]],
        exact_mask,
        AZIMUTH,
        VerifyOptions(refine=False),
        show_progress=False,
    )
    assert len(kept) > 500
    d, _ = truth_tree.query(kept.pts_in_world)
    assert (d > 0.3).mean() < 0.01  # no ghosts survive
    assert np.median(d) < 0.05
    assert (kept.hits >= 1).all() and (kept.views >= kept.hits).all()
    assert len(kept.decoded) <= len(small_scene.images)


def test_interpolated_maps_match_exact_maps(small_scene, pairs):
    geom = rectify_pair(small_scene, pairs[0].left, pairs[0].right)
    fast_x, fast_y = geom.remap_maps(1)
    exact_x, exact_y = geom.remap_maps(1, grid_step_px=1)
    view = geom.right
    valid = (exact_x >= 0) & (exact_y >= 0) & (exact_x < view.width) & (exact_y < view.height)
    assert valid.mean() > 0.3
    err = np.hypot(fast_x - exact_x, fast_y - exact_y)[valid]
    assert err.max() < 0.01  # measured ≈ 1e-3 px
