"""Rectify, triangulate, pairs and verify on known geometry (true wires, exact masks)."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest
from scipy.spatial import cKDTree

from colmap_powerline import InputError
from colmap_powerline import pairs as pairs_module
from colmap_powerline.detect import WireMask
from colmap_powerline.geometry import plan_axes
from colmap_powerline.pairs import PairsOptions, select_pairs
from colmap_powerline.pipeline import ReconstructionOptions, probe_corridor
from colmap_powerline.rectify import rectify_pair
from colmap_powerline.support import SupportOptions, keep_supported, wire_support
from colmap_powerline.synthetic import load_true_wires
from colmap_powerline.triangulate import (
    TriangulateOptions,
    WireCentres,
    triangulate_pair,
    wire_centres,
)
from colmap_powerline.verify import (
    VerifyOptions,
    ViewWirePixels,
    crossing_views,
    image_wire_direction_deg,
    verify_primitives,
)
from colmap_powerline.wires import FittedWire

AZIMUTH = 35.0  # the synthetic line's azimuth


@pytest.fixture(scope="module")
def truth(small_span):
    return load_true_wires(small_span.truth_wires)


@pytest.fixture(scope="module")
def truth_tree(truth):
    return cKDTree(np.concatenate([w.polyline(0.01) for w in truth]))


@pytest.fixture(scope="module")
def corridor(small_scene):
    """The corridor as the pipeline measures it, with the wires' direction given (~10 s)."""
    options = ReconstructionOptions(
        pairs=PairsOptions(wire_azimuth_deg=AZIMUTH), show_progress=False
    )
    return probe_corridor(small_scene, options)


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


def test_corridor_direction_estimated_from_images(small_scene, truth):
    # The whole probe: candidate directions from the images, each probed in 3D (~30 s).
    corridor = probe_corridor(small_scene, ReconstructionOptions(show_progress=False))
    err = abs((corridor.azimuth_deg - AZIMUTH + 90) % 180 - 90)
    assert err < 2.0, corridor.azimuth_deg  # measured: < 0.01°
    assert corridor.from_images and corridor.measured
    assert len(corridor.decoded) > 0
    # The measured band and heights hold the true wires' middle stretches.
    lo, hi = corridor.height_range
    mid = np.concatenate([w.points(np.linspace(0.3, 0.7, 9) * w.length_m) for w in truth])
    across = (mid[:, :2] - corridor.centre_xy) @ corridor.normal_xy
    assert np.abs(across).max() < corridor.half_width
    assert lo <= np.median(mid[:, 2]) <= hi


def _finds_the_line(scene, caplog, logged: str) -> None:
    """The probes (as patched) log ``logged`` and end with a measured corridor along the
    line."""
    with caplog.at_level("INFO", logger="colmap_powerline.pipeline"):
        corridor = probe_corridor(scene, ReconstructionOptions(show_progress=False))
    assert any(logged in r.getMessage() for r in caplog.records)
    err = abs((corridor.azimuth_deg - AZIMUTH + 90) % 180 - 90)
    assert err < 2.0 and corridor.measured, corridor.azimuth_deg


def test_the_direction_search_widens_when_no_direction_has_wires(small_scene, monkeypatch, caplog):
    """When the first look offers only directions without wires (here one across the line),
    more images are read, ranked alike at every angle, and the line is found among them."""
    import colmap_powerline.pipeline as pipeline

    real = pipeline.direction_candidates

    def first_look_misses(scene, options, wide=False, read=()):
        if wide:
            return real(scene, options, wide=True, read=read)
        across = dataclasses.replace(options, wire_azimuth_deg=(AZIMUTH + 90.0) % 180.0)
        return real(scene, across)

    monkeypatch.setattr(pipeline, "direction_candidates", first_look_misses)
    _finds_the_line(small_scene, caplog, "no direction gave wires")


def test_the_probes_go_on_down_the_wider_look_until_a_line_is_found(
    small_scene, monkeypatch, caplog
):
    """An area survey's line is seen by a few of the images read, where roads and field
    edges outrank it (shared grid seed 4: its direction eleventh): when the wider look's
    first candidates have no line either, the probes go on down its list."""
    import colmap_powerline.pipeline as pipeline
    from colmap_powerline.pairs import DirectionCandidates

    real_dirs, real_probe = pipeline.direction_candidates, pipeline._probe

    def lines_elsewhere(scene, options, wide=False, read=()):
        if not wide:
            across = dataclasses.replace(options, wire_azimuth_deg=(AZIMUTH + 90.0) % 180.0)
            return real_dirs(scene, across)
        # Eleven stronger directions (none within 8° of the line's), then the line's.
        found = real_dirs(scene, dataclasses.replace(options, wire_azimuth_deg=AZIMUTH))
        others = [(AZIMUTH + 10.0 + 7.0 * k) % 180.0 for k in range(11)]
        return DirectionCandidates(
            tuple(others) + (AZIMUTH,),
            tuple(float(20 - k) for k in range(11)) + (1.0,),
            found.analysed,
            found.ground_z,
            found.flying_height,
        )

    def probe(prov, scene, options):
        if abs((prov.azimuth_deg - AZIMUTH + 90) % 180 - 90) > 2.0:
            return None, []  # no wires in that direction (and fast)
        return real_probe(prov, scene, options)

    monkeypatch.setattr(pipeline, "direction_candidates", lines_elsewhere)
    monkeypatch.setattr(pipeline, "_probe", probe)
    _finds_the_line(small_scene, caplog, "still no line")


def test_the_wider_look_probes_the_first_looks_directions_again_in_its_own_bands(
    small_scene, monkeypatch, caplog
):
    """In a large survey the first look's few images may all miss the line: the bands it
    gives the line's direction lie where those images are (the full road flight, 162 images
    over 400 m: none of its six saw the road line). The wider look's images give that
    direction other bands, and those are probed, though the direction was probed before."""
    import colmap_powerline.pipeline as pipeline

    real_dirs, real_bands = pipeline.direction_candidates, pipeline.provisional_corridors
    first: list = []

    def directions(scene, options, wide=False, read=()):
        found = real_dirs(
            scene, dataclasses.replace(options, wire_azimuth_deg=AZIMUTH), wide=wide, read=read
        )
        if not wide:
            first.append(found)
        return found

    def bands(scene, candidates, azimuth, options, heights, slices=False):
        out = real_bands(scene, candidates, azimuth, options, heights, slices=slices)
        if first and candidates is first[0]:
            # The first look's images lie 300 m across the line: so do its bands.
            shift = 300.0 * plan_axes(azimuth)[1]
            out = [dataclasses.replace(c, centre_xy=c.centre_xy + shift) for c in out]
        return out

    monkeypatch.setattr(pipeline, "direction_candidates", directions)
    monkeypatch.setattr(pipeline, "provisional_corridors", bands)
    _finds_the_line(small_scene, caplog, "no direction gave wires")


def test_a_directions_slices_tile_its_whole_band_a_footprint_wide(small_scene):
    """Probed slice by slice, a direction's whole band is cut into slices as wide as an
    image's footprint across it, the slices with the most line pixels first."""
    from colmap_powerline.pairs import (
        _footprint_across,
        direction_candidates,
        provisional_corridors,
    )

    options = PairsOptions(wire_azimuth_deg=AZIMUTH + 90.0)  # across the strips: a wide band
    found = direction_candidates(small_scene, options)
    heights = (5.0, 60.0)
    plain = provisional_corridors(small_scene, found, AZIMUTH + 90.0, options, heights)
    cut = provisional_corridors(small_scene, found, AZIMUTH + 90.0, options, heights, slices=True)
    assert len(plain) == 2 and [c.centre_xy.tolist() for c in cut[:2]] == [
        c.centre_xy.tolist() for c in plain
    ]
    whole, parts = plain[1], cut[2:]
    normal = plan_axes(AZIMUTH + 90.0)[1]
    width = np.median([_footprint_across(v, normal, whole.height) for v, _, _ in found.analysed])
    assert len(parts) >= 2
    for part in parts:
        assert part.wires_half_width <= 0.5 * width + 1e-6
    # Together they span the whole band.
    lo = min(float(p.centre_xy @ normal) - p.wires_half_width for p in parts)
    hi = max(float(p.centre_xy @ normal) + p.wires_half_width for p in parts)
    w_mid = float(whole.centre_xy @ normal)
    assert lo <= w_mid - whole.wires_half_width + 1e-6
    assert hi >= w_mid + whole.wires_half_width - 1e-6


def test_corridor_with_given_direction_is_measured(corridor):
    assert corridor.azimuth_deg == AZIMUTH and not corridor.from_images and corridor.measured
    samples = corridor.sample_points(1.0)
    assert samples.ndim == 3 and samples.shape[0] == 2 and samples.shape[2] == 3
    np.testing.assert_allclose(samples[0, :, 2], corridor.height_range[0])
    np.testing.assert_allclose(samples[1, :, 2], corridor.height_range[1])


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


def test_select_pairs_heights_are_not_mixed(small_scene, corridor, monkeypatch):
    """Issue 9, item 5: ``crossing_views`` gets the cameras' height above the wires for every
    candidate pair (the name was reused for the height above the ground for B/H, so from the
    second pair on it got the wrong one)."""
    real = pairs_module.crossing_views
    heights = []

    def recorder(view_centres, pair_centres, azimuth_deg, height, offset):
        heights.append(height)
        return real(view_centres, pair_centres, azimuth_deg, height, offset)

    monkeypatch.setattr(pairs_module, "crossing_views", recorder)
    chosen = select_pairs(small_scene, corridor)
    centres = small_scene.centers_in_world
    above_wires = float(np.median(centres[:, 2])) - corridor.height
    # The two heights differ here (~50 vs ~75 m), so a mix-up cannot pass unnoticed.
    above_ground = centres[:, 2] - small_scene.ground_height(centres[:, :2])
    assert np.abs(above_ground - above_wires).min() > 10.0
    assert len(heights) > len(chosen) >= 2  # called for every candidate pair
    np.testing.assert_allclose(heights, above_wires, rtol=0, atol=1e-9)


def test_pair_covers_a_place_only_at_a_height_both_images_see(small_scene, corridor, monkeypatch):
    """A strip beside the line may see the far side's low wires and not its high ones: a
    pair covers a place at a height only where both of its images see it at that height.
    Here half of the images see only the lowest wire height and the others only the highest,
    so only pairs within one half cover anything."""
    from colmap_powerline.scene import SceneImage

    real = SceneImage.project
    low = {im.name for im in small_scene.images[::2]}
    z_mid = 0.5 * sum(corridor.height_range)

    def project(self, pts):
        uv, depth, inside = real(self, pts)
        z = np.asarray(pts)[:, 2]
        return uv, depth, inside & ((z < z_mid) if self.name in low else (z > z_mid))

    monkeypatch.setattr(SceneImage, "project", project)
    chosen = select_pairs(small_scene, corridor)
    assert chosen
    for p in chosen:
        assert (p.left.name in low) == (p.right.name in low), (p.left.name, p.right.name)


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
    assert (kept.crossing_views >= kept.crossing_hits).all()
    assert (kept.views >= kept.crossing_views).all()
    assert (kept.posterior >= VerifyOptions().min_posterior).all()
    assert {p.view_index for p in kept.wire_pixels} <= set(range(len(small_scene.images)))
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


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("min_posterior", 1.0),
        ("min_posterior", 0.4),
        ("tolerance_px", 0.0),
        ("tolerance_px", 25.0),
        ("crossing_offset", -0.1),
        ("crossing_offset", 2.0),
        ("prior_hit_rate", 0.0),
        ("prior_hit_rate", 1.0),
        ("num_threads", 0),
        ("margin_px", -1),
        ("template_length_px", 2),
        ("template_length_px", -5),
    ],
)
def test_verify_options_are_checked(field, value):
    VerifyOptions()  # the defaults are valid
    with pytest.raises(ValueError, match=rf"\b{field}="):
        VerifyOptions(**{field: value})


# ---------------------------------------------------------------- support


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("min_confidence", 1.0),
        ("min_confidence", 0.3),
        ("correlation_length_px", 0.5),
        ("min_projected_px", 0.0),
        ("min_pair_share", 0.0),
        ("min_pair_share", 1.5),
        ("min_hit_share", -0.1),
        ("min_hit_share", 1.1),
    ],
)
def test_support_options_are_checked(field, value):
    SupportOptions()  # the defaults are valid
    with pytest.raises(ValueError, match=rf"\b{field}="):
        SupportOptions(**{field: value})


def _fitted(wire_id, truth_wire, across=0.0, down=0.0):
    """A FittedWire on a true wire (2 m clear of its ends), moved ``across`` its plane and
    ``down``; its 100 points are indices 100 wire_id … 100 wire_id + 99."""
    d = truth_wire.direction_xy
    return FittedWire(
        wire_id=wire_id,
        plane_origin_xy=np.asarray(truth_wire.attach_a[:2]) + across * np.array([d[1], -d[0]]),
        plane_direction_xy=d,
        catenary_a=truth_wire.catenary_a_m,
        s0=truth_wire.s0,
        z0=truth_wire.z0 - down,
        s_range=(2.0, truth_wire.length_m - 2.0),
        point_indices=np.arange(100 * wire_id, 100 * wire_id + 100),
        rms_residual=0.0,
    )


def test_support_keeps_true_wires_and_drops_false_ones(small_scene, pairs, truth):
    """Whole-wire support with exact wire masks: the true wires are confirmed on strong
    geometry; a false pairing (a wire 1.5 m across and 2 m below a true one), a duplicate
    of a true wire (explained away by it) and a line on the ground are dropped."""
    n = len(truth)
    true_wires = [_fitted(k, t) for k, t in enumerate(truth)]
    false_pairing = _fitted(n, truth[0], across=1.5, down=2.0)
    duplicate = dataclasses.replace(
        true_wires[0], wire_id=n + 1, point_indices=np.arange(100 * (n + 1), 100 * (n + 2))
    )
    # A straight line 0.5 m above the ground, 20 m beside the line (a road edge): the views
    # see it (it is drawn into the masks) but it is not a wire.
    d = truth[0].direction_xy
    middle = np.mean([t.points(np.array([0.5 * t.length_m]))[0] for t in truth], axis=0)
    origin = middle[:2] + 20.0 * np.array([d[1], -d[0]]) - 50.0 * d
    ground_z = float(small_scene.ground_height((origin + 50.0 * d)[None])[0])
    ground_line = FittedWire(
        wire_id=n + 2,
        plane_origin_xy=origin,
        plane_direction_xy=d,
        catenary_a=1e6,
        s0=50.0,
        z0=ground_z + 0.5,
        s_range=(0.0, 100.0),
        point_indices=np.arange(100 * (n + 2), 100 * (n + 3)),
        rms_residual=0.0,
    )
    wires = [*true_wires, false_pairing, duplicate, ground_line]
    # Pairs 0 and 1 measured every wire but the false pairing, which pair 0 alone produced.
    point_pair = np.zeros(100 * len(wires), np.int32)
    for w in wires:
        if w is not false_pairing:
            point_pair[w.point_indices[50:]] = 1
    pair_centres = np.array([[p.left.center_in_world, p.right.center_in_world] for p in pairs[:2]])

    # Exact wire masks of every view that sees a wire, grown by the verification tolerance,
    # as verification hands them on.
    tolerance = VerifyOptions().tolerance_px
    polylines = [t.polyline(0.005) for t in truth] + [ground_line.polyline(0.005)]
    wire_pixels = []
    for v, view in enumerate(small_scene.images):
        uv = np.concatenate([view.project(pl)[0] for pl in polylines])
        mask = _oracle_mask((view.height, view.width), uv)
        if mask.any():
            near = WireMask(mask, mask.astype(np.float32), 0.0, 1).dilated(tolerance)
            direction = image_wire_direction_deg(view, middle, AZIMUTH)
            wire_pixels.append(ViewWirePixels.pack(v, 0, 0, near, direction))
    assert len(wire_pixels) >= 10

    options = SupportOptions()
    supports = wire_support(
        small_scene,
        wires,
        wire_pixels,
        point_pair,
        pair_centres,
        np.full(len(small_scene.images), 0.95),  # exact masks: the views hit true wires
        VerifyOptions().crossing_offset,
        tolerance,
        options,
    )
    assert [s.wire_id for s in supports] == [w.wire_id for w in wires]
    for s in supports[:n]:
        assert s.confidence is not None and s.confidence > 0.99, s
        assert s.geometry == "strong" and s.crossing_views > 0 and s.advice is None, s
        assert s.hit_rate > 0.95 > 0.2 > s.chance, s
    bad = supports[n]
    assert bad.confidence is not None and bad.confidence < options.min_confidence, bad
    assert bad.geometry == "strong" and bad.hit_rate < 0.2, bad
    # Everything the duplicate lies on is explained by wire 0: nothing confirms it.
    dup = supports[n + 1]
    assert dup.confidence is None or dup.confidence < options.min_confidence, dup
    assert supports[n + 2].confidence > 0.99 and supports[n + 2].height_above_ground < 1.0

    kept, kept_supports = keep_supported(wires, supports, options, min_height=5.0)
    assert [w.wire_id for w in kept] == [w.wire_id for w in true_wires]
    assert [s.wire_id for s in kept_supports] == [w.wire_id for w in true_wires]


@pytest.mark.parametrize(
    ("field", "value"),
    [("probe_candidates", 0), ("probe_pairs", 0), ("probe_views", -1), ("probe_bands", 3)],
)
def test_pairs_options_are_checked(field, value):
    with pytest.raises(ValueError, match=field):
        PairsOptions(**{field: value})


def test_image_directions_ranked_alike_favour_no_image_axis_and_find_a_faint_line():
    """Ranked alike at every angle (the wider look when no direction has wires), plain
    texture shows no direction, the image axes included (rotating by any other angle smooths
    the texture: the top responses alone lift the axes); a faint thin line over it is found."""
    from colmap_powerline.pairs import _image_directions

    rng = np.random.default_rng(3)
    noise = rng.normal(0.0, 1.0, (600, 800)).astype(np.float32)
    texture = 128 + 12 * cv2.GaussianBlur(noise, (0, 0), 1.2) / 0.24
    peaks = _image_directions(texture, PairsOptions(), fair=True)
    assert max(c for _, c in peaks) < 1.1, peaks
    # The top responses alone: the axes come first.
    axes = _image_directions(texture, PairsOptions())
    assert min(abs((a + 45) % 90 - 45) for a, _ in axes[:2]) < 1.0, axes
    line = texture.copy()
    angle = np.deg2rad(63.0)
    t = np.linspace(-400, 400, 4000)
    x = np.round(400 + t * np.cos(angle)).astype(int)
    y = np.round(300 + t * np.sin(angle)).astype(int)
    ok = (x >= 0) & (x < 800) & (y >= 0) & (y < 600)
    line[y[ok], x[ok]] += 12.0  # the texture's sigma
    peaks = _image_directions(line, PairsOptions(), fair=True)
    best = max(peaks, key=lambda p: p[1])
    assert abs(best[0] - 63.0) < 1.5 and best[1] > 1.2, peaks


def test_a_pair_that_cannot_be_rectified_is_skipped_not_fatal(small_scene, corridor, pairs, caplog):
    """A chosen pair whose images cannot be rectified together (here an image paired with
    itself: no baseline) gives no primitives and a warning; the other pairs are used."""
    from colmap_powerline.pipeline import primitives_for_pairs

    good = pairs[0]
    bad = dataclasses.replace(good, right=good.left)
    options = ReconstructionOptions(show_progress=False)
    with caplog.at_level("WARNING", logger="colmap_powerline.pipeline"):
        prims, _ = primitives_for_pairs(small_scene, [bad, good], corridor, options)
    assert [p.pair_index for p in prims] == [0, 1]
    assert len(prims[0]) == 0 and len(prims[1]) > 0
    assert any("pair 0 skipped" in r.getMessage() for r in caplog.records)


def test_a_half_pixel_line_keeps_its_direction_sampled_along_it_not_shrunk_across():
    """The wider look reads full resolution, sampled along each direction (along_step): a
    line half a pixel wide keeps its contrast there; shrunk to 40 % of the width (the first
    look's analysis width) it is averaged into the texture."""
    from colmap_powerline.pairs import _image_directions

    rng = np.random.default_rng(5)
    h, w = 1200, 1600
    noise = rng.normal(0.0, 1.0, (h, w)).astype(np.float32)
    image = 128 + 10 * cv2.GaussianBlur(noise, (0, 0), 1.5) / 0.19
    angle = np.deg2rad(131.0)
    # A wire 0.5 px wide, 20 grey levels darker: area-weighted into the pixels it crosses.
    t = np.linspace(-1100, 1100, 44000)
    x, y = w / 2 + t * np.cos(angle), h / 2 + t * np.sin(angle)
    ok = (x >= 0) & (x < w - 1) & (y >= 0) & (y < h - 1)
    np.add.at(image, (y[ok].astype(int), x[ok].astype(int)), -20.0 * 0.5 / 20)
    step = int(PairsOptions().template_length_frac * w) // 16
    sampled = _image_directions(image, PairsOptions(), 5, True, step)
    best = max(sampled, key=lambda p: p[1])
    assert abs(best[0] - 131.0) < 1.5 and best[1] > 1.2, sampled
    # Sampled along, the contrast is what every row gives.
    full = _image_directions(image, PairsOptions(), 5, True, 1)
    assert max(c for _, c in full) == pytest.approx(best[1], rel=0.1)
    small = cv2.resize(image, (640, 480), interpolation=cv2.INTER_AREA)
    shrunk = _image_directions(small, PairsOptions(), 5, True)
    assert all(abs(a - 131.0) > 1.5 or c < 1.1 for a, c in shrunk), shrunk


def test_a_line_one_image_shows_plainly_outranks_many_images_texture_peaks():
    # Twelve images' peaks at the texture's level (2-8 % over their median direction)
    # around 30 deg, and one image that sees the line at 70 deg plainly (twice its median):
    # what a direction's lines add to their images, not how many images name it, ranks it.
    rng = np.random.default_rng(0)
    texture = np.c_[30.0 + rng.uniform(-1.0, 1.0, 12), rng.uniform(1.02, 1.08, 12)]
    others = np.c_[rng.uniform(100.0, 170.0, 12), rng.uniform(1.0, 1.05, 12)]
    peaks = np.r_[texture, others, [[70.0, 2.0], [69.0, 1.02]]]
    cands = pairs_module._ranked_directions(peaks[:, 0], peaks[:, 1], 2.5, 5)
    assert abs(cands[0][0] - 70.0) < 1.0
    assert abs(cands[1][0] - 30.0) < 1.5
    # The line's azimuth: its peaks' mean weighted by their contrast.
    assert cands[0][0] == pytest.approx((70.0 * 2.0 + 69.0 * 1.02) / 3.02)
