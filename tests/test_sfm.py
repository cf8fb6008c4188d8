"""pycolmap SfM on a synthetic span with EXIF GPS, and its input errors."""

from __future__ import annotations

import json
import logging
import shutil

import numpy as np
import pycolmap
import pytest

from colmap_powerline import InputError
from colmap_powerline.georef import GeoreferenceOptions, read_georeference
from colmap_powerline.sfm import Matching, SfmOptions, _camera_groups, run_sfm

# Fewer SIFT features than the default keep the test at ~1 min on 2 cores.
FAST = {"max_num_features": 2048}


@pytest.fixture(scope="module")
def sfm_small(small_span, tmp_path_factory):
    origin = tuple(json.loads(small_span.truth_wires.read_text())["origin_wgs84"])
    opts = SfmOptions(
        **FAST, georeference=GeoreferenceOptions(origin_wgs84=origin), show_progress=False
    )
    return run_sfm(small_span.images, tmp_path_factory.mktemp("sfm") / "sparse", opts)


def test_sfm_registers_every_image_and_georeferences(sfm_small, small_span):
    rec = sfm_small.reconstruction
    assert sfm_small.num_registered == sfm_small.num_images == 32
    assert rec.compute_mean_reprojection_error() < 1.0
    assert rec.num_points3D() > 2000
    assert sfm_small.matching == Matching.SPATIAL  # the images carry GPS
    # One shared OPENCV camera, its focal length found (true 569.6 px at this scale).
    assert len(rec.cameras) == 1
    cam = next(iter(rec.cameras.values()))
    assert cam.model.name == "OPENCV"
    assert cam.mean_focal_length() == pytest.approx(569.6, rel=0.01)
    # Georeferenced from EXIF GPS: centres agree with the truth within the GPS noise
    # (σ 1.5 m horizontal, 3 m vertical, averaged over 32 images).
    gt = pycolmap.Reconstruction(small_span.sparse_gt)
    err = np.array(
        [
            rec.find_image_with_name(im.name).projection_center() - im.projection_center()
            for im in gt.images.values()
        ]
    )
    assert np.sqrt(np.mean(np.sum(err[:, :2] ** 2, axis=1))) < 1.5
    assert np.sqrt(np.mean(err[:, 2] ** 2)) < 3.0
    # Relative geometry is much better than the GPS: after a best similarity to the truth
    # the centres agree to centimetres.
    aligned = pycolmap.Reconstruction(sfm_small.model_path)
    sim = pycolmap.align_reconstructions_via_proj_centers(aligned, gt, 1.0)
    aligned.transform(sim)
    rel = [
        np.linalg.norm(aligned.find_image_with_name(im.name).projection_center()
                       - im.projection_center())
        for im in gt.images.values()
    ]
    assert np.median(rel) < 0.05
    # The written model is the same model, with its georeference next to it.
    back = pycolmap.Reconstruction(sfm_small.model_path)
    assert back.num_reg_images() == 32
    assert (sfm_small.model_path / "cameras.bin").is_file()
    georef = read_georeference(sfm_small.model_path)
    assert georef is not None and georef.source == "exif_gps" and georef.num_inliers == 32
    assert "registered 32 / 32 images" in sfm_small.summary()


def test_sfm_input_errors_are_one_line(small_span, tmp_path, caplog):
    with pytest.raises(InputError, match="image folder does not exist"):
        run_sfm(tmp_path / "nowhere", tmp_path / "out")
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="no images"):
        run_sfm(tmp_path / "empty", tmp_path / "out")
    # A folder that holds something else is never overwritten.
    busy = tmp_path / "busy"
    busy.mkdir()
    (busy / "notes.txt").write_text("mine")
    with pytest.raises(InputError, match="holds other files"):
        run_sfm(small_span.images, busy)
    # An undecodable image stops the run before any work, or is skipped on request.
    images = tmp_path / "images"
    shutil.copytree(small_span.images, images)
    (images / "DJI_0004.JPG").write_bytes(b"\xff\xd8 truncated")
    with pytest.raises(InputError, match="DJI_0004.JPG: not a readable image"):
        run_sfm(images, tmp_path / "out2")
    assert not (tmp_path / "out2").exists()
    names = sorted(p.name for p in images.iterdir())
    with caplog.at_level(logging.WARNING):
        groups = _camera_groups(images, names, skip_bad=True)
    assert "DJI_0004.JPG" in caplog.text
    assert list(groups) == [("DJI", "FC330", 1000, 750)]
    assert len(groups["DJI", "FC330", 1000, 750]) == 31
