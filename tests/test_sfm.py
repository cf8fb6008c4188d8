"""pycolmap SfM on a synthetic span with EXIF GPS, and its input errors."""

from __future__ import annotations

import json
import logging
import shutil

import numpy as np
import pycolmap
import pytest

from colmap_powerline import InputError
from colmap_powerline.evaluate import evaluate, scene_alignment
from colmap_powerline.georef import GeoreferenceOptions, read_georeference
from colmap_powerline.pipeline import ReconstructionOptions, reconstruct
from colmap_powerline.sfm import Matching, SfmOptions, _camera_groups, run_sfm
from colmap_powerline.synthetic import load_true_wires

# SIFT on images downscaled to 1000 px with 2048 features keeps SfM at ~1.5 min on 2 cores.
FAST = {"max_num_features": 2048, "max_image_size": 1000}


@pytest.fixture(scope="module")
def sfm_medium(medium_span, tmp_path_factory):
    origin = tuple(json.loads(medium_span.truth_wires.read_text())["origin_wgs84"])
    opts = SfmOptions(
        **FAST, georeference=GeoreferenceOptions(origin_wgs84=origin), show_progress=False
    )
    return run_sfm(medium_span.images, tmp_path_factory.mktemp("sfm") / "sparse", opts)


def test_sfm_registers_every_image_and_georeferences(sfm_medium, medium_span):
    sfm_small, small_span = sfm_medium, medium_span
    rec = sfm_small.reconstruction
    assert sfm_small.num_registered == sfm_small.num_images == 32
    assert rec.compute_mean_reprojection_error() < 1.0
    assert rec.num_points3D() > 2000
    assert sfm_small.matching == Matching.SPATIAL  # the images carry GPS
    # One shared OPENCV camera with focal length and principal point found (true: 1139.2 px,
    # (1005.85, 745.85): 12 px off-centre at 12 MP).
    assert len(rec.cameras) == 1
    cam = next(iter(rec.cameras.values()))
    assert cam.model.name == "OPENCV"
    assert cam.mean_focal_length() == pytest.approx(1139.2, rel=0.01)
    assert cam.principal_point_x == pytest.approx(1005.85, abs=2.0)
    assert cam.principal_point_y == pytest.approx(745.85, abs=2.0)
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
        np.linalg.norm(
            aligned.find_image_with_name(im.name).projection_center() - im.projection_center()
        )
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


@pytest.mark.slow  # SfM and a medium-span run: over a minute and a half on 2 cores
def test_pipeline_on_the_sfm_model(sfm_medium, medium_span, tmp_path):
    """The wires from an SfM model (not the true one): every conductor, its sag right.

    SfM on nadir images leaves the focal length 0.3-0.4 % off at this scale (flying height
    and focal length trade off; 0.02 % at 12 MP, where scripts/benchmark.py --sfm measures
    the full targets). Depths are then scaled by that much, so the wires sit 10-15 cm from
    the truth after any similarity: this test checks what survives that — every conductor
    found, each sag within 5 cm, wires within 30 cm, no ghosts.
    """
    model = pycolmap.Reconstruction(sfm_medium.model_path)
    model.transform(scene_alignment(model, pycolmap.Reconstruction(medium_span.sparse_gt)))
    aligned = tmp_path / "aligned"
    aligned.mkdir()
    model.write_binary(aligned)
    result = reconstruct(
        medium_span.images, aligned, tmp_path / "out", ReconstructionOptions(show_progress=False)
    )
    truth = load_true_wires(medium_span.truth_wires)
    # The reported points: those of the confirmed wires (wire_points.ply).
    ev = evaluate(result.verified.pts_in_world[result.labels >= 0], result.wires, truth)
    print(ev.summary_table())
    conductors = [w for w in ev.wires if w.kind == "conductor"]
    # A fitted wire within 30 cm (median) of each conductor, its sag within 5 cm.
    assert all(w.sag_error_m is not None for w in conductors)
    assert max(abs(w.sag_error_m) for w in conductors) < 0.05
    assert max(w.catenary_rms_m for w in conductors) < 0.2
    assert ev.ghost_wires == 0
    assert ev.outlier_share < 0.05
