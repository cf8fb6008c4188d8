"""The scene loader against pycolmap, and the synthetic span against its own truth."""

from __future__ import annotations

import logging
import shutil

import cv2
import numpy as np
import pycolmap
import pytest

from colmap_powerline import InputError, load_scene
from colmap_powerline.scene import read_image, resolve_inputs
from colmap_powerline.synthetic import (
    FlightPattern,
    SyntheticSpanOptions,
    Terrain,
    build_span,
    load_true_wires,
    read_exif_gps,
)


def test_projection_matches_pycolmap(small_span, small_scene):
    rec = pycolmap.Reconstruction(small_span.sparse_gt)
    pts = small_scene.pts_in_world
    for im in small_scene.images[:5]:
        image = rec.image(im.image_id)
        cam = rec.camera(image.camera_id)
        pose = image.cam_from_world()
        pts_in_cam = pts @ pose.rotation.matrix().T + pose.translation
        front = pts_in_cam[:, 2] > 0
        expected = cam.img_from_cam(pts_in_cam[front])
        uv, depth, _ = im.project(pts)
        ok = np.isfinite(uv[front]).all(axis=1)
        assert ok.sum() > 500
        assert np.abs(uv[front][ok] - expected[ok]).max() < 1e-6
        # Pixel → ray → point → pixel.
        rays = im.rays_in_world(uv[front][ok][:100])
        back, _, _ = im.project(im.center_in_world + 37.0 * rays)
        assert np.abs(back - uv[front][ok][:100]).max() < 1e-6


@pytest.mark.parametrize(
    "model,params",
    [
        ("PINHOLE", [500, 505, 320, 240]),
        ("SIMPLE_RADIAL", [500, 320, 240, -0.05]),
        ("RADIAL", [500, 320, 240, -0.05, 0.01]),
        ("OPENCV_FISHEYE", [500, 505, 320, 240, 0.01, -0.01, 0.001, 0.0]),
        ("FULL_OPENCV", [500, 505, 320, 240, -0.05, 0.01, 0.001, -0.001, 0.001, 0, 0, 0]),
    ],
)
def test_any_camera_model_projects_like_pycolmap(tmp_path, model, params):
    rec = pycolmap.Reconstruction()
    cam = pycolmap.Camera(model=model, width=640, height=480, params=params, camera_id=1)
    rec.add_camera_with_trivial_rig(cam)
    img = pycolmap.Image(name="a.jpg", camera_id=1, image_id=1)
    rec.add_image_with_trivial_frame(
        img, pycolmap.Rigid3d(pycolmap.Rotation3d(np.eye(3)), np.array([0.1, -0.2, 3.0]))
    )
    rec.write_text(tmp_path)
    (tmp_path / "images").mkdir()
    (tmp_path / "images" / "a.jpg").write_bytes(b"")
    scene = load_scene(tmp_path, tmp_path / "images", check_images=False)
    rng = np.random.default_rng(0)
    pts = rng.uniform([-1, -1, 1], [1, 1, 3], (50, 3))
    uv, _, _ = scene.images[0].project(pts)
    expected = cam.img_from_cam(pts + [0.1, -0.2, 3.0])
    assert np.nanmax(np.abs(uv - expected)) < 1e-6


def test_binary_and_text_models_agree(small_span, tmp_path):
    pycolmap.Reconstruction(small_span.sparse_gt).write_text(tmp_path)
    a = load_scene(small_span.sparse_gt, small_span.images)
    b = load_scene(tmp_path, small_span.images)
    assert [im.name for im in a.images] == [im.name for im in b.images]
    np.testing.assert_allclose(a.centers_in_world, b.centers_in_world, atol=1e-9)
    np.testing.assert_allclose(
        np.sort(a.pts_in_world, axis=0), np.sort(b.pts_in_world, axis=0), atol=1e-9
    )


def test_ground_height_and_helpers(small_span, small_scene):
    terrain = Terrain.load(small_span.terrain)
    rng = np.random.default_rng(0)
    xy = rng.uniform(-40, 40, (300, 2))
    err = small_scene.ground_height(xy) - terrain.height(xy)
    assert np.median(np.abs(err)) < 0.3  # tower points are ignored; measured ≈ 0.05 m
    im = small_scene.images[0]
    assert im.gsd_at_depth(50.0) == pytest.approx(50.0 / im.focal_px)
    wire = load_true_wires(small_span.truth_wires)[0]
    mid = wire.points(np.array([wire.length_m / 2]))[0]
    seeing = {v.name for v in small_scene.images_seeing(mid)}
    expected = {v.name for v in small_scene.images if v.project(mid[None])[2][0]}
    assert seeing == expected and len(seeing) >= 3
    assert small_scene.visibility(np.zeros((4, 3))).shape == (len(small_scene), 4)


def test_bad_models_give_one_line_errors(small_span, tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        load_scene(tmp_path / "missing", small_span.images)
    with pytest.raises(InputError, match="not a COLMAP model"):
        load_scene(tmp_path, small_span.images)
    broken = tmp_path / "broken"
    shutil.copytree(small_span.sparse_gt, broken)
    (broken / "cameras.bin").write_bytes((broken / "cameras.bin").read_bytes()[:10])
    with pytest.raises(InputError, match="camera 1 is invalid"):
        load_scene(broken, small_span.images)
    images = tmp_path / "images"
    shutil.copytree(small_span.images, images)
    (images / "DJI_0005.JPG").unlink()
    with pytest.raises(InputError, match="DJI_0005.JPG: image named by .* is missing on disk"):
        load_scene(small_span.sparse_gt, images)
    empty = tmp_path / "empty"
    empty.mkdir()
    rec = pycolmap.Reconstruction()
    rec.add_camera_with_trivial_rig(
        pycolmap.Camera(model="PINHOLE", width=10, height=10, params=[5, 5, 5, 5], camera_id=1)
    )
    rec.write_binary(empty)
    with pytest.raises(InputError, match="no registered images"):
        load_scene(empty, images)


def test_bad_images_stop_or_are_skipped(small_span, tmp_path, caplog):
    images = tmp_path / "images"
    shutil.copytree(small_span.images, images)
    (images / "DJI_0007.JPG").write_bytes(b"not a jpeg")
    (images / "DJI_0009.JPG").unlink()
    with pytest.raises(InputError, match="DJI_0007.JPG: image named by .* not a readable image"):
        load_scene(small_span.sparse_gt, images)
    with caplog.at_level(logging.WARNING):
        scene = load_scene(small_span.sparse_gt, images, skip_bad_images=True)
    assert len(scene) == 30
    assert "DJI_0007.JPG" in caplog.text and "DJI_0009.JPG" in caplog.text
    with pytest.raises(InputError, match=r"DJI_0007.JPG: cannot decode the image"):
        read_image(images / "DJI_0007.JPG")


def test_image_names_with_subfolders_and_undistorted_workspace(small_span, tmp_path):
    # A model whose images live in sub-folders (one per flight strip), named as such.
    rec = pycolmap.Reconstruction(small_span.sparse_gt)
    images = tmp_path / "images"
    for im in rec.images.values():
        sub = f"strip{(int(im.name[4:8]) - 1) // 8}/{im.name}"
        (images / sub).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(small_span.images / im.name, images / sub)
        im.name = sub
    model = tmp_path / "sparse"
    model.mkdir()
    rec.write_text(model)
    scene = load_scene(model, images)
    assert len(scene) == 32 and scene.image("strip3/DJI_0032.JPG").path.is_file()
    # COLMAP's image_undistorter layout: dense/{images,sparse}; images/ is found alone.
    dense = tmp_path / "dense"
    (dense / "sparse").mkdir(parents=True)
    rec.write_binary(dense / "sparse")
    (dense / "images").symlink_to(images)
    assert resolve_inputs(None, dense) == (dense / "sparse", dense / "images")
    assert resolve_inputs(images, model) == (model, images)
    with pytest.raises(InputError, match="--image_path is needed"):
        resolve_inputs(None, model)


def test_true_wires_land_on_bright_rendered_pixels(small_span, small_scene):
    """Profile across each conductor, averaged along it: a clear peak at offset 0."""
    wires = load_true_wires(small_span.truth_wires)
    offsets = np.arange(-4, 5)
    profile = np.zeros(len(offsets))
    for view in small_scene.images[8:16]:
        gray = cv2.imread(str(view.path), cv2.IMREAD_GRAYSCALE).astype(np.float32)
        for w in wires:
            if w.kind != "conductor":
                continue
            uv, _, ok = view.project(w.points(np.arange(3, w.length_m - 3, 0.2)))
            ok[:-1] &= ok[1:]
            if ok.sum() < 20:
                continue
            t = np.gradient(uv, axis=0)[ok]
            t /= np.linalg.norm(t, axis=1, keepdims=True)
            n = np.c_[-t[:, 1], t[:, 0]]
            for k, o in enumerate(offsets):
                p = (uv[ok] + o * n - 0.5).astype(np.float32)
                profile[k] += cv2.remap(gray, p[:, 0:1], p[:, 1:2], cv2.INTER_LINEAR).mean()
    profile /= profile.mean()
    assert int(np.argmax(profile)) == 4  # the peak is on the true wire
    contrast = profile[4] - profile[[0, 1, 7, 8]].mean()
    assert contrast > 0.02  # measured ≈ 0.06 of the mean grey level at 0.35 px wire width
    assert profile[0] < profile[4] and profile[8] < profile[4]


def test_exif_gps_and_model_noise(small_span, small_scene):
    import json

    origin = json.loads(small_span.truth_wires.read_text())["origin_wgs84"]
    gps = pycolmap.GPSTransform(pycolmap.GPSTransformEllipsoid.WGS84)
    lla = np.array([read_exif_gps(im.path) for im in small_scene.images])
    enu = gps.ellipsoid_to_enu(lla, *origin)
    err = enu - small_scene.centers_in_world
    rms_h = np.sqrt(np.mean(np.sum(err[:, :2] ** 2, axis=1) / 2))
    assert 0.5 < rms_h < 3.0  # simulated σ 1.5 m per axis
    assert np.abs(err[:, 2]).max() < 4 * 3.0
    perturbed = load_scene(small_span.sparse, small_span.images)
    moved = np.linalg.norm(perturbed.centers_in_world - small_scene.centers_in_world, axis=1)
    assert 0.001 < np.median(moved) < 0.1
    rec = pycolmap.Reconstruction(small_span.sparse)
    assert 0.05 < rec.compute_mean_reprojection_error() < 1.0
    assert pycolmap.Reconstruction(small_span.sparse_gt).compute_mean_reprojection_error() < 1e-3


def test_truth_is_self_consistent_and_deterministic():
    a = build_span(SyntheticSpanOptions(scale=0.05, show_progress=False))
    b = build_span(SyntheticSpanOptions(scale=0.05, show_progress=False))
    c = build_span(SyntheticSpanOptions(scale=0.05, seed=1, show_progress=False))
    assert [w.to_json() for w in a.wires] == [w.to_json() for w in b.wires]
    assert [w.catenary_a_m for w in a.wires] != [w.catenary_a_m for w in c.wires]
    for w in a.wires:
        assert w.z_at(0.0) == pytest.approx(w.attach_a[2], abs=1e-9)
        assert w.z_at(w.length_m) == pytest.approx(w.attach_b[2], abs=1e-9)
        level = (w.attach_a[2] - w.attach_b[2]) == 0
        if level:
            assert w.sag_m() == pytest.approx(w.length_m**2 / (8 * w.catenary_a_m), rel=0.01)
    assert len(a.wires) == 8 and sum(w.kind == "shield" for w in a.wires) == 2
    assert len(a.views) == len(b.views) > 10


def _strip_coverage(span) -> tuple[np.ndarray, np.ndarray]:
    """(strips,) angle (deg) between each strip and the line, and (strips, wires) the share
    of each true wire's length (2 m clear of the towers) inside the images of each strip."""
    strips = np.array(span.strips)
    az = np.deg2rad(span.options.line_azimuth_deg)
    along = np.array([np.sin(az), np.cos(az)])
    angles, cover = [], []
    for k in range(strips.max() + 1):
        views = [v for v, s in zip(span.views, strips, strict=True) if s == k]
        c = np.array([v.center_in_world[:2] for v in views])
        direction = np.linalg.svd(c - c.mean(axis=0))[2][0]  # the strip's main axis
        angles.append(np.degrees(np.arccos(min(abs(direction @ along), 1.0))))
        row = []
        for w in span.wires:
            pts = w.points(np.arange(2.0, w.length_m - 2.0, 0.5))
            seen = np.zeros(len(pts), bool)
            for v in views:
                seen |= v.project(pts)[2]
            row.append(seen.mean())
        cover.append(row)
    return np.array(angles), np.array(cover)


@pytest.mark.parametrize(
    "flight,num_strips,num_images,angle_deg",
    [
        (FlightPattern.CORRIDOR, 3, 24, 0.0),
        (FlightPattern.ALONG4, 4, 32, 0.0),
        (FlightPattern.GRID, 5, 50, 35.0),
        (FlightPattern.ACROSS, 4, 32, 90.0),
    ],
)
def test_flight_patterns(flight, num_strips, num_images, angle_deg):
    """Geometry only (no image rendered): strips, their direction, who sees the wires."""
    opts = SyntheticSpanOptions(scale=0.05, flight=flight, show_progress=False)
    span = build_span(opts)
    assert len(span.views) == num_images and len(span.strips) == num_images
    angles, cover = _strip_coverage(span)
    assert len(angles) == num_strips
    np.testing.assert_allclose(angles, angle_deg, atol=1.0)
    conductor = np.array([w.kind == "conductor" for w in span.wires])
    seen = cover >= 0.25  # a quarter of the wire inside the strip's images at least
    if flight is FlightPattern.CORRIDOR:
        # The middle strip sees every wire whole; the outer strips (65 % side overlap on
        # the ground, far less at wire height) see the near conductors only, and the
        # shield wires — highest, so with the smallest footprint — not at all.
        assert (cover[1] > 0.99).all()
        assert (seen[:, conductor].sum(axis=0) >= 2).all()
        assert (cover[[0, 2]][:, ~conductor] == 0).all()
    elif flight is FlightPattern.ALONG4:
        # The line runs between the two middle strips: both see every wire whole.
        assert (cover[[1, 2]] > 0.99).all()
        assert (cover[[0, 3]] < 0.25).all()
    elif flight is FlightPattern.GRID:
        # The strip over the line sees every wire whole, its two neighbours a part each.
        assert (cover[num_strips // 2] > 0.99).all()
        assert (seen.sum(axis=0) >= 3).all()
    else:
        # Every strip crosses the line; the two middle ones see most of every wire.
        assert (seen.sum(axis=0) >= 2).all()
    again = build_span(opts)
    np.testing.assert_array_equal(
        [v.center_in_world for v in span.views], [v.center_in_world for v in again.views]
    )


def test_grid_angle_and_along_alias():
    span = build_span(
        SyntheticSpanOptions(scale=0.05, flight="grid", grid_angle_deg=60.0, show_progress=False)
    )
    angles, _ = _strip_coverage(span)
    np.testing.assert_allclose(angles, 60.0, atol=1.0)
    with pytest.warns(DeprecationWarning, match="corridor"):
        assert FlightPattern("along") is FlightPattern.CORRIDOR
    assert SyntheticSpanOptions(flight="along4").flight_side_overlap == 0.68
    assert SyntheticSpanOptions(flight="along4", side_overlap=0.7).flight_side_overlap == 0.7
